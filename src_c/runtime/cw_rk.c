/* Dormand-Prince 5(4) with Shampine's fourth-order dense output, and
 * Dormand-Prince 8(5,3) with Hairer's seventh-order dense output (DOP853).
 * Coefficients: J. R. Dormand, P. J. Prince, J. Comput. Appl. Math. 6 (1980)
 * and 7 (1981); Hairer, Norsett, Wanner, Solving ODEs I, Sec. II.5/II.6 and
 * II.10. Their orders are checked by tests/fmu/test_rk.py through
 * libcw_rk_probe. */
#include "cw_rk.h"

#include <float.h>
#include <math.h>
#include <stddef.h>
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

/* ------------------------------------------------------------------ */
/* Dormand-Prince 8(5,3): P. J. Prince, J. R. Dormand, J. Comput. Appl.
 * Math. 7 (1981), with the 5th- and 3rd-order error estimators and the
 * seventh-order continuous extension of Hairer, Norsett, Wanner, Solving
 * ODEs I, Sec. II.10 (code DOP853). Stage s (0-based) is evaluated at
 * t + c[s] h; stages 0..11 make the step, stage 12 is f(t + h, x1) (the
 * next step's stage 0), stages 13..15 serve the dense output only. */

static const double P8C[CW_RK_MAXSTAGES] = {
    0.0,
    0.526001519587677318785587544488e-01,
    0.789002279381515978178381316732e-01,
    0.118350341907227396726757197510,
    0.281649658092772603273242802490,
    1.0 / 3.0,
    0.25,
    4.0 / 13.0,
    127.0 / 195.0,
    0.6,
    6.0 / 7.0,
    1.0,
    1.0,
    0.1,
    0.2,
    7.0 / 9.0,
};

/* a[s][j], j < s; row 12 holds the eighth-order weights b. */
static const double P8A[CW_RK_MAXSTAGES][CW_RK_MAXSTAGES - 1] = {
    [1] = {5.26001519587677318785587544488e-2},
    [2] = {1.97250569845378994544595329183e-2,
           5.91751709536136983633785987549e-2},
    [3] = {2.95875854768068491816892993775e-2, 0.0,
           8.87627564304205475450678981324e-2},
    [4] = {2.41365134159266685502369798665e-1, 0.0,
           -8.84549479328286085344864962717e-1,
           9.24834003261792003115737966543e-1},
    [5] = {3.7037037037037037037037037037e-2, 0.0, 0.0,
           1.70828608729473871279604482173e-1,
           1.25467687566822425016691814123e-1},
    [6] = {3.7109375e-2, 0.0, 0.0, 1.70252211019544039314978060272e-1,
           6.02165389804559606850219397283e-2, -1.7578125e-2},
    [7] = {3.70920001185047927108779319836e-2, 0.0, 0.0,
           1.70383925712239993810214054705e-1,
           1.07262030446373284651809199168e-1,
           -1.53194377486244017527936158236e-2,
           8.27378916381402288758473766002e-3},
    [8] = {6.24110958716075717114429577812e-1, 0.0, 0.0,
           -3.36089262944694129406857109825,
           -8.68219346841726006818189891453e-1,
           2.75920996994467083049415600797e1,
           2.01540675504778934086186788979e1,
           -4.34898841810699588477366255144e1},
    [9] = {4.77662536438264365890433908527e-1, 0.0, 0.0,
           -2.48811461997166764192642586468,
           -5.90290826836842996371446475743e-1,
           2.12300514481811942347288949897e1,
           1.52792336328824235832596922938e1,
           -3.32882109689848629194453265587e1,
           -2.03312017085086261358222928593e-2},
    [10] = {-9.3714243008598732571704021658e-1, 0.0, 0.0,
            5.18637242884406370830023853209,
            1.09143734899672957818500254654,
            -8.14978701074692612513997267357,
            -1.85200656599969598641566180701e1,
            2.27394870993505042818970056734e1,
            2.49360555267965238987089396762,
            -3.0467644718982195003823669022},
    [11] = {2.27331014751653820792359768449, 0.0, 0.0,
            -1.05344954667372501984066689879e1,
            -2.00087205822486249909675718444,
            -1.79589318631187989172765950534e1,
            2.79488845294199600508499808837e1,
            -2.85899827713502369474065508674,
            -8.87285693353062954433549289258,
            1.23605671757943030647266201528e1,
            6.43392746015763530355970484046e-1},
    [12] = {5.42937341165687622380535766363e-2, 0.0, 0.0, 0.0, 0.0,
            4.45031289275240888144113950566,
            1.89151789931450038304281599044,
            -5.8012039600105847814672114227,
            3.1116436695781989440891606237e-1,
            -1.52160949662516078556178806805e-1,
            2.01365400804030348374776537501e-1,
            4.47106157277725905176885569043e-2},
    [13] = {5.61675022830479523392909219681e-2, 0.0, 0.0, 0.0, 0.0, 0.0,
            2.53500210216624811088794765333e-1,
            -2.46239037470802489917441475441e-1,
            -1.24191423263816360469010140626e-1,
            1.5329179827876569731206322685e-1,
            8.20105229563468988491666602057e-3,
            7.56789766054569976138603589584e-3,
            -8.298e-3},
    [14] = {3.18346481635021405060768473261e-2, 0.0, 0.0, 0.0, 0.0,
            2.83009096723667755288322961402e-2,
            5.35419883074385676223797384372e-2,
            -5.49237485713909884646569340306e-2, 0.0, 0.0,
            -1.08347328697249322858509316994e-4,
            3.82571090835658412954920192323e-4,
            -3.40465008687404560802977114492e-4,
            1.41312443674632500278074618366e-1},
    [15] = {-4.28896301583791923408573538692e-1, 0.0, 0.0, 0.0, 0.0,
            -4.69762141536116384314449447206,
            7.68342119606259904184240953878,
            4.06898981839711007970213554331,
            3.56727187455281109270669543021e-1, 0.0, 0.0, 0.0,
            -1.39902416515901462129418009734e-3,
            2.9475147891527723389556272149,
            -9.15095847217987001081870187138},
};

