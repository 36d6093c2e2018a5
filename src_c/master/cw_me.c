/* The Model Exchange wrapper of the compiled core: a Model Exchange FMU
 * behind the fmi2-shaped calls the stepping core makes (cwme_doStep,
 * cwme_getReal, cwme_setReal, cwme_setInputDerivatives,
 * cwme_getOutputDerivatives, cwme_getState, cwme_setState), whose first
 * argument is a cw_me.
 *
 * The twin of clockwork/engine/me_step.py (the algorithm: integration,
 * events, inputs) and of the master's calls in model_exchange.py,
 * operation for operation, built with -ffp-contract=off like the master's files,
 * so that both engines give the same bits. The Runge-Kutta pairs are the
 * project's own (src_c/runtime/cw_rk.c, built into this library with room
 * for CW_RK_MAXN states); CVode comes from fmpy's SUNDIALS, through the
 * function table Python hands over (cw_sundials).
 *
 * Python owns every array and fills the struct (model_exchange._ME);
 * initialization, reset and freeing stay in Python.
 */

#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <string.h>

#include "cw_numerics.h"
#include "cw_polynomial.h"
#include "cw_rk.h"

#define CW_EXPORT __attribute__((visibility("default")))

#include "cw_me.h"

enum { FMI_OK = 0, FMI_WARNING = 1, FMI_DISCARD = 2, FMI_ERROR = 3 };
enum { AUTO = 0, DP54 = 1, DOP853 = 2, CVODE = 3 };         /* solver, method */
enum { CONTINUOUS = 2, EVENT = 3 };                          /* mode */
enum { REACHED, STATE, STEP, TERMINATE, STIFF, FAILED };     /* how an integration ended */
enum { FAIL_SETTLE = 20, FAIL_TIME, FAIL_RK, FAIL_CVODE, FAIL_LOCATE, FAIL_TIME_EVENTS };
enum { OWNER_CORE = 2 };                                     /* cv_owner: 1 is Python's */
enum { CV_BDF = 2, CV_ONE_STEP = 2 };

#define MAX_EVENT_ITERATIONS 1000
#define MAX_CVODE_STEPS 1000000L
#define MAX_TRIALS 200
#define SAFEGUARD_TRIALS 4
#define STIFF_STEPS 15
#define NONSTIFF_RESET 6


CW_EXPORT size_t cwme_sizeof_rk(void) { return sizeof(cw_rk); }
CW_EXPORT int cwme_max_states(void) { return CW_RK_MAXN; }

/* The compiled core's integrator workspace, as model_exchange's RungeKutta starts. */
CW_EXPORT void cwme_prepare(cw_me *me)
{
    cw_rk_init(me->rk, me->n, me->rtol, 0.0, 0.0);
}

static double py_max(double a, double b) { return b > a ? b : a; }

static double ulp(double x) { return nextafter(x, INFINITY) - x; }

/* ---- the FMU's calls, FMI 1.0, 2.0 or 3.0 (FMI 1.0's face gives functions
 * that do nothing for the event and continuous-time modes it lacks) ---- */

typedef int (*get_real2_t)(void *, const unsigned *, size_t, double *);
typedef int (*set_real2_t)(void *, const unsigned *, size_t, const double *);
typedef int (*get_real3_t)(void *, const unsigned *, size_t, double *, size_t);
typedef int (*set_real3_t)(void *, const unsigned *, size_t, const double *, size_t);
typedef int (*completed2_t)(void *, int, int *, int *);
typedef int (*completed3_t)(void *, bool, bool *, bool *);
typedef int (*update2_t)(void *, event_info2 *);
typedef int (*update3_t)(void *, bool *, bool *, bool *, bool *, bool *, double *);
/* FMI 1.0: fmiBoolean is a char; fmiEventUpdate(intermediateResults, eventInfo). */
typedef struct {
    char converged, references_changed, values_changed, terminate, upcoming;
    double next_time;
} event_info1;
typedef int (*completed1_t)(void *, char *);
typedef int (*update1_t)(void *, char, event_info1 *);

/* One function per version for each call whose shape differs, gathered in
 * a table per version (cwme_calls_fmi1/2/3). The Model Exchange face names
 * its table and Python puts its address in cw_me.calls, so the wrapper
 * calls through it and never asks which version an FMU is. */

static int get_real2(cw_me *me, const unsigned *vr, size_t n, double *out)
{
    return ((get_real2_t)me->getReal)(me->instance, vr, n, out);
}

