/* TestSum: y = k1 u1 + k2 u2 + c, no state (a test FMU). Its output follows
 * its inputs at once, so that two of them connected both ways form a real
 * algebraic loop. */
#include "cw_runtime.h"
#include "cw_vars.h"

static void calc_outputs(cw_instance *inst) { R(y) = R(k1) * R(u1) + R(k2) * R(u2) + R(c); }

static fmi2Status do_step(cw_instance *inst, double t_end) {
    inst->time = t_end;
    return fmi2OK;
}
