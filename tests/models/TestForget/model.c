/* TestForget: x integrates rate over the steps taken with
 * noSetFMUStatePriorToCurrentPoint = true and forgets the others, as
 * libcosim's quarter-truck Wheel does; kept and forgotten count the flags
 * it was given (a test FMU: tests/test_no_set_prior.py). */
#include "cw_runtime.h"
#include "cw_vars.h"

static fmi2Status do_step(cw_instance *inst, double t_end) {
    if (inst->no_set_prior) {
        R(x) += R(rate) * (t_end - inst->time);
        I(kept) += 1;
    } else {
        I(forgotten) += 1;
    }
    inst->time = t_end;
    return fmi2OK;
}