static int get_real3(cw_me *me, const unsigned *vr, size_t n, double *out)
{
    return ((get_real3_t)me->getReal)(me->instance, vr, n, out, n);
}

static int set_real2(cw_me *me, const unsigned *vr, size_t n, const double *values)
{
    return ((set_real2_t)me->setReal)(me->instance, vr, n, values);
}

static int set_real3(cw_me *me, const unsigned *vr, size_t n, const double *values)
{
    return ((set_real3_t)me->setReal)(me->instance, vr, n, values, n);
}

static int completed1(cw_me *me, int *enter, int *terminate)
{
    char call_update = 0;
    int st = ((completed1_t)me->completedStep)(me->instance, &call_update);
    *enter = call_update != 0;
    *terminate = 0; /* FMI 1.0 ends the simulation in fmiEventUpdate only */
    return st;
}

static int completed2(cw_me *me, int *enter, int *terminate)
{
    return ((completed2_t)me->completedStep)(me->instance, 0, enter, terminate);
}

static int completed3(cw_me *me, int *enter, int *terminate)
{
    bool e = false, t = false;
    int st = ((completed3_t)me->completedStep)(me->instance, false, &e, &t);
    *enter = e;
    *terminate = t;
    return st;
}

static int update1(cw_me *me, event_info2 *info)
{
    /* Until the discrete states settle (intermediateResults false); new
     * state references mean new states: read them and their nominals. */
    event_info1 e = {0};
    int st = ((update1_t)me->update)(me->instance, 0, &e);
    info->need = !e.converged;
    info->terminate = e.terminate != 0;
    info->nominals = e.references_changed != 0;
    info->values = e.values_changed != 0 || e.references_changed != 0;
    info->defined = e.upcoming != 0;
    info->next_time = e.next_time;
    return st;
}

static int update2(cw_me *me, event_info2 *info)
{
    return ((update2_t)me->update)(me->instance, info);
}

static int update3(cw_me *me, event_info2 *info)
{
    bool need = false, term = false, nominals = false, values = false, defined = false;
    int st = ((update3_t)me->update)(me->instance, &need, &term, &nominals, &values, &defined, &info->next_time);
    info->need = need;
    info->terminate = term;
    info->nominals = nominals;
    info->values = values;
    info->defined = defined;
    return st;
}

CW_EXPORT const cw_me_calls cwme_calls_fmi1 = {get_real2, set_real2, completed1, update1};
CW_EXPORT const cw_me_calls cwme_calls_fmi2 = {get_real2, set_real2, completed2, update2};
CW_EXPORT const cw_me_calls cwme_calls_fmi3 = {get_real3, set_real3, completed3, update3};

#define CALLS(me) CWME_CALLS(me)

static int fmu_get_real(cw_me *me, const unsigned *vr, size_t n, double *out)
{
    return CALLS(me)->get_real(me, vr, n, out);
}

static int fmu_set_real(cw_me *me, const unsigned *vr, size_t n, const double *values)
{
    return CALLS(me)->set_real(me, vr, n, values);
}

static int fmu_completed(cw_me *me, int *enter, int *terminate)
{
    return CALLS(me)->completed(me, enter, terminate);
}

static int fmu_update(cw_me *me, event_info2 *info)
{
    return CALLS(me)->update(me, info);
}

#define FMU(me, name, type) ((type)(me)->name)

/* ---- failures ---- */

static int failed(cw_me *me, int call, int status)
{
    if (!me->failed_call) {
        me->failed_call = call;
        me->failed_status = status;
        me->err_t = me->time;
    }
    return status;
}

static int check(cw_me *me, int status, int call)
{
    if (status > FMI_WARNING) {
        failed(me, call, status);
        return 1;
    }
    return 0;
}

/* ---- the FMU at a point ---- */

static int set_point(cw_me *me, double t, const double *x)
{
    if (check(me, FMU(me, setTime, set_time_t)(me->instance, t), 1))
        return FMI_ERROR;
    if (me->poly) {
        for (int k = 0; k < me->n_in; k++) {
            double dt = t - me->tref[k];
            me->in_val[k] = input_polynomial(me->u0[k], me->d1[k], me->d2[k], dt);
        }
        if (check(me, fmu_set_real(me, me->in_vr, (size_t)me->n_in, me->in_val), 11))
            return FMI_ERROR;
    }
    if (me->n) {
        memcpy(me->xbuf, x, (size_t)me->n * sizeof(double));
        if (check(me, FMU(me, setStates, set_vector_t)(me->instance, me->xbuf, (size_t)me->n), 2))
            return FMI_ERROR;
    }
    return FMI_OK;
}