/* Fifth-order error estimator: x1 minus a fifth-order solution. */
static const double P8E5[12] = {
    0.1312004499419488073250102996e-1, 0.0, 0.0, 0.0, 0.0,
    -0.1225156446376204440720569753e+1,
    -0.4957589496572501915214079952,
    0.1664377182454986536961530415e+1,
    -0.3503288487499736816886487290,
    0.3341791187130174790297318841,
    0.8192320648511571246570742613e-1,
    -0.2235530786388629525884427845e-1,
};

/* Third-order solution bhh (nonzero on stages 0, 8, 11); the estimator is
 * b - bhh. */
static const double P8BHH0 = 0.244094488188976377952755905512,
                    P8BHH8 = 0.733846688281611857341361741547,
                    P8BHH11 = 0.220588235294117647058823529412e-1;

/* Continuous extension: rcont[4 + r] = h sum_s d[r][s] k[s]. */
static const double P8D[4][CW_RK_MAXSTAGES] = {
    {-0.84289382761090128651353491142e+1, 0.0, 0.0, 0.0, 0.0,
     0.56671495351937776962531783590, -0.30689499459498916912797304727e+1,
     0.23846676565120698287728149680e+1, 0.21170345824450282767155149946e+1,
     -0.87139158377797299206789907490, 0.22404374302607882758541771650e+1,
     0.63157877876946881815570249290, -0.88990336451333310820698117400e-1,
     0.18148505520854727256656404962e+2, -0.91946323924783554000451984436e+1,
     -0.44360363875948939664310572000e+1},
    {0.10427508642579134603413151009e+2, 0.0, 0.0, 0.0, 0.0,
     0.24228349177525818288430175319e+3, 0.16520045171727028198505394887e+3,
     -0.37454675472269020279518312152e+3, -0.22113666853125306036270938578e+2,
     0.77334326684722638389603898808e+1, -0.30674084731089398182061213626e+2,
     -0.93321305264302278729567221706e+1, 0.15697238121770843886131091075e+2,
     -0.31139403219565177677282850411e+2, -0.93529243588444783865713862664e+1,
     0.35816841486394083752465898540e+2},
    {0.19985053242002433820987653617e+2, 0.0, 0.0, 0.0, 0.0,
     -0.38703730874935176555105901742e+3, -0.18917813819516756882830838328e+3,
     0.52780815920542364900561016686e+3, -0.11573902539959630126141871134e+2,
     0.68812326946963000169666922661e+1, -0.10006050966910838403183860980e+1,
     0.77771377980534432092869265740, -0.27782057523535084065932004339e+1,
     -0.60196695231264120758267380846e+2, 0.84320405506677161018159903784e+2,
     0.11992291136182789328035130030e+2},
    {-0.25693933462703749003312586129e+2, 0.0, 0.0, 0.0, 0.0,
     -0.15418974869023643374053993627e+3, -0.23152937917604549567536039109e+3,
     0.35763911791061412378285349910e+3, 0.93405324183624310003907691704e+2,
     -0.37458323136451633156875139351e+2, 0.10409964950896230045147246184e+3,
     0.29840293426660503123344363579e+2, -0.43533456590011143754432175058e+2,
     0.96324553959188282948394950600e+2, -0.39177261675615439165231486172e+2,
     -0.14972683625798562581422125276e+3},
};

