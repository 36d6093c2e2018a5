/* ChronometerEscapement: Ziemkiewicz Sec. IV. A constant torque acts while
 * the pendulum moves towards +phi through the window [alpha_m1, alpha_m2);
 * once per period, so the energy delivered per period is
 * torque (alpha_m2 - alpha_m1). Memoryless: no state, no commit. */
#include <math.h>

#include "cw_runtime.h"
#include "cw_vars.h"

static fmi2Status validate(cw_instance *inst) {
    if (!(R(alpha_m1) < R(alpha_m2))) {
        cw_log(inst, fmi2Error, "logStatusError",
               "ChronometerEscapement: alpha_m1 = %.17g rad must be less than "
               "alpha_m2 = %.17g rad (the impulse window is empty).",
               R(alpha_m1), R(alpha_m2));
        return fmi2Error;
    }
    return fmi2OK;
}

static void calc_outputs(cw_instance *inst) {
    const double t = inst->time;
    const double phi = IN(phi, t), w = IN(w, t);
    const int inside = R(alpha_m1) <= phi && phi < R(alpha_m2);
    R(tau) = inside && w > 0.0 ? R(torque) : 0.0;
    R(event_indicator_lower) = phi - R(alpha_m1);
    R(event_indicator_upper) = R(alpha_m2) - phi;
    R(event_indicator_turn) = inside ? w : 1.0;
    R(work_per_period) = R(torque) * (R(alpha_m2) - R(alpha_m1));
}
