/* Embedded Runge-Kutta pair of Dormand and Prince, order 5(4), with the
 * fourth-order continuous extension (dense output). One implementation
 * shared by every stateful model. */
#ifndef CW_RK_H
#define CW_RK_H

#define CW_RK_MAXN 8

typedef void (*cw_rhs)(void *ctx, double t, const double *x, double *dxdt);

typedef struct {
    int n;
    double rtol, atol; /* per-component mixed error tolerance */
    double h_max;      /* upper bound on internal steps, s; 0 = none */
    long max_steps;    /* per cw_rk_advance call */

    /* Last accepted step [t0, t0 + h], kept for dense output. */
    double t0, h;
    double x0[CW_RK_MAXN], x1[CW_RK_MAXN];
    double k[7][CW_RK_MAXN];
    double rcont[5][CW_RK_MAXN];

    long n_accepted, n_rejected, n_rhs; /* statistics since init */
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

void cw_rk_init(cw_rk *rk, int n, double rtol, double atol, double h_max);

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

/* The step of a stateful model: integrate the n states kept in
 * inst->s[first .. first + n) from inst->time to t_end, with the step-size
 * suggestion in inst->s[h_slot]. On failure, log why (naming the states)
 * and return fmi2Discard with inst->s untouched. Declared here, defined in
 * cw_runtime.c, so that every model reports failures alike. */
struct cw_instance;
int cw_integrate(struct cw_instance *inst, const char *model, cw_rhs f, int n,
                 int first, int h_slot, double t_end, double rtol, double atol,
                 double h_max, const char *const names[],
                 cw_rk_observer observer);

#endif
