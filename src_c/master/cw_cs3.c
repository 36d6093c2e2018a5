/* The FMI 3.0 Co-Simulation adapter of the compiled core: the twin of
 * clockwork/fmi/cs3.py. Its struct (cw_fmi3) is in cw_structs.h.
 *
 * Each function has the fmi2 shape the core calls and takes a cw_fmi3 as
 * its component. cw3_doStep steps through the FMU's own events: at an early
 * return it handles the event at lastSuccessfulTime and steps on to the
 * communication point; at eventHandlingNeeded it runs event mode
 * (fmi3EnterEventMode, fmi3UpdateDiscreteStates until the discrete states
 * settle, fmi3EnterStepMode) and keeps the announced next event time;
 * terminateSimulation returns Discard with `terminated` set.
 */

#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "cw_master.h"

enum { MAX_EVENT_ITERATIONS = 1000, MAX_STALLED_RETURNS = 100 };

static int fmi3_settle(cw_fmi3 *a)
{
    bool need = false, term = false, nominals = false, values = false, defined = false;
    double next_time = 0.0;
    int st = FMI_OK, k;
    for (k = 0; k < MAX_EVENT_ITERATIONS; k++) {
        int s = a->updateDiscreteStates(a->instance, &need, &term, &nominals, &values, &defined, &next_time);
        st = s > st ? s : st;
        if (s > FMI_WARNING) {
            a->failed_call = 3;
            return s;
        }
        if (term)
            a->terminated = 1;
        if (!need)
            break;
    }
    if (k == MAX_EVENT_ITERATIONS) {
        a->failed_call = 6;
        return FMI_ERROR;
    }
    a->next_event_time = defined ? next_time : INFINITY;
    a->events += 1;
    int s = a->enterStepMode(a->instance);
    if (s > FMI_WARNING)
        a->failed_call = 4;
    return s > st ? s : st;
}

static int fmi3_handle_event(cw_fmi3 *a)
{
    int st = a->enterEventMode(a->instance);
    if (st > FMI_WARNING) {
        a->failed_call = 2;
        return st;
    }
    int s = fmi3_settle(a);
    return s > st ? s : st;
}

/* The importer's side of Intermediate Update Mode (instanceEnvironment is
 * the cw_fmi3): set each fed input to its polynomial at `t`, with the
 * arithmetic of the runtime's cw_input, so that FMI 2.0 and 3.0 give the
 * same bits. Held inputs (every derivative 0) the FMU already has. */
CW_EXPORT void cw3_intermediateUpdate(void *env, double t, bool set_requested, bool get_allowed,
                                      bool step_finished, bool can_return_early, bool *early_requested,
                                      double *early_time)
{
    (void)get_allowed; (void)step_finished; (void)can_return_early; (void)early_time;
    if (early_requested)
        *early_requested = false;
    /* Only an environment the master gave (cw_log.c's registry): an FMU
     * may pass any pointer back. */
    if (!set_requested || !cw_env_known(env))
        return;
    cw_fmi3 *a = env;
    if (!a->iu_poly)
        return;
    size_t m = 0;
    for (int k = 0; k < a->n_iu; k++)
        if (a->iu_fed[k]) {
            const double dt = t - a->iu_tref[k];
            a->iu_set_vr[m] = a->iu_vr[k];
            a->iu_val[m++] = input_polynomial(a->iu_u0[k], a->iu_d1[k], a->iu_d2[k], dt);
        }
    a->iu_calls += 1;
    a->setFloat64(a->instance, a->iu_set_vr, m, a->iu_val, m);  /* a refusal fails fmi3DoStep */
}

static int iu_index(const cw_fmi3 *a, unsigned vr)
{
    for (int k = 0; k < a->n_iu; k++)
        if (a->iu_vr[k] == vr)
            return k;
    return -1;
}

static void iu_recheck(cw_fmi3 *a)
{
    a->iu_poly = 0;
    for (int k = 0; k < a->n_iu; k++)
        if (a->iu_fed[k] && (a->iu_d1[k] != 0.0 || a->iu_d2[k] != 0.0))
            a->iu_poly = 1;
}

