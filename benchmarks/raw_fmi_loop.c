/* The floor of any master on the bench_master.py clock: the same FMI calls
 * as one Gauss-Seidel communication step (escapement doStep, pendulum
 * doStep, outputs to inputs), made from C with no master logic. Built by
 * bench_master.py with the system's C compiler. */
#include "raw_fmi_loop.h"

int raw_fmi_loop(void *pend, void *esc, do_step_t pend_step, do_step_t esc_step,
                 get_real_t pend_get, set_real_t pend_set, get_real_t esc_get, set_real_t esc_set,
                 const unsigned *pend_out_vr, const unsigned *pend_in_vr,
                 const unsigned *esc_in_vr, const unsigned *esc_out_vr, long steps, double h)
{
    double phi_w[2], tau[1];
    double t = 0.0;
    for (long k = 0; k < steps; k++) {
        if (esc_step(esc, t, h, 0) > 1 || pend_step(pend, t, h, 0) > 1)
            return -1;
        t = (double)(k + 1) * h;
        if (pend_get(pend, pend_out_vr, 2, phi_w) > 1 || esc_set(esc, esc_in_vr, 2, phi_w) > 1 ||
            esc_get(esc, esc_out_vr, 1, tau) > 1 || pend_set(pend, pend_in_vr, 1, tau) > 1)
            return -1;
    }
    return 0;
}
