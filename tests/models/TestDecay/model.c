/* TestDecay: dx/dt = -k x + v by explicit Euler steps whose length is the
 * tolerance the environment gave fmi2SetupExperiment (1e-2 without one),
 * so that its result shows which tolerance it got (a test FMU). */
#include <math.h>

#include "cw_runtime.h"
#include "cw_vars.h"

static void initialize(cw_instance *inst) { R(x) = R(x0); }

static void calc_outputs(cw_instance *inst) { (void)inst; }

static fmi2Status do_step(cw_instance *inst, double t_end) {
    const double dt = inst->tolerance_defined ? inst->tolerance : 1e-2;
    double t = inst->time;
    while (t < t_end - 1e-12) {
        const double h = fmin(dt, t_end - t);
        R(x) += h * (-R(k) * R(x) + IN(v, t));
        t += h;
    }
    inst->time = t_end;
    return fmi2OK;
}
