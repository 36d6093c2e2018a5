/* What the master's files share among themselves (Python sees none of
 * it): return codes, the shared helpers, and the functions one file
 * calls in another. The structs are in cw_structs.h, the numerics in
 * cw_numerics.h and cw_polynomial.h. docs/architecture.md has the table of
 * files.
 *
 * The functions below crossed no file boundary when the master was one
 * file; the library is built with link-time optimisation where the
 * compiler has it (CMakeLists.txt), so that they are inlined as before.
 */
#ifndef CW_MASTER_H
#define CW_MASTER_H

#include <math.h>
#include <stddef.h>

#include "cw_structs.h"
#include "cw_numerics.h"
#include "cw_polynomial.h"

#define CW_EXPORT __attribute__((visibility("default")))

enum { FMI_OK = 0, FMI_WARNING = 1, FMI_DISCARD = 2, FMI_ERROR = 3, FMI_FATAL = 4 };

/* Return codes (the Python side turns errors into SimulationError). */
enum {
    CW_DONE = 0,
    CW_BUFFER_FULL = 1,     /* recording buffers full: drain and call again */
    CW_CHECK_DIVERGENCE = 2,/* an output is not finite or too large: Python names it */
    CW_WATCHED = 3,         /* a watched output changed (cw_run_marks, stop_at_change) */
    CW_ENDED = 4,           /* an instance asked to end the simulation (FMI 3.0 terminateSimulation) */
    CW_SLICE_OVER = 5,      /* the call's slice of wall time is spent: call again (Python handles signals between calls) */
    CW_CLOCK_EVENT = 6,     /* the step ended at an event of the FMI 3.0 clocks: Python runs it, then calls again */
    CW_ERR_FMI = -1,        /* an fmi2 call failed: err_port, err_call, err_status */
    CW_ERR_NO_CHECKPOINT = -2,
    CW_ERR_REPLAY = -3,
    CW_ERR_LOCATE = -4,
    CW_ERR_CAPACITY = -5,
    CW_ERR_LOOP = -6,       /* an algebraic loop did not converge: err_port is the loop, see its fail_* */
    CW_ERR_RATES = -7,      /* components at their own steps: not a whole base step (err_call says why) */
};

/* Why a step across rates was refused (CW_ERR_RATES's err_call; err_t the step's start, err_h the step or
 * the event's time): multirate.py's REFUSALS, in this order. */
enum { RATES_OFF_BASE = 0, RATES_TIME_EVENT, RATES_SAMPLE_EVENT };

/* Which call failed (err_call). */
enum {
    CALL_DO_STEP = 0, CALL_GET_REAL, CALL_SET_INPUTS, CALL_SET_INPUT_DERIVATIVES,
    CALL_GET_STATE, CALL_SET_STATE,
};

static inline double py_min(double a, double b) { return b < a ? b : a; }
static inline double py_max(double a, double b) { return b > a ? b : a; }

static inline double ulp(double x)  /* math.ulp for finite x >= 0 */
{
    return nextafter(x, INFINITY) - x;
}

static inline int fail(cw_master *m, int port, int call, int status, double t, double h)
{
    m->err_port = port;
    m->err_call = call;
    m->err_status = status;
    m->err_t = t;
    m->err_h = h;
    return CW_ERR_FMI;
}

#define TRY(x) do { int rc_ = (x); if (rc_ < 0) return rc_; } while (0)

/* math.isclose(a, b) with its defaults (relative 1e-9), as fmpy compares times. */
static inline int cw_isclose(double a, double b)
{
    if (a == b)
        return 1;
    if (isinf(a) || isinf(b))
        return 0;
    double diff = fabs(b - a);
    return diff <= fabs(1e-9 * b) || diff <= fabs(1e-9 * a) || diff <= 0.0;
}

/* What plan (cw_events.c) tells step (cw_step.c) about the step ahead. */
enum { PLAN_NONE = 0, PLAN_CLEAR = 1, PLAN_APPROACH = 2, PLAN_LAND = 3 };

/* cw_inputs.c: outputs read, inputs set (from sources, samples, polynomials) */
int port_read(cw_master *m, int i, double t);
int port_pull(cw_master *m, int i, double t);
double inputs_next_event(const cw_inputs *in, double t);
int inputs_event_at(const cw_inputs *in, double t);
int inputs_set(cw_master *m, int i, double t, int after_event);
void history_forget(cw_master *m);
void record_history(cw_master *m);
int set_coupled_inputs(cw_master *m, int i, double t, double h);
int set_inputs(cw_master *m, int i, double t, double h, int smooth);

/* cw_loops.c: algebraic loops, and the outputs handed on in dependency order */
int loop_solve(cw_master *m, int i, double t);
int propagate(cw_master *m, const int *order, int n, double t);

/* cw_events.c: event location */
void remember_sources(cw_master *m);
void sample_sources(cw_master *m, double t);
int plan(cw_master *m, double t, double h, double *step_out);
int land_on_events(cw_master *m, double t, double h, int near, int checkpointed, int predicted, double *taken);

/* cw_advance.c: the communication step, checkpoints, rollback and replay, strong coupling */
void indicators(cw_master *m, double *z);
int advance(cw_master *m, double t, double h);
int checkpoint_mark(cw_master *m);
int checkpoint_take(cw_master *m);
int rollback(cw_master *m);
int since_append(cw_master *m, double h);
int replay_to(cw_master *m, double t);
int iterate_step(cw_master *m, double t, double h);
int diverged(const cw_master *m);

/* cw_clocks.c: FMI 3.0 clocks (the step cut to the next tick; an event due) */
double clocks_cut(const cw_clocks *c, double t, double h);
int clocks_due(const cw_clocks *c, double t, int after_event_step);

/* cw_rates.c: components at their own steps */
void rates_start(cw_master *m);
int rates_step(cw_master *m, double h, double *taken);

/* cw_record.c: recording */
void record_point(cw_master *m, cw_recorder *r);

/* cw_log.c: FMU log messages (cw_logger; it trusts nothing an FMU passes) */
int cw_env_known(const void *key);

#endif
