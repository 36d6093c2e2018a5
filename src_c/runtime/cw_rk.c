/* Dormand-Prince 5(4) with Shampine's fourth-order dense output.
 * Coefficients: J. R. Dormand, P. J. Prince, J. Comput. Appl. Math. 6 (1980)
 * and Hairer, Norsett, Wanner, Solving ODEs I, Sec. II.5/II.6. Their order
 * conditions are checked by tests/fmu/test_rk.py through libcw_rk_probe. */
#include "cw_rk.h"

#include <float.h>
#include <math.h>
#include <string.h>

/* fmi2DoStep cannot be interrupted (no fmi2CancelStep), so the work of one
 * call is bounded: past this many internal steps the step is given up and
 * the model returns fmi2Discard, and the master can retry with a shorter
 * one. 1e6 steps are some 1e4 pendulum periods and well under a second;
 * the fuzz build lowers it to keep executions fast (found by fuzzing: a
 * 1e300 s step ran 1e8 internal steps, minutes, before giving up). */
#ifndef CW_RK_MAX_STEPS
#define CW_RK_MAX_STEPS 1000000L
#endif

static const double C2 = 1.0 / 5.0, C3 = 3.0 / 10.0, C4 = 4.0 / 5.0,
                    C5 = 8.0 / 9.0;

static const double A21 = 1.0 / 5.0;
static const double A31 = 3.0 / 40.0, A32 = 9.0 / 40.0;
static const double A41 = 44.0 / 45.0, A42 = -56.0 / 15.0, A43 = 32.0 / 9.0;
static const double A51 = 19372.0 / 6561.0, A52 = -25360.0 / 2187.0,
                    A53 = 64448.0 / 6561.0, A54 = -212.0 / 729.0;
static const double A61 = 9017.0 / 3168.0, A62 = -355.0 / 33.0,
                    A63 = 46732.0 / 5247.0, A64 = 49.0 / 176.0,
                    A65 = -5103.0 / 18656.0;
/* Fifth-order weights (= row 7, first same as last). */
static const double B1 = 35.0 / 384.0, B3 = 500.0 / 1113.0,
                    B4 = 125.0 / 192.0, B5 = -2187.0 / 6784.0,
                    B6 = 11.0 / 84.0;
/* Difference between fifth- and fourth-order weights. */
static const double E1 = 71.0 / 57600.0, E3 = -71.0 / 16695.0,
                    E4 = 71.0 / 1920.0, E5 = -17253.0 / 339200.0,
                    E6 = 22.0 / 525.0, E7 = -1.0 / 40.0;
/* Continuous extension. */
static const double D1 = -12715105075.0 / 11282082432.0,
                    D3 = 87487479700.0 / 32700410799.0,
                    D4 = -10690763975.0 / 1880347072.0,
                    D5 = 701980252875.0 / 199316789632.0,
                    D6 = -1453857185.0 / 822651844.0,
                    D7 = 69997945.0 / 29380423.0;

void cw_rk_init(cw_rk *rk, int n, double rtol, double atol, double h_max) {
    memset(rk, 0, sizeof *rk);
    rk->n = n;
    rk->rtol = rtol;
    rk->atol = atol;
    rk->h_max = h_max;
    rk->max_steps = CW_RK_MAX_STEPS;
}

/* Stages 2..7 of one step; k[0] must hold f(t, x). Writes x_new. The end
 * of the step is passed as t_next: t + h can round past t_end by an ulp. */