CW_EXPORT int cw3_doStep(void *comp, double t, double h, int no_set_prior)
{
    cw_fmi3 *a = comp;
    double end = t + h, now = t, step_size = h;
    int worst = FMI_OK, stalled = 0;
    for (;;) {
        bool handling = false, term = false, early = false;
        double last = 0.0;
        int st = a->doStep(a->instance, now, step_size, no_set_prior != 0, &handling, &term, &early, &last);
        if (st > FMI_WARNING) {
            a->failed_call = 1;
            return st;
        }
        worst = st > worst ? st : worst;
        double reached = early ? last : end;
        if (handling && a->event_mode_used) {
            /* An FMU with clocks: the master's handler (engine/clocks.py) runs the event. */
            st = a->clock_event ? a->clock_event(reached) : fmi3_handle_event(a);
            if (st > FMI_WARNING)
                return st;
            worst = st > worst ? st : worst;
        }
        if (term)
            reached = last;  /* where the FMU stopped, early return or not */
        if (term || a->terminated) {
            /* A whole step is kept; one the FMU stopped short of is discarded. */
            a->terminated = 1;
            a->end_time = reached;
            return reached >= end ? worst : FMI_DISCARD;
        }
        if (!early || reached >= end) {
            a->iu_time = end;
            return worst;
        }
        a->early_returns += 1;
        stalled = reached <= now ? stalled + 1 : 0;
        if (stalled > MAX_STALLED_RETURNS) {
            a->failed_call = 5;
            return FMI_ERROR;
        }
        now = reached;
        step_size = end - reached;
        /* The FMU's step must end on `end` itself (now + step_size rounds),
         * so that it lands where a step without early return lands. */
        while (now + step_size < end)
            step_size = nextafter(step_size, INFINITY);
        while (now + step_size > end)
            step_size = nextafter(step_size, 0.0);
    }
}

/* The element number of a code, or -1 for a plain value reference. */
static int code_element(const cw_fmi3 *a, unsigned code)
{
    unsigned e = code - a->code_base;  /* wraps for codes below the base */
    return e < (unsigned)a->n_codes ? (int)e : -1;
}

/* Translate n codes into a->scratch_vr (and their orders, when given, into
 * a->scratch_order): *m value references, each array whole. 0 when the
 * request holds part of an array, an array out of order, an array with
 * orders that differ, or more references than the scratch holds. */
static int code_runs(cw_fmi3 *a, const unsigned *vr, size_t n, const int *order, size_t *m)
{
    size_t k = 0, j = 0;
    while (k < n) {
        if (j >= (size_t)a->scratch_cap)
            return 0;
        int e = code_element(a, vr[k]);
        size_t size = 1;
        if (e >= 0) {
            size = (size_t)a->code_size[e];
            if (a->code_off[e] != 0 || k + size > n)
                return 0;
            for (size_t i = 1; i < size; i++)
                if (vr[k + i] != vr[k] + i || (order && order[k + i] != order[k]))
                    return 0;
            a->scratch_vr[j] = a->code_vr[e];
        } else {
            a->scratch_vr[j] = vr[k];
        }
        if (order)
            a->scratch_order[j] = order[k];
        j++;
        k += size;
    }
    *m = j;
    return 1;
}

/* fmi3GetFloat64 (order NULL) or fmi3GetOutputDerivatives of n codes,
 * element by element: each element's whole array, then its value. */
static int get_elementwise(cw_fmi3 *a, const unsigned *vr, size_t n, const int *order, double *out)
{
    int worst = FMI_OK;
    for (size_t k = 0; k < n; k++) {
        int e = code_element(a, vr[k]);
        unsigned one = e >= 0 ? a->code_vr[e] : vr[k];
        size_t size = e >= 0 ? (size_t)a->code_size[e] : 1;
        int st = order ? a->getOutputDerivatives(a->instance, &one, 1, &order[k], a->scratch_val, size)
                       : a->getFloat64(a->instance, &one, 1, a->scratch_val, size);
        worst = st > worst ? st : worst;
        if (st > FMI_WARNING)
            return st;
        out[k] = a->scratch_val[e >= 0 ? a->code_off[e] : 0];
    }
    return worst;
}

CW_EXPORT int cw3_getReal(void *comp, const unsigned *vr, size_t n, double *out)
{
    cw_fmi3 *a = comp;
    if (!a->n_codes)
        return a->getFloat64(a->instance, vr, n, out, n);
    size_t m;
    if (code_runs(a, vr, n, NULL, &m))
        return a->getFloat64(a->instance, a->scratch_vr, m, out, n);
    return get_elementwise(a, vr, n, NULL, out);
}

