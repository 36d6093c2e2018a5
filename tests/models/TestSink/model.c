/* TestSink: dy/dt = u[1] + ... + u[1000], one explicit Euler step over
 * each communication step (a test FMU: many sources into one sink). */
#include "cw_runtime.h"
#include "cw_vars.h"

enum { N_INPUTS = VR_u_1000_ - VR_u_1_ + 1 };

static void initialize(cw_instance *inst) { R(y) = R(y0); }

static void calc_outputs(cw_instance *inst) { (void)inst; }

static fmi2Status do_step(cw_instance *inst, double t_end) {
    double sum = 0.0;
    for (int k = 0; k < N_INPUTS; k++)
        sum += inst->r[VR_u_1_ + k];
    R(y) += (t_end - inst->time) * sum;
    inst->time = t_end;
    return fmi2OK;
}