static void stages(cw_rk *rk, cw_rhs f, void *ctx, double t, const double *x,
                   double h, double t_next, double *x_new) {
    const int n = rk->n;
    double y[CW_RK_MAXN] = {0};
    double(*k)[CW_RK_MAXN] = rk->k;
    for (int i = 0; i < n; i++) y[i] = x[i] + h * A21 * k[0][i];
    f(ctx, t + C2 * h, y, k[1]);
    for (int i = 0; i < n; i++) y[i] = x[i] + h * (A31 * k[0][i] + A32 * k[1][i]);
    f(ctx, t + C3 * h, y, k[2]);
    for (int i = 0; i < n; i++)
        y[i] = x[i] + h * (A41 * k[0][i] + A42 * k[1][i] + A43 * k[2][i]);
    f(ctx, t + C4 * h, y, k[3]);
    for (int i = 0; i < n; i++)
        y[i] = x[i] + h * (A51 * k[0][i] + A52 * k[1][i] + A53 * k[2][i] +
                           A54 * k[3][i]);
    f(ctx, t + C5 * h, y, k[4]);
    for (int i = 0; i < n; i++)
        y[i] = x[i] + h * (A61 * k[0][i] + A62 * k[1][i] + A63 * k[2][i] +
                           A64 * k[3][i] + A65 * k[4][i]);
    f(ctx, t_next, y, k[5]);
    for (int i = 0; i < n; i++)
        x_new[i] = x[i] + h * (B1 * k[0][i] + B3 * k[2][i] + B4 * k[3][i] +
                               B5 * k[4][i] + B6 * k[5][i]);
    f(ctx, t_next, x_new, k[6]);
    rk->n_rhs += 6;
}

static double error_norm(const cw_rk *rk, const double *x, const double *x_new,
                         double h) {
    double sum = 0.0;
    const double(*k)[CW_RK_MAXN] = rk->k;
    for (int i = 0; i < rk->n; i++) {
        double e = h * (E1 * k[0][i] + E3 * k[2][i] + E4 * k[3][i] +
                        E5 * k[4][i] + E6 * k[5][i] + E7 * k[6][i]);
        double scale = rk->atol + rk->rtol * fmax(fabs(x[i]), fabs(x_new[i]));
        double r = e / scale;
        sum += r * r;
    }
    return sqrt(sum / rk->n);
}

static double initial_step(cw_rk *rk, cw_rhs f, void *ctx, double t,
                           const double *x, double span) {
    const int n = rk->n;
    double d0 = 0, d1 = 0;
    for (int i = 0; i < n; i++) {
        double sc = rk->atol + rk->rtol * fabs(x[i]);
        d0 += (x[i] / sc) * (x[i] / sc);
        d1 += (rk->k[0][i] / sc) * (rk->k[0][i] / sc);
    }
    d0 = sqrt(d0 / n);
    d1 = sqrt(d1 / n);
    double h0 = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
    h0 = fmin(h0, span);
    double y[CW_RK_MAXN], f1[CW_RK_MAXN];
    for (int i = 0; i < n; i++) y[i] = x[i] + h0 * rk->k[0][i];
    f(ctx, t + h0, y, f1);
    rk->n_rhs++;
    double d2 = 0;
    for (int i = 0; i < n; i++) {
        double sc = rk->atol + rk->rtol * fabs(x[i]);
        double r = (f1[i] - rk->k[0][i]) / sc;
        d2 += r * r;
    }
    d2 = sqrt(d2 / n) / h0;
    double dm = fmax(d1, d2);
    double h1 = dm <= 1e-15 ? fmax(1e-6, h0 * 1e-3) : pow(0.01 / dm, 0.2);
    return fmin(100 * h0, h1);
}

static void prepare_dense(cw_rk *rk, double h) {
    for (int i = 0; i < rk->n; i++) {
        double dx = rk->x1[i] - rk->x0[i];
        double bspl = h * rk->k[0][i] - dx;
        rk->rcont[0][i] = rk->x0[i];
        rk->rcont[1][i] = dx;
        rk->rcont[2][i] = bspl;
        rk->rcont[3][i] = dx - h * rk->k[6][i] - bspl;
        rk->rcont[4][i] =
            h * (D1 * rk->k[0][i] + D3 * rk->k[2][i] + D4 * rk->k[3][i] +
                 D5 * rk->k[4][i] + D6 * rk->k[5][i] + D7 * rk->k[6][i]);
    }
}

