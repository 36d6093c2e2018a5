/* The compiled stepping core of the co-simulation master: the loop.
 *
 * The same algorithm as clockwork/engine/master.py (with coupling.py,
 * location.py, events.py, checkpoints.py and recording.py), operation for
 * operation, so that the two paths give the same bits: the Python master is
 * the readable reference, this is its fast twin. Every FMU is called
 * through the fmi2-shaped function pointers of its port (cw_port): fmpy's
 * fmi2 functions for an FMI 2.0 Co-Simulation FMU, so any such FMU works,
 * not only ours, and the adapters' for the others (cw_cs3.c, cw_cs1.c,
 * cw_me.c), chosen once by Python, so that the loop never asks which
 * version an FMU is.
 *
 * Python owns every array (ctypes), fills the structs (cw_structs.h) and
 * calls cw_step or cw_run_until. Python floats are IEEE doubles and the
 * core is built with -ffp-contract=off, so each expression here is
 * evaluated as in Python when written in the same order; py_min/py_max
 * keep Python's min()/max() (the first argument wins ties and NaN
 * comparisons).
 *
 * Not covered (the Python master serves it): step doubling
 * (master.richardson). Algebraic loops are solved in the steps as
 * loops.py solves them (cw_loops.c); their start in Initialization Mode
 * is Python's.
 *
 * Here: the instances stepped (advance, also at once on the pool),
 * checkpoints, rollback and replay, strong coupling, the accurate step
 * (step) and the entry points that run it (cw_step, cw_run_until, ...).
 */

#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "cw_master.h"

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

static int checkpoint_take(cw_master *m)
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
static int iterate_step(cw_master *m, double t, double h)
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

/* -- the accurate step (Master.step) ------------------------------------------------ */

int diverged(const cw_master *m)
{
    double s = 0.0;
    for (int i = 0; i < m->n_buffer; i++)
        s += fabs(m->buffer[i]);
    return !(s < m->divergence_limit);  /* NaN fails too */
}
/* Something changed outside the wiring (Master.discontinuity). */
static void discontinuity(cw_master *m)
{
    m->after_event = 1;
    m->time_to_zero = 0.0;
    history_forget(m);
    record_history(m);
}

static int step(cw_master *m, double h, double *taken_out)
{
    if (m->rates)  /* components at their own steps: whole base steps (cw_rates.c) */
        return rates_step(m, h, taken_out);
    double t = m->t;
    /* 0. An instance that asked to end the simulation ends it here; its
     * announced time event caps the step. */
    for (int i = 0; i < m->n_announcers; i++)
        if (cw_asked_to_end(m->announcers[i]))
            return CW_ENDED;
    for (int i = 0; i < m->n_announcers; i++) {
        double te = cw_announced_event_time(m->announcers[i]);
        if (t < te && te < t + h)
            h = te - t;
    }
    /* A sampled input's event is a discontinuity at the step's start and
     * ends a step that would pass it. */
    if (m->inputs) {
        if (inputs_event_at(m->inputs, t))
            discontinuity(m);
        double te = inputs_next_event(m->inputs, t);
        if (t + h > te && !cw_isclose(t + h, te))
            h = te - t;
    }
    /* 1. The indicators' sources cap the step. */
    if (m->has_sources) {
        if (!m->prev_valid)
            h *= 1.0 / 64;  /* no time scale known yet: a short first step */
        else if (h > m->step_cap)
            h = m->step_cap;
    }
    m->after_event_step = 0;
    /* 2. A checkpoint where the step may need a rollback. */
    int locating = m->locating;
    int near = locating && (m->after_event || m->time_to_zero <= 4.0 * h);
    int predicted = PLAN_NONE;
    if (m->predicting) {
        if (m->after_event || m->time_to_zero <= 16.0 * h)
            sample_sources(m, t);
        if (near && !m->after_event) {
            double planned;
            predicted = plan(m, t, h, &planned);
            if (predicted)
                h = planned;
        }
    }
    int possible = (near && !predicted) || (locating && m->n_since >= m->max_replay_steps);
    if (near && m->stale_sources) {
        remember_sources(m);  /* the hidden-crossing check needs them at the step start */
        m->stale_sources = 0;
    }
    if (possible || m->iterations)
        TRY(checkpoint_take(m));
    /* 3. The step; one that lands past a predicted crossing plainly, as
     * locate takes its trials. */
    if (!m->iterations || predicted == PLAN_LAND)
        TRY(advance(m, t, h));
    else
        TRY(iterate_step(m, t, h));
    double taken = h;
    /* 4. Events. */
    if (locating) {
        TRY(land_on_events(m, t, h, near && !predicted, possible || m->iterations, predicted, &taken));
        m->last_valid = !m->after_event_step;
        if (m->last_valid) {
            m->last_t = t;
            memcpy(m->last_z, m->z_start, (size_t)m->n_z * sizeof(double));
        }
    }
    if (m->has_sources) {
        m->sample_countdown--;
        if (near || m->sample_countdown <= 0 || !m->prev_valid) {
            remember_sources(m);
            m->sample_countdown = 16;
            m->stale_sources = 0;
        } else {
            m->stale_sources = 1;
        }
    }
    m->after_event = m->after_event_step;
    m->steps++;
    /* 5. NaN, infinities, divergence: Python names the output (err_t: the
     * last good communication point, the step's start). */
    m->diverged = diverged(m);
    if (m->diverged)
        m->err_t = t;
    if (m->extrapolation)
        record_history(m);
    *taken_out = taken;
    return m->diverged ? CW_CHECK_DIVERGENCE : CW_DONE;
}

