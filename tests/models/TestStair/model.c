/* TestStair: a counter that steps up every second and ends the simulation
 * at end_time, as Reference-FMUs' Stair does (a test FMU). On FMI 2.0 its
 * messages go to the logger as a printf format with arguments, as FMI 2.0
 * allows; on FMI 3.0 (whose logger takes the text) the runtime formats them.
 * shifted and odd follow its Integer and Boolean inputs (discrete links). */
#include <math.h>
#include <string.h>

#include "cw_runtime.h"
#include "cw_vars.h"

/* FMI 2.0's fmi2CallbackLogger, declared here so that the FMI 3.0 build
 * needs no FMI 2.0 header. */
typedef void (*fmi2_logger)(void *env, const char *instance, int status, const char *category,
                            const char *message, ...);

static void calc_outputs(cw_instance *inst) {
    I(shifted) = I(counter) + I(offset);
    I(odd) = (I(counter) % 2 != 0) != (I(flip) != 0);
}

static fmi2Status do_step(cw_instance *inst, double t_end) {
    const int fmi2 = strcmp(inst->api, "fmi2") == 0;
    const fmi2_logger log = (fmi2_logger)inst->env_logger;
    if (t_end > R(end_time) + 1e-9) {
        const char *fmt = "%s: the stair ends at t = %g s; the step to %g s is %s.";
        const char *what = I(terminate) ? "not taken" : "refused";
        if (!I(quiet) && fmi2)
            log(inst->env, inst->instance_name, fmi2Discard, "logStatusDiscard", fmt, inst->instance_name,
                R(end_time), t_end, what);
        else if (!I(quiet))
            cw_log(inst, fmi2Discard, "logStatusDiscard", fmt, inst->instance_name, R(end_time), t_end, what);
        inst->terminate_requested = I(terminate);
        return fmi2Discard;
    }
    const int level = (int)floor(t_end + 1e-9);
    if (level != I(counter) && fmi2)
        log(inst->env, inst->instance_name, fmi2Warning, "logStatusWarning",
            "%s reached level %d at t = %g s", inst->instance_name, level, t_end);
    else if (level != I(counter))
        cw_log(inst, fmi2Warning, "logStatusWarning", "%s reached level %d at t = %g s", inst->instance_name,
               level, t_end);
    I(counter) = level;
    R(level) = level;
    inst->time = t_end;
    return fmi2OK;
}
