"""The embedded Runge-Kutta pairs of src_c/runtime/cw_rk.c, in Python.

The Model Exchange wrapper (``model_exchange.py``) integrates an FMU's
continuous states with the project's own pairs: Dormand-Prince 5(4) with
Shampine's fourth-order dense output, and Dormand-Prince 8(5,3) (Hairer's
DOP853) with its seventh-order dense output. The compiled core runs
cw_rk.c itself (built into libcw_master); this is its twin, expression for
expression and in the same order, so that the two engines give the same
bits (tests/test_model_exchange.py compares them, and checks the tables
below against cw_rk.c's).

``RungeKutta.advance`` integrates from t to t_end exactly, with the
step-size suggestion carried between calls, an observer called after
every accepted step (which may stop the integration there), the dense
output of the last accepted step (``dense``), optional per-component
absolute tolerances (``atolv``) and Hairer's stiffness estimate
(``h_lambda``, with ``stiffness_test``).
"""

from __future__ import annotations

import math
import sys

DP54, DOP853 = 1, 2  # cw_rk_method
AUTO_RTOL = 1e-6  # CW_RK_AUTO_RTOL: DOP853 at rtol <= this
MAX_STEPS = 1000000  # CW_RK_MAX_STEPS
OK, STEP_TOO_SMALL, TOO_MANY_STEPS, NONFINITE, STOPPED = range(5)  # cw_rk_result
DBL_MAX = sys.float_info.max

_C2, _C3, _C4, _C5 = 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0
_A21 = 1.0 / 5.0
_A31, _A32 = 3.0 / 40.0, 9.0 / 40.0
_A41, _A42, _A43 = 44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0
_A51, _A52, _A53, _A54 = 19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0
_A61, _A62, _A63, _A64, _A65 = 9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0
_B1, _B3, _B4, _B5, _B6 = 35.0 / 384.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0
_E1, _E3, _E4, _E5, _E6, _E7 = (71.0 / 57600.0, -71.0 / 16695.0, 71.0 / 1920.0, -17253.0 / 339200.0,
                                22.0 / 525.0, -1.0 / 40.0)
_D1, _D3, _D4 = -12715105075.0 / 11282082432.0, 87487479700.0 / 32700410799.0, -10690763975.0 / 1880347072.0
_D5, _D6, _D7 = 701980252875.0 / 199316789632.0, -1453857185.0 / 822651844.0, 69997945.0 / 29380423.0
_BHH0, _BHH8, _BHH11 = (0.244094488188976377952755905512, 0.733846688281611857341361741547,
                        0.220588235294117647058823529412e-1)


def choose(integrator: int, rtol: float) -> int:
    """cw_rk_choose: the pair for an `integrator` value (0 auto, 1, 2) at rtol."""
    if integrator in (DP54, DOP853):
        return integrator
    return DOP853 if rtol <= AUTO_RTOL else DP54