static void rk_rhs(void *ctx, double t, const double *x, double *dxdt)
{
    cw_me *me = ctx;
    if (!me->failed_call && set_point(me, t, x) == FMI_OK) {
        me->rhs += 1;
        int st = FMU(me, getDerivatives, vector_t)(me->instance, me->dx, (size_t)me->n);
        if (st <= FMI_WARNING) {
            memcpy(dxdt, me->dx, (size_t)me->n * sizeof(double));
            return;
        }
        if (st > FMI_DISCARD)
            failed(me, 3, st);
    }
    for (int i = 0; i < me->n; i++)
        dxdt[i] = NAN;
}

static int cv_rhs(double t, void *y, void *ydot, void *user_data)
{
    cw_me *me = user_data;
    const cw_sundials *sun = me->sundials;
    if (me->failed_call)
        return -1;
    if (set_point(me, t, sun->N_VGetArrayPointer(y)) != FMI_OK)
        return -1;
    me->rhs += 1;
    int st = FMU(me, getDerivatives, vector_t)(me->instance, sun->N_VGetArrayPointer(ydot), (size_t)me->n);
    if (st <= FMI_WARNING)
        return 0;
    if (st == FMI_DISCARD)
        return 1;
    failed(me, 3, st);
    return -1;
}

/* The indicators into me->z; 0 when the FMU failed. */
static int read_indicators(cw_me *me)
{
    return !check(me, FMU(me, getIndicators, vector_t)(me->instance, me->z, (size_t)me->nz), 4);
}

static int indicators_at(cw_me *me, double t, const double *x)
{
    return set_point(me, t, x) == FMI_OK && read_indicators(me);
}

/* ---- events ---- */

static int read_nominals(cw_me *me)
{
    if (check(me, FMU(me, getNominals, vector_t)(me->instance, me->nominal, (size_t)me->n), 10))
        return FMI_ERROR;
    for (int i = 0; i < me->n; i++) {
        double nominal = fabs(me->nominal[i]);
        me->atolv[i] = me->rtol * (nominal > 0.0 ? nominal : 1.0);
    }
    return FMI_OK;
}

/* In event mode: update the discrete states until they settle, then
 * continuous-time mode (me_step.ModelExchangeSteps._settle). `counter`
 * names the event's kind, or NULL. */
static int settle(cw_me *me, long long *counter)
{
    int values_changed = 0, nominals_changed = 0, k;
    event_info2 info = {0, 0, 0, 0, 0, 0.0};
    for (k = 0; k < MAX_EVENT_ITERATIONS; k++) {
        if (check(me, fmu_update(me, &info), 7))
            return FMI_ERROR;
        values_changed = values_changed || info.values;
        nominals_changed = nominals_changed || info.nominals;
        if (info.terminate) {
            me->terminated = 1;
            break;
        }
        if (!info.need)
            break;
    }
    if (k == MAX_EVENT_ITERATIONS)
        return failed(me, FAIL_SETTLE, FMI_ERROR);
    if (counter)
        *counter += 1;
    me->restart = 1;
    if (me->terminated) {
        me->end_time = me->time;
        return FMI_OK;
    }
    me->next_event_time = info.defined ? info.next_time : INFINITY;
    if (check(me, FMU(me, enterContinuousMode, mode_t_)(me->instance), 8))
        return FMI_ERROR;
    me->mode = CONTINUOUS;
    if (values_changed && me->n && check(me, FMU(me, getStates, vector_t)(me->instance, me->x, (size_t)me->n), 9))
        return FMI_ERROR;
    if (nominals_changed && me->n && read_nominals(me) != FMI_OK)
        return FMI_ERROR;
    if (me->nz) {
        if (!read_indicators(me))
            return FMI_ERROR;
        memcpy(me->z_prev, me->z, (size_t)me->nz * sizeof(double));
    }
    return FMI_OK;
}

static int handle_event(cw_me *me, long long *counter)
{
    if (check(me, FMU(me, enterEventMode, mode_t_)(me->instance), 6))
        return FMI_ERROR;
    me->mode = EVENT;
    return settle(me, counter);
}

/* fmi2CompletedIntegratorStep where the FMU needs it. */
static int completed(cw_me *me, int *enter, int *terminate)
{
    *enter = *terminate = 0;
    if (!me->needs_completed)
        return FMI_OK;
    int st = fmu_completed(me, enter, terminate);
    if (check(me, st, 5)) {
        *enter = *terminate = 0;
        return FMI_ERROR;
    }
    return FMI_OK;
}

