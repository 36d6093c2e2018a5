/* Hold: an FMI 1.0 Co-Simulation test FMU whose output is computed in
 * fmiDoStep only, as FMI 1.0 Co-Simulation has it: y is the input u as of
 * the last fmiDoStep, a step of size 0 included (FMI 1.0's iteration at a
 * communication point); setting u changes y only at the next step. Its
 * modelDescription.xml declares that y depends on u directly, so a master
 * that reads y at a communication point after setting u must first call
 * fmiDoStep with a zero step to get y = u. Built by CMake into
 * build/test-fmus/fmi1/Hold.fmu for tests/test_fmi1.py. */
#include <stdlib.h>
#include <string.h>

#include "fmi1Functions.h"

#define EXPORT __attribute__((visibility("default")))
#define GUID "{cw-fmi1-hold}"
enum { VR_U = 0, VR_Y = 1 };

typedef struct {
    double u, y, time;
    long zero_steps;
    fmi1CallbackFunctions cb;
    char name[64];
} Hold;

static fmi1Status refuse(Hold *h, const char *what) {
    if (h && h->cb.logger) h->cb.logger(h, h->name, fmi1Error, "logStatusError", what);
    return fmi1Error;
}

EXPORT const char *Hold_fmiGetTypesPlatform(void) { return "standard32"; }
EXPORT const char *Hold_fmiGetVersion(void) { return "1.0"; }
EXPORT fmi1Status Hold_fmiSetDebugLogging(fmi1Component c, fmi1Boolean on) { (void)c; (void)on; return fmi1OK; }

EXPORT fmi1Component Hold_fmiInstantiateSlave(fmi1String name, fmi1String guid, fmi1String location,
                                              fmi1String mime, fmi1Real timeout, fmi1Boolean visible,
                                              fmi1Boolean interactive, fmi1CallbackFunctions cb,
                                              fmi1Boolean logging) {
    (void)location; (void)mime; (void)timeout; (void)visible; (void)interactive; (void)logging;
    if (!guid || strcmp(guid, GUID) != 0 || !cb.allocateMemory || !cb.freeMemory) return NULL;
    Hold *h = cb.allocateMemory(1, sizeof(Hold));
    if (!h) return NULL;
    h->cb = cb;
    strncpy(h->name, name ? name : "?", sizeof h->name - 1);
    return h;
}

EXPORT void Hold_fmiFreeSlaveInstance(fmi1Component c) {
    Hold *h = c;
    if (h) h->cb.freeMemory(h);
}

EXPORT fmi1Status Hold_fmiInitializeSlave(fmi1Component c, fmi1Real t, fmi1Boolean stop_defined, fmi1Real stop) {
    (void)stop_defined; (void)stop;
    Hold *h = c;
    h->time = t;
    h->y = h->u;
    return fmi1OK;
}

EXPORT fmi1Status Hold_fmiDoStep(fmi1Component c, fmi1Real t, fmi1Real dt, fmi1Boolean new_step) {
    Hold *h = c;
    if (!new_step || dt < 0 || t != h->time) return refuse(h, "Hold: a step that does not start where Hold stands");
#ifdef CW_HOSTILE  /* tests/test_fmu_crash.py: bad strings to the logger, then a NULL dereference past t = 0.3 */
    h->cb.logger(h, (const char *)8, fmi1OK, (const char *)16, (const char *)24);
    h->cb.logger(NULL, NULL, fmi1OK, NULL, NULL);
    if (t + dt > 0.3 + 1e-9)
        *(volatile int *)(t > -1 ? NULL : h) = 1;
#endif
    h->y = h->u; /* the output, computed here only */
    h->time = t + dt;
    if (dt == 0) h->zero_steps++;
    return fmi1OK;
}

EXPORT fmi1Status Hold_fmiSetReal(fmi1Component c, const fmi1ValueReference vr[], size_t n, const fmi1Real v[]) {
    Hold *h = c;
    for (size_t k = 0; k < n; k++) {
        if (vr[k] != VR_U) return refuse(h, "Hold: only u can be set");
        h->u = v[k];
    }
    return fmi1OK;
}

EXPORT fmi1Status Hold_fmiGetReal(fmi1Component c, const fmi1ValueReference vr[], size_t n, fmi1Real v[]) {
    Hold *h = c;
    for (size_t k = 0; k < n; k++) {
        if (vr[k] == VR_U) v[k] = h->u;
        else if (vr[k] == VR_Y) v[k] = h->y;
        else return refuse(h, "Hold: no such Real");
    }
    return fmi1OK;
}

EXPORT fmi1Status Hold_fmiGetInteger(fmi1Component c, const fmi1ValueReference vr[], size_t n, fmi1Integer v[]) {
    Hold *h = c;
    for (size_t k = 0; k < n; k++) {
        if (vr[k] != 2) return refuse(h, "Hold: no such Integer");
        v[k] = (fmi1Integer)h->zero_steps;
    }
    return fmi1OK;
}

#define NONE(name, ...) EXPORT fmi1Status Hold_##name(fmi1Component c, __VA_ARGS__) { return refuse(c, "Hold: " #name " is not provided"); }
NONE(fmiSetInteger, const fmi1ValueReference vr[], size_t n, const fmi1Integer v[])
NONE(fmiSetBoolean, const fmi1ValueReference vr[], size_t n, const fmi1Boolean v[])
NONE(fmiSetString, const fmi1ValueReference vr[], size_t n, const fmi1String v[])
NONE(fmiGetBoolean, const fmi1ValueReference vr[], size_t n, fmi1Boolean v[])
NONE(fmiGetString, const fmi1ValueReference vr[], size_t n, fmi1String v[])
NONE(fmiSetRealInputDerivatives, const fmi1ValueReference vr[], size_t n, const fmi1Integer o[], const fmi1Real v[])
NONE(fmiGetRealOutputDerivatives, const fmi1ValueReference vr[], size_t n, const fmi1Integer o[], fmi1Real v[])
NONE(fmiGetStatus, const fmi1StatusKind s, fmi1Status *v)
NONE(fmiGetRealStatus, const fmi1StatusKind s, fmi1Real *v)
NONE(fmiGetIntegerStatus, const fmi1StatusKind s, fmi1Integer *v)
NONE(fmiGetBooleanStatus, const fmi1StatusKind s, fmi1Boolean *v)
NONE(fmiGetStringStatus, const fmi1StatusKind s, fmi1String *v)
EXPORT fmi1Status Hold_fmiCancelStep(fmi1Component c) { return refuse(c, "Hold: nothing to cancel"); }
EXPORT fmi1Status Hold_fmiTerminateSlave(fmi1Component c) { (void)c; return fmi1OK; }
EXPORT fmi1Status Hold_fmiResetSlave(fmi1Component c) {
    Hold *h = c;
    h->u = h->y = h->time = 0.0;
    h->zero_steps = 0;
    return fmi1OK;
}
