/* The FMI 1.0 Co-Simulation adapter of the compiled core: the twin of
 * clockwork/fmi/cs1.py. Its struct (cw_fmi1) is in cw_structs.h.
 *
 * Each function has the fmi2 shape the core calls and takes a cw_fmi1 as
 * its component. fmiDoStep's last argument is FMI 1.0's newStep, an
 * fmiBoolean (a char), where fmi2DoStep has an int: cw1_doStep calls it
 * through its own type, always with newStep = true (a step of an FMU
 * without state is never repeated). FMI 1.0 computes outputs in fmiDoStep:
 * outputs read after inputs were set (no step between) are computed first
 * by a step of size 0 at the communication point (cw1_fresh), FMI 1.0's
 * iteration, as FMI 2.0 computes them on the get. A negated alias has a value reference
 * of its own (negated_vr), turned into the FMU's (base_vr) with its value
 * negated both ways. FMI 1.0 has no FMU state: the master refuses every
 * setting that needs one before the first step.
 */

#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "cw_master.h"

enum { CW1_CHUNK = 64 };  /* value references translated at a time */

/* The FMU's value references for vr[0..n) (n <= CW1_CHUNK) and which are negated. */
static void cw1_own(const cw_fmi1 *a, const unsigned *vr, size_t n, unsigned *own, int *negated)
{
    for (size_t k = 0; k < n; k++) {
        own[k] = vr[k];
        negated[k] = 0;
        for (int j = 0; j < a->n_negated; j++)
            if (a->negated_vr[j] == vr[k]) {
                own[k] = a->base_vr[j];
                negated[k] = 1;
                break;
            }
    }
}

CW_EXPORT int cw1_doStep(void *comp, double t, double h, int no_set_prior)
{
    cw_fmi1 *a = comp;
    (void)no_set_prior;  /* FMI 1.0 has no FMU state to set */
    int st = a->doStep(a->instance, t, h, (fmi1_boolean)1);
    if (st <= FMI_WARNING) {
        a->time = t + h;
        a->stale = 0;
    }
    return st;
}

/* FMI 1.0 computes outputs in fmiDoStep: where inputs were set since the
 * last step, a step of size 0 at the communication point first (FMI 1.0's
 * iteration; FMI 2.0 computes them on the get). */
static int cw1_fresh(cw_fmi1 *a)
{
    if (!a->stale)
        return FMI_OK;
    int st = a->doStep(a->instance, a->time, 0.0, (fmi1_boolean)1);
    if (st > FMI_WARNING) {
        a->failed_zero = 1;
        return st;
    }
    a->stale = 0;
    a->zero_steps++;
    return st;
}

/* A call with negated aliases among vr: through the FMU's value references,
 * CW1_CHUNK at a time, values given negated and values read negated back. */
enum { CW1_GET_REAL, CW1_SET_REAL, CW1_SET_DER, CW1_GET_DER };

static int cw1_translated(cw_fmi1 *a, int call, const unsigned *vr, size_t n, const int *order,
                          const double *given, double *out)
{
    int worst = FMI_OK;
    for (size_t at = 0; at < n; at += CW1_CHUNK) {
        size_t m = n - at < CW1_CHUNK ? n - at : CW1_CHUNK;
        unsigned own[CW1_CHUNK];
        int negated[CW1_CHUNK];
        double values[CW1_CHUNK];
        cw1_own(a, vr + at, m, own, negated);
        if (given)
            for (size_t k = 0; k < m; k++)
                values[k] = negated[k] ? -given[at + k] : given[at + k];
        int st;
        switch (call) {
        case CW1_GET_REAL: st = a->getReal(a->instance, own, m, out + at); break;
        case CW1_SET_REAL: st = a->setReal(a->instance, own, m, values); break;
        case CW1_SET_DER: st = a->setInputDerivatives(a->instance, own, m, order + at, values); break;
        default: st = a->getOutputDerivatives(a->instance, own, m, order + at, out + at); break;
        }
        if (st > FMI_WARNING)
            return st;
        worst = st > worst ? st : worst;
        if (out)
            for (size_t k = 0; k < m; k++)
                if (negated[k])
                    out[at + k] = -out[at + k];
    }
    return worst;
}

CW_EXPORT int cw1_getReal(void *comp, const unsigned *vr, size_t n, double *out)
{
    cw_fmi1 *a = comp;
    int fresh = cw1_fresh(a);
    if (fresh > FMI_WARNING)
        return fresh;
    int st = a->n_negated ? cw1_translated(a, CW1_GET_REAL, vr, n, NULL, NULL, out)
                          : a->getReal(a->instance, vr, n, out);
    return st > fresh ? st : fresh;
}

CW_EXPORT int cw1_setReal(void *comp, const unsigned *vr, size_t n, const double *values)
{
    cw_fmi1 *a = comp;
    int st = a->n_negated ? cw1_translated(a, CW1_SET_REAL, vr, n, NULL, values, NULL)
                          : a->setReal(a->instance, vr, n, values);
    if (n)
        a->stale = 1;
    return st;
}

CW_EXPORT int cw1_setInputDerivatives(void *comp, const unsigned *vr, size_t n, const int *order,
                                      const double *values)
{
    cw_fmi1 *a = comp;
    return a->n_negated ? cw1_translated(a, CW1_SET_DER, vr, n, order, values, NULL)
                        : a->setInputDerivatives(a->instance, vr, n, order, values);
}

CW_EXPORT int cw1_getOutputDerivatives(void *comp, const unsigned *vr, size_t n, const int *order, double *out)
{
    cw_fmi1 *a = comp;
    int fresh = cw1_fresh(a);
    if (fresh > FMI_WARNING)
        return fresh;
    int st = a->n_negated ? cw1_translated(a, CW1_GET_DER, vr, n, order, NULL, out)
                          : a->getOutputDerivatives(a->instance, vr, n, order, out);
    return st > fresh ? st : fresh;
}

/* Never called: the master refuses rollback for FMI 1.0 before the first step. */
CW_EXPORT int cw1_getState(void *comp, void **state)
{
    (void)comp;
    (void)state;
    return FMI_ERROR;
}

CW_EXPORT int cw1_setState(void *comp, void *state)
{
    (void)comp;
    (void)state;
    return FMI_ERROR;
}
