/* TestTypes: y = p + u for every variable type the runtime stores (y_str:
 * p_str followed by u_str), and a state x with dx/dt = u_real whose output
 * depends on x alone (a test FMU: tests/test_generic_fmu.py). */
#include <math.h>

#include "cw_runtime.h"
#include "cw_vars.h"

static void calc_outputs(cw_instance *inst) {
    const double t = inst->time;
    R(y_real) = R(gain_k) * R(p_real) + IN(u_real, t);
    I(y_int) = I(p_int) + I(u_int);
    I(y_bool) = (I(p_bool) != 0) != (I(u_bool) != 0);
    I(y_enum) = I(p_enum) > I(u_enum) ? I(p_enum) : I(u_enum);
    /* Out of memory is logged; the old text stays. */
    cw_set_string(inst, VR_y_str, S(p_str), S(u_str));
    R(y_mm) = IN(u_mm, t);
    R(y_k) = IN(u_k, t);
    R(y_state) = R(x);
    R(der_x_) = IN(u_real, t);
    R(u_rate) = cw_input_rate(inst, VR_u_real, t);
}

static fmi2Status do_step(cw_instance *inst, double t_end) {
    /* The trapezoidal rule is exact for the input's polynomial of order 1. */
    const double t = inst->time;
    R(x) += 0.5 * (IN(u_real, t) + IN(u_real, t_end)) * (t_end - t);
    I(count) += 1;
    inst->time = t_end;
    return fmi2OK;
}
