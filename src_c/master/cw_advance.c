/* The communication step (clockwork/engine/master.py's Master.advance,
 * checkpoints.py, coupling.iterate_step): the instances stepped (advance,
 * also at once on the pool), the indicators read at the step's ends,
 * checkpoints, rollback and replay, and the strongly coupled step
 * (iterate_step). Event location (cw_events.c) and the loop (cw_step.c)
 * call these; they call neither.
 */

#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "cw_master.h"

/* The run diverged: the outputs' absolute sum past master.divergence_limit, or NaN
 * (the loop's step and cw_rates.c's base step both ask). */
int diverged(const cw_master *m)
{
    double s = 0.0;
    for (int i = 0; i < m->n_buffer; i++)
        s += fabs(m->buffer[i]);
    return !(s < m->divergence_limit);  /* NaN fails too */
}


/* The indicators' values, from the outputs last read, into z. */
void indicators(cw_master *m, double *z)
{
    for (int k = 0; k < m->n_z; k++)
        z[k] = m->ports[m->z_port[k]].out[m->z_pos[k]];
}

/* -- instances stepped at once (master.threads, cw_pool.c) ------------------- */

typedef struct {
    cw_master *m;
    const int *ports;
    double t, h;
    int first;  /* feedthrough-only instances (advance's part 1), else dynamic ones */
    int no_set_prior;  /* noSetFMUStatePriorToCurrentPoint, as advance passes it */
} par_job;

/* One instance of a par_step, on whichever thread takes it: what advance
 * does for it, the statuses kept for the checks in order afterwards. */
static void par_item(void *ctx, int a)
{
    const par_job *job = ctx;
    cw_master *m = job->m;
    cw_port *p = &m->ports[job->ports[a]];
    int *st = &m->par_status[2 * a];
    st[0] = p->doStep(p->comp, job->t, job->h, job->no_set_prior);
    st[1] = FMI_OK;
    if (st[0] > FMI_WARNING)
        return;
    if (job->first) {
        if (p->n_z && m->after_event)
            p->getReal(p->comp, p->out_vr, (size_t)p->n_out, p->out);
        return;
    }
    double t_new = job->t + job->h;
    if (p->n_out)
        st[1] = p->getReal(p->comp, p->out_vr, (size_t)p->n_out, p->out);
    if (st[1] <= FMI_WARNING)
        p->out_time = t_new;
}

/* ports[0..n) step from t by h at once, then are checked in their order:
 * the first failure is the one the serial loop would meet. */
static int par_step(cw_master *m, const int *ports, int n, double t, double h, int first, int no_set_prior)
{
    par_job job = {m, ports, t, h, first, no_set_prior};
    cw_pool_run(m->pool, n, par_item, &job);
    for (int a = 0; a < n; a++) {
        const int *st = &m->par_status[2 * a];
        if (st[0] > FMI_WARNING)
            return fail(m, ports[a], CALL_DO_STEP, st[0], t, h);
        if (st[1] > FMI_WARNING)
            return fail(m, ports[a], CALL_GET_REAL, st[1], t + h, 0.0);
    }
    return 0;
}

/* dynamic[a..e), which depend on none of each other within the step: their
 * inputs set in order (Gauss-Seidel; Jacobi's are set already), then they
 * step at once. A refused input stops there, after the ones before it. */
static int par_group(cw_master *m, int a, int e, double t, double h, int smooth, int no_set_prior)
{
    int set = e, rc = 0;
    if (!m->jacobi)
        for (int b = a; b < e && set == e; b++)
            if (m->ports[m->dynamic[b]].n_in && (rc = set_inputs(m, m->dynamic[b], t, h, smooth)) < 0)
                set = b;
    if (set > a)
        TRY(par_step(m, m->dynamic + a, set - a, t, h, 0, no_set_prior));
    return rc;
}

/* -- the communication step (Master.advance) --------------------------------- */

