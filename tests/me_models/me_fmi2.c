/* The FMI 2.0 Model Exchange face of the test models (the model's file is
 * ME_MODEL). Every call checks the instance's mode first (me_core.h). */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#include ME_MODEL
#include "me_core.h"

typedef struct {
    me_instance m;
    fmi2CallbackFunctions cb;
    char name[64];
} face;

static fmi2Status fail(face *f, const char *fmt, ...) {
    char text[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    if (f->cb.logger) f->cb.logger(f->cb.componentEnvironment, f->name, fmi2Error, "logStatusError", "%s", text);
    return fmi2Error;
}

/* The call is allowed in one of the modes of `mask`. */
#define ALLOW(mask, what)                                                                     \
    face *f = (face *)c;                                                                      \
    if (!me_allowed(&f->m, (mask))) return fail(f, "%s is not allowed in mode %d", (what), (int)f->m.mode)

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
    (void)c; (void)on; (void)n; (void)cats;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean logging) {
    (void)resources; (void)visible; (void)logging;
    if (type != fmi2ModelExchange || !cb || !guid || strcmp(guid, MODEL_GUID) != 0) return NULL;
    face *f = calloc(1, sizeof *f);
    if (!f) return NULL;
    f->cb = *cb;
    snprintf(f->name, sizeof f->name, "%s", name ? name : "");
    me_start(&f->m);
    return f;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tol_defined, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stop_defined, fmi2Real stop) {
    ALLOW(B(M_INSTANTIATED), "fmi2SetupExperiment");
    (void)tol_defined; (void)tol; (void)stop_defined; (void)stop;
    f->m.time = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    ALLOW(B(M_INSTANTIATED), "fmi2EnterInitializationMode");
    f->m.mode = M_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    ALLOW(B(M_INIT), "fmi2ExitInitializationMode");
    me_exit_init(&f->m);
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    ALLOW(B(M_EVENT) | B(M_CONTINUOUS), "fmi2Terminate");
    f->m.mode = M_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    me_start(&((face *)c)->m);
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    ALLOW(ANY_RUNNING, "fmi2GetReal");
    me_refresh(&f->m);
    for (size_t k = 0; k < n; k++) {
        if (vr[k] >= ME_MAX_VR) return fail(f, "fmi2GetReal: no variable %u", vr[k]);
        v[k] = f->m.r[vr[k]];
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    face *f = (face *)c;
    for (size_t k = 0; k < n; k++)
        if (!me_settable(&f->m, vr[k]))
            return fail(f, "fmi2SetReal: variable %u cannot be set in mode %d", vr[k], (int)f->m.mode);
    for (size_t k = 0; k < n; k++) f->m.r[vr[k]] = v[k];
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) {
    ALLOW(ANY_RUNNING, "fmi2GetInteger");
    for (size_t k = 0; k < n; k++) {
        if (vr[k] >= ME_MAX_VR) return fail(f, "fmi2GetInteger: no variable %u", vr[k]);
        v[k] = f->m.i[vr[k]];
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) {
    face *f = (face *)c;
    for (size_t k = 0; k < n; k++)
        if (!me_settable(&f->m, vr[k]))
            return fail(f, "fmi2SetInteger: variable %u cannot be set in mode %d", vr[k], (int)f->m.mode);
    for (size_t k = 0; k < n; k++) f->m.i[vr[k]] = v[k];
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) {
    return fmi2GetInteger(c, vr, n, v);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) {
    return fmi2SetInteger(c, vr, n, v);
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) {
    (void)vr; (void)n; (void)v;
    return fail((face *)c, "no String variables");
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]) {
    (void)vr; (void)n; (void)v;
    return fail((face *)c, "no String variables");
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    ALLOW(B(M_EVENT) | B(M_CONTINUOUS), "fmi2GetFMUstate");
    if (!*state) *state = malloc(sizeof(me_instance));
    if (!*state) return fail(f, "out of memory");
    memcpy(*state, &f->m, sizeof(me_instance));
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    ALLOW(B(M_EVENT) | B(M_CONTINUOUS), "fmi2SetFMUstate");
    if (!state) return fail(f, "fmi2SetFMUstate: no state");
    memcpy(&f->m, state, sizeof(me_instance));
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    (void)c;
    free(*state);
    *state = NULL;
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *size) {
    (void)s; (void)size;
    return fail((face *)c, "no serialization");
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t size) {
    (void)s; (void)b; (void)size;
    return fail((face *)c, "no serialization");
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t size, fmi2FMUstate *s) {
    (void)b; (void)size; (void)s;
    return fail((face *)c, "no serialization");
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real dv[],
                                        fmi2Real dz[]) {
    (void)u; (void)nu; (void)z; (void)nz; (void)dv; (void)dz;
    return fail((face *)c, "no directional derivatives");
}

fmi2Status fmi2EnterEventMode(fmi2Component c) {
    ALLOW(B(M_EVENT) | B(M_CONTINUOUS), "fmi2EnterEventMode");
    f->m.mode = M_EVENT;
    f->m.updates = 0;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info) {
    ALLOW(B(M_EVENT), "fmi2NewDiscreteStates");
    me_instance *m = &f->m;
    int again = me_update(m);
    info->newDiscreteStatesNeeded = again ? fmi2True : fmi2False;
    info->terminateSimulation = m->terminate ? fmi2True : fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->valuesOfContinuousStatesChanged = m->values_changed ? fmi2True : fmi2False;
    info->nextEventTimeDefined = m->next_event_defined ? fmi2True : fmi2False;
    info->nextEventTime = m->next_event_time;
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    ALLOW(B(M_EVENT), "fmi2EnterContinuousTimeMode");
    f->m.mode = M_CONTINUOUS;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean no_set_prior, fmi2Boolean *enter,
                                       fmi2Boolean *terminate) {
    ALLOW(B(M_CONTINUOUS), "fmi2CompletedIntegratorStep");
    (void)no_set_prior;
    *enter = model_step_event(&f->m) ? fmi2True : fmi2False;
    *terminate = f->m.terminate ? fmi2True : fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) {
    ALLOW(B(M_EVENT) | B(M_CONTINUOUS), "fmi2SetTime");
    f->m.time = t;
    return fmi2OK;
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t n) {
    ALLOW(B(M_CONTINUOUS), "fmi2SetContinuousStates");
    if (n != N_STATES) return fail(f, "fmi2SetContinuousStates: %zu states, expected %d", n, N_STATES);
    me_set_states(&f->m, x);
    return fmi2OK;
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t n) {
    ALLOW(ANY_RUNNING, "fmi2GetDerivatives");
    if (n != N_STATES) return fail(f, "fmi2GetDerivatives: %zu states, expected %d", n, N_STATES);
    me_derivatives(&f->m, dx);
    return fmi2OK;
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t n) {
    ALLOW(ANY_RUNNING, "fmi2GetEventIndicators");
    if (n != N_INDICATORS) return fail(f, "fmi2GetEventIndicators: %zu indicators, expected %d", n, N_INDICATORS);
    me_refresh(&f->m);
    model_indicators(&f->m, z);
    return fmi2OK;
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t n) {
    ALLOW(ANY_RUNNING, "fmi2GetContinuousStates");
    if (n != N_STATES) return fail(f, "fmi2GetContinuousStates: %zu states, expected %d", n, N_STATES);
    me_get_states(&f->m, x);
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x[], size_t n) {
    ALLOW(ANY_RUNNING, "fmi2GetNominalsOfContinuousStates");
    if (n != N_STATES) return fail(f, "fmi2GetNominalsOfContinuousStates: %zu states, expected %d", n, N_STATES);
    for (size_t k = 0; k < n; k++) x[k] = 1.0;
    return fmi2OK;
}
