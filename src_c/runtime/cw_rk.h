/* Embedded Runge-Kutta pairs of Dormand and Prince with dense output, one
 * implementation shared by every stateful model:
 *   CW_RK_DP54:   order 5(4), fourth-order continuous extension, 6
 *                 right-hand sides per step (first same as last);
 *   CW_RK_DOP853: order 8(5,3) (Hairer's DOP853), seventh-order continuous
 *                 extension, 12 right-hand sides per accepted step, 11 per
 *                 rejected one, and 3 more for the dense output of a step,
 *                 spent only when cw_rk_dense is called on it.
 * The 8th-order pair needs far fewer steps at tight tolerances. */
#ifndef CW_RK_H
#define CW_RK_H

/* States per integrator; the master's Model Exchange wrapper (built into
 * libcw_master) defines a larger bound. */
#ifndef CW_RK_MAXN
#define CW_RK_MAXN 8
#endif
#define CW_RK_MAXSTAGES 16 /* DOP853: 12 stages, f(x1), 3 dense-output stages */

/* The values of a model's `integrator` parameter. */
typedef enum {
    CW_RK_AUTO = 0,  /* chosen by the tolerance: see cw_rk_choose */
    CW_RK_DP54 = 1,  /* Dormand-Prince 5(4) */
    CW_RK_DOP853 = 2 /* Dormand-Prince 8(5,3) */
} cw_rk_method;

/* CW_RK_AUTO picks DOP853 at rtol <= CW_RK_AUTO_RTOL. Measured right-hand
 * sides per period of the free pendulum (atol = 1e-2 rtol A, one long
 * advance), DP5(4) / DOP853: at 0.05 rad 136 / 57 (rtol 1e-5), 221 / 75
 * (1e-6), 1222 / 236 (1e-10); at 1.5 rad 107 / 121 (1e-5), 176 / 142
 * (1e-6), 878 / 374 (1e-10). DOP853 wins at every amplitude from 1e-6
 * down; tests/fmu/test_rk.py::test_auto_choice_saves_evaluations. */
#define CW_RK_AUTO_RTOL 1e-6

typedef void (*cw_rhs)(void *ctx, double t, const double *x, double *dxdt);

typedef struct {
    int n;
    double rtol, atol; /* per-component mixed error tolerance */
    double h_max;      /* upper bound on internal steps, s; 0 = none */
    long max_steps;    /* per cw_rk_advance call */

    /* Last accepted step [t0, t0 + h], kept for dense output. */
    double t0, h;
    double x0[CW_RK_MAXN], x1[CW_RK_MAXN];
    double k[CW_RK_MAXSTAGES][CW_RK_MAXN];
    double rcont[8][CW_RK_MAXN];

    long n_accepted, n_rejected, n_rhs; /* statistics since init */

    int method; /* CW_RK_DP54 (the default of cw_rk_init) or CW_RK_DOP853 */
    /* DOP853 builds its dense output on first use, with the right-hand
     * side of the last cw_rk_advance call: cw_rk_dense must be called
     * while f and ctx are still valid (in the observer, or right after
     * cw_rk_advance returns). */
    int dense_ready;
    cw_rhs f;
    void *ctx;

    /* Optional, both off after cw_rk_init (the models use neither):
     * atolv, per-component absolute tolerances in place of atol (n values
     * the caller owns); stiffness_test, which makes every step estimate
     * h |lambda| along its last two stages (Hairer's test: the norm of
     * f(x1) - f(y_s) over the norm of x1 - y_s, with y_s the last stage
     * point, at the same time as x1) into h_lambda. The boundary of the
     * stability region along the negative real axis is near 3.3 for
     * DP5(4) and 6.1 for DOP853. */
    const double *atolv;
    int stiffness_test;
    double h_lambda;
    double y_last[CW_RK_MAXN];
} cw_rk;

/* Called after every accepted step; may read cw_rk_dense. Return nonzero to
 * stop the integration early (then *t is the end of that step). */
typedef int (*cw_rk_observer)(void *ctx, const cw_rk *rk);

typedef enum {
    CW_RK_OK = 0,
    CW_RK_STEP_TOO_SMALL = 1,
    CW_RK_TOO_MANY_STEPS = 2,
    CW_RK_NONFINITE = 3,
    CW_RK_STOPPED = 4
} cw_rk_result;

/* Initializes for CW_RK_DP54. */
void cw_rk_init(cw_rk *rk, int n, double rtol, double atol, double h_max);

/* The pair for an `integrator` parameter value (0 = auto, 1, 2) at the
 * relative tolerance rtol. */
cw_rk_method cw_rk_choose(int integrator, double rtol);

/* Selects the pair: cw_rk_choose(integrator, rk->rtol). */
void cw_rk_set_method(cw_rk *rk, int integrator);

/* Integrate x from *t to t_end exactly: the last step is shortened so that
 * *t == t_end on return, bit for bit. *h_next is the step-size suggestion
 * carried between calls (0 lets the integrator choose a first step). */
cw_rk_result cw_rk_advance(cw_rk *rk, cw_rhs f, void *ctx, double *t,
                           double t_end, double *x, double *h_next,
                           cw_rk_observer observer, void *observer_ctx);

/* Dense output of the last accepted step at time t in [t0, t0 + h]. */
void cw_rk_dense(const cw_rk *rk, double t, double *x);

/* One fifth-order step of size h from (t, x) without error control, as
 * used to polish a located crossing. */
void cw_rk_single_step(int n, cw_rhs f, void *ctx, double t, const double *x,
                       double h, double *x_out);

/* The same with the given pair (CW_RK_DP54 or CW_RK_DOP853). */
void cw_rk_single_step_with(int method, int n, cw_rhs f, void *ctx, double t,
                            const double *x, double h, double *x_out);

/* The step of a stateful model: integrate the n states kept in
 * inst->s[first .. first + n) from inst->time to t_end, with the step-size
 * suggestion in inst->s[h_slot]. On failure, log why (naming the states)
 * and return fmi2Discard with inst->s untouched. `integrator` is the
 * model's parameter of that name (see cw_rk_choose). Declared here, defined in
 * cw_runtime.c, so that every model reports failures alike. */
struct cw_instance;
int cw_integrate(struct cw_instance *inst, const char *model, cw_rhs f, int n,
                 int first, int h_slot, double t_end, double rtol, double atol,
                 double h_max, int integrator, const char *const names[],
                 cw_rk_observer observer);

/* An event of a model's own state: g(x) changes sign. `settle` puts a
 * state located on the event exactly on it (so that the next step does not
 * find it again). */
typedef double (*cw_event_fn)(const struct cw_instance *inst, const double *x);
typedef void (*cw_settle_fn)(const struct cw_instance *inst, double *x);

/* cw_integrate (without an observer) that, when the importer allows early
 * return (cw_may_return_early), ends the step at the first sign change of
 * g inside it: located on the dense output (Illinois), the state there
 * from a full step of the pair, settled, and reported with
 * cw_return_early. Without early return it is cw_integrate, bit for bit. */
int cw_integrate_to_event(struct cw_instance *inst, const char *model, cw_rhs f,
                          int n, int first, int h_slot, double t_end,
                          double rtol, double atol, double h_max,
                          int integrator, const char *const names[],
                          cw_event_fn g, cw_settle_fn settle);

#endif