/* The FMU stands at the end of an accepted step (_after_step); `stiffness`
 * is the pair's h |lambda|, or NaN. */
static int after_step(cw_me *me, double stiffness)
{
    if (me->nz) {
        if (!read_indicators(me))
            return FAILED;
        for (int k = 0; k < me->nz; k++)
            if (crossed(me->z_prev[k], me->z[k])) {
                memcpy(me->z_end, me->z, (size_t)me->nz * sizeof(double));
                return STATE;
            }
    }
    int enter, term;
    if (completed(me, &enter, &term) != FMI_OK)
        return FAILED;
    if (term)
        return TERMINATE;
    if (me->nz)
        memcpy(me->z_prev, me->z, (size_t)me->nz * sizeof(double));
    if (enter)
        return STEP;
    if (!isnan(stiffness)) {
        if (stiffness > (me->method == DP54 ? 3.25 : 6.1)) {
            me->nonstiff_count = 0;
            me->stiff_count += 1;
            if (me->stiff_count >= STIFF_STEPS)
                return STIFF;
        } else {
            me->nonstiff_count += 1;
            if (me->nonstiff_count >= NONSTIFF_RESET)
                me->stiff_count = 0;
        }
    }
    return REACHED;
}

/* The dense output of the integration that just ended, at t into out. */
typedef void (*dense_t)(cw_me *me, double t, double *out);

static void dense_rk(cw_me *me, double t, double *out) { cw_rk_dense(me->rk, t, out); }

static void dense_cvode(cw_me *me, double t, double *out)
{
    const cw_sundials *sun = me->sundials;
    if (sun->CVodeGetDky(me->cv_mem, t, 0, me->cv_dky)) {
        for (int i = 0; i < me->n; i++)
            out[i] = NAN;
        return;
    }
    memcpy(out, sun->N_VGetArrayPointer(me->cv_dky), (size_t)me->n * sizeof(double));
}

static void dense_none(cw_me *me, double t, double *out) { (void)me; (void)t; (void)out; }

/* The earliest crossing inside the accepted step [t0, t1] (_locate): 1 with
 * *t_event and the states in me->xd (*at_end: the step's own end), 0 when
 * the FMU failed. */
static int locate(cw_me *me, double t0, double t1, dense_t dense, double *t_event, int *at_end)
{
    const int nz = me->nz;
    double *z0 = me->z0, *z1 = me->z_end, *z_lo = me->z_lo, *z = me->z;
    memcpy(z0, me->z_prev, (size_t)nz * sizeof(double));
    memcpy(z_lo, z0, (size_t)nz * sizeof(double));
    double h = t1 - t0;
    int lead = -1;
    double best = 0.0;
    for (int k = 0; k < nz; k++)
        if (crossed(z0[k], z1[k])) {
            double x = z0[k] / (z0[k] - z1[k]);
            if (lead < 0 || x < best) {
                lead = k;
                best = x;
            }
        }
    illinois search = illinois_new(0.0, z0[lead], h, z1[lead]);
    double hi = h;
    double tol = py_max(me->event_time_tolerance, 4 * ulp(fabs(t0) + h));
    int trials = 0;
    double widths[SAFEGUARD_TRIALS];
    for (int k = 0; k < SAFEGUARD_TRIALS; k++)
        widths[k] = INFINITY;
    while (hi - search.lo > tol) {
        double width = hi - search.lo;
        double trial = illinois_next(&search);
        if (!(search.lo < trial && trial < hi) || width > 0.5 * widths[0])
            trial = 0.5 * (search.lo + hi);
        memmove(widths, widths + 1, (SAFEGUARD_TRIALS - 1) * sizeof(double));
        widths[SAFEGUARD_TRIALS - 1] = width;
        dense(me, t0 + trial, me->xd);
        if (!indicators_at(me, t0 + trial, me->xd))
            return 0;
        me->event_iterations += 1;
        trials++;
        int any = 0;
        for (int k = 0; k < nz; k++)
            any = any || crossed(z0[k], z[k]);
        if (any) {
            if (!crossed(z0[lead], z[lead])) {
                lead = -1;
                for (int k = 0; k < nz; k++)
                    if (crossed(z0[k], z[k])) {
                        double x = z_lo[k] / (z_lo[k] - z[k]);
                        if (lead < 0 || x < best) {
                            lead = k;
                            best = x;
                        }
                    }
                search = illinois_new(search.lo, z_lo[lead], trial, z[lead]);
            } else {
                illinois_update(&search, trial, z[lead], 1);
            }
            hi = trial;
        } else {
            illinois_update(&search, trial, z[lead], 0);
            memcpy(z_lo, z, (size_t)nz * sizeof(double));
        }
        if (trials > MAX_TRIALS) {
            failed(me, FAIL_LOCATE, FMI_ERROR);
            return 0;
        }
    }
    if (hi == h) {
        *t_event = t1;
        *at_end = 1;
        return 1;
    }
    *t_event = t0 + hi;
    *at_end = 0;
    dense(me, t0 + hi, me->xd);
    return 1;
}

