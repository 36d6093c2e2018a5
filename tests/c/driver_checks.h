/* What the drivers of the FMI 3.0 and FMI 1.0 builds (tests/c/fmu_driver3.c,
 * fmu_driver1.c) share: the check counters, CHECK and REFUSED, and the
 * input values they drive a model with. Include after the model's
 * cw_vars.h (its variable table). */
#ifndef CW_DRIVER_CHECKS_H
#define CW_DRIVER_CHECKS_H

#include <math.h>
#include <stdio.h>
#include <string.h>

static long n_checks, n_failures, n_messages, n_errors;
static char last[1100];             /* the last message logged */
static const char *section = "";

#define CHECK(cond, ...)                                                     \
    do {                                                                     \
        n_checks++;                                                          \
        if (!(cond)) {                                                       \
            n_failures++;                                                    \
            fprintf(stderr, "FAIL [%s] line %d: ", section, __LINE__);       \
            fprintf(stderr, __VA_ARGS__);                                    \
            fprintf(stderr, " (last message: %s)\n", last);                  \
        }                                                                    \
    } while (0)

/* A refused call: Error (3 in every FMI version), with a message. */
#define REFUSED(call, ...)                                                   \
    do {                                                                     \
        long before_ = n_errors;                                             \
        int st_ = (int)(call);                                               \
        CHECK(st_ == 3 && n_errors > before_, __VA_ARGS__);                  \
    } while (0)

/* A smooth input inside the variable's range (the escapements' phi and w
 * swing as a pendulum would). */
static double input_value(const cw_var_info *v, double t) {
    if (strcmp(v->name, "phi") == 0) return 0.3 * sin(3.14159 * t);
    if (strcmp(v->name, "w") == 0) return 0.94 * cos(3.14159 * t);
    double x = v->start + 1e-3 * sin(3 * t + v->vr);
    return fmin(fmax(x, v->min), v->max);
}

#endif
