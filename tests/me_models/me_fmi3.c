/* The FMI 3.0 Model Exchange face of the test models (the model's file is
 * ME_MODEL), on the same core as the FMI 2.0 face. Value reference 0 is
 * the independent variable time. */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"

#include ME_MODEL
#include "me_core.h"

typedef struct {
    me_instance m;
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
} face;

static fmi3Status fail(face *f, const char *fmt, ...) {
    char text[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    if (f->log) f->log(f->env, fmi3Error, "logStatusError", text);
    return fmi3Error;
}

#define ALLOW(mask, what)                                                                     \
    face *f = (face *)instance;                                                               \
    if (!me_allowed(&f->m, (mask))) return fail(f, "%s is not allowed in mode %d", (what), (int)f->m.mode)

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean on, size_t n, const fmi3String cats[]) {
    (void)instance; (void)on; (void)n; (void)cats;
    return fmi3OK;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token, fmi3String resources,
                                          fmi3Boolean visible, fmi3Boolean logging, fmi3InstanceEnvironment env,
                                          fmi3LogMessageCallback log) {
    (void)name; (void)resources; (void)visible; (void)logging;
    if (!token || strcmp(token, MODEL_GUID) != 0) return NULL;
    face *f = calloc(1, sizeof *f);
    if (!f) return NULL;
    f->env = env;
    f->log = log;
    me_start(&f->m);
    return f;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String resources,
                                         fmi3Boolean visible, fmi3Boolean logging, fmi3Boolean event_mode,
                                         fmi3Boolean early, const fmi3ValueReference req[], size_t n_req,
                                         fmi3InstanceEnvironment env, fmi3LogMessageCallback log,
                                         fmi3IntermediateUpdateCallback update) {
    (void)name; (void)token; (void)resources; (void)visible; (void)logging; (void)event_mode; (void)early;
    (void)req; (void)n_req; (void)env; (void)log; (void)update;
    return NULL;  /* Model Exchange only */
}

void fmi3FreeInstance(fmi3Instance instance) { free(instance); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean tol_defined, fmi3Float64 tol,
                                       fmi3Float64 start, fmi3Boolean stop_defined, fmi3Float64 stop) {
    ALLOW(B(M_INSTANTIATED), "fmi3EnterInitializationMode");
    (void)tol_defined; (void)tol; (void)stop_defined; (void)stop;
    f->m.time = start;
    f->m.mode = M_INIT;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    ALLOW(B(M_INIT), "fmi3ExitInitializationMode");
    me_exit_init(&f->m);
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    ALLOW(B(M_EVENT) | B(M_CONTINUOUS), "fmi3Terminate");
    f->m.mode = M_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    me_start(&((face *)instance)->m);
    return fmi3OK;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3Float64 v[],
                          size_t nv) {
    ALLOW(ANY_RUNNING, "fmi3GetFloat64");
    if (nv != n) return fail(f, "fmi3GetFloat64: %zu values for %zu variables", nv, n);
    me_refresh(&f->m);
    for (size_t k = 0; k < n; k++) {
        if (vr[k] >= ME_MAX_VR) return fail(f, "fmi3GetFloat64: no variable %u", vr[k]);
        v[k] = vr[k] == 0 ? f->m.time : f->m.r[vr[k]];
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
                          const fmi3Float64 v[], size_t nv) {
    face *f = (face *)instance;
    if (nv != n) return fail(f, "fmi3SetFloat64: %zu values for %zu variables", nv, n);
    for (size_t k = 0; k < n; k++)
        if (vr[k] == 0 || !me_settable(&f->m, vr[k]))
            return fail(f, "fmi3SetFloat64: variable %u cannot be set in mode %d", vr[k], (int)f->m.mode);
    for (size_t k = 0; k < n; k++) f->m.r[vr[k]] = v[k];
    return fmi3OK;
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3Int32 v[], size_t nv) {
    ALLOW(ANY_RUNNING, "fmi3GetInt32");
    if (nv != n) return fail(f, "fmi3GetInt32: %zu values for %zu variables", nv, n);
    for (size_t k = 0; k < n; k++) {
        if (vr[k] >= ME_MAX_VR) return fail(f, "fmi3GetInt32: no variable %u", vr[k]);
        v[k] = f->m.i[vr[k]];
    }
    return fmi3OK;
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, const fmi3Int32 v[],
                        size_t nv) {
    face *f = (face *)instance;
    if (nv != n) return fail(f, "fmi3SetInt32: %zu values for %zu variables", nv, n);
    for (size_t k = 0; k < n; k++)
        if (!me_settable(&f->m, vr[k]))
            return fail(f, "fmi3SetInt32: variable %u cannot be set in mode %d", vr[k], (int)f->m.mode);
    for (size_t k = 0; k < n; k++) f->m.i[vr[k]] = v[k];
    return fmi3OK;
}

fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3Boolean v[],
                          size_t nv) {
    ALLOW(ANY_RUNNING, "fmi3GetBoolean");
    if (nv != n) return fail(f, "fmi3GetBoolean: %zu values for %zu variables", nv, n);
    for (size_t k = 0; k < n; k++) {
        if (vr[k] >= ME_MAX_VR) return fail(f, "fmi3GetBoolean: no variable %u", vr[k]);
        v[k] = f->m.i[vr[k]] != 0;
    }
    return fmi3OK;
}

fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, const fmi3Boolean v[],
                          size_t nv) {
    face *f = (face *)instance;
    if (nv != n) return fail(f, "fmi3SetBoolean: %zu values for %zu variables", nv, n);
    for (size_t k = 0; k < n; k++)
        if (!me_settable(&f->m, vr[k]))
            return fail(f, "fmi3SetBoolean: variable %u cannot be set in mode %d", vr[k], (int)f->m.mode);
    for (size_t k = 0; k < n; k++) f->m.i[vr[k]] = v[k] ? 1 : 0;
    return fmi3OK;
}

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *state) {
    ALLOW(B(M_EVENT) | B(M_CONTINUOUS), "fmi3GetFMUState");
    if (!*state) *state = malloc(sizeof(me_instance));
    if (!*state) return fail(f, "out of memory");
    memcpy(*state, &f->m, sizeof(me_instance));
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState state) {
    ALLOW(B(M_EVENT) | B(M_CONTINUOUS), "fmi3SetFMUState");
    if (!state) return fail(f, "fmi3SetFMUState: no state");
    memcpy(&f->m, state, sizeof(me_instance));
    return fmi3OK;
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *state) {
    (void)instance;
    free(*state);
    *state = NULL;
    return fmi3OK;
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    ALLOW(B(M_EVENT) | B(M_CONTINUOUS), "fmi3EnterEventMode");
    f->m.mode = M_EVENT;
    f->m.updates = 0;
    return fmi3OK;
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *need, fmi3Boolean *terminate,
                                    fmi3Boolean *nominals, fmi3Boolean *values, fmi3Boolean *defined,
                                    fmi3Float64 *next) {
    ALLOW(B(M_EVENT), "fmi3UpdateDiscreteStates");
    me_instance *m = &f->m;
    *need = me_update(m) != 0;
    *terminate = m->terminate != 0;
    *nominals = false;
    *values = m->values_changed != 0;
    *defined = m->next_event_defined != 0;
    *next = m->next_event_time;
    return fmi3OK;
}

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {
    ALLOW(B(M_EVENT), "fmi3EnterContinuousTimeMode");
    f->m.mode = M_CONTINUOUS;
    return fmi3OK;
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean no_set_prior, fmi3Boolean *enter,
                                       fmi3Boolean *terminate) {
    ALLOW(B(M_CONTINUOUS), "fmi3CompletedIntegratorStep");
    (void)no_set_prior;
    *enter = model_step_event(&f->m) != 0;
    *terminate = f->m.terminate != 0;
    return fmi3OK;
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 t) {
    ALLOW(B(M_EVENT) | B(M_CONTINUOUS), "fmi3SetTime");
    f->m.time = t;
    return fmi3OK;
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 x[], size_t n) {
    ALLOW(B(M_CONTINUOUS), "fmi3SetContinuousStates");
    if (n != N_STATES) return fail(f, "fmi3SetContinuousStates: %zu states, expected %d", n, N_STATES);
    me_set_states(&f->m, x);
    return fmi3OK;
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 dx[], size_t n) {
    ALLOW(ANY_RUNNING, "fmi3GetContinuousStateDerivatives");
    if (n != N_STATES) return fail(f, "fmi3GetContinuousStateDerivatives: %zu states, expected %d", n, N_STATES);
    me_derivatives(&f->m, dx);
    return fmi3OK;
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 z[], size_t n) {
    ALLOW(ANY_RUNNING, "fmi3GetEventIndicators");
    if (n != N_INDICATORS) return fail(f, "fmi3GetEventIndicators: %zu indicators, expected %d", n, N_INDICATORS);
    me_refresh(&f->m);
    model_indicators(&f->m, z);
    return fmi3OK;
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 x[], size_t n) {
    ALLOW(ANY_RUNNING, "fmi3GetContinuousStates");
    if (n != N_STATES) return fail(f, "fmi3GetContinuousStates: %zu states, expected %d", n, N_STATES);
    me_get_states(&f->m, x);
    return fmi3OK;
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 x[], size_t n) {
    ALLOW(ANY_RUNNING, "fmi3GetNominalsOfContinuousStates");
    if (n != N_STATES) return fail(f, "fmi3GetNominalsOfContinuousStates: %zu states, expected %d", n, N_STATES);
    for (size_t k = 0; k < n; k++) x[k] = 1.0;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *n) {
    (void)instance;
    *n = N_INDICATORS;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *n) {
    (void)instance;
    *n = N_STATES;
    return fmi3OK;
}