/* Take the integration's end (t1, x1) and handle what ended it (_end_integration). */
static int end_integration(cw_me *me, int reason, double t0, double t1, const double *x1, dense_t dense)
{
    const size_t bytes = (size_t)me->n * sizeof(double);
    if (reason == FAILED)
        return me->failed_status;
    if (reason == STATE) {
        double t_event;
        int at_end;
        if (!locate(me, t0, t1, dense, &t_event, &at_end))
            return me->failed_status;
        me->time = t_event;
        if (me->n)
            memcpy(me->x, at_end ? x1 : me->xd, bytes);
        if (set_point(me, me->time, me->x) != FMI_OK)
            return FMI_ERROR;
        int enter, term;
        if (completed(me, &enter, &term) != FMI_OK)
            return FMI_ERROR;
        if (term) {
            me->terminated = 1;
            me->end_time = me->time;
            return FMI_OK;
        }
        return handle_event(me, &me->state_events);
    }
    me->time = t1;
    if (me->n)
        memcpy(me->x, x1, bytes);
    if (reason == STEP)
        return handle_event(me, &me->step_events);
    if (reason == TERMINATE) {
        me->terminated = 1;
        me->end_time = me->time;
    } else if (reason == STIFF) {
        me->method = CVODE;
        me->switches += 1;
        me->restart = 1;
    }
    return FMI_OK;
}

/* ---- the integrators ---- */

static int integrate_without_states(cw_me *me, double t_stop)
{
    double t0 = me->time;
    if (set_point(me, t_stop, me->x) != FMI_OK)
        return FMI_ERROR;
    me->steps += 1;
    int reason = after_step(me, NAN);
    return end_integration(me, reason, t0, t_stop, me->x, dense_none);
}

typedef struct {
    cw_me *me;
    int reason;
} observation;

static int observe(void *ctx, const cw_rk *rk)
{
    observation *o = ctx;
    o->reason = after_step(o->me, rk->stiffness_test ? rk->h_lambda : NAN);
    return o->reason != REACHED;
}

static int integrate_rk(cw_me *me, double t_stop)
{
    cw_rk *rk = me->rk;
    rk->method = me->method;
    rk->rtol = me->rtol;
    rk->atolv = me->atolv;
    rk->stiffness_test = me->solver == AUTO;
    rk->n_accepted = rk->n_rejected = rk->n_rhs = 0;
    observation o = {me, REACHED};
    double *x = me->xw;
    memcpy(x, me->x, (size_t)me->n * sizeof(double));
    double t1 = me->time;
    cw_rk_result result = cw_rk_advance(rk, rk_rhs, me, &t1, t_stop, x, &me->h_next, observe, &o);
    me->steps += rk->n_accepted;
    me->rejected += rk->n_rejected;
    if (me->failed_call)
        return me->failed_status;
    if (result != CW_RK_OK && result != CW_RK_STOPPED) {
        me->err_t = t1;
        me->failed_detail = (int)result;
        return failed(me, FAIL_RK, FMI_ERROR);
    }
    return end_integration(me, o.reason, rk->t0, t1, x, dense_rk);
}

static void cvode_free(cw_me *me)
{
    const cw_sundials *sun = me->sundials;
    if (me->cv_mem)
        sun->CVodeFree(&me->cv_mem);
    if (me->cv_LS)
        sun->SUNLinSolFree(me->cv_LS);
    if (me->cv_A)
        sun->SUNMatDestroy(me->cv_A);
    if (me->cv_y)
        sun->N_VDestroy(me->cv_y);
    if (me->cv_abstol)
        sun->N_VDestroy(me->cv_abstol);
    if (me->cv_dky)
        sun->N_VDestroy(me->cv_dky);
    if (me->cv_ctx)
        sun->SUNContext_Free(&me->cv_ctx);
    me->cv_mem = me->cv_LS = me->cv_A = me->cv_y = me->cv_abstol = me->cv_dky = me->cv_ctx = NULL;
    me->cv_owner = 0;
}

