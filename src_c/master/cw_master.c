/* The compiled stepping core of the co-simulation master.
 *
 * The same algorithm as clockwork/engine/master.py (with coupling.py,
 * location.py, events.py, checkpoints.py and recording.py), operation for
 * operation, so that the two paths give the same bits: the Python master is
 * the readable reference, this is its fast twin. Every FMU is called
 * through the fmi2 function pointers that fmpy's loaded library exposes, so
 * any FMI 2.0 Co-Simulation FMU works, not only ours.
 *
 * Python owns every array (ctypes), fills the structs below and calls
 * cw_step or cw_run_until. Python floats are IEEE doubles and this file is
 * built with -ffp-contract=off, so each expression here is evaluated as in
 * Python when written in the same order; py_min/py_max keep Python's
 * min()/max() (the first argument wins ties and NaN comparisons).
 *
 * Not covered (the Python master serves it): step doubling
 * (master.richardson). Algebraic loops are solved in the steps as
 * loops.py solves them (loop_solve); their start in Initialization Mode
 * is Python's.
 *
 * FMI 3.0 and FMI 1.0 instances are called through the adapters at the
 * end of this file (cw3_*, cw1_*): fmi2-shaped functions whose first
 * argument is a cw_fmi3 or a cw_fmi1, the twins of clockwork/fmi/cs3.py
 * and fmu1.py, so the stepping code above never asks which version an FMU is.
 */

#include <math.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "cw_pool.h"
#include "cw_numerics.h"
#include "cw_polynomial.h"

#define CW_EXPORT __attribute__((visibility("default")))

#include "cw_layout.h"

typedef int (*cw_doStep_t)(void *, double, double, int);
typedef int (*cw_getReal_t)(void *, const unsigned *, size_t, double *);
typedef int (*cw_setReal_t)(void *, const unsigned *, size_t, const double *);
typedef int (*cw_setDer_t)(void *, const unsigned *, size_t, const int *, const double *);
typedef int (*cw_getDer_t)(void *, const unsigned *, size_t, const int *, double *);
typedef int (*cw_getState_t)(void *, void **);
typedef int (*cw_setState_t)(void *, void *);

enum { FMI_OK = 0, FMI_WARNING = 1, FMI_DISCARD = 2, FMI_ERROR = 3, FMI_FATAL = 4 };

/* Return codes (the Python side turns errors into SimulationError). */
enum {
    CW_DONE = 0,
    CW_BUFFER_FULL = 1,     /* recording buffers full: drain and call again */
    CW_CHECK_DIVERGENCE = 2,/* an output is not finite or too large: Python names it */
    CW_WATCHED = 3,         /* a watched output changed (cw_run_watch) */
    CW_ENDED = 4,           /* an FMI 3.0 instance asked to end the simulation (terminateSimulation) */
    CW_SLICE_OVER = 5,      /* the call's slice of wall time is spent: call again (Python handles signals between calls) */
    CW_ERR_FMI = -1,        /* an fmi2 call failed: err_port, err_call, err_status */
    CW_ERR_NO_CHECKPOINT = -2,
    CW_ERR_REPLAY = -3,
    CW_ERR_LOCATE = -4,
    CW_ERR_CAPACITY = -5,
    CW_ERR_LOOP = -6,       /* an algebraic loop did not converge: err_port is the loop, see its fail_* */
};

/* Which call failed (err_call). */
enum {
    CALL_DO_STEP = 0, CALL_GET_REAL, CALL_SET_INPUTS, CALL_SET_INPUT_DERIVATIVES,
    CALL_GET_STATE, CALL_SET_STATE,
};

#define HISTORY 3  /* input history kept for divided differences */

typedef struct {
    void *comp;
    cw_doStep_t doStep;
    cw_getReal_t getReal;
    cw_setReal_t setReal;
    cw_setDer_t setInputDerivatives;
    cw_getDer_t getOutputDerivatives;
    cw_getState_t getState;
    cw_setState_t setState;
    void **state;             /* the instance's one saved FMU state (freed by Python) */
    const unsigned *out_vr;   /* connected and recorded outputs, then indicators */
    double *out;              /* a slice of the master's one output buffer */
    const unsigned *in_vr;
    double *inp;
    const unsigned *der_vr;   /* inputs twice: first and second derivatives */
    const int *der_order;
    double *der;
    const int *src_port;      /* per input: the port and output position it comes from */
    const int *src_pos;
    double *sent;             /* inputs last given to the FMU (zero-order hold) */
    const int *dsrc_port;     /* per input: the port offering output derivatives, or -1 */
    const unsigned *dsrc_vr;  /* per input: (vr, vr) of that output */
    const int *dsrc_m;        /* per input: highest derivative order offered (1 or 2) */
    double *hist_t;           /* HISTORY + 1 times of the input history, s */
    double *hist_v;           /* (HISTORY + 1) * n_in source values */
    double *snap_hist_t;      /* the history at the checkpoint */
    double *snap_hist_v;
    const int *scaled;        /* inputs whose link is not the identity: factor * output + offset */
    const double *in_factor;  /* per scaled input */
    const double *in_offset;
    double out_time;          /* when `out` was read, s */
    double lowered_at;        /* when ext_order was last lowered, s */
    int n_out, n_in, n_z;
    int max_output_derivative_order;
    int sent_valid;
    int hist_n, snap_hist_n;
    int n_scaled;
    int ext_order;            /* order of this FMU's input polynomials (lowered where refused) */
    int pad_;
    /* Strong coupling (coupling.iterate_step): the sources' values at the
     * step's start and at the last iterate's end, per input. */
    double *it_start, *it_end;
    int can_interpolate;      /* canInterpolateInputs: the iterate's line is handed over as a slope */
    int pad2_;
} cw_port;

/* One algebraic loop solved at communication points (clockwork/engine/loops.py). */
typedef struct {
    const int *members;       /* its ports, in instance order */
    const int *u_port;        /* per unknown (a Real input fed from inside the loop): port and input position */
    const int *u_pos;
    const int *u_src;         /* ... its source port and output position */
    const int *u_src_pos;
    const double *u_factor;   /* ... and its link's transformation, where u_scaled */
    const double *u_offset;
    const int *u_scaled;
    double *r;                /* n: the residual of the sweeps */
    double fail_worst;        /* a failure: the largest residual, where, after what */
    int n_members, n;
    int fail_why, fail_at, fail_sweeps, fail_newton;
} cw_loop;

typedef struct {
    cw_loop *loop;
    double tolerance;         /* master.iteration_tolerance */
    long long iterations, fallbacks;
    int n_loops, pad_;
} cw_loops;

typedef struct {
    cw_port *ports;
    const int *first;          /* feedthrough-only ports, stepped first */
    const int *dynamic;        /* dynamic ports, in step order */
    const int *first_in_order; /* feedthrough-only ports in dependency order */
    const int *final_order;    /* ports updated at t + h, in dependency order */
    double *buffer;            /* every output of every port */
    const int *z_port;         /* per indicator: its port and output position */
    const int *z_pos;
    double *z_start, *z_end;   /* indicators at t+ of the step and at its end */
    const int *zs_port;        /* per indicator: the source port of its single input, or -1 */
    const int *zs_pos;
    const unsigned *zs_vr;
    int *prev_kind;            /* sources at the last sample: 0 none, 1 (u, None), 2 (u, du) */
    double *prev_u, *prev_du;
    double *amp_u, *amp_du;    /* slowly forgotten max |u|, max |du/dt| */
    double *z_seen;            /* NaN = not seen */
    int *end_rate_set;
    double *end_rate;          /* d(source)/dt at the step's end */
    double *snap_z_end;
    double *since;             /* steps taken since the checkpoint, s */
    double t, start_time, step;
    double event_time_tolerance, event_indicator_tolerance, divergence_limit;
    double time_to_zero, step_cap, located_from;
    double snap_t, snap_time_to_zero;
    double err_t, err_h;
    long long steps, events, event_iterations, rollbacks, replays, states_saved;
    int n_ports, n_first, n_dynamic, n_first_in_order, n_final, n_buffer, n_z, cap_since;
    int jacobi, extrapolation, locating, has_sources;
    int after_event, after_event_step, sample_countdown, prev_valid, stale_sources;
    int snap_valid, snap_after_event, n_since;
    int max_replay_steps;      /* a checkpoint after this many steps bounds replay work */
    int diverged;
    int err_port, err_call, err_status;
    int orders_lowered;        /* a port's ext_order was lowered: Python says so */
    int n_fmi3;                /* FMI 3.0 instances, whose announced time events cap the step */
    int pad4_;
    struct cw_fmi3 **fmi3;
    /* Prediction (EventLocator.sample and .plan): per indicator, the
     * sources at the last two sampled step starts, [0, n_z) the newer and
     * [n_z, 2 n_z) the older: kind 0 none, 1 (u, du/dt), 2 (u, du/dt, d2u/dt2). */
    int *pred_kind;
    double *pred_u, *pred_du, *pred_ddu;
    double *last_z;            /* the indicators at the last step's start (t+) */
    double sampled_t, sampled_before_t, last_t;
    long long predicted_landings, mispredicted;
    int predicting, last_valid;
    /* Strong coupling: fixed-point iterations per step (0: off). */
    double iteration_tolerance;
    long long coupling_iterations;
    int iterations, pad3_;
    cw_loops *loops;           /* algebraic loops: an order's entry -(i + 1) is loop i */
    cw_pool *pool;             /* master.threads > 1: instances step at once (cw_pool.c); else NULL */
    const int *par_end;        /* per dynamic position a: the end of the run of instances from a that
                                  depend on none of each other within a step (engine/parallel.py) */
    int *par_status;           /* 2 per port: fmi2DoStep's and fmi2GetReal's status, stepped at once */
    const int *after_start;    /* per dynamic position a: after_order[after_start[a] .. after_start[a + 1]) */
    const int *after_order;    /* ... is the part of first_in_order updated after it steps (parallel.py) */
    struct cw_inputs *inputs;  /* inputs driven from samples, or NULL */
} cw_master;

/* Inputs driven from samples (engine/samples.py): the sample table, its
 * input events, and per port the Real inputs it drives. */
typedef struct cw_inputs {
    const double *times;      /* n_times sample times, s, non-decreasing */
    const double *values;     /* n_signals * n_times values, signal after signal */
    const int *continuous;    /* per signal: interpolated (1) or held (0) */
    const double *events;     /* n_events input events, s, sorted */
    const int *port_start;    /* per port, its first target; n_ports + 1 entries */
    const unsigned *vr;       /* per target: the input's value reference */
    const int *signal;        /* per target: its signal */
    double *value;            /* per target: the value set */
    const int *after_step;    /* per port: 1 where its inputs are set again after its step (at t + h,
                                 before its outputs are read): only where outputs may follow inputs */
    int n_times, n_signals, n_events, pad_;
} cw_inputs;

typedef struct {
    const int *col_port;  /* per recorded column: port and output position */
    const int *col_pos;
    double *rows;         /* capacity rows of (time, columns...) */
    double *ticks;
    double last_tick;
    long long grid_seen;  /* grid points seen (the stride counts them) */
    long long grid_k;     /* run_until's next grid index; -1: compute it */
    int n_cols, capacity, n_rows, tick_capacity, n_ticks, stride, tick_port, tick_pos;
    int has_interval, pad_;
} cw_recorder;


static double py_min(double a, double b) { return b < a ? b : a; }
static double py_max(double a, double b) { return b > a ? b : a; }

static double ulp(double x)  /* math.ulp for finite x >= 0 */
{
    return nextafter(x, INFINITY) - x;
}

static int fail(cw_master *m, int port, int call, int status, double t, double h)
{
    m->err_port = port;
    m->err_call = call;
    m->err_status = status;
    m->err_t = t;
    m->err_h = h;
    return CW_ERR_FMI;
}

#define TRY(x) do { int rc_ = (x); if (rc_ < 0) return rc_; } while (0)

/* -- ports ------------------------------------------------------------- */

static int port_read(cw_master *m, int i, double t)
{
    cw_port *p = &m->ports[i];
    if (p->n_out) {
        int st = p->getReal(p->comp, p->out_vr, (size_t)p->n_out, p->out);
        if (st > FMI_WARNING)
            return fail(m, i, CALL_GET_REAL, st, t, 0.0);
    }
    p->out_time = t;
    return 0;
}

/* The links' linear transformations (Port.scale); the identity is skipped. */
static void scale_inputs(cw_port *p)
{
    for (int a = 0; a < p->n_scaled; a++) {
        int k = p->scaled[a];
        p->inp[k] = p->in_factor[a] * p->inp[k] + p->in_offset[a];
    }
}

static int port_pull(cw_master *m, int i, double t)
{
    cw_port *p = &m->ports[i];
    if (p->n_in) {
        for (int k = 0; k < p->n_in; k++)
            p->inp[k] = m->ports[p->src_port[k]].out[p->src_pos[k]];
        scale_inputs(p);
        int st = p->setReal(p->comp, p->in_vr, (size_t)p->n_in, p->inp);
        if (st > FMI_WARNING)
            return fail(m, i, CALL_SET_INPUTS, st, t, 0.0);
        p->sent_valid = 0;
    }
    return port_read(m, i, t);
}