static int advance_coupled(cw_master *m, double t, double h, int coupled)
{
    double t_new = t + h;
    /* noSetFMUStatePriorToCurrentPoint: true only while no checkpoint is
     * held that a rollback or replay may set again (Checkpoints.held). */
    const int no_set_prior = !m->snap_valid;
    /* Sampled inputs at t, after an event there. */
    if (m->inputs)
        for (int i = 0; i < m->n_ports; i++)
            TRY(inputs_set(m, i, t, 1));
    /* 1. Feedthrough-only instances commit the mode decided at t. */
    if (m->pool && m->n_first > 1)
        TRY(par_step(m, m->first, m->n_first, t, h, 1, no_set_prior));
    else
    for (int a = 0; a < m->n_first; a++) {
        cw_port *p = &m->ports[m->first[a]];
        int st = p->doStep(p->comp, t, h, no_set_prior);
        if (st > FMI_WARNING)
            return fail(m, m->first[a], CALL_DO_STEP, st, t, h);
        if (p->n_z && m->after_event)  /* a commit may have switched the mode: z at t+ */
            p->getReal(p->comp, p->out_vr, (size_t)p->n_out, p->out);
    }
    if (m->inputs)  /* their outputs are next read at t + h: sampled inputs there, before an event */
        for (int a = 0; a < m->n_first; a++)
            TRY(inputs_set(m, m->first[a], t_new, 0));
    if (m->locating) {
        if (m->after_event)
            indicators(m, m->z_start);
        else
            memcpy(m->z_start, m->z_end, (size_t)m->n_z * sizeof(double));
    }
    /* 2. Dynamic instances step, their inputs set by the coupling. */
    int smooth = !m->after_event;
    if (m->jacobi)
        for (int a = 0; a < m->n_dynamic; a++)
            if (m->ports[m->dynamic[a]].n_in)
                TRY(coupled ? set_coupled_inputs(m, m->dynamic[a], t, h) : set_inputs(m, m->dynamic[a], t, h, smooth));
    for (int a = 0; a < m->n_dynamic; a++) {
        /* A strongly coupled step sets each input from its iterate's line:
         * one after the other (par_group sets the plain coupling's). */
        int e = m->pool && !coupled ? m->par_end[a] : a + 1;
        if (e > a + 1) {  /* instances independent within the step, stepped at once */
            TRY(par_group(m, a, e, t, h, smooth, no_set_prior));
            a = e - 1;
            if (!m->jacobi && e != m->n_dynamic)
                TRY(propagate(m, m->first_in_order, m->n_first_in_order, t_new));
            continue;
        }
        int i = m->dynamic[a];
        cw_port *p = &m->ports[i];
        if (!m->jacobi && p->n_in)
            TRY(coupled ? set_coupled_inputs(m, i, t, h) : set_inputs(m, i, t, h, smooth));
        int st = p->doStep(p->comp, t, h, no_set_prior);
        if (st > FMI_WARNING)
            return fail(m, i, CALL_DO_STEP, st, t, h);
        if (m->inputs && m->inputs->after_step[i])
            TRY(inputs_set(m, i, t_new, 0));
        TRY(port_read(m, i, t_new));
        if (!m->jacobi && a != m->n_dynamic - 1)  /* newest values flow on, where they reach */
            TRY(propagate(m, m->after_order + m->after_start[a], m->after_start[a + 1] - m->after_start[a],
                          t_new));
    }
    /* 3. Outputs at t + h, in dependency order. */
    m->t = t_new;
    TRY(propagate(m, m->final_order, m->n_final, t_new));
    if (m->locating)
        indicators(m, m->z_end);
    return 0;
}

int advance(cw_master *m, double t, double h)
{
    return advance_coupled(m, t, h, 0);
}

/* -- checkpoints ------------------------------------------------------------- */

/* The input history into the checkpoint (save) or back from it. */
static void copy_history(cw_master *m, int save)
{
    for (int a = 0; a < m->n_dynamic; a++) {
        cw_port *p = &m->ports[m->dynamic[a]];
        int n = save ? p->hist_n : p->snap_hist_n;
        size_t nt = (size_t)n * sizeof(double), nv = (size_t)(n * p->n_in) * sizeof(double);
        if (save) {
            memcpy(p->snap_hist_t, p->hist_t, nt);
            memcpy(p->snap_hist_v, p->hist_v, nv);
            p->snap_hist_n = n;
        } else {
            memcpy(p->hist_t, p->snap_hist_t, nt);
            memcpy(p->hist_v, p->snap_hist_v, nv);
            p->hist_n = n;
        }
    }
}