/* fmax(|a|, |b|) without the call into libm: the larger magnitude, the
 * other one where one is NaN (as fmax; no signed zeros after fabs). */
static inline double larger_size(double a, double b) {
    a = fabs(a);
    b = fabs(b);
    return a > b || b != b ? a : b;
}

/* The absolute tolerance of component i. */
static double atol_at(const cw_rk *rk, int i) {
    return rk->atolv ? rk->atolv[i] : rk->atol;
}

/* Hairer's stiffness estimate h |lambda| of an accepted step, from the
 * right-hand sides at its end (k_end at x1) and at the last stage point
 * (k_last at y_last), both at the step's end time. */
static void estimate_stiffness(cw_rk *rk, const double *k_end,
                               const double *k_last, const double *x1,
                               double h) {
    double num = 0.0, den = 0.0;
    for (int i = 0; i < rk->n; i++) {
        double a = k_end[i] - k_last[i], b = x1[i] - rk->y_last[i];
        num += a * a;
        den += b * b;
    }
    rk->h_lambda = den > 0.0 ? fabs(h) * sqrt(num / den) : 0.0;
}

/* x + h sum_{j < s} a[s][j] k[j] for n components (inlined with constant
 * n where the caller has one). Unrolling it with constant s too saves
 * instructions but not time: the sums are chains of dependent additions,
 * as long either way, and the bits forbid reordering them. */
static inline __attribute__((always_inline)) void
stage_point8_n(const cw_rk *rk, int s, int n, const double *x, double h, double *y) {
    const double *a = P8A[s];
    for (int i = 0; i < n; i++) {
        double sum = 0.0;
        for (int j = 0; j < s; j++) sum += a[j] * rk->k[j][i];
        y[i] = x[i] + h * sum;
    }
}

static void stage_point8(const cw_rk *rk, int s, const double *x, double h,
                         double *y) {
    stage_point8_n(rk, s, rk->n, x, h, y);
}

/* Stages 1..11 of one step; k[0] must hold f(t, x). Writes x_new (stage
 * 12's point). The last stage is at t_next, the exact end of the step. */
static void stages8(cw_rk *rk, cw_rhs f, void *ctx, double t, const double *x,
                    double h, double t_next, double *x_new) {
    double y[CW_RK_MAXN] = {0};
    for (int s = 1; s < 12; s++) {
        stage_point8(rk, s, x, h, y);
        f(ctx, s == 11 ? t_next : t + P8C[s] * h, y, rk->k[s]);
    }
    if (rk->stiffness_test) memcpy(rk->y_last, y, sizeof(double) * rk->n);
    stage_point8(rk, 12, x, h, x_new);
    rk->n_rhs += 11;
}