static int loop_solve(cw_master *m, int i, double t);

static int propagate(cw_master *m, const int *order, int n, double t)
{
    for (int a = 0; a < n; a++) {
        if (order[a] < 0)
            TRY(loop_solve(m, -order[a] - 1, t));
        else
            TRY(port_pull(m, order[a], t));
    }
    return 0;
}

/* -- algebraic loops (loops.py) ------------------------------------------------------ */

enum { LOOP_PLAIN_SWEEPS = 50, LOOP_NEWTON_ITERATIONS = 20, LOOP_HALVINGS = 10 };
#define LOOP_FD_STEP 1.4901161193847656e-08  /* 2 ** -26 */
enum { LOOP_NOT_CONVERGED = 0, LOOP_SINGULAR = 1, LOOP_NO_DECREASE = 2, LOOP_NO_MEMORY = 4 };

/* r = what the sources give minus the inputs (x, else those set); the
 * largest |r| into *worst and where into *at (-1: none larger than zero). */
static void loop_residual(cw_master *m, const cw_loop *L, const double *x, double *r, double *worst, int *at)
{
    double w = 0.0;
    int where = -1;
    for (int i = 0; i < L->n; i++) {
        double g = m->ports[L->u_src[i]].out[L->u_src_pos[i]];
        if (L->u_scaled[i])
            g = L->u_factor[i] * g + L->u_offset[i];
        r[i] = g - (x ? x[i] : m->ports[L->u_port[i]].inp[L->u_pos[i]]);
        double a = fabs(r[i]);
        if (a > w || a != a) {
            w = a;
            where = i;
        }
    }
    *worst = w;
    *at = where;
}

static int loop_small(cw_master *m, const cw_loop *L, const double *r)
{
    double tol = m->loops->tolerance;
    for (int i = 0; i < L->n; i++)
        if (!(fabs(r[i]) <= tol * py_max(1.0, fabs(m->ports[L->u_port[i]].inp[L->u_pos[i]]))))
            return 0;
    return 1;
}

/* Set the loop's inputs to x, read the members' outputs; r = g(x) - x. */
static int loop_evaluate(cw_master *m, const cw_loop *L, const double *x, double *r, double t,
                         double *worst, int *at)
{
    for (int i = 0; i < L->n; i++)
        m->ports[L->u_port[i]].inp[L->u_pos[i]] = x[i];
    for (int a = 0; a < L->n_members; a++) {
        int i = L->members[a];
        cw_port *p = &m->ports[i];
        if (p->n_in) {
            int st = p->setReal(p->comp, p->in_vr, (size_t)p->n_in, p->inp);
            if (st > FMI_WARNING)
                return fail(m, i, CALL_SET_INPUTS, st, t, 0.0);
            p->sent_valid = 0;
        }
        TRY(port_read(m, i, t));
    }
    loop_residual(m, L, x, r, worst, at);
    return 0;
}

/* Gaussian elimination with partial pivoting (loops.solve_linear). */
static int solve_linear(double *a, double *b, int n)
{
    for (int c = 0; c < n; c++) {
        int piv = c;
        double best = fabs(a[c * n + c]);
        for (int row = c + 1; row < n; row++) {
            double v = fabs(a[row * n + c]);
            if (v > best) {
                piv = row;
                best = v;
            }
        }
        if (!(best > 0.0 && best < INFINITY))
            return 0;
        if (piv != c) {
            for (int k = 0; k < n; k++) {
                double tmp = a[c * n + k];
                a[c * n + k] = a[piv * n + k];
                a[piv * n + k] = tmp;
            }
            double tmp = b[c];
            b[c] = b[piv];
            b[piv] = tmp;
        }
        for (int row = c + 1; row < n; row++) {
            double f = a[row * n + c] / a[c * n + c];
            for (int k = c; k < n; k++)
                a[row * n + k] = a[row * n + k] - f * a[c * n + k];
            b[row] = b[row] - f * b[c];
        }
    }
    for (int row = n - 1; row >= 0; row--) {
        double s = b[row];
        for (int k = row + 1; k < n; k++)
            s = s - a[row * n + k] * b[k];
        b[row] = s / a[row * n + row];
    }
    return 1;
}

static int loop_fail(cw_master *m, int i, cw_loop *L, int why, double worst, int at, int sweeps, int newton,
                     double t)
{
    L->fail_why = why;
    L->fail_worst = worst;
    L->fail_at = at;
    L->fail_sweeps = sweeps;
    L->fail_newton = newton;
    m->err_port = i;
    m->err_t = t;
    return CW_ERR_LOOP;
}

static int newton_iterate(cw_master *m, int li, cw_loop *L, double t, int sweeps, double *work);

/* Newton's work arrays (5 n + n * n doubles) are taken only when a loop
 * needs the fallback, and given back after it: a large formal loop never
 * pays for an n x n Jacobian. */
static int loop_newton(cw_master *m, int li, cw_loop *L, double t, int sweeps, double worst)
{
    size_t n = (size_t)L->n;
    double *work = malloc((5 * n + n * n) * sizeof(double) + 1);
    if (!work)
        return loop_fail(m, li, L, LOOP_NO_MEMORY, worst, -1, sweeps, 0, t);
    int rc = newton_iterate(m, li, L, t, sweeps, work);
    free(work);
    return rc;
}

static int newton_iterate(cw_master *m, int li, cw_loop *L, double t, int sweeps, double *work)
{
    int n = L->n;
    double *x = work, *xn = work + n, *r = work + 2 * n, *rj = work + 3 * n, *dx = work + 4 * n;
    double *jac = work + 5 * n;
    double worst, worst_n = 0.0;
    int at, at_n = -1;
    for (int i = 0; i < n; i++)
        x[i] = m->ports[L->u_port[i]].inp[L->u_pos[i]];
    TRY(loop_evaluate(m, L, x, r, t, &worst, &at));
    int iterations = 0;
    while (!loop_small(m, L, r)) {
        if (iterations == LOOP_NEWTON_ITERATIONS)
            return loop_fail(m, li, L, LOOP_NOT_CONVERGED, worst, at, sweeps, iterations, t);
        iterations++;
        m->loops->iterations++;
        for (int j = 0; j < n; j++) {
            double xj = x[j];
            x[j] = xj + LOOP_FD_STEP * py_max(1.0, fabs(xj));
            double d = x[j] - xj;
            double w;
            int a;
            TRY(loop_evaluate(m, L, x, rj, t, &w, &a));
            x[j] = xj;
            for (int i = 0; i < n; i++)
                jac[i * n + j] = (rj[i] - r[i]) / d;
        }
        for (int i = 0; i < n; i++)
            dx[i] = -r[i];
        if (!solve_linear(jac, dx, n))
            return loop_fail(m, li, L, LOOP_SINGULAR, worst, at, sweeps, iterations, t);
        double lam = 1.0;
        int accepted = 0;
        for (int h = 0; h < LOOP_HALVINGS; h++) {
            for (int i = 0; i < n; i++)
                xn[i] = x[i] + lam * dx[i];
            TRY(loop_evaluate(m, L, xn, rj, t, &worst_n, &at_n));
            if (worst_n < worst) {
                accepted = 1;
                break;
            }
            lam *= 0.5;
        }
        if (!accepted)
            return loop_fail(m, li, L, LOOP_NO_DECREASE, worst, at, sweeps, iterations, t);
        double *swap = x;
        x = xn;
        xn = swap;
        swap = r;
        r = rj;
        rj = swap;
        worst = worst_n;
        at = at_n;
    }
    return 0;
}

/* Loop i's inputs to a fixed point at t: Gauss-Seidel sweeps over its
 * members, then Newton's method where they do not contract (Loop.solve). */
static int loop_solve(cw_master *m, int i, double t)
{
    cw_loop *L = &m->loops->loop[i];
    double prev = INFINITY, worst = 0.0;
    int at = -1, sweeps = 0;
    while (sweeps < LOOP_PLAIN_SWEEPS) {
        for (int a = 0; a < L->n_members; a++)
            TRY(port_pull(m, L->members[a], t));
        sweeps++;
        m->loops->iterations++;
        loop_residual(m, L, NULL, L->r, &worst, &at);
        if (loop_small(m, L, L->r))
            return 0;
        if (!(worst < prev))
            break;  /* not contracting: growing, stalled or NaN */
        prev = worst;
    }
    m->loops->fallbacks++;
    return loop_newton(m, i, L, t, sweeps, worst);
}

static void indicators(cw_master *m, double *z)
{
    for (int k = 0; k < m->n_z; k++)
        z[k] = m->ports[m->z_port[k]].out[m->z_pos[k]];
}

/* -- inputs from samples (engine/samples.py) --------------------------- */

/* math.isclose(a, b) with its defaults (relative 1e-9), as fmpy compares times. */
static int cw_isclose(double a, double b)
{
    if (a == b)
        return 1;
    if (isinf(a) || isinf(b))
        return 0;
    double diff = fabs(b - a);
    return diff <= fabs(1e-9 * b) || diff <= fabs(1e-9 * a) || diff <= 0.0;
}

static int bisect_left(const double *a, int n, double x)
{
    int lo = 0, hi = n;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (a[mid] < x)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

static int bisect_right(const double *a, int n, double x)
{
    int lo = 0, hi = n;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (x < a[mid])
            hi = mid;
        else
            lo = mid + 1;
    }
    return lo;
}

/* Samples.next_event */
static double inputs_next_event(const cw_inputs *in, double t)
{
    for (int i = bisect_right(in->events, in->n_events, t); i < in->n_events; i++)
        if (!cw_isclose(in->events[i], t))
            return in->events[i];
    return INFINITY;
}

/* Samples.event_at */
static int inputs_event_at(const cw_inputs *in, double t)
{
    int i = bisect_left(in->events, in->n_events, t);
    for (int j = i - 1; j <= i; j++)
        if (j >= 0 && j < in->n_events && cw_isclose(in->events[j], t))
            return 1;
    return 0;
}

/* Samples.at for the targets [from, to): their values at `time`, after an
 * event there when after_event, else before it. */
static void inputs_at(const cw_inputs *in, int from, int to, double time, int after_event, double *out)
{
    const double *t = in->times;
    int n = in->n_times;
    int first = n < 2, i0 = 0;
    if (!first) {
        i0 = bisect_left(t, n, time);
        first = i0 == 0;
    }
    if (first || i0 == n) {
        for (int k = from; k < to; k++)
            out[k] = in->values[(size_t)in->signal[k] * (size_t)n + (size_t)(first ? 0 : n - 1)];
        return;
    }
    int held = i0 - 1;
    if (after_event)
        while (held + 1 < n && (t[held + 1] < time || cw_isclose(time, t[held + 1])))
            held++;
    int row = -1;
    double w0 = 0.0, w1 = 0.0;
    if (cw_isclose(time, t[i0]) && i0 < n - 1 && cw_isclose(t[i0], t[i0 + 1])) {
        row = i0;
        if (after_event)
            while (row < n - 1 && cw_isclose(t[row], t[row + 1]))
                row++;
    } else {
        double t0 = t[i0 - 1], t1 = t[i0];
        w0 = (t1 - time) / (t1 - t0);
        w1 = 1 - w0;
    }
    for (int k = from; k < to; k++) {
        const double *v = &in->values[(size_t)in->signal[k] * (size_t)n];
        if (!in->continuous[in->signal[k]])
            out[k] = v[held];
        else if (row >= 0)
            out[k] = v[row];
        else
            out[k] = w0 * v[i0 - 1] + w1 * v[i0];
    }
}

/* FileInputs.set for port i */
static int inputs_set(cw_master *m, int i, double t, int after_event)
{
    const cw_inputs *in = m->inputs;
    int from = in->port_start[i], to = in->port_start[i + 1];
    if (from == to)
        return 0;
    inputs_at(in, from, to, t, after_event, in->value);
    cw_port *p = &m->ports[i];
    int st = p->setReal(p->comp, &in->vr[from], (size_t)(to - from), &in->value[from]);
    if (st > FMI_WARNING)
        return fail(m, i, CALL_SET_INPUTS, st, t, 0.0);
    return 0;
}

/* -- coupling ------------------------------------------------------------- */

static void history_forget(cw_master *m)
{
    for (int a = 0; a < m->n_dynamic; a++)
        m->ports[m->dynamic[a]].hist_n = 0;
}

static void record_history(cw_master *m)
{
    if (!m->extrapolation)
        return;
    if (m->after_event_step || m->after_event)
        history_forget(m);
    for (int a = 0; a < m->n_dynamic; a++) {
        cw_port *p = &m->ports[m->dynamic[a]];
        if (!p->n_in)
            continue;
        int n = p->hist_n;
        p->hist_t[n] = m->t;
        for (int k = 0; k < p->n_in; k++)
            p->hist_v[n * p->n_in + k] = m->ports[p->src_port[k]].out[p->src_pos[k]];
        n++;
        if (n > HISTORY) {
            memmove(p->hist_t, p->hist_t + 1, (size_t)(n - 1) * sizeof(double));
            memmove(p->hist_v, p->hist_v + p->n_in, (size_t)((n - 1) * p->n_in) * sizeof(double));
            n--;
        }
        p->hist_n = n;
    }
}

