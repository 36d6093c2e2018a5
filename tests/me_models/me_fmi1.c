/* The FMI 1.0 Model Exchange face of the test models (the model's file is
 * ME_MODEL; MODEL_IDENTIFIER, the prefix of every function, is its name).
 * FMI 1.0 differs from FMI 2.0's face in: no event mode or continuous-time
 * mode of its own (fmiEventUpdate handles an event from the stepping state
 * and iterates until the discrete states settle unless intermediate results
 * are asked for); fmiInitialize is setup, initialization and the first event
 * iteration in one call; fmiBoolean is a char; there is no FMU state and no
 * reset; the callbacks come by value, without an environment. The types are
 * FMI 1.0's (fmiModelTypes.h), written out here. Every call checks the
 * instance's mode first (me_core.h). Built for the tests only. */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include ME_MODEL
#include "me_core.h"

#ifndef MODEL_IDENTIFIER
#error "MODEL_IDENTIFIER (the modelIdentifier, prefix of every function) must be defined"
#endif
#define ME1_JOIN2(a, b) a##_##b
#define ME1_JOIN(a, b) ME1_JOIN2(a, b)
#define FMI1(name) ME1_JOIN(MODEL_IDENTIFIER, name)
#define EXPORT __attribute__((visibility("default")))

typedef void *fmiComponent;
typedef unsigned int fmiValueReference;
typedef double fmiReal;
typedef int fmiInteger;
typedef char fmiBoolean;
typedef const char *fmiString;
#define fmiTrue 1
#define fmiFalse 0
typedef enum { fmiOK, fmiWarning, fmiDiscard, fmiError, fmiFatal } fmiStatus;
typedef void (*fmiCallbackLogger)(fmiComponent, fmiString, fmiStatus, fmiString, fmiString, ...);
typedef struct {
    fmiCallbackLogger logger;
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
} fmiCallbackFunctions;
typedef struct {
    fmiBoolean iterationConverged;
    fmiBoolean stateValueReferencesChanged;
    fmiBoolean stateValuesChanged;
    fmiBoolean terminateSimulation;
    fmiBoolean upcomingTimeEvent;
    fmiReal nextEventTime;
} fmiEventInfo;

typedef struct {
    me_instance m;
    fmiCallbackFunctions cb;
    char name[64];
} face;

