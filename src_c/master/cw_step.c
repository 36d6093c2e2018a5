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
 * Here: the accurate step (step) and the entry points that run it
 * (cw_step, cw_run_until, ...). The communication step it takes, with its
 * checkpoints and strong coupling, is cw_advance.c's; event location,
 * cw_events.c's.
 */

#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "cw_master.h"

/* -- the accurate step (Master.step) ------------------------------------------------ */

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
    /* -- FMI 3.0 clocks (cw_clocks.c): a communication point on every tick. */
    if (m->clocks) {
        h = clocks_cut(m->clocks, t, h);
        m->clocks->pending = 0;
        m->clocks->due = 0;
    }
    /* -- end clocks */
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
    /* -- FMI 3.0 clocks: an event at the step's end is Python's (after a divergence check). */
    if (m->clocks && clocks_due(m->clocks, m->t, m->after_event_step)) {
        m->clocks->due = 1;
        if (!m->diverged)
            return CW_CLOCK_EVENT;
    }
    /* -- end clocks */
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
        if (rc == CW_CHECK_DIVERGENCE || rc == CW_CLOCK_EVENT) {
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