/* -- the entry points ------------------------------------------------------------------ */

CW_EXPORT int cw_step(cw_master *m, double h, double *taken)
{
    return step(m, h, taken);
}

/* The master's soft state at a new start (after initialization): the
 * history and the checkpoint forgotten, the indicators read, the sources
 * sampled. */
CW_EXPORT void cw_start(cw_master *m)
{
    history_forget(m);
    m->snap_valid = 0;
    m->n_since = 0;
    m->after_event = 1;
    m->prev_valid = 0;
    for (int k = 0; k < m->n_z; k++) {
        m->amp_u[k] = 0.0;
        m->amp_du[k] = 0.0;
        m->z_seen[k] = NAN;
        m->end_rate_set[k] = 0;
    }
    m->step_cap = INFINITY;
    m->stale_sources = 0;
    m->sampled_t = m->sampled_before_t = NAN;
    m->last_valid = 0;
    /* As in Python: the time to the next zero and the sampling countdown
     * carry over a reset; after_event makes the next step check anyway. */
    record_history(m);
    indicators(m, m->z_end);
    if (m->rates)
        rates_start(m);
    if (m->has_sources) {
        remember_sources(m);
        if (m->step_cap == INFINITY)
            m->prev_valid = 0;
    }
}

/* Something changed outside the wiring (Master.discontinuity). */
CW_EXPORT void cw_discontinuity(cw_master *m)
{
    discontinuity(m);
}

/* Long runs return to Python after `slice_s` of wall time (Python passes
 * 0.05 s), so that a signal (Ctrl-C, SIGTERM) is handled within a fraction
 * of a second rather than when a run of minutes ends. The clock is read
 * every CW_SLICE_STEPS steps only (a vDSO call, ~20 ns, against a step's
 * microseconds); the caller continues where the call stopped, so the bits
 * do not change. */
#define CW_SLICE_STEPS 16u

static int slice_over(const struct timespec *began, unsigned *steps, double slice_s)
{
    if (++*steps % CW_SLICE_STEPS)
        return 0;
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    return (double)(now.tv_sec - began->tv_sec) + 1e-9 * (double)(now.tv_nsec - began->tv_nsec) >= slice_s;
}

/* Step to t_stop on the grid start + k * step, plus located events
 * (Master.run_until), recording into r when given. Returns CW_BUFFER_FULL,
 * CW_SLICE_OVER or CW_CHECK_DIVERGENCE to be called again, r->grid_k keeping
 * the place. */
CW_EXPORT int cw_run_until(cw_master *m, double t_stop, cw_recorder *r, double slice_s)
{
    double h_nom = m->step, t0 = m->start_time;
    double eps = 1e-12 * py_max(1.0, fabs(t_stop));
    long long k = r && r->grid_k >= 0 ? r->grid_k : (long long)floor((m->t - t0) / h_nom + 1e-9) + 1;
    struct timespec began;
    clock_gettime(CLOCK_MONOTONIC, &began);
    unsigned steps = 0;
    while (m->t < t_stop - eps) {
        if (r && (r->n_rows >= r->capacity || r->n_ticks >= r->tick_capacity)) {
            r->grid_k = k;
            return CW_BUFFER_FULL;
        }
        if (r && slice_over(&began, &steps, slice_s)) {
            r->grid_k = k;
            return CW_SLICE_OVER;
        }
        double grid = t0 + (double)k * h_nom;
        if (grid > t_stop)
            grid = t_stop;
        double h = grid - m->t;
        if (h <= eps) {
            k++;
            continue;
        }
        double taken;
        int rc = step(m, h, &taken);
        if (rc < 0 || rc == CW_ENDED)
            return rc;
        if (m->t >= grid - eps)
            k++;
        if (rc == CW_CHECK_DIVERGENCE) {
            /* Not recorded yet: a failed run keeps the points before this
             * one only; where Python finds every output legal, it records
             * the point (cw_record_point) and calls again. */
            if (r)
                r->grid_k = k;
            return rc;
        }
        if (r)
            record_point(m, r);
    }
    if (r)
        r->grid_k = -1;
    return CW_DONE;
}

