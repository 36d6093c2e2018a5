/* AveragedPendulum: Hoyng's amplitude-phase (KBM averaged) equations.
 *
 * In normalized time tau = omega0 t, omega0 = sqrt(g/L), with
 * phi = lambda sin(psi), epsilon = 1/(2Q) and torques in units of m g L:
 *
 * escapement = 0 (model escapement, mu = drive/(m g L); Eqs. 15-16)
 *   d(lambda^2)/dtau = -2 eps lambda^2 + 4 mu phi_r/pi
 *   dpsi/dtau        = 1 + circ(lambda)
 *                      + (2 mu/(pi lambda)) sqrt(1 - (phi_r/lambda)^2)
 * escapement = 1 (one impulse of work e = drive/(m g L) per period at
 * phi_1; Eqs. C4-C5, C4 rewritten for lambda^2)
 *   d(lambda^2)/dtau = -2 eps lambda^2 + e/pi
 *   dpsi/dtau        = 1 + circ(lambda) - (e/(2 pi lambda^2)) tan(psi1),
 *   tan(psi1) = phi_1/sqrt(lambda^2 - phi_1^2)
 * circ(lambda) = J1(lambda)/lambda - 1/2 (Eq. A1) or -lambda^2/16.
 *
 * Stall: when lambda <= phi_r (or <= |phi_1|) the pendulum no longer
 * reaches the angle where the escapement acts; the escapement terms are 0
 * and the amplitude decays freely. Nothing restarts a stalled pendulum, as
 * in a real clock.
 *
 * The state is lambda^2 (its equation is linear, so constant driving gives
 * an exact exponential) and the phase deviation D = psi - omega0 t, which
 * keeps the slow part of the phase away from the large, exactly known
 * nominal part; integration is in laboratory time t. */
#define _DEFAULT_SOURCE /* j1() from <math.h> */
#include <math.h>

#include "cw_rk.h"
#include "cw_runtime.h"
#include "cw_vars.h"

static const double PI = 3.14159265358979323846;

static double omega0(const cw_instance *inst) { return sqrt(R(g) / R(L)); }

static double epsilon(const cw_instance *inst) {
    return R(Q) > 0 ? 0.5 / R(Q) : 0.0;
}

/* J1(x)/x - 1/2. The power series avoids the cancellation of the Bessel
 * form at small amplitudes; it alternates with shrinking terms for x < 2. */
static double circ_bessel(double x) {
    if (x >= 2.0) return j1(x) / x - 0.5;
    const double q = -0.25 * x * x;
    double term = 0.5, sum = 0.0;
    for (int k = 1; k < 40; k++) {
        term *= q / ((double)k * (double)(k + 1));
        sum += term;
        if (fabs(term) <= 1e-17 * fabs(sum)) break;
    }
    return sum;
}

static double circ(const cw_instance *inst, double lambda) {
    return I(circular) ? circ_bessel(lambda) : -lambda * lambda / 16.0;
}

typedef struct {
    double dlam2; /* d(lambda^2)/dtau */
    double dev;   /* dpsi/dtau - 1 */
    int stalled;
} averaged;

static averaged averages(const cw_instance *inst, double lam2, double drive) {
    const double lam = sqrt(fmax(lam2, 0.0));
    const double drive_n = drive / (R(m) * R(g) * R(L));
    averaged a;
    a.dlam2 = -2.0 * epsilon(inst) * lam2;
    a.dev = circ(inst, lam);
    if (I(escapement) == 0) {
        const double phi0 = R(phi_r);
        a.stalled = !(lam > phi0);
        if (!a.stalled) {
            const double r = phi0 / lam;
            a.dlam2 += 4.0 * drive_n * phi0 / PI;
            a.dev += (2.0 * drive_n / (PI * lam)) * sqrt(1.0 - r * r);
        }
    } else {
        const double phi1 = R(phi_1);
        a.stalled = !(lam > fabs(phi1));
        if (!a.stalled) {
            const double tan_psi1 = phi1 / sqrt(lam2 - phi1 * phi1);
            a.dlam2 += drive_n / PI;
            a.dev -= (drive_n / (2.0 * PI * lam2)) * tan_psi1;
        }
    }
    return a;
}

static void rhs(void *ctx, double t, const double *x, double *dx) {
    const cw_instance *inst = ctx;
    const double w0 = omega0(inst);
    averaged a = averages(inst, x[0], IN(drive, t));
    dx[0] = w0 * a.dlam2;
    dx[1] = w0 * a.dev;
}

static void initialize(cw_instance *inst) {
    inst->s[S_LAM2] = R(amplitude_start) * R(amplitude_start);
    inst->s[S_DEV] = R(phase_start) - omega0(inst) * inst->start_time;
    inst->s[S_H_NEXT] = 0.0;
}

static void calc_outputs(cw_instance *inst) {
    const double w0 = omega0(inst), t = inst->time;
    const double lam2 = inst->s[S_LAM2], dev = inst->s[S_DEV];
    averaged a = averages(inst, lam2, IN(drive, t));
    R(amplitude) = sqrt(fmax(lam2, 0.0));
    R(phase) = w0 * t + dev;
    R(pendulum_time) = t + dev / w0;
    R(rate) = 1.0 + a.dev;
    R(rate_s_per_day) = 86400.0 * a.dev;
    I(stalled) = a.stalled;
}

/* The stall is the model's own event: lambda^2 falls through the square of
 * the angle where the escapement acts. */
static double stall_threshold(const cw_instance *inst) {
    const double a = I(escapement) == 0 ? R(phi_r) : fabs(R(phi_1));
    return a * a;
}

static double stall_margin(const cw_instance *inst, const double *x) {
    return x[0] - stall_threshold(inst);
}

static void settle_on_stall(const cw_instance *inst, double *x) {
    x[0] = stall_threshold(inst); /* lambda = phi_r exactly: stalled */
}

static fmi2Status do_step(cw_instance *inst, double t_end) {
    static const char *const names[] = {"lambda^2", "psi - omega0 t"};
    return (fmi2Status)cw_integrate_to_event(inst, "AveragedPendulum", rhs, 2, S_LAM2,
                                             S_H_NEXT, t_end, R(rtol), R(atol), R(h_max),
                                             I(integrator), names, stall_margin,
                                             settle_on_stall);
}