/* Fill p->inp (values at t) and p->der (derivatives at t) from the sources. */
static void extrapolate(cw_master *m, cw_port *p, double t)
{
    int order = p->ext_order;
    int n = p->n_in;
    for (int k = 0; k < n; k++) {
        cw_port *src = &m->ports[p->src_port[k]];
        double ta = src->out_time, ua = src->out[p->src_pos[k]];
        double d1 = 0.0, d2 = 0.0;
        if (p->dsrc_port[k] >= 0) {
            cw_port *ds = &m->ports[p->dsrc_port[k]];
            static const int orders[2] = {1, 2};
            double got[2];
            int mm = p->dsrc_m[k] < order ? p->dsrc_m[k] : order;
            if (ds->getOutputDerivatives(ds->comp, &p->dsrc_vr[2 * k], (size_t)mm, orders, got) <= FMI_WARNING) {
                d1 = got[0];
                d2 = mm == 2 ? got[1] : 0.0;
            }
        } else {
            /* Divided differences through the history and the current value. */
            double pt[HISTORY + 1], pu[HISTORY + 1];
            int np = 0;
            for (int a = 0; a < p->hist_n; a++)
                if (p->hist_t[a] < ta - 1e-15) {
                    pt[np] = p->hist_t[a];
                    pu[np] = p->hist_v[a * n + k];
                    np++;
                }
            int keep = np < order ? np : order;
            int from = np - keep;
            for (int a = 0; a < keep; a++) {
                pt[a] = pt[from + a];
                pu[a] = pu[from + a];
            }
            np = keep;
            pt[np] = ta;
            pu[np] = ua;
            np++;
            if (np >= 2) {
                double t1 = pt[np - 2], u1 = pu[np - 2], t2 = pt[np - 1], u2 = pu[np - 1];
                d1 = (u2 - u1) / (t2 - t1);
                if (order >= 2 && np >= 3) {
                    double t0 = pt[np - 3], u0 = pu[np - 3];
                    double d0 = (u1 - u0) / (t1 - t0);
                    d2 = 2.0 * (d1 - d0) / (t2 - t0);
                    d1 += 0.5 * d2 * (t2 - t1);
                }
            }
        }
        double dt = t - ta;
        p->inp[k] = input_polynomial(ua, d1, d2, dt);
        p->der[k] = d1 + d2 * dt;
        p->der[n + k] = d2;
    }
    for (int a = 0; a < p->n_scaled; a++) {
        int k = p->scaled[a];
        double f = p->in_factor[a];
        p->inp[k] = f * p->inp[k] + p->in_offset[a];
        p->der[k] = f * p->der[k];
        p->der[n + k] = f * p->der[n + k];
    }
}

/* Strong coupling: inputs from the step's start, as a line towards the last
 * iterate's end where the FMU can interpolate them (coupling.set_inputs
 * with coupling_end). */
static int set_coupled_inputs(cw_master *m, int i, double t, double h)
{
    cw_port *p = &m->ports[i];
    int n = p->n_in;
    memcpy(p->inp, p->it_start, (size_t)n * sizeof(double));
    double end[n > 0 ? n : 1];
    memcpy(end, p->it_end, (size_t)n * sizeof(double));
    for (int a = 0; a < p->n_scaled; a++) {
        int k = p->scaled[a];
        p->inp[k] = p->in_factor[a] * p->inp[k] + p->in_offset[a];
        end[k] = p->in_factor[a] * end[k] + p->in_offset[a];
    }
    int st = p->setReal(p->comp, p->in_vr, (size_t)n, p->inp);
    if (st > FMI_WARNING)
        return fail(m, i, CALL_SET_INPUTS, st, t, h);
    memcpy(p->sent, p->inp, (size_t)n * sizeof(double));
    p->sent_valid = 0;
    if (p->can_interpolate) {
        for (int k = 0; k < n; k++) {
            p->der[k] = (end[k] - p->inp[k]) / h;
            p->der[n + k] = 0.0;
        }
        st = p->setInputDerivatives(p->comp, p->der_vr, (size_t)n, p->der_order, p->der);
        if (st > FMI_WARNING)
            return fail(m, i, CALL_SET_INPUT_DERIVATIVES, st, t, h);
    }
    return 0;
}