/* Hairer's combination of the 5th- and 3rd-order estimates: the error is
 * |h| E5^2 / sqrt(E5^2 + 0.01 E3^2), which behaves like the 8th-order
 * error the step actually makes. */
static inline __attribute__((always_inline)) double
error_norm8(const cw_rk *rk, int n, const double *x, const double *x_new, double h) {
    double e5 = 0.0, e3 = 0.0;
    const double(*k)[CW_RK_MAXN] = rk->k;
    for (int i = 0; i < n; i++) {
        double scale = atol_at(rk, i) + rk->rtol * larger_size(x[i], x_new[i]);
        double r5 = 0.0, bsum = 0.0;
        for (int s = 0; s < 12; s++) {
            r5 += P8E5[s] * k[s][i];
            bsum += P8A[12][s] * k[s][i];
        }
        double r3 = bsum - P8BHH0 * k[0][i] - P8BHH8 * k[8][i] -
                    P8BHH11 * k[11][i];
        r5 /= scale;
        r3 /= scale;
        e5 += r5 * r5;
        e3 += r3 * r3;
    }
    if (e5 == 0.0 && e3 == 0.0) return 0.0;
    return fabs(h) * e5 / sqrt((e5 + 0.01 * e3) * n);
}

/* The three extra stages and the coefficients of the continuous extension
 * of the last accepted step; k[0..12] are that step's. */
static inline __attribute__((always_inline)) void prepare_dense8_n(cw_rk *rk, int n) {
    const double h = rk->h;
    double y[CW_RK_MAXN] = {0};
    for (int s = 13; s < 16; s++) {
        stage_point8_n(rk, s, n, rk->x0, h, y);
        rk->f(rk->ctx, rk->t0 + P8C[s] * h, y, rk->k[s]);
    }
    rk->n_rhs += 3;
    for (int i = 0; i < n; i++) {
        double dx = rk->x1[i] - rk->x0[i];
        double bspl = h * rk->k[0][i] - dx;
        rk->rcont[0][i] = rk->x0[i];
        rk->rcont[1][i] = dx;
        rk->rcont[2][i] = bspl;
        rk->rcont[3][i] = dx - h * rk->k[12][i] - bspl;
        for (int r = 0; r < 4; r++) {
            double sum = 0.0;
            for (int s = 0; s < 16; s++) sum += P8D[r][s] * rk->k[s][i];
            rk->rcont[4 + r][i] = h * sum;
        }
    }
    rk->dense_ready = 1;
}

/* DOP853's dense output for n components; inlined with n = 2 (cw_rk_dense)
 * as cw_rk_advance is, the same operations in the same order. */
static inline __attribute__((always_inline)) void dense8(const cw_rk *rk, int n, double t, double *x) {
    if (!rk->dense_ready) {
        if (!rk->f || rk->n_accepted == 0) { /* no step yet: nothing to build */
            memcpy(x, rk->x0, sizeof(double) * n);
            return;
        }
        prepare_dense8_n((cw_rk *)rk, n); /* a cache, built once per step */
    }
    double th = rk->h != 0 ? (t - rk->t0) / rk->h : 0.0;
    double th1 = 1.0 - th;
    const double(*r)[CW_RK_MAXN] = rk->rcont;
    for (int i = 0; i < n; i++) {
        double tail = r[4][i] + th * (r[5][i] + th1 * (r[6][i] + th * r[7][i]));
        x[i] = r[0][i] +
               th * (r[1][i] + th1 * (r[2][i] + th * (r[3][i] + th1 * tail)));
    }
}

/* cw_rk_init skips exactly the stages k: nothing may lie between them and rcont. */
_Static_assert(offsetof(cw_rk, rcont) == offsetof(cw_rk, k) + sizeof(((cw_rk *)0)->k),
               "cw_rk: the stages k must be followed directly by rcont");