class RungeKutta:
    """cw_rk: one integrator's settings, last accepted step and counts."""

    def __init__(self, n: int, rtol: float, atol: float, h_max: float = 0.0):
        self.n = n
        self.rtol, self.atol, self.h_max = rtol, atol, h_max
        self.atolv: list[float] | None = None
        self.max_steps = MAX_STEPS
        self.method = DP54
        self.t0 = self.h = 0.0
        self.x0 = [0.0] * n
        self.x1 = [0.0] * n
        self.k = [[0.0] * n for _ in range(16)]
        self.rcont = [[0.0] * n for _ in range(8)]
        self.n_accepted = self.n_rejected = self.n_rhs = 0
        self.dense_ready = False
        self.f = None
        self.stiffness_test = False
        self.h_lambda = 0.0
        self.y_last = [0.0] * n

    # -- tolerances and the stiffness estimate -----------------------------

    def _atol(self, i: int) -> float:
        return self.atolv[i] if self.atolv is not None else self.atol

    def _estimate_stiffness(self, k_end, k_last, x1, h) -> None:
        num = den = 0.0
        y = self.y_last
        for i in range(self.n):
            a = k_end[i] - k_last[i]
            b = x1[i] - y[i]
            num += a * a
            den += b * b
        self.h_lambda = abs(h) * math.sqrt(num / den) if den > 0.0 else 0.0

    # -- Dormand-Prince 5(4) -------------------------------------------------

    def _stages(self, f, t, x, h, t_next, x_new) -> None:
        n = self.n
        k0, k1, k2, k3, k4, k5, k6 = self.k[:7]
        y = [x[i] + h * _A21 * k0[i] for i in range(n)]
        f(t + _C2 * h, y, k1)
        y = [x[i] + h * (_A31 * k0[i] + _A32 * k1[i]) for i in range(n)]
        f(t + _C3 * h, y, k2)
        y = [x[i] + h * (_A41 * k0[i] + _A42 * k1[i] + _A43 * k2[i]) for i in range(n)]
        f(t + _C4 * h, y, k3)
        y = [x[i] + h * (_A51 * k0[i] + _A52 * k1[i] + _A53 * k2[i] + _A54 * k3[i]) for i in range(n)]
        f(t + _C5 * h, y, k4)
        y = [x[i] + h * (_A61 * k0[i] + _A62 * k1[i] + _A63 * k2[i] + _A64 * k3[i] + _A65 * k4[i])
             for i in range(n)]
        if self.stiffness_test:
            self.y_last[:] = y
        f(t_next, y, k5)
        for i in range(n):
            x_new[i] = x[i] + h * (_B1 * k0[i] + _B3 * k2[i] + _B4 * k3[i] + _B5 * k4[i] + _B6 * k5[i])
        f(t_next, x_new, k6)
        self.n_rhs += 6

    def _error_norm(self, x, x_new, h) -> float:
        k0, _, k2, k3, k4, k5, k6 = self.k[:7]
        total = 0.0
        for i in range(self.n):
            e = h * (_E1 * k0[i] + _E3 * k2[i] + _E4 * k3[i] + _E5 * k4[i] + _E6 * k5[i] + _E7 * k6[i])
            scale = self._atol(i) + self.rtol * max(abs(x[i]), abs(x_new[i]))
            r = e / scale
            total += r * r
        return math.sqrt(total / self.n)

    def _prepare_dense(self, h) -> None:
        k0, _, k2, k3, k4, k5, k6 = self.k[:7]
        r0, r1, r2, r3, r4 = self.rcont[:5]
        for i in range(self.n):
            dx = self.x1[i] - self.x0[i]
            bspl = h * k0[i] - dx
            r0[i] = self.x0[i]
            r1[i] = dx
            r2[i] = bspl
            r3[i] = dx - h * k6[i] - bspl
            r4[i] = h * (_D1 * k0[i] + _D3 * k2[i] + _D4 * k3[i] + _D5 * k4[i] + _D6 * k5[i] + _D7 * k6[i])

    # -- Dormand-Prince 8(5,3) -----------------------------------------------

    def _stage_point8(self, s, x, h, y) -> None:
        a = _A8[s]
        k = self.k
        for i in range(self.n):
            total = 0.0
            for j in range(s):
                total += a[j] * k[j][i]
            y[i] = x[i] + h * total

    def _stages8(self, f, t, x, h, t_next, x_new) -> None:
        y = [0.0] * self.n
        for s in range(1, 12):
            self._stage_point8(s, x, h, y)
            f(t_next if s == 11 else t + _C8[s] * h, y, self.k[s])
        if self.stiffness_test:
            self.y_last[:] = y
        self._stage_point8(12, x, h, x_new)
        self.n_rhs += 11

    def _error_norm8(self, x, x_new, h) -> float:
        e5 = e3 = 0.0
        k = self.k
        b = _A8[12]
        for i in range(self.n):
            scale = self._atol(i) + self.rtol * max(abs(x[i]), abs(x_new[i]))
            r5 = bsum = 0.0
            for s in range(12):
                r5 += _E8[s] * k[s][i]
                bsum += b[s] * k[s][i]
            r3 = bsum - _BHH0 * k[0][i] - _BHH8 * k[8][i] - _BHH11 * k[11][i]
            r5 /= scale
            r3 /= scale
            e5 += r5 * r5
            e3 += r3 * r3
        if e5 == 0.0 and e3 == 0.0:
            return 0.0
        return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * self.n)

    def _prepare_dense8(self) -> None:
        h = self.h
        y = [0.0] * self.n
        for s in range(13, 16):
            self._stage_point8(s, self.x0, h, y)
            self.f(self.t0 + _C8[s] * h, y, self.k[s])
        self.n_rhs += 3
        k, r = self.k, self.rcont
        for i in range(self.n):
            dx = self.x1[i] - self.x0[i]
            bspl = h * k[0][i] - dx
            r[0][i] = self.x0[i]
            r[1][i] = dx
            r[2][i] = bspl
            r[3][i] = dx - h * k[12][i] - bspl
            for row in range(4):
                d = _D8[row]
                total = 0.0
                for s in range(16):
                    total += d[s] * k[s][i]
                r[4 + row][i] = h * total
        self.dense_ready = True

    # -- shared ----------------------------------------------------------------

    def dense(self, t: float) -> list[float]:
        """cw_rk_dense: the dense output of the last accepted step at t."""
        if self.method == DOP853:
            if not self.dense_ready:
                if self.f is None or self.n_accepted == 0:
                    return list(self.x0)
                self._prepare_dense8()
            th = (t - self.t0) / self.h if self.h != 0 else 0.0
            th1 = 1.0 - th
            r = self.rcont
            out = []
            for i in range(self.n):
                tail = r[4][i] + th * (r[5][i] + th1 * (r[6][i] + th * r[7][i]))
                out.append(r[0][i] + th * (r[1][i] + th1 * (r[2][i] + th * (r[3][i] + th1 * tail))))
            return out
        th = (t - self.t0) / self.h if self.h != 0 else 0.0
        th1 = 1.0 - th
        r0, r1, r2, r3, r4 = self.rcont[:5]
        return [r0[i] + th * (r1[i] + th1 * (r2[i] + th * (r3[i] + th1 * r4[i]))) for i in range(self.n)]

    def _initial_step(self, f, t, x, span) -> float:
        n = self.n
        k0 = self.k[0]
        d0 = d1 = 0.0
        for i in range(n):
            sc = self._atol(i) + self.rtol * abs(x[i])
            d0 += (x[i] / sc) * (x[i] / sc)
            d1 += (k0[i] / sc) * (k0[i] / sc)
        d0 = math.sqrt(d0 / n)
        d1 = math.sqrt(d1 / n)
        h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
        h0 = min(h0, span)
        y = [x[i] + h0 * k0[i] for i in range(n)]
        f1 = [0.0] * n
        f(t + h0, y, f1)
        self.n_rhs += 1
        d2 = 0.0
        for i in range(n):
            sc = self._atol(i) + self.rtol * abs(x[i])
            r = (f1[i] - k0[i]) / sc
            d2 += r * r
        d2 = math.sqrt(d2 / n) / h0
        dm = max(d1, d2)
        h1 = max(1e-6, h0 * 1e-3) if dm <= 1e-15 else (0.01 / dm) ** (0.125 if self.method == DOP853 else 0.2)
        return min(100 * h0, h1)

    def advance(self, f, t: float, t_end: float, x: list[float], h_next: float,
                observer=None) -> tuple[int, float, float]:
        """cw_rk_advance: integrate x (changed in place) from t to t_end
        exactly. f(t, x, dxdt) fills dxdt; observer(rk) after each accepted
        step returns True to stop there. Returns (result, t reached, h_next)."""
        n = self.n
        if not t_end > t:
            return OK, t, h_next
        eight = self.method == DOP853
        expo = -0.125 if eight else -0.2
        x_new = [0.0] * n
        k = self.k
        self.f = f
        self.dense_ready = False
        fsal = False
        f(t, x, k[0])
        self.n_rhs += 1
        if not all(map(math.isfinite, k[0])):
            return NONFINITE, t, h_next
        h = h_next
        if not h > 0:
            h = self._initial_step(f, t, x, t_end - t)
        if self.h_max > 0:
            h = min(h, self.h_max)
        steps = 0
        while True:
            remaining = t_end - t
            last = h >= remaining * 0.99
            h_try = remaining if last else h
            if not last and h_try <= 16 * 2.2e-16 * abs(t) + 1e-300:
                return STEP_TOO_SMALL, t, h_next
            steps += 1
            if steps > self.max_steps:
                return TOO_MANY_STEPS, t, h_next
            t_next = t_end if last else t + h_try
            if eight:
                if fsal:
                    k[0][:] = k[12]
                    fsal = False
                self._stages8(f, t, x, h_try, t_next, x_new)
                err = self._error_norm8(x, x_new, h_try)
            else:
                self._stages(f, t, x, h_try, t_next, x_new)
                err = self._error_norm(x, x_new, h_try)
            if not math.isfinite(err):
                err = 1e10
            fac = 0.9 * err ** expo if err > 0 else 5.0
            fac = min(5.0, max(0.2, fac))
            if err <= 1.0:
                self.n_accepted += 1
                self.t0 = t
                self.h = h_try
                self.x0[:] = x
                self.x1[:] = x_new
                if eight:
                    f(t_next, x_new, k[12])
                    self.n_rhs += 1
                    self.dense_ready = False
                    fsal = True
                    if self.stiffness_test:
                        self._estimate_stiffness(k[12], k[11], x_new, h_try)
                else:
                    self._prepare_dense(h_try)
                    if self.stiffness_test:
                        self._estimate_stiffness(k[6], k[5], x_new, h_try)
                t = t_next
                x[:] = x_new
                if not eight:
                    k[0][:] = k[6]
                suggested = h_try * fac
                if last and h_try < h:
                    suggested = max(suggested, h)
                if self.h_max > 0:
                    suggested = min(suggested, self.h_max)
                h = min(suggested, DBL_MAX)
                h_next = h
                if observer is not None and observer(self):
                    return STOPPED, t, h_next
                if last:
                    return OK, t, h_next
            else:
                self.n_rejected += 1
                h = h_try * min(1.0, fac)
                if not all(map(math.isfinite, x_new)) and h < 1e-300:
                    return NONFINITE, t, h_next