static fmiStatus fail(face *f, const char *fmt, ...) {
    char text[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    if (f->cb.logger) f->cb.logger(f, f->name, fmiError, "error", "%s", text);
    return fmiError;
}

#define ALLOW(mask, what)                                                                     \
    face *f = (face *)c;                                                                      \
    if (!me_allowed(&f->m, (mask))) return fail(f, "%s is not allowed in mode %d", (what), (int)f->m.mode)

EXPORT const char *FMI1(fmiGetModelTypesPlatform)(void) { return "standard32"; }
EXPORT const char *FMI1(fmiGetVersion)(void) { return "1.0"; }

EXPORT fmiComponent FMI1(fmiInstantiateModel)(fmiString name, fmiString guid, fmiCallbackFunctions cb,
                                              fmiBoolean logging) {
    (void)logging;
    if (!guid || strcmp(guid, MODEL_GUID) != 0 || !cb.allocateMemory || !cb.freeMemory) return NULL;
    face *f = calloc(1, sizeof *f);
    if (!f) return NULL;
    f->cb = cb;
    snprintf(f->name, sizeof f->name, "%s", name ? name : "");
    me_start(&f->m);
    return f;
}

EXPORT void FMI1(fmiFreeModelInstance)(fmiComponent c) { free(c); }

EXPORT fmiStatus FMI1(fmiSetDebugLogging)(fmiComponent c, fmiBoolean on) {
    (void)c; (void)on;
    return fmiOK;
}

/* Events until the discrete states settle (one update if intermediate). */
static void iterate(me_instance *m, fmiBoolean intermediate, fmiEventInfo *info) {
    int changed = 0, again;
    m->mode = M_EVENT;
    m->updates = 0;
    do {
        again = me_update(m);
        changed = changed || m->values_changed;
    } while (again && !intermediate && !m->terminate);
    info->iterationConverged = again ? fmiFalse : fmiTrue;
    info->stateValueReferencesChanged = fmiFalse;
    info->stateValuesChanged = changed ? fmiTrue : fmiFalse;
    info->terminateSimulation = m->terminate ? fmiTrue : fmiFalse;
    info->upcomingTimeEvent = m->next_event_defined ? fmiTrue : fmiFalse;
    info->nextEventTime = m->next_event_time;
    if (!again || !intermediate) m->mode = m->terminate ? M_TERMINATED : M_CONTINUOUS;
}

EXPORT fmiStatus FMI1(fmiInitialize)(fmiComponent c, fmiBoolean tol_controlled, fmiReal tol, fmiEventInfo *info) {
    ALLOW(B(M_INSTANTIATED), "fmiInitialize");
    (void)tol_controlled; (void)tol;
    if (!info) return fail(f, "fmiInitialize: no eventInfo");
    me_exit_init(&f->m);
    iterate(&f->m, fmiFalse, info);
    return fmiOK;
}

EXPORT fmiStatus FMI1(fmiEventUpdate)(fmiComponent c, fmiBoolean intermediate, fmiEventInfo *info) {
    ALLOW(B(M_EVENT) | B(M_CONTINUOUS), "fmiEventUpdate");
    if (!info) return fail(f, "fmiEventUpdate: no eventInfo");
    iterate(&f->m, intermediate, info);
    return fmiOK;
}

EXPORT fmiStatus FMI1(fmiCompletedIntegratorStep)(fmiComponent c, fmiBoolean *call_event_update) {
    ALLOW(B(M_CONTINUOUS), "fmiCompletedIntegratorStep");
    *call_event_update = model_step_event(&f->m) ? fmiTrue : fmiFalse;
    return fmiOK;
}

EXPORT fmiStatus FMI1(fmiTerminate)(fmiComponent c) {
    ALLOW(B(M_EVENT) | B(M_CONTINUOUS) | B(M_TERMINATED), "fmiTerminate");
    f->m.mode = M_TERMINATED;
    return fmiOK;
}

EXPORT fmiStatus FMI1(fmiSetTime)(fmiComponent c, fmiReal t) {
    ALLOW(B(M_INSTANTIATED) | B(M_EVENT) | B(M_CONTINUOUS), "fmiSetTime");
    f->m.time = t;
    return fmiOK;
}

EXPORT fmiStatus FMI1(fmiSetContinuousStates)(fmiComponent c, const fmiReal x[], size_t n) {
    ALLOW(B(M_CONTINUOUS), "fmiSetContinuousStates");
    if (n != N_STATES) return fail(f, "fmiSetContinuousStates: %zu states, expected %d", n, N_STATES);
    me_set_states(&f->m, x);
    return fmiOK;
}

EXPORT fmiStatus FMI1(fmiGetDerivatives)(fmiComponent c, fmiReal dx[], size_t n) {
    ALLOW(B(M_EVENT) | B(M_CONTINUOUS) | B(M_TERMINATED), "fmiGetDerivatives");
    if (n != N_STATES) return fail(f, "fmiGetDerivatives: %zu states, expected %d", n, N_STATES);
    me_derivatives(&f->m, dx);
    return fmiOK;
}

EXPORT fmiStatus FMI1(fmiGetEventIndicators)(fmiComponent c, fmiReal z[], size_t n) {
    ALLOW(B(M_EVENT) | B(M_CONTINUOUS) | B(M_TERMINATED), "fmiGetEventIndicators");
    if (n != N_INDICATORS) return fail(f, "fmiGetEventIndicators: %zu indicators, expected %d", n, N_INDICATORS);
    me_refresh(&f->m);
    model_indicators(&f->m, z);
    return fmiOK;
}

EXPORT fmiStatus FMI1(fmiGetContinuousStates)(fmiComponent c, fmiReal x[], size_t n) {
    ALLOW(B(M_EVENT) | B(M_CONTINUOUS) | B(M_TERMINATED), "fmiGetContinuousStates");
    if (n != N_STATES) return fail(f, "fmiGetContinuousStates: %zu states, expected %d", n, N_STATES);
    me_get_states(&f->m, x);
    return fmiOK;
}

EXPORT fmiStatus FMI1(fmiGetNominalContinuousStates)(fmiComponent c, fmiReal x[], size_t n) {
    ALLOW(B(M_EVENT) | B(M_CONTINUOUS) | B(M_TERMINATED), "fmiGetNominalContinuousStates");
    if (n != N_STATES) return fail(f, "fmiGetNominalContinuousStates: %zu states, expected %d", n, N_STATES);
    for (size_t k = 0; k < n; k++) x[k] = 1.0;
    return fmiOK;
}

EXPORT fmiStatus FMI1(fmiGetStateValueReferences)(fmiComponent c, fmiValueReference vr[], size_t n) {
    ALLOW(B(M_EVENT) | B(M_CONTINUOUS) | B(M_TERMINATED), "fmiGetStateValueReferences");
    if (n != N_STATES) return fail(f, "fmiGetStateValueReferences: %zu states, expected %d", n, N_STATES);
    for (size_t k = 0; k < n; k++) vr[k] = STATE_VR[k];
    return fmiOK;
}

EXPORT fmiStatus FMI1(fmiGetReal)(fmiComponent c, const fmiValueReference vr[], size_t n, fmiReal v[]) {
    ALLOW(B(M_INSTANTIATED) | B(M_EVENT) | B(M_CONTINUOUS) | B(M_TERMINATED), "fmiGetReal");
    if (f->m.mode != M_INSTANTIATED) me_refresh(&f->m);
    for (size_t k = 0; k < n; k++) {
        if (vr[k] >= ME_MAX_VR) return fail(f, "fmiGetReal: no variable %u", vr[k]);
        v[k] = f->m.r[vr[k]];
    }
    return fmiOK;
}

EXPORT fmiStatus FMI1(fmiSetReal)(fmiComponent c, const fmiValueReference vr[], size_t n, const fmiReal v[]) {
    face *f = (face *)c;
    for (size_t k = 0; k < n; k++)
        if (!me_settable(&f->m, vr[k]))
            return fail(f, "fmiSetReal: variable %u cannot be set in mode %d", vr[k], (int)f->m.mode);
    for (size_t k = 0; k < n; k++) f->m.r[vr[k]] = v[k];
    return fmiOK;
}

EXPORT fmiStatus FMI1(fmiGetInteger)(fmiComponent c, const fmiValueReference vr[], size_t n, fmiInteger v[]) {
    ALLOW(B(M_INSTANTIATED) | B(M_EVENT) | B(M_CONTINUOUS) | B(M_TERMINATED), "fmiGetInteger");
    for (size_t k = 0; k < n; k++) {
        if (vr[k] >= ME_MAX_VR) return fail(f, "fmiGetInteger: no variable %u", vr[k]);
        v[k] = f->m.i[vr[k]];
    }
    return fmiOK;
}

EXPORT fmiStatus FMI1(fmiSetInteger)(fmiComponent c, const fmiValueReference vr[], size_t n, const fmiInteger v[]) {
    face *f = (face *)c;
    for (size_t k = 0; k < n; k++)
        if (!me_settable(&f->m, vr[k]))
            return fail(f, "fmiSetInteger: variable %u cannot be set in mode %d", vr[k], (int)f->m.mode);
    for (size_t k = 0; k < n; k++) f->m.i[vr[k]] = v[k];
    return fmiOK;
}

EXPORT fmiStatus FMI1(fmiGetBoolean)(fmiComponent c, const fmiValueReference vr[], size_t n, fmiBoolean v[]) {
    ALLOW(B(M_INSTANTIATED) | B(M_EVENT) | B(M_CONTINUOUS) | B(M_TERMINATED), "fmiGetBoolean");
    for (size_t k = 0; k < n; k++) {
        if (vr[k] >= ME_MAX_VR) return fail(f, "fmiGetBoolean: no variable %u", vr[k]);
        v[k] = f->m.i[vr[k]] ? fmiTrue : fmiFalse;
    }
    return fmiOK;
}

EXPORT fmiStatus FMI1(fmiSetBoolean)(fmiComponent c, const fmiValueReference vr[], size_t n, const fmiBoolean v[]) {
    face *f = (face *)c;
    for (size_t k = 0; k < n; k++)
        if (!me_settable(&f->m, vr[k]))
            return fail(f, "fmiSetBoolean: variable %u cannot be set in mode %d", vr[k], (int)f->m.mode);
    for (size_t k = 0; k < n; k++) f->m.i[vr[k]] = v[k] != fmiFalse;
    return fmiOK;
}

EXPORT fmiStatus FMI1(fmiGetString)(fmiComponent c, const fmiValueReference vr[], size_t n, fmiString v[]) {
    (void)vr; (void)n; (void)v;
    return fail((face *)c, "no String variables");
}

EXPORT fmiStatus FMI1(fmiSetString)(fmiComponent c, const fmiValueReference vr[], size_t n, const fmiString v[]) {
    (void)vr; (void)n; (void)v;
    return fail((face *)c, "no String variables");
}
