/* What the Model Exchange wrapper (cw_me.c) and the Model Exchange group
 * (cw_me_group.c) share: the shapes of the FMU functions, the table of
 * the calls whose shape differs by FMU (cw_me.calls points at one) and
 * the event information it returns. */
#ifndef CW_ME_H
#define CW_ME_H

#include <stddef.h>

#include "cw_structs.h"

/* The shapes of the FMU functions a cw_me points at (its setTime ... setState). */
typedef int (*set_time_t)(void *, double);
typedef int (*vector_t)(void *, double *, size_t);
typedef int (*set_vector_t)(void *, const double *, size_t);
typedef int (*mode_t_)(void *);
typedef int (*get_state_t)(void *, void **);
typedef int (*set_state_t)(void *, void *);

typedef struct {
    int need, terminate, nominals, values, defined;
    double next_time;
} event_info2;

/* One table per kind of FMU (cwme_calls_fmi1/2/3) and one for a group
 * (cwmg_calls): the wrapper calls through it and never asks which. */
typedef struct {
    int (*get_real)(cw_me *me, const unsigned *vr, size_t n, double *out);
    int (*set_real)(cw_me *me, const unsigned *vr, size_t n, const double *values);
    int (*completed)(cw_me *me, int *enter, int *terminate);
    int (*update)(cw_me *me, event_info2 *info);
} cw_me_calls;

#define CWME_CALLS(me) ((const cw_me_calls *)(me)->calls)

#endif