static void cvode_put(cw_me *me, void *vector, const double *values)
{
    memcpy(me->sundials->N_VGetArrayPointer(vector), values, (size_t)me->n * sizeof(double));
}

static int cvode_create(cw_me *me, double t, const double *x)
{
    const cw_sundials *sun = me->sundials;
    cvode_free(me);
    if (sun->SUNContext_Create(0, &me->cv_ctx))
        return -1;
    sun->SUNContext_ClearErrHandlers(me->cv_ctx);
    me->cv_y = sun->N_VNew_Serial(me->n, me->cv_ctx);
    me->cv_abstol = sun->N_VNew_Serial(me->n, me->cv_ctx);
    me->cv_dky = sun->N_VNew_Serial(me->n, me->cv_ctx);
    me->cv_A = sun->SUNDenseMatrix(me->n, me->n, me->cv_ctx);
    me->cv_LS = sun->SUNLinSol_Dense(me->cv_y, me->cv_A, me->cv_ctx);
    me->cv_mem = sun->CVodeCreate(CV_BDF, me->cv_ctx);
    if (!(me->cv_y && me->cv_abstol && me->cv_dky && me->cv_A && me->cv_LS && me->cv_mem))
        return -1;
    cvode_put(me, me->cv_y, x);
    cvode_put(me, me->cv_abstol, me->atolv);
    int flag = sun->CVodeInit(me->cv_mem, cv_rhs, t, me->cv_y);
    if (!flag)
        flag = sun->CVodeSVtolerances(me->cv_mem, me->rtol, me->cv_abstol);
    if (!flag)
        flag = sun->CVodeSetLinearSolver(me->cv_mem, me->cv_LS, me->cv_A);
    if (!flag)
        flag = sun->CVodeSetUserData(me->cv_mem, me);
    return flag;
}

static int cvode_reinit(cw_me *me, double t, const double *x)
{
    const cw_sundials *sun = me->sundials;
    cvode_put(me, me->cv_y, x);
    cvode_put(me, me->cv_abstol, me->atolv);
    int flag = sun->CVodeReInit(me->cv_mem, t, me->cv_y);
    if (!flag)
        flag = sun->CVodeSVtolerances(me->cv_mem, me->rtol, me->cv_abstol);
    return flag;
}

static long cvode_failures(cw_me *me)
{
    long a = 0, b = 0;
    if (!me->cv_mem)
        return 0;
    me->sundials->CVodeGetNumErrTestFails(me->cv_mem, &a);
    me->sundials->CVodeGetNumNonlinSolvConvFails(me->cv_mem, &b);
    return a + b;
}

static int integrate_cvode(cw_me *me, double t_stop)
{
    const cw_sundials *sun = me->sundials;
    const size_t bytes = (size_t)me->n * sizeof(double);
    int flag = 0;
    if (me->cv_owner != OWNER_CORE) {
        flag = cvode_create(me, me->time, me->x);
        me->cv_owner = OWNER_CORE;
    } else if (me->restart) {
        flag = cvode_reinit(me, me->time, me->x);
    }
    me->restart = 0;
    if (flag) {
        me->failed_detail = flag;
        return failed(me, FAIL_CVODE, FMI_ERROR);
    }
    long failures0 = cvode_failures(me);
    int reason = REACHED;
    double t0 = me->time, t1 = me->time;
    double *x1 = me->xw;
    memcpy(x1, me->x, bytes);
    long k;
    for (k = 0; k < MAX_CVODE_STEPS; k++) {
        double reached = 0.0;
        flag = sun->CVodeSetStopTime(me->cv_mem, t_stop);
        if (!flag)
            flag = sun->CVode(me->cv_mem, t_stop, me->cv_y, &reached, CV_ONE_STEP);
        t1 = reached;
        if (me->failed_call)
            break;
        if (flag < 0) {
            me->err_t = me->time;
            me->failed_detail = flag;
            failed(me, FAIL_CVODE, FMI_ERROR);
            break;
        }
        me->steps += 1;
        memcpy(x1, sun->N_VGetArrayPointer(me->cv_y), bytes);
        if (set_point(me, t1, x1) != FMI_OK) {
            reason = FAILED;
            break;
        }
        reason = after_step(me, NAN);
        if (reason != REACHED || t1 >= t_stop)
            break;
        me->time = t1;
        memcpy(me->x, x1, bytes);
        t0 = t1;
    }
    if (k == MAX_CVODE_STEPS) {
        me->failed_detail = 0;
        failed(me, FAIL_CVODE, FMI_ERROR);
    }
    me->rejected += cvode_failures(me) - failures0;
    if (me->failed_call)
        return me->failed_status;
    return end_integration(me, reason, t0, t1, x1, dense_cvode);
}