/* A row of a run to marks: (t, outputs, the outputs before the last step). */
static void marks_row(const cw_master *m, cw_marks *k)
{
    double *row = &k->rows[(size_t)k->n_rows * (size_t)(1 + k->n_out + k->n_prev)];
    row[0] = m->t;
    for (int j = 0; j < k->n_out; j++)
        row[1 + j] = m->ports[k->out_port[j]].out[k->out_pos[j]];
    for (int j = 0; j < k->n_prev; j++)
        row[1 + k->n_out + j] = k->previous[j];
    k->n_rows++;
}

/* What mark i does: give the inputs their value, or record a row. */
static int marks_act(cw_master *m, cw_marks *k, int i)
{
    if (k->sets[i]) {
        for (int a = 0; a < k->n_in; a++) {
            cw_port *p = &m->ports[k->in_port[a]];
            int st = p->setReal(p->comp, &k->in_vr[a], 1, &k->values[i]);
            if (st > FMI_WARNING)
                return fail(m, k->in_port[a], CALL_SET_INPUTS, st, m->t, 0.0);
        }
    } else if (k->record) {
        marks_row(m, k);
    }
    return CW_DONE;
}

/* Step toward t_stop through the marks (Master.run_marks, the same loop
 * line for line): a point on each mark (reached once less than the
 * tolerance ahead, or by a step aimed at it and taken whole), steps of at
 * most max_step, of margin once no mark lies ahead; a row where a watched
 * output changed, the followed event moving the mark. Returns CW_DONE,
 * CW_WATCHED (stop_at_change), CW_BUFFER_FULL or CW_SLICE_OVER (call
 * again), or a step's code (CW_CHECK_DIVERGENCE after the point's rows:
 * Python names the output, and `stopped` says whether the run stopped there). */
CW_EXPORT int cw_run_marks(cw_master *m, double t_stop, cw_marks *k, double slice_s)
{
    double eps = 1e-12 * py_max(1.0, fabs(t_stop));
    double tol = k->tolerance < 0.0 ? eps : k->tolerance;
    struct timespec began;
    clock_gettime(CLOCK_MONOTONIC, &began);
    unsigned steps = 0;
    for (;;) {
        /* The marks reached (at the start, or passed by a step that was cut short). */
        while (k->next < k->n_times && !(m->t < k->times[k->next] - tol)) {
            if (k->n_rows >= k->capacity)
                return CW_BUFFER_FULL;
            TRY(marks_act(m, k, k->next));
            k->next++;
        }
        if (m->t >= t_stop - eps && (k->next >= k->n_times || k->times[k->next] > t_stop))
            return CW_DONE;
        if (k->n_rows + 2 > k->capacity)  /* room for a mark's row and a change's */
            return CW_BUFFER_FULL;
        if (slice_over(&began, &steps, slice_s))
            return CW_SLICE_OVER;
        for (int j = 0; j < k->n_prev; j++)
            k->previous[j] = m->ports[k->prev_port[j]].out[k->prev_pos[j]];
        int i = k->next;
        double target = i < k->n_times ? k->times[i] : (k->margin > 0.0 ? m->t + k->margin : t_stop);
        double aim = target - m->t;
        double h = py_min(py_min(k->max_step, aim), t_stop - m->t);
        double taken;
        int rc = step(m, h, &taken);
        if (rc < 0 || rc == CW_ENDED)
            return rc;
        if (i < k->n_times && h == aim && taken == h) {  /* a step aimed at the mark, taken whole */
            TRY(marks_act(m, k, i));
            k->next++;
        }
        int changed = 0;
        for (int j = 0; j < k->n_watch; j++)
            if (m->ports[k->watch_port[j]].out[k->watch_pos[j]] != k->seen[j])  /* NaN: a change */
                changed = 1;
        if (changed) {
            for (int j = 0; j < k->n_watch; j++)
                k->seen[j] = m->ports[k->watch_port[j]].out[k->watch_pos[j]];
            marks_row(m, k);
            if (k->follow >= 0) {
                double tt = k->seen[k->follow];
                if (tt != k->last_event) {
                    if (k->last_event > 0) {
                        k->prev_event = k->last_event;
                        k->has_prev = 1;
                    }
                    k->last_event = tt;
                    double interval = k->has_prev ? tt - k->prev_event : k->period;
                    k->times[0] = tt + interval + k->margin;
                    k->next = 0;
                    k->n_times = 1;
                }
            }
            if (k->stop_at_change) {
                k->stopped = 1;
                return rc == CW_CHECK_DIVERGENCE ? rc : CW_WATCHED;
            }
        }
        if (rc == CW_CHECK_DIVERGENCE)
            return rc;
    }
}
