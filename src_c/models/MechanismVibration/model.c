/* MechanismVibration: a vibration mode of the clock mechanism, the second
 * line of Ziemkiewicz Eq. (7),
 *   a2'' + gamma2 a2' + omega02^2 a2 + kappa a2^3 + C2 a1(t) = 0,
 * driven by the pendulum angle a1 (input). The first line of Eq. (7),
 *   a1'' + ... + C1 a2 = M / (m L^2),
 * is the pendulum's; moved to the right-hand side and multiplied by the
 * pendulum's inertia I = m L^2 it is the torque tau = -C1 I a2 that this
 * FMU feeds back. tau depends on the state only, so the pendulum-mechanism
 * loop has no algebraic loop. */
#include <math.h>

#include "cw_rk.h"
#include "cw_runtime.h"
#include "cw_vars.h"

static double acceleration(const cw_instance *inst, double t, double a2,
                           double a2dot) {
    const double w0 = R(omega02);
    return -R(gamma2) * a2dot - w0 * w0 * a2 - R(kappa) * a2 * a2 * a2 -
           R(C2) * IN(a1, t);
}

static void rhs(void *ctx, double t, const double *x, double *dx) {
    const cw_instance *inst = ctx;
    dx[0] = x[1];
    dx[1] = acceleration(inst, t, x[0], x[1]);
}

static void initialize(cw_instance *inst) {
    inst->s[S_A2] = R(a2_start);
    inst->s[S_A2DOT] = R(a2dot_start);
    inst->s[S_H_NEXT] = 0.0;
}

static void calc_outputs(cw_instance *inst) {
    const double a2 = inst->s[S_A2], a2dot = inst->s[S_A2DOT];
    const double w0 = R(omega02);
    R(a2) = a2;
    R(a2dot) = a2dot;
    R(a2ddot) = acceleration(inst, inst->time, a2, a2dot);
    R(tau) = -R(C1) * R(inertia) * a2;
    R(energy) = 0.5 * a2dot * a2dot + 0.5 * w0 * w0 * a2 * a2 +
                0.25 * R(kappa) * a2 * a2 * a2 * a2;
}

static fmi2Status do_step(cw_instance *inst, double t_end) {
    static const char *const names[] = {"a2", "a2dot"};
    return (fmi2Status)cw_integrate(inst, "MechanismVibration", rhs, 2, S_A2, S_H_NEXT, t_end,
                                    R(rtol), R(atol), R(h_max), I(integrator), names, NULL);
}

static int output_derivative(cw_instance *inst, unsigned vr, int order,
                             double *value) {
    const double a2 = inst->s[S_A2], a2dot = inst->s[S_A2DOT];
    const double a2ddot = acceleration(inst, inst->time, a2, a2dot);
    const double k = -R(C1) * R(inertia);
    if (vr == VR_a2 && (order == 1 || order == 2)) {
        *value = order == 1 ? a2dot : a2ddot;
        return 1;
    }
    if (vr == VR_a2dot && order == 1) {
        *value = a2ddot;
        return 1;
    }
    if (vr == VR_tau && (order == 1 || order == 2)) {
        *value = k * (order == 1 ? a2dot : a2ddot);
        return 1;
    }
    return 0;
}
