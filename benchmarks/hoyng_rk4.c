/* Hoyng's clock integrated his own way: classical RK4 at a fixed step on the
 * whole clock (normalized units, L = g = m = 1), the escapement a relay with
 * hysteresis checked after each step. The compiled yardstick for a period of
 * the co-simulation (benchmarks/bench_hoyng_period.py builds and loads it).
 *
 *   phi'' = -sin(phi) - 2 eps phi' + d mu0,  d -> -1 at phi >= phi0, +1 at phi <= -phi0
 */
#include <math.h>

static void rhs(double eps, double torque, const double x[2], double dx[2]) {
    dx[0] = x[1];
    dx[1] = -sin(x[0]) - 2.0 * eps * x[1] + torque;
}

/* Integrates `steps` steps of `dt` from (phi, w, d) in state[0..2]; returns
 * the number of upward zero crossings of phi (ticks) on the way. */
long hoyng_rk4(double *state, long steps, double dt, double eps, double mu0, double phi0) {
    double x[2] = {state[0], state[1]}, d = state[2];
    double k1[2], k2[2], k3[2], k4[2], y[2];
    long ticks = 0;
    for (long n = 0; n < steps; n++) {
        const double torque = d * mu0;
        rhs(eps, torque, x, k1);
        y[0] = x[0] + 0.5 * dt * k1[0]; y[1] = x[1] + 0.5 * dt * k1[1];
        rhs(eps, torque, y, k2);
        y[0] = x[0] + 0.5 * dt * k2[0]; y[1] = x[1] + 0.5 * dt * k2[1];
        rhs(eps, torque, y, k3);
        y[0] = x[0] + dt * k3[0]; y[1] = x[1] + dt * k3[1];
        rhs(eps, torque, y, k4);
        const double phi_old = x[0];
        x[0] += dt / 6.0 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]);
        x[1] += dt / 6.0 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]);
        if (phi_old < 0.0 && x[0] >= 0.0) ticks++;
        if (d > 0.0 && x[0] >= phi0) d = -1.0;
        else if (d < 0.0 && x[0] <= -phi0) d = 1.0;
    }
    state[0] = x[0]; state[1] = x[1]; state[2] = d;
    return ticks;
}