void cw_rk_init(cw_rk *rk, int n, double rtol, double atol, double h_max) {
    /* Everything zero but the stages k (1 KiB, more than the rest): each
     * stage is written before it is read, and a model inits a cw_rk at
     * every step. */
    memset(rk, 0, offsetof(cw_rk, k));
    memset((char *)rk + offsetof(cw_rk, rcont), 0, sizeof *rk - offsetof(cw_rk, rcont));
    rk->n = n;
    rk->rtol = rtol;
    rk->atol = atol;
    rk->h_max = h_max;
    rk->max_steps = CW_RK_MAX_STEPS;
    rk->method = CW_RK_DP54;
}

cw_rk_method cw_rk_choose(int integrator, double rtol) {
    if (integrator == CW_RK_DP54 || integrator == CW_RK_DOP853)
        return (cw_rk_method)integrator;
    return rtol <= CW_RK_AUTO_RTOL ? CW_RK_DOP853 : CW_RK_DP54;
}

void cw_rk_set_method(cw_rk *rk, int integrator) {
    rk->method = cw_rk_choose(integrator, rk->rtol);
}

/* Stages 2..7 of one step; k[0] must hold f(t, x). Writes x_new. The end
 * of the step is passed as t_next: t + h can round past t_end by an ulp. */
static inline __attribute__((always_inline)) void
stages(cw_rk *rk, int n, cw_rhs f, void *ctx, double t, const double *x, double h,
       double t_next, double *x_new) {
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
    if (rk->stiffness_test) memcpy(rk->y_last, y, sizeof(double) * n);
    f(ctx, t_next, y, k[5]);
    for (int i = 0; i < n; i++)
        x_new[i] = x[i] + h * (B1 * k[0][i] + B3 * k[2][i] + B4 * k[3][i] +
                               B5 * k[4][i] + B6 * k[5][i]);
    f(ctx, t_next, x_new, k[6]);
    rk->n_rhs += 6;
}

static inline __attribute__((always_inline)) double
error_norm(const cw_rk *rk, int n, const double *x, const double *x_new, double h) {
    double sum = 0.0;
    const double(*k)[CW_RK_MAXN] = rk->k;
    for (int i = 0; i < n; i++) {
        double e = h * (E1 * k[0][i] + E3 * k[2][i] + E4 * k[3][i] +
                        E5 * k[4][i] + E6 * k[5][i] + E7 * k[6][i]);
        double scale = atol_at(rk, i) + rk->rtol * larger_size(x[i], x_new[i]);
        double r = e / scale;
        sum += r * r;
    }
    return sqrt(sum / n);
}

