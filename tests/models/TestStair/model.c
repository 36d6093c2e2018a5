/* TestStair: a counter that steps up every second and ends the simulation
 * at end_time, as Reference-FMUs' Stair does (a test FMU). Its messages go
 * to the logger as a printf format with arguments, as FMI 2.0 allows. */
#include <math.h>

#include "fmi2FunctionTypes.h" /* fmi2CallbackLogger: this test model is FMI 2.0 only */
#include "cw_runtime.h"
#include "cw_vars.h"

static fmi2Status do_step(cw_instance *inst, double t_end) {
    const fmi2CallbackLogger log = (fmi2CallbackLogger)inst->env_logger;
    if (t_end > R(end_time) + 1e-9) {
        if (!I(quiet))
            log(inst->env, inst->instance_name, fmi2Discard, "logStatusDiscard",
                "%s: the stair ends at t = %g s; the step to %g s is %s.", inst->instance_name,
                R(end_time), t_end, I(terminate) ? "not taken" : "refused");
        inst->terminate_requested = I(terminate);
        return fmi2Discard;
    }
    const int level = (int)floor(t_end + 1e-9);
    if (level != I(counter))
        log(inst->env, inst->instance_name, fmi2Warning, "logStatusWarning",
            "%s reached level %d at t = %g s", inst->instance_name, level, t_end);
    I(counter) = level;
    R(level) = level;
    inst->time = t_end;
    return fmi2OK;
}
