/* raw_fmi_loop.c's function and types (fmi2's, with the enums as int),
 * for bench_master.py's ctypes call and raw_fmi_main.c. */
#ifndef RAW_FMI_LOOP_H
#define RAW_FMI_LOOP_H

#include <stddef.h>

typedef int (*do_step_t)(void *, double, double, int);
typedef int (*get_real_t)(void *, const unsigned *, size_t, double *);
typedef int (*set_real_t)(void *, const unsigned *, size_t, const double *);

int raw_fmi_loop(void *pend, void *esc, do_step_t pend_step, do_step_t esc_step,
                 get_real_t pend_get, set_real_t pend_set, get_real_t esc_get, set_real_t esc_set,
                 const unsigned *pend_out_vr, const unsigned *pend_in_vr,
                 const unsigned *esc_in_vr, const unsigned *esc_out_vr, long steps, double h);

#endif