CW_EXPORT int cw3_setReal(void *comp, const unsigned *vr, size_t n, const double *values)
{
    cw_fmi3 *a = comp;
    int st;
    if (!a->n_codes) {
        st = a->setFloat64(a->instance, vr, n, values, n);
    } else {
        size_t m;
        if (!code_runs(a, vr, n, NULL, &m))
            return FMI_ERROR;  /* part of an array: the ports set arrays whole */
        st = a->setFloat64(a->instance, a->scratch_vr, m, values, n);
    }
    if (st <= FMI_WARNING && a->n_iu) {
        /* A value without derivatives is held (as fmi2SetReal on FMI 2.0). */
        for (size_t k = 0; k < n; k++) {
            int j = iu_index(a, vr[k]);
            if (j >= 0) {
                a->iu_u0[j] = values[k];
                a->iu_d1[j] = a->iu_d2[j] = 0.0;
                a->iu_tref[j] = a->iu_time;
                a->iu_fed[j] = 1;
            }
        }
        iu_recheck(a);
    }
    return st;
}

/* FMI 3.0 CS has no input derivatives: with intermediate update they are
 * kept for cw3_intermediateUpdate; without it (n_iu = 0) they are refused
 * (the master refuses extrapolation into such an FMU first). */
CW_EXPORT int cw3_setInputDerivatives(void *comp, const unsigned *vr, size_t n, const int *order,
                                      const double *values)
{
    cw_fmi3 *a = comp;
    for (size_t k = 0; k < n; k++) {
        int j = iu_index(a, vr[k]);
        if (j < 0 || !a->iu_fed[j] || order[k] < 1 || order[k] > 2 || !isfinite(values[k]))
            return FMI_ERROR;
    }
    for (size_t k = 0; k < n; k++) {
        int j = iu_index(a, vr[k]);
        if (a->iu_tref[j] != a->iu_time) {
            /* Re-based at the FMU's time, as the FMI 2.0 runtime does. */
            const double dt = a->iu_time - a->iu_tref[j];
            a->iu_u0[j] = input_polynomial(a->iu_u0[j], a->iu_d1[j], a->iu_d2[j], dt);
            a->iu_d1[j] = a->iu_d2[j] = 0.0;
            a->iu_tref[j] = a->iu_time;
        }
        if (order[k] == 1)
            a->iu_d1[j] = values[k];
        else
            a->iu_d2[j] = values[k];
    }
    iu_recheck(a);
    return FMI_OK;
}

CW_EXPORT int cw3_getOutputDerivatives(void *comp, const unsigned *vr, size_t n, const int *order, double *out)
{
    cw_fmi3 *a = comp;
    if (!a->n_codes)
        return a->getOutputDerivatives(a->instance, vr, n, order, out, n);
    size_t m;
    if (code_runs(a, vr, n, order, &m))
        return a->getOutputDerivatives(a->instance, a->scratch_vr, m, a->scratch_order, out, n);
    return get_elementwise(a, vr, n, order, out);
}

CW_EXPORT int cw3_getState(void *comp, void **state)
{
    cw_fmi3 *a = comp;
    int st = a->getState(a->instance, state);
    a->saved_next_event_time = a->next_event_time;
    if (a->n_iu) {
        size_t n = (size_t)a->n_iu;
        memcpy(a->iu_saved, a->iu_u0, n * sizeof(double));
        memcpy(a->iu_saved + n, a->iu_d1, n * sizeof(double));
        memcpy(a->iu_saved + 2 * n, a->iu_d2, n * sizeof(double));
        memcpy(a->iu_saved + 3 * n, a->iu_tref, n * sizeof(double));
        memcpy(a->iu_saved_fed, a->iu_fed, n * sizeof(int));
        a->iu_saved_time = a->iu_time;
    }
    return st;
}

CW_EXPORT int cw3_setState(void *comp, void *state)
{
    cw_fmi3 *a = comp;
    int st = a->setState(a->instance, state);
    a->next_event_time = a->saved_next_event_time;
    if (a->n_iu) {
        size_t n = (size_t)a->n_iu;
        memcpy(a->iu_u0, a->iu_saved, n * sizeof(double));
        memcpy(a->iu_d1, a->iu_saved + n, n * sizeof(double));
        memcpy(a->iu_d2, a->iu_saved + 2 * n, n * sizeof(double));
        memcpy(a->iu_tref, a->iu_saved + 3 * n, n * sizeof(double));
        memcpy(a->iu_fed, a->iu_saved_fed, n * sizeof(int));
        a->iu_time = a->iu_saved_time;
        iu_recheck(a);
    }
    return st;
}