static double initial_step(cw_rk *rk, cw_rhs f, void *ctx, double t,
                           const double *x, double span) {
    const int n = rk->n;
    double d0 = 0, d1 = 0;
    for (int i = 0; i < n; i++) {
        double sc = atol_at(rk, i) + rk->rtol * fabs(x[i]);
        d0 += (x[i] / sc) * (x[i] / sc);
        d1 += (rk->k[0][i] / sc) * (rk->k[0][i] / sc);
    }
    d0 = sqrt(d0 / n);
    d1 = sqrt(d1 / n);
    double h0 = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
    h0 = fmin(h0, span);
    double y[CW_RK_MAXN] = {0}, f1[CW_RK_MAXN];
    for (int i = 0; i < n; i++) y[i] = x[i] + h0 * rk->k[0][i];
    f(ctx, t + h0, y, f1);
    rk->n_rhs++;
    double d2 = 0;
    for (int i = 0; i < n; i++) {
        double sc = atol_at(rk, i) + rk->rtol * fabs(x[i]);
        double r = (f1[i] - rk->k[0][i]) / sc;
        d2 += r * r;
    }
    d2 = sqrt(d2 / n) / h0;
    double dm = fmax(d1, d2);
    double h1 = dm <= 1e-15 ? fmax(1e-6, h0 * 1e-3)
                            : pow(0.01 / dm, rk->method == CW_RK_DOP853 ? 0.125 : 0.2);
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
    if (rk->method == CW_RK_DOP853) {
        if (rk->n == 2)
            dense8(rk, 2, t, x);
        else
            dense8(rk, rk->n, t, x);
        return;
    }
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

/* cw_rk_advance for n components; inlined with n = 2 (both pendulum FMUs)
 * its loops unroll and its copies are a few moves. The same operations in
 * the same order either way, so the same bits. */
static inline __attribute__((always_inline)) cw_rk_result
advance_n(cw_rk *rk, const int n, cw_rhs f, void *ctx, double *t, double t_end, double *x,
          double *h_next, cw_rk_observer observer, void *observer_ctx) {
    if (!(t_end > *t)) return CW_RK_OK;
    const int eight = rk->method == CW_RK_DOP853;
    const double expo = eight ? -0.125 : -0.2;
    double x_new[CW_RK_MAXN];
    rk->f = f;
    rk->ctx = ctx;
    rk->dense_ready = 0;
    int fsal = 0; /* DOP853: k[12] holds f at the start of the next step */
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
        const double t_next = last ? t_end : *t + h_try;
        double err;
        if (eight) {
            if (fsal) {
                memcpy(rk->k[0], rk->k[12], sizeof(double) * n);
                fsal = 0;
            }
            stages8(rk, f, ctx, *t, x, h_try, t_next, x_new);
            err = error_norm8(rk, n, x, x_new, h_try);
        } else {
            stages(rk, n, f, ctx, *t, x, h_try, t_next, x_new);
            err = error_norm(rk, n, x, x_new, h_try);
        }
        if (!isfinite(err)) err = 1e10; /* treat overflow as a rejection */
        double fac = err > 0 ? 0.9 * pow(err, expo) : 5.0;
        /* fmin(5.0, fmax(0.2, fac)) without two calls into libm: NaN
         * gives 0.2 as there, and fac >= 0.2 has no signed zero. */
        fac = fac > 0.2 ? fac : 0.2;
        fac = fac < 5.0 ? fac : 5.0;
        if (err <= 1.0) {
            rk->n_accepted++;
            rk->t0 = *t;
            rk->h = h_try;
            memcpy(rk->x0, x, sizeof(double) * n);
            memcpy(rk->x1, x_new, sizeof(double) * n);
            if (eight) {
                /* f at the new point: the dense output's end slope and the
                 * next step's first stage. The stages stay in k until the
                 * next step begins, for a dense output built on demand. */
                f(ctx, t_next, x_new, rk->k[12]);
                rk->n_rhs++;
                rk->dense_ready = 0;
                fsal = 1;
                if (rk->stiffness_test)
                    estimate_stiffness(rk, rk->k[12], rk->k[11], x_new, h_try);
            } else {
                prepare_dense(rk, h_try);
                if (rk->stiffness_test)
                    estimate_stiffness(rk, rk->k[6], rk->k[5], x_new, h_try);
            }
            *t = t_next;
            memcpy(x, x_new, sizeof(double) * n);
            if (!eight) memcpy(rk->k[0], rk->k[6], sizeof(double) * n);
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

cw_rk_result cw_rk_advance(cw_rk *rk, cw_rhs f, void *ctx, double *t,
                           double t_end, double *x, double *h_next,
                           cw_rk_observer observer, void *observer_ctx) {
    if (rk->n == 2)
        return advance_n(rk, 2, f, ctx, t, t_end, x, h_next, observer, observer_ctx);
    return advance_n(rk, rk->n, f, ctx, t, t_end, x, h_next, observer, observer_ctx);
}

void cw_rk_single_step_with(int method, int n, cw_rhs f, void *ctx, double t,
                            const double *x, double h, double *x_out) {
    cw_rk rk;
    cw_rk_init(&rk, n, 1, 1, 0);
    f(ctx, t, x, rk.k[0]);
    if (method == CW_RK_DOP853)
        stages8(&rk, f, ctx, t, x, h, t + h, x_out);
    else
        stages(&rk, n, f, ctx, t, x, h, t + h, x_out);
}

void cw_rk_single_step(int n, cw_rhs f, void *ctx, double t, const double *x,
                       double h, double *x_out) {
    cw_rk_single_step_with(CW_RK_DP54, n, f, ctx, t, x, h, x_out);
}
