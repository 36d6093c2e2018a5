/* TestIntegrator: dx/dt = k u with u held over the step, so x(t + h) =
 * x(t) + h k u exactly; y = x. Its modelDescription declares no
 * dependencies for y (a test FMU for formal algebraic loops). */
#include "cw_runtime.h"
#include "cw_vars.h"

static void initialize(cw_instance *inst) { R(x) = R(x0); }

static void calc_outputs(cw_instance *inst) { R(y) = R(x); }

static fmi2Status do_step(cw_instance *inst, double t_end) {
    R(x) += (t_end - inst->time) * R(k) * R(u);
    inst->time = t_end;
    return fmi2OK;
}