int checkpoint_mark(cw_master *m)
{
    for (int i = 0; i < m->n_ports; i++) {
        cw_port *p = &m->ports[i];
        int st = p->getState(p->comp, p->state);
        if (st > FMI_WARNING)
            return fail(m, i, CALL_GET_STATE, st, m->t, 0.0);
    }
    m->states_saved++;
    memcpy(m->snap_z_end, m->z_end, (size_t)m->n_z * sizeof(double));
    m->snap_t = m->t;
    copy_history(m, 1);
    m->snap_after_event = m->after_event;
    m->snap_time_to_zero = m->time_to_zero;
    m->snap_valid = 1;
    return 0;
}

int checkpoint_take(cw_master *m)
{
    TRY(checkpoint_mark(m));
    m->n_since = 0;
    return 0;
}

static int restore_states(cw_master *m)
{
    for (int i = 0; i < m->n_ports; i++) {
        cw_port *p = &m->ports[i];
        int st = p->setState(p->comp, *p->state);
        if (st > FMI_WARNING)
            return fail(m, i, CALL_SET_STATE, st, m->t, 0.0);
        p->sent_valid = 0;
    }
    for (int k = 0; k < m->n_z; k++)
        m->end_rate_set[k] = 0;
    m->rollbacks++;
    return 0;
}

static int restore_soft_state(cw_master *m)
{
    memcpy(m->z_end, m->snap_z_end, (size_t)m->n_z * sizeof(double));
    m->t = m->snap_t;
    copy_history(m, 0);
    m->after_event = m->snap_after_event;
    m->time_to_zero = m->snap_time_to_zero;
    /* The FMU states hold their inputs; only the cached outputs are stale. */
    for (int i = 0; i < m->n_ports; i++)
        TRY(port_read(m, i, m->t));
    return 0;
}

int rollback(cw_master *m)
{
    TRY(restore_states(m));
    return restore_soft_state(m);
}

int since_append(cw_master *m, double h)
{
    if (m->n_since >= m->cap_since)
        return CW_ERR_CAPACITY;
    m->since[m->n_since++] = h;
    return 0;
}

/* An event in a step predicted free of them: back to the checkpoint, redo
 * the steps since then, and take a checkpoint at t. */
int replay_to(cw_master *m, double t)
{
    m->replays++;
    if (!m->snap_valid) {
        m->err_t = t;
        return CW_ERR_NO_CHECKPOINT;
    }
    TRY(restore_states(m));
    int n = m->n_since;
    TRY(restore_soft_state(m));
    for (int a = 0; a < n; a++) {
        TRY(advance(m, m->t, m->since[a]));
        record_history(m);
    }
    if (fabs(m->t - t) > 1e-9 * py_max(1.0, fabs(t))) {
        m->err_t = t;
        m->err_h = m->t;
        return CW_ERR_REPLAY;
    }
    m->t = t;
    return checkpoint_take(m);
}

/* -- strong coupling (coupling.iterate_step) ------------------------------------------ */

/* The sources' values of every dynamic instance's inputs, into it_start or it_end. */
static void coupling_sources(cw_master *m, int end)
{
    for (int a = 0; a < m->n_dynamic; a++) {
        cw_port *p = &m->ports[m->dynamic[a]];
        double *to = end ? p->it_end : p->it_start;
        for (int k = 0; k < p->n_in; k++)
            to[k] = m->ports[p->src_port[k]].out[p->src_pos[k]];
    }
}

/* The step from t (a checkpoint) repeated with the dynamic instances'
 * inputs interpolated between the step's start and the last iterate's end,
 * until they reach a fixed point or the iteration budget is spent. */
int iterate_step(cw_master *m, double t, double h)
{
    coupling_sources(m, 0);
    TRY(advance(m, t, h));
    for (int it = 0; it < m->iterations; it++) {
        coupling_sources(m, 1);
        TRY(rollback(m));
        TRY(advance_coupled(m, t, h, 1));
        m->coupling_iterations++;
        double change = 0.0;
        int first = 1;  /* Python's max(): the first value, then any larger */
        for (int a = 0; a < m->n_dynamic; a++) {
            cw_port *p = &m->ports[m->dynamic[a]];
            for (int k = 0; k < p->n_in; k++) {
                double d = fabs(m->ports[p->src_port[k]].out[p->src_pos[k]] - p->it_end[k]);
                if (first || d > change) {
                    change = d;
                    first = 0;
                }
            }
        }
        if (change <= m->iteration_tolerance)
            break;
    }
    return 0;
}