/* Inputs of a dynamic instance for the step from t (coupling.set_inputs). */
static int set_inputs(cw_master *m, int i, double t, double h, int smooth)
{
    cw_port *p = &m->ports[i];
    int n = p->n_in;
again:
    for (int k = 0; k < n; k++)
        p->inp[k] = m->ports[p->src_port[k]].out[p->src_pos[k]];
    scale_inputs(p);
    int polynomial = p->ext_order && smooth;
    if (polynomial) {
        extrapolate(m, p, t);
    } else if (p->sent_valid) {
        int same = 1;
        for (int k = 0; k < n; k++)
            if (!(p->sent[k] == p->inp[k])) {
                same = 0;
                break;
            }
        if (same)
            return 0;  /* held value unchanged: the FMU already has it */
    }
    int st = p->setReal(p->comp, p->in_vr, (size_t)n, p->inp);
    if (st > FMI_WARNING)
        return fail(m, i, CALL_SET_INPUTS, st, t, h);
    memcpy(p->sent, p->inp, (size_t)n * sizeof(double));
    p->sent_valid = !polynomial;
    if (polynomial) {
        size_t nd = (size_t)n * (p->ext_order >= 2 ? 2 : 1);
        st = p->setInputDerivatives(p->comp, p->der_vr, nd, p->der_order, p->der);
        if (st > FMI_WARNING) {
            if (st >= FMI_FATAL)
                return fail(m, i, CALL_SET_INPUT_DERIVATIVES, st, t, h);
            /* Refused: one order lower, from the same sources, and never again this order. */
            p->ext_order--;
            p->lowered_at = t;
            m->orders_lowered = 1;
            goto again;
        }
    }
    return 0;
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

static int advance(cw_master *m, double t, double h)
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

static int checkpoint_mark(cw_master *m)
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

static int rollback(cw_master *m)
{
    TRY(restore_states(m));
    return restore_soft_state(m);
}

static int since_append(cw_master *m, double h)
{
    if (m->n_since >= m->cap_since)
        return CW_ERR_CAPACITY;
    m->since[m->n_since++] = h;
    return 0;
}

/* An event in a step predicted free of them: back to the checkpoint, redo
 * the steps since then, and take a checkpoint at t. */
static int replay_to(cw_master *m, double t)
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

/* -- event location: polynomials (events.py) ------------------------------------- */

static void hermite_coefficients(double h, double z0, double dz0, double z1, double dz1,
                                 double *a, double *b, double *c, double *d)
{
    *c = h * dz0;
    *d = z0;
    *a = 2 * z0 - 2 * z1 + h * dz0 + h * dz1;
    *b = -3 * z0 + 3 * z1 - 2 * h * dz0 - h * dz1;
}

static double horner(const double *coef, int n, double x)
{
    double value = 0.0;
    for (int k = n - 1; k >= 0; k--)
        value = value * x + coef[k];
    return value;
}

/* A root of the polynomial (n coefficients, n <= 6) in (lo, hi), where it
 * is `positive` at lo: Newton's method from x, kept inside the shrinking
 * bracket by bisection, until a step is below 1e-15 (relative: <= 1e-15
 * hi) (events._newton_in_bracket). */
static double newton_in_bracket(const double *coef, int n, double x, double lo, double hi, int positive,
                                int relative)
{
    double slope[5];
    for (int k = 1; k < n; k++)
        slope[k - 1] = (double)k * coef[k];
    for (int it = 0; it < 50; it++) {
        double f = horner(coef, n, x);
        if (f == 0.0)
            break;
        if ((f > 0.0) == positive)
            lo = x;
        else
            hi = x;
        double df = horner(slope, n - 1, x);
        double x_new = df != 0.0 ? x - f / df : 0.5 * (lo + hi);
        if (!(lo < x_new && x_new < hi))
            x_new = 0.5 * (lo + hi);
        if (relative ? fabs(x_new - x) <= 1e-15 * hi : fabs(x_new - x) < 1e-15)
            return x_new;
        x = x_new;
    }
    return x;
}

/* Root in (0, h) of the indicator's Hermite interpolant, or NAN. */
static double hermite_root(double h, double z0, double dz0, double z1, double dz1,
                           int curvature, double ddz0, double ddz1)
{
    if (!(z0 * z1 < 0.0 || z1 == 0.0))
        return NAN;
    double coef[6];
    int n;
    if (curvature) {
        double c0 = z0, c1 = h * dz0, c2 = 0.5 * h * h * ddz0;
        double a = z1 - (c0 + c1 + c2);
        double b = h * dz1 - (c1 + 2.0 * c2);
        double c = h * h * ddz1 - 2.0 * c2;
        coef[0] = c0;
        coef[1] = c1;
        coef[2] = c2;
        coef[3] = 10.0 * a - 4.0 * b + 0.5 * c;
        coef[4] = -15.0 * a + 7.0 * b - c;
        coef[5] = 6.0 * a - 3.0 * b + 0.5 * c;
        n = 6;
    } else {
        hermite_coefficients(h, z0, dz0, z1, dz1, &coef[3], &coef[2], &coef[1], &coef[0]);
        n = 4;
    }
    double x = newton_in_bracket(coef, n, z0 != z1 ? z0 / (z0 - z1) : 0.5, 0.0, 1.0, z0 > 0.0, 0);
    return (0.0 < x && x < 1.0) ? x * h : NAN;
}

/* Where in (0, h) the cubic interpolant reaches the other sign, or NAN. */
static double hermite_extremum(double h, double z0, double dz0, double z1, double dz1)
{
    double a, b, c, d;
    hermite_coefficients(h, z0, dz0, z1, dz1, &a, &b, &c, &d);
    double roots[2];
    int n = 0;
    if (fabs(a) < 1e-300) {
        if (b != 0) {
            roots[0] = -c / (2 * b);
            n = 1;
        }
    } else {
        double disc = b * b - 3 * a * c;
        if (disc >= 0) {
            double r = pow(disc, 0.5);  /* as Python's disc ** 0.5 */
            roots[0] = (-b - r) / (3 * a);
            roots[1] = (-b + r) / (3 * a);
            n = 2;
            if (roots[1] < roots[0]) {
                double s = roots[0];
                roots[0] = roots[1];
                roots[1] = s;
            }
        }
    }
    for (int k = 0; k < n; k++) {
        double sx = roots[k];
        if (0.0 < sx && sx < 1.0) {
            double val = ((a * sx + b) * sx + c) * sx + d;
            if ((val > 0) != (z0 > 0) || val == 0.0)
                return sx * h;
        }
    }
    return NAN;
}

/* -- prediction: where an indicator will cross, before the step (events.py) -------- */

#define PREDICTION_HORIZON 16.0 /* extrapolate at most this many times the last step */
#define PREDICTION_SCAN 8       /* points scanned for the extrapolant's first sign change */

/* The Hermite polynomials through the last step of h s (a: z0..., b: z1...)
 * continued past b, in y = (time since b) / h: the higher order into high
 * (n_high coefficients), the lower into low (events.extrapolants). */
static void extrapolants(double h, double z0, double dz0, double z1, double dz1, int second, double ddz0,
                         double ddz1, double *high, int *n_high, double *low, int *n_low)
{
    double c1 = h * dz1;
    if (second) {
        double hh = h * h;
        double c2 = 0.5 * hh * ddz1;
        double e0 = z0 - ((z1 - c1) + c2);
        double e1 = h * dz0 - (c1 - hh * ddz1);
        double e2 = hh * ddz0 - hh * ddz1;
        high[0] = z1;
        high[1] = c1;
        high[2] = c2;
        high[3] = -0.5 * (e2 + 8.0 * e1 + 20.0 * e0);
        high[4] = -(e2 + 7.0 * e1 + 15.0 * e0);
        high[5] = -0.5 * (e2 + 6.0 * e1 + 12.0 * e0);
        *n_high = 6;
        low[0] = z1;
        low[1] = c1;
        low[2] = c2;
        low[3] = -(4.0 * e0 + e1);
        low[4] = -(3.0 * e0 + e1);
        *n_low = 5;
    } else {
        double e0 = z0 - (z1 - c1);
        double e1 = h * dz0 - c1;
        high[0] = z1;
        high[1] = c1;
        high[2] = 3.0 * e0 + e1;
        high[3] = 2.0 * e0 + e1;
        *n_high = 4;
        low[0] = z1;
        low[1] = c1;
        low[2] = e0;
        *n_low = 3;
    }
}

static double slope_at(const double *coef, int n, double y)
{
    double slope[5];
    for (int k = 1; k < n; k++)
        slope[k - 1] = (double)k * coef[k];
    return horner(slope, n - 1, y);
}

/* The first y in (0, y_max] where the polynomial leaves its sign at 0, or
 * NAN (events.first_root). */
static double first_root(const double *coef, int n, double y_max)
{
    double z0 = coef[0];
    int positive = z0 > 0.0;
    double lo = 0.0, f_lo = z0, hi = 0.0, f_hi = 0.0;
    int found = 0;
    for (int i = 1; i <= PREDICTION_SCAN; i++) {
        double y = y_max * (double)i / (double)PREDICTION_SCAN;
        double f = horner(coef, n, y);
        if (f == 0.0 || (f > 0.0) != positive) {
            hi = y;
            f_hi = f;
            found = 1;
            break;
        }
        lo = y;
        f_lo = f;
    }
    if (!found)
        return NAN;
    if (f_hi == 0.0)
        return hi;
    return newton_in_bracket(coef, n, lo + (hi - lo) * (f_lo / (f_lo - f_hi)), lo, hi, positive, 1);
}

/* -- event location: the locator (location.py) ----------------------------------- */

/* -1 when an indicator changed sign over the step; else the time until the
 * nearest one would reach zero at its rate over the step, s. */
static double scan(const double *z0, const double *z1, int n, double h)
{
    double steps = INFINITY;
    for (int k = 0; k < n; k++) {
        double a = z0[k], b = z1[k];
        if ((a > 0.0 && b <= 0.0) || (a < 0.0 && b >= 0.0))
            return -1.0;
        double dist = fabs(b);
        if (dist <= 1e-15)
            return 0.0;
        double change = fabs(b - a);
        if (dist < steps * change)
            steps = dist / change;
    }
    return steps * h;
}

/* d^order u/dt^order of indicator k's source output; 0 when refused. */
static int output_rate(cw_master *m, int k, int order, double *rate)
{
    cw_port *src = &m->ports[m->zs_port[k]];
    int orders[1] = {order};
    return src->getOutputDerivatives(src->comp, &m->zs_vr[k], 1, orders, rate) <= FMI_WARNING;
}

/* du/dt and d2u/dt2 of indicator k's source in one call (EventLocator.
 * output_rates): 0 when du/dt is refused; *have_acc when d2u/dt2 came too. */
static int output_rates(cw_master *m, int k, double *du, double *ddu, int *have_acc)
{
    cw_port *src = &m->ports[m->zs_port[k]];
    *have_acc = 0;
    if (src->max_output_derivative_order >= 2) {
        unsigned vr2[2] = {m->zs_vr[k], m->zs_vr[k]};
        static const int orders[2] = {1, 2};
        double got[2];
        if (src->getOutputDerivatives(src->comp, vr2, 2, orders, got) <= FMI_WARNING) {
            *du = got[0];
            *ddu = got[1];
            *have_acc = 1;
            return 1;
        }
    }
    return output_rate(m, k, 1, du);
}

static void remember_sources(cw_master *m)
{
    double cap = INFINITY;
    for (int k = 0; k < m->n_z; k++) {
        if (m->zs_port[k] < 0) {
            m->prev_kind[k] = 0;
            continue;
        }
        cw_port *src = &m->ports[m->zs_port[k]];
        double u = src->out[m->zs_pos[k]];
        double z_now = m->z_end[k];
        int constant = z_now == m->z_seen[k];
        m->z_seen[k] = z_now;
        m->prev_u[k] = u;
        if (constant) {
            /* An indicator that did not move says nothing about its source's time scale. */
            m->prev_kind[k] = 1;
            continue;
        }
        double du, acc = 0.0;
        int have_du = 1, have_acc = 0;
        int second = src->max_output_derivative_order >= 2 && u != 0.0;
        if (m->end_rate_set[k])
            du = m->end_rate[k];
        else if (second)  /* both derivatives in one call where both are wanted */
            have_du = output_rates(m, k, &du, &acc, &have_acc);
        else
            have_du = output_rate(m, k, 1, &du);
        m->prev_kind[k] = have_du ? 2 : 1;
        m->prev_du[k] = du;
        if (have_du) {
            double amp_u = py_max(fabs(u), 0.999 * m->amp_u[k]);
            double amp_du = py_max(fabs(du), 0.999 * m->amp_du[k]);
            m->amp_u[k] = amp_u;
            m->amp_du[k] = amp_du;
            double omega = amp_u > 0.0 ? amp_du / amp_u : 0.0;
            if (second) {
                if (!have_acc)
                    have_acc = output_rate(m, k, 2, &acc);
                if (have_acc)
                    omega = py_max(omega, sqrt(fabs(acc / u)));
            }
            if (omega > 0.0)
                cap = py_min(cap, 0.2 * 2 * M_PI / omega);
        }
    }
    m->prev_valid = 1;
    m->step_cap = cap;
    for (int k = 0; k < m->n_z; k++)
        m->end_rate_set[k] = 0;
}

/* Offset of an indicator's extremum inside the step where its interpolant
 * changes sign although z has one sign at both ends, or NAN. */
static double hidden_crossing(cw_master *m, double h, const double *z0, const double *z1)
{
    if (!m->prev_valid)
        return NAN;
    double best = NAN;
    for (int k = 0; k < m->n_z; k++) {
        if (m->zs_port[k] < 0 || m->prev_kind[k] != 2)
            continue;
        double u0 = m->prev_u[k], du0 = m->prev_du[k];
        double u1 = m->ports[m->zs_port[k]].out[m->zs_pos[k]];
        if (u1 == u0 || z0[k] == 0.0)
            continue;
        double ratio = (z1[k] - z0[k]) / (u1 - u0);
        double dz0 = ratio * du0;
        if (z0[k] * dz0 >= 0.0)
            continue;  /* moving away from zero at the start */
        double du1;
        if (!output_rate(m, k, 1, &du1))
            continue;
        m->end_rate[k] = du1;
        m->end_rate_set[k] = 1;
        double dz1 = ratio * du1;
        if (z1[k] * dz1 <= 0.0)
            continue;  /* still approaching at the end */
        double x = hermite_extremum(h, z0[k], dz0, z1[k], dz1);
        if (!isnan(x) && (isnan(best) || x < best))
            best = x;
    }
    return best;
}

enum { PLAN_NONE = 0, PLAN_CLEAR = 1, PLAN_APPROACH = 2, PLAN_LAND = 3 };

/* The sources' values and derivatives at t (EventLocator.sample). */
static void sample_sources(cw_master *m, double t)
{
    int nz = m->n_z;
    memcpy(m->pred_kind + nz, m->pred_kind, (size_t)nz * sizeof(int));
    memcpy(m->pred_u + nz, m->pred_u, (size_t)nz * sizeof(double));
    memcpy(m->pred_du + nz, m->pred_du, (size_t)nz * sizeof(double));
    memcpy(m->pred_ddu + nz, m->pred_ddu, (size_t)nz * sizeof(double));
    m->sampled_before_t = m->sampled_t;
    for (int k = 0; k < nz; k++) {
        m->pred_kind[k] = 0;
        if (m->zs_port[k] < 0)
            continue;
        int same = -1;  /* an earlier indicator with the same source output: asked once */
        for (int j = 0; j < k && same < 0; j++)
            if (m->zs_port[j] == m->zs_port[k] && m->zs_vr[j] == m->zs_vr[k])
                same = j;
        if (same >= 0) {
            m->pred_kind[k] = m->pred_kind[same];
            m->pred_u[k] = m->pred_u[same];
            m->pred_du[k] = m->pred_du[same];
            m->pred_ddu[k] = m->pred_ddu[same];
            continue;
        }
        cw_port *src = &m->ports[m->zs_port[k]];
        int have_acc;
        if (output_rates(m, k, &m->pred_du[k], &m->pred_ddu[k], &have_acc)) {
            m->pred_u[k] = src->out[m->zs_pos[k]];
            m->pred_kind[k] = have_acc ? 2 : 1;
        }
    }
    m->sampled_t = t;
}

/* Before the step from t of h s: PLAN_CLEAR, PLAN_APPROACH or PLAN_LAND
 * with *step, when every indicator's next crossing can be predicted from
 * the Hermite polynomial through the last step; else PLAN_NONE
 * (EventLocator.plan). */
static int plan(cw_master *m, double t, double h, double *step_out)
{
    if (!m->last_valid || m->sampled_t != t || m->sampled_before_t != m->last_t)
        return PLAN_NONE;
    double span = t - m->last_t;
    if (!(span > 0.0))
        return PLAN_NONE;
    int nz = m->n_z, kind = PLAN_CLEAR;
    double step = h;
    for (int k = 0; k < nz; k++) {
        double za = m->last_z[k], zb = m->z_end[k];
        if (za == zb)
            continue;  /* did not move: does not cross by moving */
        int now = m->pred_kind[k], before = m->pred_kind[nz + k];
        if (!now || !before || zb == 0.0)
            return PLAN_NONE;
        double u1 = m->pred_u[k], u0 = m->pred_u[nz + k];
        if (u1 == u0)
            return PLAN_NONE;
        double ratio = (zb - za) / (u1 - u0);
        int second = before == 2 && now == 2;
        double high[6], low[5];
        int n_high, n_low;
        extrapolants(span, za, ratio * m->pred_du[nz + k], zb, ratio * m->pred_du[k], second,
                     second ? ratio * m->pred_ddu[nz + k] : 0.0, second ? ratio * m->pred_ddu[k] : 0.0,
                     high, &n_high, low, &n_low);
        double y_max = py_min(h / span, PREDICTION_HORIZON);
        double y_high = first_root(high, n_high, y_max), y_low = first_root(low, n_low, y_max);
        if (isnan(y_high)) {
            if (!isnan(y_low) || h / span > PREDICTION_HORIZON)
                return PLAN_NONE;
            continue;  /* clear of this indicator */
        }
        if (isnan(y_low))
            return PLAN_NONE;
        double at = y_high * span;
        double err = fabs(at - y_low * span);
        double rate = slope_at(high, n_high, y_high) / span;
        double past = 0.25 * m->event_time_tolerance;
        if (rate != 0.0)
            past = py_min(past, 0.25 * m->event_indicator_tolerance / fabs(rate));
        int this;
        double mine;
        if (2.0 * err <= past && at + past <= h) {
            this = PLAN_LAND;
            mine = at + past;
        } else if (2.0 * err < 0.95 * at) {
            this = PLAN_APPROACH;
            mine = at - 2.0 * err;
        } else {
            return PLAN_NONE;
        }
        if (mine < step) {
            kind = this;
            step = mine;
        }
    }
    if ((t + step) - t < 8 * ulp(fabs(t) + step + 1.0))
        return PLAN_NONE;
    *step_out = step;
    return kind;
}

/* The indicator among the crossing ones whose linear interpolant crosses first. */
static int earliest(const int *crossing, const double *z0, const double *z1, int n)
{
    int lead = -1;
    double best = 0.0;
    for (int k = 0; k < n; k++) {
        if (!crossing[k])
            continue;
        double x = z0[k] / (z0[k] - z1[k]);
        if (lead < 0 || x < best) {
            lead = k;
            best = x;
        }
    }
    return lead;
}

/* How close locate brackets a crossing in the step from t of h s: far from
 * t = 0 a double cannot resolve the tolerance, so a few ulps. */
static double time_tolerance(const cw_master *m, double t, double h)
{
    return py_max(m->event_time_tolerance, 4 * ulp(fabs(t) + h));
}

/* Shorten the step from t (a checkpoint) to land just past the earliest
 * crossing (EventLocator.locate); *taken gets the step, s. */
static int locate(cw_master *m, double t, double h, const int *crossings, const double *z0,
                  const double *z1, double *taken)
{
    int nz = m->n_z;
    int lead = earliest(crossings, z0, z1, nz);
    /* The source's slope at the step's end, before the rollback. */
    int have_slope = 0, have_dd1 = 0;
    double u1 = 0.0, du1 = 0.0, ddu1 = 0.0;
    if (m->zs_port[lead] >= 0 && output_rate(m, lead, 1, &du1)) {
        have_slope = 1;
        u1 = m->ports[m->zs_port[lead]].out[m->zs_pos[lead]];
        if (m->ports[m->zs_port[lead]].max_output_derivative_order >= 2)
            have_dd1 = output_rate(m, lead, 2, &ddu1);
    }
    TRY(rollback(m));
    double first = 0.0;
    int have_first = 0;  /* a trial proposed by the interpolant or by Newton (may be NaN) */
    int newton = 0, newton_lead = -1, curvature = 0;
    double ratio = 0.0;
    if (have_slope) {
        double u0 = m->ports[m->zs_port[lead]].out[m->zs_pos[lead]];
        double du0, ddu0 = 0.0;
        int have_du0 = output_rate(m, lead, 1, &du0);
        int have_dd0 = have_dd1 ? output_rate(m, lead, 2, &ddu0) : 0;
        if (have_du0 && u1 != u0) {
            /* The indicator is affine in its source near the crossing: z' = ratio u'. */
            ratio = (z1[lead] - z0[lead]) / (u1 - u0);
            curvature = have_dd0 && have_dd1;
            first = hermite_root(h, z0[lead], ratio * du0, z1[lead], ratio * du1, curvature,
                                 curvature ? ratio * ddu0 : 0.0, curvature ? ratio * ddu1 : 0.0);
            have_first = !isnan(first);  /* NaN: no root in the step */
            newton = 1;
            newton_lead = lead;
        }
    }
    illinois search = illinois_new(0.0, z0[lead], h, z1[lead]);
    double hi = h;
    double z_hi[nz > 0 ? nz : 1], z_lo[nz > 0 ? nz : 1];
    int now[nz > 0 ? nz : 1];
    memcpy(z_hi, z1, (size_t)nz * sizeof(double));
    memcpy(z_lo, z0, (size_t)nz * sizeof(double));
    double base = 0.0;
    int have_last = 0;  /* the FMUs stand at the checkpoint after the rollback */
    double last = 0.0;
    double time_tol = time_tolerance(m, t, h);
    for (;;) {
        if (hi - search.lo <= time_tol || fabs(z_hi[lead]) <= m->event_indicator_tolerance)
            break;
        double trial;
        if (have_first) {
            trial = first;
            have_first = 0;
        } else {
            trial = illinois_next(&search);
        }
        if (!(search.lo < trial && trial < hi))
            trial = 0.5 * (search.lo + hi);
        /* A trial must move the FMUs' clock: at least a few ulps past lo. */
        double min_move = 8 * ulp(fabs(t) + fabs(hi) + 1.0);
        if ((t + trial) - (t + search.lo) < min_move)
            trial = search.lo + py_min(0.5 * (hi - search.lo),
                                       py_max(min_move, 0.25 * m->event_time_tolerance));
        if (have_last)
            TRY(rollback(m));
        TRY(advance(m, m->t, (t + trial) - m->t));
        m->event_iterations++;
        have_last = 1;
        last = trial;
        const double *z = m->z_end;
        if (newton && newton_lead == lead) {
            /* Newton from this trial, aimed a hair past the root in time. */
            double rate;
            if (output_rate(m, lead, 1, &rate) && rate != 0.0) {
                double slope = ratio * rate;
                double delta = -z[lead] / slope;
                double acc;
                if (curvature && output_rate(m, lead, 2, &acc)) {
                    double bend = ratio * acc;
                    double disc = slope * slope - 2.0 * z[lead] * bend;
                    if (disc >= 0.0)
                        delta = -2.0 * z[lead] / (slope + copysign(sqrt(disc), slope));
                }
                double past = py_min(0.25 * m->event_time_tolerance,
                                     0.25 * m->event_indicator_tolerance / fabs(slope));
                first = trial + delta + past;
                have_first = 1;
            }
        }
        int any = 0;
        for (int k = 0; k < nz; k++) {
            now[k] = crossed(m->z_start[k], z[k]);
            any |= now[k];
        }
        if (any) {
            if (!now[lead]) {
                /* Another indicator crosses first: restart on it. */
                lead = earliest(now, z_lo, z, nz);
                search = illinois_new(search.lo, z_lo[lead], trial, z[lead]);
                have_first = 0;
            } else {
                illinois_update(&search, trial, z[lead], 1);
            }
            hi = trial;
            memcpy(z_hi, z, (size_t)nz * sizeof(double));
        } else {
            illinois_update(&search, trial, z[lead], 0);
            /* Later trials start here: no need to integrate [t, t + trial] again. */
            memcpy(z_lo, z, (size_t)nz * sizeof(double));
            TRY(checkpoint_mark(m));
            base = trial;
            have_last = 0;
        }
        if (search.iterations > 200) {
            m->err_t = t;
            m->err_h = h;
            return CW_ERR_LOCATE;
        }
    }
    if (!have_last || last != hi) {
        if (have_last)
            TRY(rollback(m));
        TRY(advance(m, m->t, (t + hi) - m->t));
    }
    if (base > 0.0)
        m->n_since = 0;
    m->located_from = t + base;
    m->events++;
    *taken = hi;
    return 0;
}

/* After the step from t of h s: when an indicator crossed zero, land just
 * past the earliest crossing instead (Master._land_on_events). */
static int land_on_events(cw_master *m, double t, double h, int near, int checkpointed, int predicted,
                          double *taken)
{
    int nz = m->n_z;
    double z0[nz > 0 ? nz : 1], z1[nz > 0 ? nz : 1];
    int crossings[nz > 0 ? nz : 1];
    memcpy(z0, m->z_start, (size_t)nz * sizeof(double));
    memcpy(z1, m->z_end, (size_t)nz * sizeof(double));
    double time_to_zero = scan(z0, z1, nz, h);
    int hit = time_to_zero < 0.0;
    if (!hit && near && m->has_sources) {
        double hidden = hidden_crossing(m, h, z0, z1);
        if (!isnan(hidden)) {
            /* Two crossings inside one step cancel at its ends: try the
             * step up to the interpolant's extremum. */
            TRY(rollback(m));
            TRY(advance(m, t, hidden));
            m->event_iterations++;
            memcpy(z0, m->z_start, (size_t)nz * sizeof(double));
            memcpy(z1, m->z_end, (size_t)nz * sizeof(double));
            time_to_zero = scan(z0, z1, nz, hidden);
            hit = time_to_zero < 0.0;
            if (hit) {
                h = hidden;
            } else {  /* the interpolant was wrong: redo the whole step */
                TRY(rollback(m));
                TRY(advance(m, t, h));
                memcpy(z0, m->z_start, (size_t)nz * sizeof(double));
                memcpy(z1, m->z_end, (size_t)nz * sizeof(double));
                time_to_zero = scan(z0, z1, nz, h);
            }
        }
    }
    if (!hit) {
        m->time_to_zero = time_to_zero;
        TRY(since_append(m, h));
        *taken = h;
        return 0;
    }
    for (int k = 0; k < nz; k++)
        crossings[k] = crossed(z0[k], z1[k]);
    int lead = earliest(crossings, z0, z1, nz);
    if (fabs(z1[lead]) <= m->event_indicator_tolerance || h <= time_tolerance(m, t, h)) {
        /* Already just past the crossing, where locate would stop at once. */
        if (predicted == PLAN_LAND)
            m->predicted_landings++;
        m->events++;
        m->located_from = t;
        m->after_event_step = 1;
        m->time_to_zero = 0.0;
        *taken = h;
        return since_append(m, h);
    }
    if (predicted)
        m->mispredicted++;
    if (!checkpointed) {
        /* An event in a step predicted free of them: replay from the checkpoint. */
        TRY(replay_to(m, t));
        TRY(advance(m, t, h));
    }
    TRY(locate(m, t, h, crossings, z0, z1, taken));
    m->after_event_step = 1;
    m->time_to_zero = 0.0;
    return since_append(m, m->t - m->located_from);
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

static int diverged(const cw_master *m)
{
    double s = 0.0;
    for (int i = 0; i < m->n_buffer; i++)
        s += fabs(m->buffer[i]);
    return !(s < m->divergence_limit);  /* NaN fails too */
}

static double fmi3_next_event_time(const struct cw_fmi3 *a);
static int fmi3_terminated(const struct cw_fmi3 *a);

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
    double t = m->t;
    /* 0. An FMI 3.0 instance that asked to end the simulation ends it here;
     * its announced time event caps the step. */
    for (int i = 0; i < m->n_fmi3; i++)
        if (fmi3_terminated(m->fmi3[i]))
            return CW_ENDED;
    for (int i = 0; i < m->n_fmi3; i++) {
        double te = fmi3_next_event_time(m->fmi3[i]);
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

static void record_point(cw_master *m, cw_recorder *r)
{
    if (r->tick_port >= 0) {
        double tt = m->ports[r->tick_port].out[r->tick_pos];
        if (tt != r->last_tick && tt > 0) {
            r->ticks[r->n_ticks++] = tt;
            r->last_tick = tt;
        }
    }
    if (!r->n_cols)
        return;
    double k = (m->t - m->start_time) / m->step;
    if (fabs(k - nearbyint(k)) < 1e-6) {  /* on the grid (events add points off it) */
        r->grid_seen++;
        if (r->grid_seen % r->stride)
            return;
    } else if (r->has_interval) {
        return;
    }
    double *row = &r->rows[(size_t)r->n_rows * (size_t)(r->n_cols + 1)];
    row[0] = m->t;
    for (int c = 0; c < r->n_cols; c++)
        row[c + 1] = m->ports[r->col_port[c]].out[r->col_pos[c]];
    r->n_rows++;
}

/* Record the current point (after a divergence check that found every output legal). */
CW_EXPORT void cw_record_point(cw_master *m, cw_recorder *r)
{
    record_point(m, r);
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

/* Step toward t_stop with steps of at most max_step, landing on `mark`
 * while it lies ahead and taking steps of `margin` after it, until one of
 * the watched outputs changes (Master.run_watch). `previous` gets the
 * values of the `n_prev` outputs at the point before the last one. */
CW_EXPORT int cw_run_watch(cw_master *m, double t_stop, double mark, double margin, double max_step,
                           int n_watch, const int *watch_port, const int *watch_pos,
                           int n_prev, const int *prev_port, const int *prev_pos, double *previous,
                           double slice_s)
{
    double eps = 1e-12 * py_max(1.0, fabs(t_stop));
    double seen[n_watch > 0 ? n_watch : 1];
    for (int k = 0; k < n_watch; k++)
        seen[k] = m->ports[watch_port[k]].out[watch_pos[k]];
    struct timespec began;
    clock_gettime(CLOCK_MONOTONIC, &began);
    unsigned steps = 0;
    while (m->t < t_stop - eps) {
        if (slice_over(&began, &steps, slice_s))
            return CW_SLICE_OVER;  /* nothing changed yet: calling again continues the same watch */
        for (int k = 0; k < n_prev; k++)
            previous[k] = m->ports[prev_port[k]].out[prev_pos[k]];
        double target = m->t < mark - eps ? mark : m->t + margin;
        double taken;
        int rc = step(m, py_min(py_min(max_step, target - m->t), t_stop - m->t), &taken);
        if (rc)
            return rc;
        for (int k = 0; k < n_watch; k++) {
            double now = m->ports[watch_port[k]].out[watch_pos[k]];
            if (now != seen[k])  /* NaN counts as a change, as in Python */
                return CW_WATCHED;
        }
    }
    return CW_DONE;
}

/* Tick points (Master.run_ticks): the watched outputs (the first a tick
 * time) recorded as rows (t, values...) wherever one changed, and the
 * next mark put `margin` after where the next tick is expected. */
typedef struct {
    const int *watch_port, *watch_pos;
    double *seen;              /* the watched values at the last row */
    double *rows;              /* capacity rows of (t, watched values) */
    double mark, margin, period, last_tick, prev_tick;
    int n_watch, capacity, n_rows, has_prev;
} cw_ticks;


/* Step toward t_stop with steps of at most max_step, landing on k->mark
 * while it lies ahead and taking steps of k->margin after it; a row where
 * a watched output changed; after a tick, the next mark one tick period
 * (the last one, else k->period) plus the margin after it. Returns
 * CW_DONE, CW_BUFFER_FULL or CW_SLICE_OVER (call again), or a step's
 * code (CW_CHECK_DIVERGENCE after the step's row: Python names the output). */
CW_EXPORT int cw_run_ticks(cw_master *m, double t_stop, double max_step, cw_ticks *k, double slice_s)
{
    double eps = 1e-12 * py_max(1.0, fabs(t_stop));
    struct timespec began;
    clock_gettime(CLOCK_MONOTONIC, &began);
    unsigned steps = 0;
    while (m->t < t_stop - eps) {
        if (k->n_rows >= k->capacity)
            return CW_BUFFER_FULL;
        if (slice_over(&began, &steps, slice_s))
            return CW_SLICE_OVER;
        double target = m->t < k->mark - eps ? k->mark : m->t + k->margin;
        double taken;
        int rc = step(m, py_min(py_min(max_step, target - m->t), t_stop - m->t), &taken);
        if (rc < 0 || rc == CW_ENDED)
            return rc;
        int changed = 0;
        for (int j = 0; j < k->n_watch; j++)
            if (m->ports[k->watch_port[j]].out[k->watch_pos[j]] != k->seen[j])  /* NaN: a change */
                changed = 1;
        if (changed) {
            double *row = &k->rows[(size_t)k->n_rows * (size_t)(k->n_watch + 1)];
            row[0] = m->t;
            for (int j = 0; j < k->n_watch; j++)
                row[j + 1] = k->seen[j] = m->ports[k->watch_port[j]].out[k->watch_pos[j]];
            k->n_rows++;
            double tt = k->seen[0];
            if (tt != k->last_tick) {
                if (k->last_tick > 0) {
                    k->prev_tick = k->last_tick;
                    k->has_prev = 1;
                }
                k->last_tick = tt;
                double period = k->has_prev ? tt - k->prev_tick : k->period;
                k->mark = tt + period + k->margin;
            }
        }
        if (rc == CW_CHECK_DIVERGENCE)
            return rc;
    }
    return CW_DONE;
}

/* Step to each of the increasing times in turn, one step each (none where
 * the master stands there already); there, where sets[k], give values[k]
 * to the n_in inputs (in_port, in_vr: unconnected inputs), else append the
 * n_out outputs as a row of `samples` (Master.run_schedule). *next and
 * *n_rows keep the place across calls (CW_SLICE_OVER, a divergence check). */
CW_EXPORT int cw_run_schedule(cw_master *m, int n, const double *times, const int *sets, const double *values,
                              int n_in, const int *in_port, const unsigned *in_vr, int n_out, const int *out_port,
                              const int *out_pos, double *samples, int *next, int *n_rows, double slice_s)
{
    struct timespec began;
    clock_gettime(CLOCK_MONOTONIC, &began);
    unsigned steps = 0;
    while (*next < n) {
        if (slice_over(&began, &steps, slice_s))
            return CW_SLICE_OVER;
        int k = *next, rc = CW_DONE;
        if (times[k] > m->t) {
            double taken;
            rc = step(m, times[k] - m->t, &taken);
            if (rc < 0 || rc == CW_ENDED)
                return rc;
        }
        if (sets[k]) {
            for (int a = 0; a < n_in; a++) {
                cw_port *p = &m->ports[in_port[a]];
                int st = p->setReal(p->comp, &in_vr[a], 1, &values[k]);
                if (st > FMI_WARNING)
                    return fail(m, in_port[a], CALL_SET_INPUTS, st, m->t, 0.0);
            }
        } else {
            double *row = &samples[(size_t)*n_rows * (size_t)n_out];
            for (int j = 0; j < n_out; j++)
                row[j] = m->ports[out_port[j]].out[out_pos[j]];
            (*n_rows)++;
        }
        (*next)++;
        if (rc == CW_CHECK_DIVERGENCE)
            return rc;
    }
    return CW_DONE;
}

/* FMU log messages: cw_logger, in cw_guard.c (it trusts nothing an FMU passes). */
int cw_env_known(const void *key);

/* ---- FMI 3.0: the adapter (the twin of clockwork/fmi/cs3.py) ----------
 *
 * Each function has the fmi2 shape the core calls and takes a cw_fmi3 as
 * its component. cw3_doStep steps through the FMU's own events: at an early
 * return it handles the event at lastSuccessfulTime and steps on to the
 * communication point; at eventHandlingNeeded it runs event mode
 * (fmi3EnterEventMode, fmi3UpdateDiscreteStates until the discrete states
 * settle, fmi3EnterStepMode) and keeps the announced next event time;
 * terminateSimulation returns Discard with `terminated` set.
 */

enum { MAX_EVENT_ITERATIONS = 1000, MAX_STALLED_RETURNS = 100 };

typedef int (*fmi3DoStep_t)(void *, double, double, bool, bool *, bool *, bool *, double *);
typedef int (*fmi3GetFloat64_t)(void *, const unsigned *, size_t, double *, size_t);
typedef int (*fmi3SetFloat64_t)(void *, const unsigned *, size_t, const double *, size_t);
typedef int (*fmi3GetOutputDerivatives_t)(void *, const unsigned *, size_t, const int *, double *, size_t);
typedef int (*fmi3GetFMUState_t)(void *, void **);
typedef int (*fmi3SetFMUState_t)(void *, void *);
typedef int (*fmi3ModeChange_t)(void *);
typedef int (*fmi3UpdateDiscreteStates_t)(void *, bool *, bool *, bool *, bool *, bool *, double *);

typedef struct cw_fmi3 {
    void *instance;
    fmi3DoStep_t doStep;
    fmi3GetFloat64_t getFloat64;
    fmi3SetFloat64_t setFloat64;
    fmi3GetOutputDerivatives_t getOutputDerivatives;
    fmi3GetFMUState_t getState;
    fmi3SetFMUState_t setState;
    fmi3ModeChange_t enterEventMode;
    fmi3UpdateDiscreteStates_t updateDiscreteStates;
    fmi3ModeChange_t enterStepMode;
    double next_event_time;       /* s; INFINITY when none is announced */
    double saved_next_event_time; /* with the saved FMU state */
    double end_time;              /* where terminateSimulation stopped the FMU, s */
    long long early_returns, events;
    int event_mode_used, terminated;
    int failed_call;              /* 0, or which call failed (fmu3.FAILED_CALLS) */
    int pad_;
    /* Intermediate update: the input polynomials FMI 2.0 would hand over
     * with fmi2SetRealInputDerivatives, kept here as an FMI 2.0 FMU keeps
     * them (u0 + d1 dt + d2 dt^2/2, dt from iu_tref: the FMU's time when
     * the value was set) and set by cw3_intermediateUpdate at the times
     * the FMU asks for. */
    int n_iu;                     /* inputs with intermediateUpdate = true */
    int iu_poly;                  /* some derivative is not 0 */
    const unsigned *iu_vr;
    double *iu_u0, *iu_d1, *iu_d2, *iu_tref;
    int *iu_fed;                  /* set by the master at least once */
    unsigned *iu_set_vr;          /* scratch for the callback's fmi3SetFloat64 */
    double *iu_val;
    double iu_time;               /* the FMU's time: start, then the end of each step, s */
    double iu_saved_time;
    long long iu_calls;           /* callbacks that set inputs */
    double *iu_saved;             /* u0, d1, d2, tref (4 n_iu) with the saved FMU state, */
    int *iu_saved_fed;            /* as FMI 2.0 saves its polynomials in its state */
    /* Array elements (fmu3.Instance3._number_elements): the code
     * code_base + k names value code_off[k] of the code_size[k] values of
     * the array variable code_vr[k]. A request whose codes cover whole
     * arrays in order is one fmi3 call with nValues > nValueReferences;
     * any other is served element by element. */
    unsigned code_base;
    int n_codes;
    const unsigned *code_vr;
    const int *code_off, *code_size;
    unsigned *scratch_vr;         /* the value references of one call, translated */
    int *scratch_order;           /* and their derivative orders */
    double *scratch_val;          /* one array's values */
    int scratch_cap, scratch_val_cap;
} cw_fmi3;


static double fmi3_next_event_time(const cw_fmi3 *a) { return a->next_event_time; }
static int fmi3_terminated(const cw_fmi3 *a) { return a->terminated; }

static int fmi3_settle(cw_fmi3 *a)
{
    bool need = false, term = false, nominals = false, values = false, defined = false;
    double next_time = 0.0;
    int st = FMI_OK, k;
    for (k = 0; k < MAX_EVENT_ITERATIONS; k++) {
        int s = a->updateDiscreteStates(a->instance, &need, &term, &nominals, &values, &defined, &next_time);
        st = s > st ? s : st;
        if (s > FMI_WARNING) {
            a->failed_call = 3;
            return s;
        }
        if (term)
            a->terminated = 1;
        if (!need)
            break;
    }
    if (k == MAX_EVENT_ITERATIONS) {
        a->failed_call = 6;
        return FMI_ERROR;
    }
    a->next_event_time = defined ? next_time : INFINITY;
    a->events += 1;
    int s = a->enterStepMode(a->instance);
    if (s > FMI_WARNING)
        a->failed_call = 4;
    return s > st ? s : st;
}

static int fmi3_handle_event(cw_fmi3 *a)
{
    int st = a->enterEventMode(a->instance);
    if (st > FMI_WARNING) {
        a->failed_call = 2;
        return st;
    }
    int s = fmi3_settle(a);
    return s > st ? s : st;
}

/* The importer's side of Intermediate Update Mode (instanceEnvironment is
 * the cw_fmi3): set each fed input to its polynomial at `t`, with the
 * arithmetic of the runtime's cw_input, so that FMI 2.0 and 3.0 give the
 * same bits. Held inputs (every derivative 0) the FMU already has. */
CW_EXPORT void cw3_intermediateUpdate(void *env, double t, bool set_requested, bool get_allowed,
                                      bool step_finished, bool can_return_early, bool *early_requested,
                                      double *early_time)
{
    (void)get_allowed; (void)step_finished; (void)can_return_early; (void)early_time;
    if (early_requested)
        *early_requested = false;
    /* Only an environment the master gave (cw_guard.c's registry): an FMU
     * may pass any pointer back. */
    if (!set_requested || !cw_env_known(env))
        return;
    cw_fmi3 *a = env;
    if (!a->iu_poly)
        return;
    size_t m = 0;
    for (int k = 0; k < a->n_iu; k++)
        if (a->iu_fed[k]) {
            const double dt = t - a->iu_tref[k];
            a->iu_set_vr[m] = a->iu_vr[k];
            a->iu_val[m++] = input_polynomial(a->iu_u0[k], a->iu_d1[k], a->iu_d2[k], dt);
        }
    a->iu_calls += 1;
    a->setFloat64(a->instance, a->iu_set_vr, m, a->iu_val, m);  /* a refusal fails fmi3DoStep */
}

static int iu_index(const cw_fmi3 *a, unsigned vr)
{
    for (int k = 0; k < a->n_iu; k++)
        if (a->iu_vr[k] == vr)
            return k;
    return -1;
}

static void iu_recheck(cw_fmi3 *a)
{
    a->iu_poly = 0;
    for (int k = 0; k < a->n_iu; k++)
        if (a->iu_fed[k] && (a->iu_d1[k] != 0.0 || a->iu_d2[k] != 0.0))
            a->iu_poly = 1;
}

CW_EXPORT int cw3_doStep(void *comp, double t, double h, int no_set_prior)
{
    cw_fmi3 *a = comp;
    double end = t + h, now = t, step_size = h;
    int worst = FMI_OK, stalled = 0;
    for (;;) {
        bool handling = false, term = false, early = false;
        double last = 0.0;
        int st = a->doStep(a->instance, now, step_size, no_set_prior != 0, &handling, &term, &early, &last);
        if (st > FMI_WARNING) {
            a->failed_call = 1;
            return st;
        }
        worst = st > worst ? st : worst;
        double reached = early ? last : end;
        if (handling && a->event_mode_used) {
            st = fmi3_handle_event(a);
            if (st > FMI_WARNING)
                return st;
            worst = st > worst ? st : worst;
        }
        if (term)
            reached = last;  /* where the FMU stopped, early return or not */
        if (term || a->terminated) {
            /* A whole step is kept; one the FMU stopped short of is discarded. */
            a->terminated = 1;
            a->end_time = reached;
            return reached >= end ? worst : FMI_DISCARD;
        }
        if (!early || reached >= end) {
            a->iu_time = end;
            return worst;
        }
        a->early_returns += 1;
        stalled = reached <= now ? stalled + 1 : 0;
        if (stalled > MAX_STALLED_RETURNS) {
            a->failed_call = 5;
            return FMI_ERROR;
        }
        now = reached;
        step_size = end - reached;
        /* The FMU's step must end on `end` itself (now + step_size rounds),
         * so that it lands where a step without early return lands. */
        while (now + step_size < end)
            step_size = nextafter(step_size, INFINITY);
        while (now + step_size > end)
            step_size = nextafter(step_size, 0.0);
    }
}

/* The element number of a code, or -1 for a plain value reference. */
static int code_element(const cw_fmi3 *a, unsigned code)
{
    unsigned e = code - a->code_base;  /* wraps for codes below the base */
    return e < (unsigned)a->n_codes ? (int)e : -1;
}

/* Translate n codes into a->scratch_vr (and their orders, when given, into
 * a->scratch_order): *m value references, each array whole. 0 when the
 * request holds part of an array, an array out of order, an array with
 * orders that differ, or more references than the scratch holds. */
static int code_runs(cw_fmi3 *a, const unsigned *vr, size_t n, const int *order, size_t *m)
{
    size_t k = 0, j = 0;
    while (k < n) {
        if (j >= (size_t)a->scratch_cap)
            return 0;
        int e = code_element(a, vr[k]);
        size_t size = 1;
        if (e >= 0) {
            size = (size_t)a->code_size[e];
            if (a->code_off[e] != 0 || k + size > n)
                return 0;
            for (size_t i = 1; i < size; i++)
                if (vr[k + i] != vr[k] + i || (order && order[k + i] != order[k]))
                    return 0;
            a->scratch_vr[j] = a->code_vr[e];
        } else {
            a->scratch_vr[j] = vr[k];
        }
        if (order)
            a->scratch_order[j] = order[k];
        j++;
        k += size;
    }
    *m = j;
    return 1;
}

/* fmi3GetFloat64 (order NULL) or fmi3GetOutputDerivatives of n codes,
 * element by element: each element's whole array, then its value. */
static int get_elementwise(cw_fmi3 *a, const unsigned *vr, size_t n, const int *order, double *out)
{
    int worst = FMI_OK;
    for (size_t k = 0; k < n; k++) {
        int e = code_element(a, vr[k]);
        unsigned one = e >= 0 ? a->code_vr[e] : vr[k];
        size_t size = e >= 0 ? (size_t)a->code_size[e] : 1;
        int st = order ? a->getOutputDerivatives(a->instance, &one, 1, &order[k], a->scratch_val, size)
                       : a->getFloat64(a->instance, &one, 1, a->scratch_val, size);
        worst = st > worst ? st : worst;
        if (st > FMI_WARNING)
            return st;
        out[k] = a->scratch_val[e >= 0 ? a->code_off[e] : 0];
    }
    return worst;
}

CW_EXPORT int cw3_getReal(void *comp, const unsigned *vr, size_t n, double *out)
{
    cw_fmi3 *a = comp;
    if (!a->n_codes)
        return a->getFloat64(a->instance, vr, n, out, n);
    size_t m;
    if (code_runs(a, vr, n, NULL, &m))
        return a->getFloat64(a->instance, a->scratch_vr, m, out, n);
    return get_elementwise(a, vr, n, NULL, out);
}

CW_EXPORT int cw3_setReal(void *comp, const unsigned *vr, size_t n, const double *values)
{
    cw_fmi3 *a = comp;
    int st;
    if (!a->n_codes) {
        st = a->setFloat64(a->instance, vr, n, values, n);
    } else {
        size_t m;
        if (!code_runs(a, vr, n, NULL, &m))
            return FMI_ERROR;  /* part of an array: the ports set arrays whole */
        st = a->setFloat64(a->instance, a->scratch_vr, m, values, n);
    }
    if (st <= FMI_WARNING && a->n_iu) {
        /* A value without derivatives is held (as fmi2SetReal on FMI 2.0). */
        for (size_t k = 0; k < n; k++) {
            int j = iu_index(a, vr[k]);
            if (j >= 0) {
                a->iu_u0[j] = values[k];
                a->iu_d1[j] = a->iu_d2[j] = 0.0;
                a->iu_tref[j] = a->iu_time;
                a->iu_fed[j] = 1;
            }
        }
        iu_recheck(a);
    }
    return st;
}

/* FMI 3.0 CS has no input derivatives: with intermediate update they are
 * kept for cw3_intermediateUpdate; without it (n_iu = 0) they are refused
 * (the master refuses extrapolation into such an FMU first). */
CW_EXPORT int cw3_setInputDerivatives(void *comp, const unsigned *vr, size_t n, const int *order,
                                      const double *values)
{
    cw_fmi3 *a = comp;
    for (size_t k = 0; k < n; k++) {
        int j = iu_index(a, vr[k]);
        if (j < 0 || !a->iu_fed[j] || order[k] < 1 || order[k] > 2 || !isfinite(values[k]))
            return FMI_ERROR;
    }
    for (size_t k = 0; k < n; k++) {
        int j = iu_index(a, vr[k]);
        if (a->iu_tref[j] != a->iu_time) {
            /* Re-based at the FMU's time, as the FMI 2.0 runtime does. */
            const double dt = a->iu_time - a->iu_tref[j];
            a->iu_u0[j] = input_polynomial(a->iu_u0[j], a->iu_d1[j], a->iu_d2[j], dt);
            a->iu_d1[j] = a->iu_d2[j] = 0.0;
            a->iu_tref[j] = a->iu_time;
        }
        if (order[k] == 1)
            a->iu_d1[j] = values[k];
        else
            a->iu_d2[j] = values[k];
    }
    iu_recheck(a);
    return FMI_OK;
}

CW_EXPORT int cw3_getOutputDerivatives(void *comp, const unsigned *vr, size_t n, const int *order, double *out)
{
    cw_fmi3 *a = comp;
    if (!a->n_codes)
        return a->getOutputDerivatives(a->instance, vr, n, order, out, n);
    size_t m;
    if (code_runs(a, vr, n, order, &m))
        return a->getOutputDerivatives(a->instance, a->scratch_vr, m, a->scratch_order, out, n);
    return get_elementwise(a, vr, n, order, out);
}

CW_EXPORT int cw3_getState(void *comp, void **state)
{
    cw_fmi3 *a = comp;
    int st = a->getState(a->instance, state);
    a->saved_next_event_time = a->next_event_time;
    if (a->n_iu) {
        size_t n = (size_t)a->n_iu;
        memcpy(a->iu_saved, a->iu_u0, n * sizeof(double));
        memcpy(a->iu_saved + n, a->iu_d1, n * sizeof(double));
        memcpy(a->iu_saved + 2 * n, a->iu_d2, n * sizeof(double));
        memcpy(a->iu_saved + 3 * n, a->iu_tref, n * sizeof(double));
        memcpy(a->iu_saved_fed, a->iu_fed, n * sizeof(int));
        a->iu_saved_time = a->iu_time;
    }
    return st;
}

CW_EXPORT int cw3_setState(void *comp, void *state)
{
    cw_fmi3 *a = comp;
    int st = a->setState(a->instance, state);
    a->next_event_time = a->saved_next_event_time;
    if (a->n_iu) {
        size_t n = (size_t)a->n_iu;
        memcpy(a->iu_u0, a->iu_saved, n * sizeof(double));
        memcpy(a->iu_d1, a->iu_saved + n, n * sizeof(double));
        memcpy(a->iu_d2, a->iu_saved + 2 * n, n * sizeof(double));
        memcpy(a->iu_tref, a->iu_saved + 3 * n, n * sizeof(double));
        memcpy(a->iu_fed, a->iu_saved_fed, n * sizeof(int));
        a->iu_time = a->iu_saved_time;
        iu_recheck(a);
    }
    return st;
}

/* ---- FMI 1.0: the adapter (the twin of clockwork/fmi/cs1.py) ----------
 *
 * Each function has the fmi2 shape the core calls and takes a cw_fmi1 as
 * its component. fmiDoStep's last argument is FMI 1.0's newStep, an
 * fmiBoolean (a char), where fmi2DoStep has an int: cw1_doStep calls it
 * through its own type, always with newStep = true (a step of an FMU
 * without state is never repeated). FMI 1.0 computes outputs in fmiDoStep:
 * outputs read after inputs were set (no step between) are computed first
 * by a step of size 0 at the communication point (cw1_fresh), FMI 1.0's
 * iteration, as FMI 2.0 computes them on the get. A negated alias has a value reference
 * of its own (negated_vr), turned into the FMU's (base_vr) with its value
 * negated both ways. FMI 1.0 has no FMU state: the master refuses every
 * setting that needs one before the first step.
 */

typedef char fmi1_boolean;
typedef int (*fmi1DoStep_t)(void *, double, double, fmi1_boolean);

typedef struct cw_fmi1 {
    void *instance;
    fmi1DoStep_t doStep;
    cw_getReal_t getReal;
    cw_setReal_t setReal;
    cw_setDer_t setInputDerivatives;
    cw_getDer_t getOutputDerivatives;
    const unsigned *negated_vr; /* the master's value references of negated aliases */
    const unsigned *base_vr;    /* the FMU's, whose value they negate */
    double time;                /* the FMU's communication point, s */
    long long zero_steps;       /* steps of size 0 taken to compute outputs */
    int n_negated;
    int stale;                  /* inputs set since fmiDoStep last computed the outputs */
    int failed_zero;            /* the last zero step failed (fmu1.Instance1.fail says so) */
    int pad_;
} cw_fmi1;


enum { CW1_CHUNK = 64 };  /* value references translated at a time */

/* The FMU's value references for vr[0..n) (n <= CW1_CHUNK) and which are negated. */
static void cw1_own(const cw_fmi1 *a, const unsigned *vr, size_t n, unsigned *own, int *negated)
{
    for (size_t k = 0; k < n; k++) {
        own[k] = vr[k];
        negated[k] = 0;
        for (int j = 0; j < a->n_negated; j++)
            if (a->negated_vr[j] == vr[k]) {
                own[k] = a->base_vr[j];
                negated[k] = 1;
                break;
            }
    }
}

CW_EXPORT int cw1_doStep(void *comp, double t, double h, int no_set_prior)
{
    cw_fmi1 *a = comp;
    (void)no_set_prior;  /* FMI 1.0 has no FMU state to set */
    int st = a->doStep(a->instance, t, h, (fmi1_boolean)1);
    if (st <= FMI_WARNING) {
        a->time = t + h;
        a->stale = 0;
    }
    return st;
}

/* FMI 1.0 computes outputs in fmiDoStep: where inputs were set since the
 * last step, a step of size 0 at the communication point first (FMI 1.0's
 * iteration; FMI 2.0 computes them on the get). */
static int cw1_fresh(cw_fmi1 *a)
{
    if (!a->stale)
        return FMI_OK;
    int st = a->doStep(a->instance, a->time, 0.0, (fmi1_boolean)1);
    if (st > FMI_WARNING) {
        a->failed_zero = 1;
        return st;
    }
    a->stale = 0;
    a->zero_steps++;
    return st;
}

/* A call with negated aliases among vr: through the FMU's value references,
 * CW1_CHUNK at a time, values given negated and values read negated back. */
enum { CW1_GET_REAL, CW1_SET_REAL, CW1_SET_DER, CW1_GET_DER };

static int cw1_translated(cw_fmi1 *a, int call, const unsigned *vr, size_t n, const int *order,
                          const double *given, double *out)
{
    int worst = FMI_OK;
    for (size_t at = 0; at < n; at += CW1_CHUNK) {
        size_t m = n - at < CW1_CHUNK ? n - at : CW1_CHUNK;
        unsigned own[CW1_CHUNK];
        int negated[CW1_CHUNK];
        double values[CW1_CHUNK];
        cw1_own(a, vr + at, m, own, negated);
        if (given)
            for (size_t k = 0; k < m; k++)
                values[k] = negated[k] ? -given[at + k] : given[at + k];
        int st;
        switch (call) {
        case CW1_GET_REAL: st = a->getReal(a->instance, own, m, out + at); break;
        case CW1_SET_REAL: st = a->setReal(a->instance, own, m, values); break;
        case CW1_SET_DER: st = a->setInputDerivatives(a->instance, own, m, order + at, values); break;
        default: st = a->getOutputDerivatives(a->instance, own, m, order + at, out + at); break;
        }
        if (st > FMI_WARNING)
            return st;
        worst = st > worst ? st : worst;
        if (out)
            for (size_t k = 0; k < m; k++)
                if (negated[k])
                    out[at + k] = -out[at + k];
    }
    return worst;
}

CW_EXPORT int cw1_getReal(void *comp, const unsigned *vr, size_t n, double *out)
{
    cw_fmi1 *a = comp;
    int fresh = cw1_fresh(a);
    if (fresh > FMI_WARNING)
        return fresh;
    int st = a->n_negated ? cw1_translated(a, CW1_GET_REAL, vr, n, NULL, NULL, out)
                          : a->getReal(a->instance, vr, n, out);
    return st > fresh ? st : fresh;
}

CW_EXPORT int cw1_setReal(void *comp, const unsigned *vr, size_t n, const double *values)
{
    cw_fmi1 *a = comp;
    int st = a->n_negated ? cw1_translated(a, CW1_SET_REAL, vr, n, NULL, values, NULL)
                          : a->setReal(a->instance, vr, n, values);
    if (n)
        a->stale = 1;
    return st;
}

CW_EXPORT int cw1_setInputDerivatives(void *comp, const unsigned *vr, size_t n, const int *order,
                                      const double *values)
{
    cw_fmi1 *a = comp;
    return a->n_negated ? cw1_translated(a, CW1_SET_DER, vr, n, order, values, NULL)
                        : a->setInputDerivatives(a->instance, vr, n, order, values);
}

CW_EXPORT int cw1_getOutputDerivatives(void *comp, const unsigned *vr, size_t n, const int *order, double *out)
{
    cw_fmi1 *a = comp;
    int fresh = cw1_fresh(a);
    if (fresh > FMI_WARNING)
        return fresh;
    int st = a->n_negated ? cw1_translated(a, CW1_GET_DER, vr, n, order, NULL, out)
                          : a->getOutputDerivatives(a->instance, vr, n, order, out);
    return st > fresh ? st : fresh;
}

/* Never called: the master refuses rollback for FMI 1.0 before the first step. */
CW_EXPORT int cw1_getState(void *comp, void **state)
{
    (void)comp;
    (void)state;
    return FMI_ERROR;
}

CW_EXPORT int cw1_setState(void *comp, void *state)
{
    (void)comp;
    (void)state;
    return FMI_ERROR;
}

/* The layouts Python checks its ctypes mirrors against (cw_layout.h). */
static const cw_field port_layout[] = {
    CW_FIELD(cw_port, comp), CW_FIELD(cw_port, doStep), CW_FIELD(cw_port, getReal),
    CW_FIELD(cw_port, setReal), CW_FIELD(cw_port, setInputDerivatives),
    CW_FIELD(cw_port, getOutputDerivatives), CW_FIELD(cw_port, getState), CW_FIELD(cw_port, setState),
    CW_FIELD(cw_port, state), CW_FIELD(cw_port, out_vr), CW_FIELD(cw_port, out), CW_FIELD(cw_port, in_vr),
    CW_FIELD(cw_port, inp), CW_FIELD(cw_port, der_vr), CW_FIELD(cw_port, der_order), CW_FIELD(cw_port, der),
    CW_FIELD(cw_port, src_port), CW_FIELD(cw_port, src_pos), CW_FIELD(cw_port, sent),
    CW_FIELD(cw_port, dsrc_port), CW_FIELD(cw_port, dsrc_vr), CW_FIELD(cw_port, dsrc_m),
    CW_FIELD(cw_port, hist_t), CW_FIELD(cw_port, hist_v), CW_FIELD(cw_port, snap_hist_t),
    CW_FIELD(cw_port, snap_hist_v), CW_FIELD(cw_port, scaled), CW_FIELD(cw_port, in_factor),
    CW_FIELD(cw_port, in_offset), CW_FIELD(cw_port, out_time), CW_FIELD(cw_port, lowered_at),
    CW_FIELD(cw_port, n_out), CW_FIELD(cw_port, n_in), CW_FIELD(cw_port, n_z),
    CW_FIELD(cw_port, max_output_derivative_order), CW_FIELD(cw_port, sent_valid), CW_FIELD(cw_port, hist_n),
    CW_FIELD(cw_port, snap_hist_n), CW_FIELD(cw_port, n_scaled), CW_FIELD(cw_port, ext_order),
    CW_FIELD(cw_port, pad_), CW_FIELD(cw_port, it_start), CW_FIELD(cw_port, it_end),
    CW_FIELD(cw_port, can_interpolate), CW_FIELD(cw_port, pad2_),
};
static const cw_field loop_layout[] = {
    CW_FIELD(cw_loop, members), CW_FIELD(cw_loop, u_port), CW_FIELD(cw_loop, u_pos), CW_FIELD(cw_loop, u_src),
    CW_FIELD(cw_loop, u_src_pos), CW_FIELD(cw_loop, u_factor), CW_FIELD(cw_loop, u_offset),
    CW_FIELD(cw_loop, u_scaled), CW_FIELD(cw_loop, r), CW_FIELD(cw_loop, fail_worst),
    CW_FIELD(cw_loop, n_members), CW_FIELD(cw_loop, n), CW_FIELD(cw_loop, fail_why),
    CW_FIELD(cw_loop, fail_at), CW_FIELD(cw_loop, fail_sweeps), CW_FIELD(cw_loop, fail_newton),
};
static const cw_field loops_layout[] = {
    CW_FIELD(cw_loops, loop), CW_FIELD(cw_loops, tolerance), CW_FIELD(cw_loops, iterations),
    CW_FIELD(cw_loops, fallbacks), CW_FIELD(cw_loops, n_loops), CW_FIELD(cw_loops, pad_),
};
static const cw_field master_layout[] = {
    CW_FIELD(cw_master, ports), CW_FIELD(cw_master, first), CW_FIELD(cw_master, dynamic),
    CW_FIELD(cw_master, first_in_order), CW_FIELD(cw_master, final_order), CW_FIELD(cw_master, buffer),
    CW_FIELD(cw_master, z_port), CW_FIELD(cw_master, z_pos), CW_FIELD(cw_master, z_start),
    CW_FIELD(cw_master, z_end), CW_FIELD(cw_master, zs_port), CW_FIELD(cw_master, zs_pos),
    CW_FIELD(cw_master, zs_vr), CW_FIELD(cw_master, prev_kind), CW_FIELD(cw_master, prev_u),
    CW_FIELD(cw_master, prev_du), CW_FIELD(cw_master, amp_u), CW_FIELD(cw_master, amp_du),
    CW_FIELD(cw_master, z_seen), CW_FIELD(cw_master, end_rate_set), CW_FIELD(cw_master, end_rate),
    CW_FIELD(cw_master, snap_z_end), CW_FIELD(cw_master, since), CW_FIELD(cw_master, t),
    CW_FIELD(cw_master, start_time), CW_FIELD(cw_master, step), CW_FIELD(cw_master, event_time_tolerance),
    CW_FIELD(cw_master, event_indicator_tolerance), CW_FIELD(cw_master, divergence_limit),
    CW_FIELD(cw_master, time_to_zero), CW_FIELD(cw_master, step_cap), CW_FIELD(cw_master, located_from),
    CW_FIELD(cw_master, snap_t), CW_FIELD(cw_master, snap_time_to_zero), CW_FIELD(cw_master, err_t),
    CW_FIELD(cw_master, err_h), CW_FIELD(cw_master, steps), CW_FIELD(cw_master, events),
    CW_FIELD(cw_master, event_iterations), CW_FIELD(cw_master, rollbacks), CW_FIELD(cw_master, replays),
    CW_FIELD(cw_master, states_saved), CW_FIELD(cw_master, n_ports), CW_FIELD(cw_master, n_first),
    CW_FIELD(cw_master, n_dynamic), CW_FIELD(cw_master, n_first_in_order), CW_FIELD(cw_master, n_final),
    CW_FIELD(cw_master, n_buffer), CW_FIELD(cw_master, n_z), CW_FIELD(cw_master, cap_since),
    CW_FIELD(cw_master, jacobi), CW_FIELD(cw_master, extrapolation), CW_FIELD(cw_master, locating),
    CW_FIELD(cw_master, has_sources), CW_FIELD(cw_master, after_event), CW_FIELD(cw_master, after_event_step),
    CW_FIELD(cw_master, sample_countdown), CW_FIELD(cw_master, prev_valid),
    CW_FIELD(cw_master, stale_sources), CW_FIELD(cw_master, snap_valid),
    CW_FIELD(cw_master, snap_after_event), CW_FIELD(cw_master, n_since),
    CW_FIELD(cw_master, max_replay_steps), CW_FIELD(cw_master, diverged), CW_FIELD(cw_master, err_port),
    CW_FIELD(cw_master, err_call), CW_FIELD(cw_master, err_status), CW_FIELD(cw_master, orders_lowered),
    CW_FIELD(cw_master, n_fmi3), CW_FIELD(cw_master, pad4_), CW_FIELD(cw_master, fmi3), CW_FIELD(cw_master, pred_kind),
    CW_FIELD(cw_master, pred_u), CW_FIELD(cw_master, pred_du), CW_FIELD(cw_master, pred_ddu),
    CW_FIELD(cw_master, last_z), CW_FIELD(cw_master, sampled_t), CW_FIELD(cw_master, sampled_before_t),
    CW_FIELD(cw_master, last_t), CW_FIELD(cw_master, predicted_landings),
    CW_FIELD(cw_master, mispredicted), CW_FIELD(cw_master, predicting), CW_FIELD(cw_master, last_valid),
    CW_FIELD(cw_master, iteration_tolerance), CW_FIELD(cw_master, coupling_iterations),
    CW_FIELD(cw_master, iterations), CW_FIELD(cw_master, pad3_), CW_FIELD(cw_master, loops),
    CW_FIELD(cw_master, pool), CW_FIELD(cw_master, par_end), CW_FIELD(cw_master, par_status),
    CW_FIELD(cw_master, after_start), CW_FIELD(cw_master, after_order), CW_FIELD(cw_master, inputs),
};
static const cw_field inputs_layout[] = {
    CW_FIELD(cw_inputs, times), CW_FIELD(cw_inputs, values), CW_FIELD(cw_inputs, continuous),
    CW_FIELD(cw_inputs, events), CW_FIELD(cw_inputs, port_start), CW_FIELD(cw_inputs, vr),
    CW_FIELD(cw_inputs, signal), CW_FIELD(cw_inputs, value), CW_FIELD(cw_inputs, after_step), CW_FIELD(cw_inputs, n_times),
    CW_FIELD(cw_inputs, n_signals), CW_FIELD(cw_inputs, n_events), CW_FIELD(cw_inputs, pad_),
};
static const cw_field recorder_layout[] = {
    CW_FIELD(cw_recorder, col_port), CW_FIELD(cw_recorder, col_pos), CW_FIELD(cw_recorder, rows),
    CW_FIELD(cw_recorder, ticks), CW_FIELD(cw_recorder, last_tick), CW_FIELD(cw_recorder, grid_seen),
    CW_FIELD(cw_recorder, grid_k), CW_FIELD(cw_recorder, n_cols), CW_FIELD(cw_recorder, capacity),
    CW_FIELD(cw_recorder, n_rows), CW_FIELD(cw_recorder, tick_capacity), CW_FIELD(cw_recorder, n_ticks),
    CW_FIELD(cw_recorder, stride), CW_FIELD(cw_recorder, tick_port), CW_FIELD(cw_recorder, tick_pos),
    CW_FIELD(cw_recorder, has_interval), CW_FIELD(cw_recorder, pad_),
};
static const cw_field ticks_layout[] = {
    CW_FIELD(cw_ticks, watch_port), CW_FIELD(cw_ticks, watch_pos), CW_FIELD(cw_ticks, seen),
    CW_FIELD(cw_ticks, rows), CW_FIELD(cw_ticks, mark), CW_FIELD(cw_ticks, margin),
    CW_FIELD(cw_ticks, period), CW_FIELD(cw_ticks, last_tick), CW_FIELD(cw_ticks, prev_tick),
    CW_FIELD(cw_ticks, n_watch), CW_FIELD(cw_ticks, capacity), CW_FIELD(cw_ticks, n_rows),
    CW_FIELD(cw_ticks, has_prev),
};
static const cw_field fmi3_layout[] = {
    CW_FIELD(cw_fmi3, instance), CW_FIELD(cw_fmi3, doStep), CW_FIELD(cw_fmi3, getFloat64),
    CW_FIELD(cw_fmi3, setFloat64), CW_FIELD(cw_fmi3, getOutputDerivatives), CW_FIELD(cw_fmi3, getState),
    CW_FIELD(cw_fmi3, setState), CW_FIELD(cw_fmi3, enterEventMode), CW_FIELD(cw_fmi3, updateDiscreteStates),
    CW_FIELD(cw_fmi3, enterStepMode), CW_FIELD(cw_fmi3, next_event_time),
    CW_FIELD(cw_fmi3, saved_next_event_time), CW_FIELD(cw_fmi3, end_time),
    CW_FIELD(cw_fmi3, early_returns), CW_FIELD(cw_fmi3, events), CW_FIELD(cw_fmi3, event_mode_used),
    CW_FIELD(cw_fmi3, terminated), CW_FIELD(cw_fmi3, failed_call), CW_FIELD(cw_fmi3, pad_),
    CW_FIELD(cw_fmi3, n_iu), CW_FIELD(cw_fmi3, iu_poly), CW_FIELD(cw_fmi3, iu_vr), CW_FIELD(cw_fmi3, iu_u0),
    CW_FIELD(cw_fmi3, iu_d1), CW_FIELD(cw_fmi3, iu_d2), CW_FIELD(cw_fmi3, iu_tref), CW_FIELD(cw_fmi3, iu_fed),
    CW_FIELD(cw_fmi3, iu_set_vr), CW_FIELD(cw_fmi3, iu_val), CW_FIELD(cw_fmi3, iu_time),
    CW_FIELD(cw_fmi3, iu_saved_time), CW_FIELD(cw_fmi3, iu_calls), CW_FIELD(cw_fmi3, iu_saved),
    CW_FIELD(cw_fmi3, iu_saved_fed), CW_FIELD(cw_fmi3, code_base), CW_FIELD(cw_fmi3, n_codes),
    CW_FIELD(cw_fmi3, code_vr), CW_FIELD(cw_fmi3, code_off), CW_FIELD(cw_fmi3, code_size),
    CW_FIELD(cw_fmi3, scratch_vr), CW_FIELD(cw_fmi3, scratch_order), CW_FIELD(cw_fmi3, scratch_val),
    CW_FIELD(cw_fmi3, scratch_cap), CW_FIELD(cw_fmi3, scratch_val_cap),
};
static const cw_field fmi1_layout[] = {
    CW_FIELD(cw_fmi1, instance), CW_FIELD(cw_fmi1, doStep), CW_FIELD(cw_fmi1, getReal),
    CW_FIELD(cw_fmi1, setReal), CW_FIELD(cw_fmi1, setInputDerivatives),
    CW_FIELD(cw_fmi1, getOutputDerivatives), CW_FIELD(cw_fmi1, negated_vr), CW_FIELD(cw_fmi1, base_vr),
    CW_FIELD(cw_fmi1, time), CW_FIELD(cw_fmi1, zero_steps), CW_FIELD(cw_fmi1, n_negated),
    CW_FIELD(cw_fmi1, stale), CW_FIELD(cw_fmi1, failed_zero), CW_FIELD(cw_fmi1, pad_),
};

CW_EXPORT const cw_field *cw_layout(const char *name, size_t *n_fields, size_t *struct_size)
{
    CW_LAYOUT_CASE(port)
    CW_LAYOUT_CASE(loop)
    CW_LAYOUT_CASE(loops)
    CW_LAYOUT_CASE(master)
    CW_LAYOUT_CASE(inputs)
    CW_LAYOUT_CASE(recorder)
    CW_LAYOUT_CASE(ticks)
    CW_LAYOUT_CASE(fmi3)
    CW_LAYOUT_CASE(fmi1)
    *n_fields = 0;
    *struct_size = 0;
    return NULL;
}