static int integrate(cw_me *me, double t_stop)
{
    if (!me->n)
        return integrate_without_states(me, t_stop);
    if (me->method == CVODE)
        return integrate_cvode(me, t_stop);
    return integrate_rk(me, t_stop);
}

/* ---- the master's calls ---- */

CW_EXPORT int cwme_doStep(void *comp, double t, double h, int no_set_prior)
{
    cw_me *me = comp;
    (void)no_set_prior;
    me->failed_call = 0;
    if (me->terminated)
        return FMI_DISCARD;
    if (t != me->time || me->mode != CONTINUOUS)
        return failed(me, FAIL_TIME, FMI_ERROR);
    double end = t + h;
    if (me->nz && me->inputs_dirty) {
        /* Inputs that jumped at this communication point may have crossed an indicator. */
        if (!read_indicators(me))
            return FMI_ERROR;
        int any = 0;
        for (int k = 0; k < me->nz; k++)
            any = any || crossed(me->z_prev[k], me->z[k]);
        if (any) {
            int st = handle_event(me, &me->input_events);
            if (st != FMI_OK)
                return st;
        } else {
            memcpy(me->z_prev, me->z, (size_t)me->nz * sizeof(double));
        }
    }
    me->inputs_dirty = 0;
    int at_once = 0;
    while (!me->terminated) {
        if (me->next_event_time <= me->time) {
            at_once += 1;
            if (at_once > MAX_EVENT_ITERATIONS)
                return failed(me, FAIL_TIME_EVENTS, FMI_ERROR);
            int st = handle_event(me, &me->time_events);
            if (st != FMI_OK)
                return st;
            continue;
        }
        if (me->time >= end)
            break;
        at_once = 0;
        int st = integrate(me, me->next_event_time > end ? end : me->next_event_time);
        if (st != FMI_OK)
            return st;
    }
    if (me->terminated)
        return me->end_time >= end ? FMI_OK : FMI_DISCARD;
    return set_point(me, me->time, me->x) == FMI_OK ? FMI_OK : FMI_ERROR;
}

CW_EXPORT int cwme_getReal(void *comp, const unsigned *vr, size_t n, double *out)
{
    return fmu_get_real(comp, vr, n, out);
}

static int input_index(const cw_me *me, unsigned vr)
{
    for (int k = 0; k < me->n_in; k++)
        if (me->in_vr[k] == vr)
            return k;
    return -1;
}

static void recheck_poly(cw_me *me)
{
    me->poly = 0;
    for (int k = 0; k < me->n_in; k++)
        if (me->d1[k] != 0.0 || me->d2[k] != 0.0)
            me->poly = 1;
}

/* fmi2SetReal: continuous inputs directly, their polynomials held from the
 * wrapper's time; anything else in event mode. */
CW_EXPORT int cwme_setReal(void *comp, const unsigned *vr, size_t n, const double *values)
{
    cw_me *me = comp;
    int others = 0;
    for (size_t j = 0; j < n; j++)
        others = others || input_index(me, vr[j]) < 0;
    int st;
    if (me->mode == CONTINUOUS && others) {
        if (check(me, FMU(me, enterEventMode, mode_t_)(me->instance), 6))
            return FMI_ERROR;
        me->mode = EVENT;
        st = fmu_set_real(me, vr, n, values);
        if (st > FMI_WARNING)
            return st;
        int s = settle(me, &me->input_events);
        st = s > st ? s : st;
    } else {
        st = fmu_set_real(me, vr, n, values);
    }
    if (st > FMI_WARNING || !me->n_in)
        return st;
    for (size_t j = 0; j < n; j++) {
        int k = input_index(me, vr[j]);
        if (k < 0)
            continue;
        double dt = me->time - me->tref[k];
        double now = input_polynomial(me->u0[k], me->d1[k], me->d2[k], dt);
        if (values[j] != now || me->d1[k] != 0.0 || me->d2[k] != 0.0)
            me->inputs_dirty = me->restart = 1;
        me->u0[k] = values[j];
        me->d1[k] = me->d2[k] = 0.0;
        me->tref[k] = me->time;
    }
    recheck_poly(me);
    return st;
}

/* fmi2SetRealInputDerivatives on continuous inputs (order 1 or 2),
 * re-based at the wrapper's time as the FMI 2.0 runtime does. */