# Dormand-Prince 8(5,3) (cw_rk.c's P8C, P8A, P8E5, P8D, same literals):
# stage s at t + c[s] h; rows 0..11 make the step, row 12 holds the
# eighth-order weights, rows 13..15 serve the dense output.
_C8 = (
    0.0, 0.526001519587677318785587544488e-01, 0.789002279381515978178381316732e-01,
    0.118350341907227396726757197510, 0.281649658092772603273242802490, 1.0 / 3.0,
    0.25, 4.0 / 13.0, 127.0 / 195.0,
    0.6, 6.0 / 7.0, 1.0,
    1.0, 0.1, 0.2,
    7.0 / 9.0,
)
_A8 = (
    (),
    (5.26001519587677318785587544488e-2,),
    (1.97250569845378994544595329183e-2, 5.91751709536136983633785987549e-2,),
    (2.95875854768068491816892993775e-2, 0.0, 8.87627564304205475450678981324e-2,),
    (
        2.41365134159266685502369798665e-1, 0.0, -8.84549479328286085344864962717e-1,
        9.24834003261792003115737966543e-1,
    ),
    (
        3.7037037037037037037037037037e-2, 0.0, 0.0, 1.70828608729473871279604482173e-1,
        1.25467687566822425016691814123e-1,
    ),
    (
        3.7109375e-2, 0.0, 0.0, 1.70252211019544039314978060272e-1, 6.02165389804559606850219397283e-2,
        -1.7578125e-2,
    ),
    (
        3.70920001185047927108779319836e-2, 0.0, 0.0, 1.70383925712239993810214054705e-1,
        1.07262030446373284651809199168e-1, -1.53194377486244017527936158236e-2,
        8.27378916381402288758473766002e-3,
    ),
    (
        6.24110958716075717114429577812e-1, 0.0, 0.0, -3.36089262944694129406857109825,
        -8.68219346841726006818189891453e-1, 2.75920996994467083049415600797e1,
        2.01540675504778934086186788979e1, -4.34898841810699588477366255144e1,
    ),
    (
        4.77662536438264365890433908527e-1, 0.0, 0.0, -2.48811461997166764192642586468,
        -5.90290826836842996371446475743e-1, 2.12300514481811942347288949897e1,
        1.52792336328824235832596922938e1, -3.32882109689848629194453265587e1,
        -2.03312017085086261358222928593e-2,
    ),
    (
        -9.3714243008598732571704021658e-1, 0.0, 0.0, 5.18637242884406370830023853209,
        1.09143734899672957818500254654, -8.14978701074692612513997267357, -1.85200656599969598641566180701e1,
        2.27394870993505042818970056734e1, 2.49360555267965238987089396762, -3.0467644718982195003823669022,
    ),
    (
        2.27331014751653820792359768449, 0.0, 0.0, -1.05344954667372501984066689879e1,
        -2.00087205822486249909675718444, -1.79589318631187989172765950534e1,
        2.79488845294199600508499808837e1, -2.85899827713502369474065508674, -8.87285693353062954433549289258,
        1.23605671757943030647266201528e1, 6.43392746015763530355970484046e-1,
    ),
    (
        5.42937341165687622380535766363e-2, 0.0, 0.0, 0.0, 0.0, 4.45031289275240888144113950566,
        1.89151789931450038304281599044, -5.8012039600105847814672114227, 3.1116436695781989440891606237e-1,
        -1.52160949662516078556178806805e-1, 2.01365400804030348374776537501e-1,
        4.47106157277725905176885569043e-2,
    ),
    (
        5.61675022830479523392909219681e-2, 0.0, 0.0, 0.0, 0.0, 0.0, 2.53500210216624811088794765333e-1,
        -2.46239037470802489917441475441e-1, -1.24191423263816360469010140626e-1,
        1.5329179827876569731206322685e-1, 8.20105229563468988491666602057e-3,
        7.56789766054569976138603589584e-3, -8.298e-3,
    ),
    (
        3.18346481635021405060768473261e-2, 0.0, 0.0, 0.0, 0.0, 2.83009096723667755288322961402e-2,
        5.35419883074385676223797384372e-2, -5.49237485713909884646569340306e-2, 0.0, 0.0,
        -1.08347328697249322858509316994e-4, 3.82571090835658412954920192323e-4,
        -3.40465008687404560802977114492e-4, 1.41312443674632500278074618366e-1,
    ),
    (
        -4.28896301583791923408573538692e-1, 0.0, 0.0, 0.0, 0.0, -4.69762141536116384314449447206,
        7.68342119606259904184240953878, 4.06898981839711007970213554331, 3.56727187455281109270669543021e-1,
        0.0, 0.0, 0.0, -1.39902416515901462129418009734e-3, 2.9475147891527723389556272149,
        -9.15095847217987001081870187138,
    ),
)
_E8 = (
    0.1312004499419488073250102996e-1, 0.0, 0.0,
    0.0, 0.0, -0.1225156446376204440720569753e+1,
    -0.4957589496572501915214079952, 0.1664377182454986536961530415e+1, -0.3503288487499736816886487290,
    0.3341791187130174790297318841, 0.8192320648511571246570742613e-1, -0.2235530786388629525884427845e-1,
)
_D8 = (
    (
        -0.84289382761090128651353491142e+1, 0.0, 0.0, 0.0, 0.0, 0.56671495351937776962531783590,
        -0.30689499459498916912797304727e+1, 0.23846676565120698287728149680e+1,
        0.21170345824450282767155149946e+1, -0.87139158377797299206789907490,
        0.22404374302607882758541771650e+1, 0.63157877876946881815570249290,
        -0.88990336451333310820698117400e-1, 0.18148505520854727256656404962e+2,
        -0.91946323924783554000451984436e+1, -0.44360363875948939664310572000e+1,
    ),
    (
        0.10427508642579134603413151009e+2, 0.0, 0.0, 0.0, 0.0, 0.24228349177525818288430175319e+3,
        0.16520045171727028198505394887e+3, -0.37454675472269020279518312152e+3,
        -0.22113666853125306036270938578e+2, 0.77334326684722638389603898808e+1,
        -0.30674084731089398182061213626e+2, -0.93321305264302278729567221706e+1,
        0.15697238121770843886131091075e+2, -0.31139403219565177677282850411e+2,
        -0.93529243588444783865713862664e+1, 0.35816841486394083752465898540e+2,
    ),
    (
        0.19985053242002433820987653617e+2, 0.0, 0.0, 0.0, 0.0, -0.38703730874935176555105901742e+3,
        -0.18917813819516756882830838328e+3, 0.52780815920542364900561016686e+3,
        -0.11573902539959630126141871134e+2, 0.68812326946963000169666922661e+1,
        -0.10006050966910838403183860980e+1, 0.77771377980534432092869265740,
        -0.27782057523535084065932004339e+1, -0.60196695231264120758267380846e+2,
        0.84320405506677161018159903784e+2, 0.11992291136182789328035130030e+2,
    ),
    (
        -0.25693933462703749003312586129e+2, 0.0, 0.0, 0.0, 0.0, -0.15418974869023643374053993627e+3,
        -0.23152937917604549567536039109e+3, 0.35763911791061412378285349910e+3,
        0.93405324183624310003907691704e+2, -0.37458323136451633156875139351e+2,
        0.10409964950896230045147246184e+3, 0.29840293426660503123344363579e+2,
        -0.43533456590011143754432175058e+2, 0.96324553959188282948394950600e+2,
        -0.39177261675615439165231486172e+2, -0.14972683625798562581422125276e+3,
    ),
)
