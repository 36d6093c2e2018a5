/* TestOscillator: x = amplitude cos(omega t), v = dx/dt, computed exactly
 * at every communication point; the output derivatives it reports are
 * (1 + derivative_error) times the true ones (a test FMU). */
#include <math.h>

#include "cw_runtime.h"
#include "cw_vars.h"

static void at(cw_instance *inst, double t) {
    inst->s[S_X] = R(amplitude) * cos(R(omega) * t);
    inst->s[S_V] = -R(amplitude) * R(omega) * sin(R(omega) * t);
}

static void initialize(cw_instance *inst) { at(inst, inst->time); }

static void calc_outputs(cw_instance *inst) {
    R(x) = inst->s[S_X];
    R(v) = inst->s[S_V];
}

static fmi2Status do_step(cw_instance *inst, double t_end) {
    at(inst, t_end);
    return fmi2OK;
}

static int output_derivative(cw_instance *inst, unsigned vr, int order, double *value) {
    const double w2 = R(omega) * R(omega), x = inst->s[S_X], v = inst->s[S_V];
    const double f = 1.0 + R(derivative_error);
    if (vr == VR_x)
        *value = f * (order == 1 ? v : -w2 * x);
    else if (vr == VR_v)
        *value = f * (order == 1 ? -w2 * x : -w2 * v);
    else
        return 0;
    return order == 1 || order == 2;
}