CW_EXPORT int cwme_setInputDerivatives(void *comp, const unsigned *vr, size_t n, const int *order,
                                       const double *values)
{
    cw_me *me = comp;
    for (size_t j = 0; j < n; j++)
        if (input_index(me, vr[j]) < 0 || order[j] < 1 || order[j] > 2 || !isfinite(values[j]))
            return FMI_ERROR;
    for (size_t j = 0; j < n; j++) {
        int k = input_index(me, vr[j]);
        if (me->tref[k] != me->time) {
            double dt = me->time - me->tref[k];
            me->u0[k] = input_polynomial(me->u0[k], me->d1[k], me->d2[k], dt);
            me->d1[k] = me->d2[k] = 0.0;
            me->tref[k] = me->time;
        }
        double *d = order[j] == 1 ? &me->d1[k] : &me->d2[k];
        if (*d != values[j])
            me->restart = 1;
        *d = values[j];
    }
    recheck_poly(me);
    return FMI_OK;
}

/* Derivatives of outputs that are states: the first from the derivatives
 * at the current point, the second where the state's derivative is a
 * state too; Error for any other. */
CW_EXPORT int cwme_getOutputDerivatives(void *comp, const unsigned *vr, size_t n, const int *order, double *out)
{
    cw_me *me = comp;
    if (me->mode != CONTINUOUS || !me->n)
        return FMI_ERROR;
    for (size_t j = 0; j < n; j++) {
        int i = -1;
        for (int s = 0; s < me->n && i < 0; s++)
            if (me->state_vr[s] == vr[j])
                i = s;
        if (i < 0 || order[j] < 1 || order[j] > 2 || (order[j] == 2 && me->der_state[i] < 0))
            return FMI_ERROR;
    }
    int st = FMU(me, getDerivatives, vector_t)(me->instance, me->dx, (size_t)me->n);
    me->rhs += 1;
    if (st > FMI_WARNING)
        return st;
    for (size_t j = 0; j < n; j++) {
        int i = -1;
        for (int s = 0; s < me->n && i < 0; s++)
            if (me->state_vr[s] == vr[j])
                i = s;
        out[j] = me->dx[order[j] == 2 ? me->der_state[i] : i];
    }
    return FMI_OK;
}

/* fmi2GetFMUstate, and the wrapper's own state beside it. */
CW_EXPORT int cwme_getState(void *comp, void **state)
{
    cw_me *me = comp;
    int st = FMU(me, getState, get_state_t)(me->instance, state);
    if (st > FMI_WARNING)
        return st;
    const int n = me->n, nz = me->nz;
    double *saved = me->saved;
    memcpy(saved, me->x, (size_t)n * sizeof(double));
    memcpy(saved + n, me->z_prev, (size_t)nz * sizeof(double));
    for (int k = 0; k < me->n_in; k++) {
        double *s = saved + n + nz + 4 * k;
        s[0] = me->u0[k];
        s[1] = me->d1[k];
        s[2] = me->d2[k];
        s[3] = me->tref[k];
    }
    me->saved_time = me->time;
    me->saved_next_event_time = me->next_event_time;
    me->saved_end_time = me->end_time;
    me->saved_h_next = me->h_next;
    me->saved_method = me->method;
    me->saved_stiff_count = me->stiff_count;
    me->saved_nonstiff_count = me->nonstiff_count;
    me->saved_terminated = me->terminated;
    me->saved_poly = me->poly;
    me->saved_mode = me->mode;
    return st;
}

CW_EXPORT int cwme_setState(void *comp, void *state)
{
    cw_me *me = comp;
    int st = FMU(me, setState, set_state_t)(me->instance, state);
    if (st > FMI_WARNING)
        return st;
    const int n = me->n, nz = me->nz;
    const double *saved = me->saved;
    memcpy(me->x, saved, (size_t)n * sizeof(double));
    memcpy(me->z_prev, saved + n, (size_t)nz * sizeof(double));
    for (int k = 0; k < me->n_in; k++) {
        const double *s = saved + n + nz + 4 * k;
        me->u0[k] = s[0];
        me->d1[k] = s[1];
        me->d2[k] = s[2];
        me->tref[k] = s[3];
    }
    me->time = me->saved_time;
    me->next_event_time = me->saved_next_event_time;
    me->end_time = me->saved_end_time;
    me->h_next = me->saved_h_next;
    me->method = me->saved_method;
    me->stiff_count = me->saved_stiff_count;
    me->nonstiff_count = me->saved_nonstiff_count;
    me->terminated = me->saved_terminated;
    me->poly = me->saved_poly;
    me->mode = me->saved_mode;
    me->restart = 1;
    me->inputs_dirty = 0;
    return st;
}