void cw_rk_dense(const cw_rk *rk, double t, double *x) {
    double th = rk->h != 0 ? (t - rk->t0) / rk->h : 0.0;
    double th1 = 1.0 - th;
    for (int i = 0; i < rk->n; i++)
        x[i] = rk->rcont[0][i] +
               th * (rk->rcont[1][i] +
                     th1 * (rk->rcont[2][i] +
                            th * (rk->rcont[3][i] + th1 * rk->rcont[4][i])));
}

static int all_finite(const double *x, int n) {
    for (int i = 0; i < n; i++)
        if (!isfinite(x[i])) return 0;
    return 1;
}

cw_rk_result cw_rk_advance(cw_rk *rk, cw_rhs f, void *ctx, double *t,
                           double t_end, double *x, double *h_next,
                           cw_rk_observer observer, void *observer_ctx) {
    const int n = rk->n;
    if (!(t_end > *t)) return CW_RK_OK;
    double x_new[CW_RK_MAXN];
    f(ctx, *t, x, rk->k[0]);
    rk->n_rhs++;
    if (!all_finite(rk->k[0], n)) return CW_RK_NONFINITE;
    double h = *h_next;
    if (!(h > 0)) h = initial_step(rk, f, ctx, *t, x, t_end - *t);
    if (rk->h_max > 0) h = fmin(h, rk->h_max);
    long steps = 0;
    for (;;) {
        double remaining = t_end - *t;
        /* Land exactly on t_end; stretch by up to 1% rather than leave a
         * sliver step behind. */
        int last = h >= remaining * 0.99;
        double h_try = last ? remaining : h;
        /* A short final step is the caller's choice (a master may land a
         * few ulps past an event): take it. Only a controller-shrunk step
         * can be too small. */
        if (!last && h_try <= 16 * 2.2e-16 * fabs(*t) + 1e-300)
            return CW_RK_STEP_TOO_SMALL;
        if (++steps > rk->max_steps) return CW_RK_TOO_MANY_STEPS;
        stages(rk, f, ctx, *t, x, h_try, last ? t_end : *t + h_try, x_new);
        double err = error_norm(rk, x, x_new, h_try);
        if (!isfinite(err)) err = 1e10; /* treat overflow as a rejection */
        double fac = err > 0 ? 0.9 * pow(err, -0.2) : 5.0;
        fac = fmin(5.0, fmax(0.2, fac));
        if (err <= 1.0) {
            rk->n_accepted++;
            rk->t0 = *t;
            rk->h = h_try;
            memcpy(rk->x0, x, sizeof(double) * n);
            memcpy(rk->x1, x_new, sizeof(double) * n);
            prepare_dense(rk, h_try);
            *t = last ? t_end : *t + h_try;
            memcpy(x, x_new, sizeof(double) * n);
            memcpy(rk->k[0], rk->k[6], sizeof(double) * n);
            /* A clipped last step says nothing about the natural step:
             * keep the larger suggestion. */
            double suggested = h_try * fac;
            if (last && h_try < h) suggested = fmax(suggested, h);
            if (rk->h_max > 0) suggested = fmin(suggested, rk->h_max);
            /* 5 x a huge last step overflows; the suggestion is kept in
             * the FMU state, which must stay finite (found by fuzzing). */
            h = fmin(suggested, DBL_MAX);
            *h_next = h;
            if (observer && observer(observer_ctx, rk)) return CW_RK_STOPPED;
            if (last) return CW_RK_OK;
        } else {
            rk->n_rejected++;
            h = h_try * fmin(1.0, fac);
            if (!all_finite(x_new, n) && h < 1e-300) return CW_RK_NONFINITE;
        }
    }
}

void cw_rk_single_step(int n, cw_rhs f, void *ctx, double t, const double *x,
                       double h, double *x_out) {
    cw_rk rk;
    cw_rk_init(&rk, n, 1, 1, 0);
    f(ctx, t, x, rk.k[0]);
    stages(&rk, f, ctx, t, x, h, t + h, x_out);
}
