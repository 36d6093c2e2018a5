/* The FMI 1.0 Co-Simulation face of the runtime: the fmi functions of FMI
 * 1.0 for Co-Simulation, named <modelIdentifier>_fmiXxx (MODEL_IDENTIFIER
 * is defined by the build), each a thin call into the same core as the
 * fmi2 and fmi3 faces (cw_runtime.c). What FMI 1.0 differs in:
 * fmiInitializeSlave is FMI 2.0's setup, initialization mode and its exit
 * in one call; fmiBoolean is a char; there is no FMU state, so a step is
 * never repeated (newStep = false is refused: canRejectSteps is false) and
 * the model is always told that no earlier state will be set; a step of
 * size 0 is FMI 1.0's iteration at a communication point (the outputs of
 * new inputs); the callbacks come by value and the logger gets the
 * component, not an environment.
 * Built for the tests only (build/test-fmus/fmi1/). */
#include <stdint.h>
#include <string.h>

#include "fmi1Functions.h"
#include "cw_core.h"

#ifndef MODEL_IDENTIFIER
#error "MODEL_IDENTIFIER (the modelIdentifier, prefix of every function) must be defined"
#endif
#define CW_JOIN2(a, b) a##_##b
#define CW_JOIN(a, b) CW_JOIN2(a, b)
#define FMI1(name) CW_JOIN(MODEL_IDENTIFIER, name)
#define EXPORT __attribute__((visibility("default")))

/* The runtime reports fmi2Status values; FMI 1.0's have the same numbers. */
typedef char cw_status_values_agree[(fmi1OK == (int)fmi2OK &&
                                     fmi1Warning == (int)fmi2Warning &&
                                     fmi1Discard == (int)fmi2Discard &&
                                     fmi1Error == (int)fmi2Error &&
                                     fmi1Fatal == (int)fmi2Fatal)
                                        ? 1
                                        : -1];

#define INST ((cw_instance *)c)
#define S(x) ((fmi1Status)(x))

/* The environment's logger takes the message as a printf format and the
 * component (none yet while the instance is being made). */
static void emit1(const cw_instance *inst, fmi2Status status,
                  const char *category, const char *message) {
    char buf[1024];
    cw_core_plain_text(buf, sizeof buf, message);
    fmi1CallbackLogger logger = (fmi1CallbackLogger)inst->env_logger;
    if (logger)
        logger(inst->state ? (fmi1Component)inst : NULL, inst->instance_name,
               (fmi1Status)status, category, buf);
}

/* ------------------------------------------------------------------ */
/* Version, logging, instances                                        */

EXPORT const char *FMI1(fmiGetTypesPlatform)(void) { return "standard32"; }
EXPORT const char *FMI1(fmiGetVersion)(void) { return "1.0"; }

EXPORT fmi1Status FMI1(fmiSetDebugLogging)(fmi1Component c, fmi1Boolean loggingOn) {
    return S(cw_core_set_debug_logging(INST, "fmiSetDebugLogging", loggingOn, 0, NULL));
}

EXPORT fmi1Component FMI1(fmiInstantiateSlave)(
    fmi1String instanceName, fmi1String fmuGUID, fmi1String fmuLocation,
    fmi1String mimeType, fmi1Real timeout, fmi1Boolean visible,
    fmi1Boolean interactive, fmi1CallbackFunctions functions,
    fmi1Boolean loggingOn) {
    (void)fmuLocation;
    (void)mimeType;
    (void)timeout;
    (void)visible;
    (void)interactive;
    if (!functions.allocateMemory || !functions.freeMemory)
        return NULL; /* nobody to tell: the standard requires these */
    cw_instance proto;
    memset(&proto, 0, sizeof proto);
    proto.alloc_mem = functions.allocateMemory;
    proto.free_mem = functions.freeMemory;
    proto.emit = emit1;
    proto.env_logger = (void (*)(void))functions.logger;
    proto.api = "fmi1";
    proto.model = &CW_MODEL;
    proto.instance_name = (char *)(instanceName ? instanceName : "?");
    proto.logging_on = loggingOn ? 1 : 0;
    return cw_core_instantiate(&proto, "fmiInstantiateSlave", instanceName,
                               fmuGUID, "GUID");
}

EXPORT void FMI1(fmiFreeSlaveInstance)(fmi1Component c) { cw_core_free_instance(INST); }

/* ------------------------------------------------------------------ */
/* Initialization, termination, reset                                 */

EXPORT fmi1Status FMI1(fmiInitializeSlave)(fmi1Component c, fmi1Real tStart,
                                           fmi1Boolean StopTimeDefined,
                                           fmi1Real tStop) {
    static const char fn[] = "fmiInitializeSlave";
    if (!cw_core_allowed(INST, fn, CW_INSTANTIATED)) return fmi1Error;
    fmi2Status st = cw_core_setup(INST, fn, tStart, StopTimeDefined, tStop);
    if (st > fmi2Warning) return S(st);
    cw_core_enter_initialization(INST, fn);
    return S(cw_core_exit_initialization(INST, fn, CW_STEP_COMPLETE));
}

EXPORT fmi1Status FMI1(fmiTerminateSlave)(fmi1Component c) {
    return S(cw_core_terminate(INST, "fmiTerminateSlave"));
}

EXPORT fmi1Status FMI1(fmiResetSlave)(fmi1Component c) {
    return S(cw_core_reset(INST, "fmiResetSlave"));
}

/* ------------------------------------------------------------------ */
/* Values. fmiBoolean is a char: converted through int32 values, which
 * the core stores (on the stack for a few, else allocated, so that a
 * refused set changes nothing). */

#define FEW 64

static int32_t *int_buffer(cw_instance *inst, int32_t *few, size_t n) {
    return n <= FEW ? few : inst->alloc_mem(n, sizeof(int32_t));
}

static void release(cw_instance *inst, int32_t *few, int32_t *buf) {
    if (buf && buf != few) inst->free_mem(buf);
}

EXPORT fmi1Status FMI1(fmiGetReal)(fmi1Component c, const fmi1ValueReference vr[],
                                   size_t nvr, fmi1Real value[]) {
    return S(cw_core_get_real(INST, "fmiGetReal", vr, nvr, value));
}

EXPORT fmi1Status FMI1(fmiGetInteger)(fmi1Component c, const fmi1ValueReference vr[],
                                      size_t nvr, fmi1Integer value[]) {
    return S(cw_core_get_int(INST, "fmiGetInteger", CW_INTEGER, vr, nvr, value, 0));
}

EXPORT fmi1Status FMI1(fmiGetBoolean)(fmi1Component c, const fmi1ValueReference vr[],
                                      size_t nvr, fmi1Boolean value[]) {
    static const char fn[] = "fmiGetBoolean";
    if (!c) return fmi1Error;
    if (nvr > 0 && !value) return S(cw_core_get_int(INST, fn, CW_BOOLEAN, vr, nvr, NULL, 0));
    int32_t few[FEW] = {0};
    int32_t *got = int_buffer(INST, few, nvr);
    if (!got) return S(cw_core_fail(INST, "%s: out of memory.", fn));
    fmi2Status st = cw_core_get_int(INST, fn, CW_BOOLEAN, vr, nvr, got, 0);
    if (st <= fmi2Warning)
        for (size_t k = 0; k < nvr; k++) value[k] = got[k] ? fmi1True : fmi1False;
    release(INST, few, got);
    return S(st);
}

EXPORT fmi1Status FMI1(fmiGetString)(fmi1Component c, const fmi1ValueReference vr[],
                                     size_t nvr, fmi1String value[]) {
    return S(cw_core_get_string(INST, "fmiGetString", vr, nvr, value));
}

EXPORT fmi1Status FMI1(fmiSetReal)(fmi1Component c, const fmi1ValueReference vr[],
                                   size_t nvr, const fmi1Real value[]) {
    return S(cw_core_set_real(INST, "fmiSetReal", vr, nvr, value));
}

EXPORT fmi1Status FMI1(fmiSetInteger)(fmi1Component c, const fmi1ValueReference vr[],
                                      size_t nvr, const fmi1Integer value[]) {
    return S(cw_core_set_int(INST, "fmiSetInteger", CW_INTEGER, vr, nvr, value, 0));
}

EXPORT fmi1Status FMI1(fmiSetBoolean)(fmi1Component c, const fmi1ValueReference vr[],
                                      size_t nvr, const fmi1Boolean value[]) {
    static const char fn[] = "fmiSetBoolean";
    if (!c) return fmi1Error;
    if (nvr > 0 && !value) return S(cw_core_set_int(INST, fn, CW_BOOLEAN, vr, nvr, NULL, 0));
    int32_t few[FEW] = {0};
    int32_t *given = int_buffer(INST, few, nvr);
    if (!given) return S(cw_core_fail(INST, "%s: out of memory.", fn));
    for (size_t k = 0; k < nvr; k++) given[k] = value[k] != fmi1False;
    fmi2Status st = cw_core_set_int(INST, fn, CW_BOOLEAN, vr, nvr, given, 0);
    release(INST, few, given);
    return S(st);
}

EXPORT fmi1Status FMI1(fmiSetString)(fmi1Component c, const fmi1ValueReference vr[],
                                     size_t nvr, const fmi1String value[]) {
    return S(cw_core_set_string(INST, "fmiSetString", vr, nvr, value));
}

/* ------------------------------------------------------------------ */
/* Co-Simulation                                                      */

EXPORT fmi1Status FMI1(fmiSetRealInputDerivatives)(fmi1Component c,
                                                   const fmi1ValueReference vr[],
                                                   size_t nvr,
                                                   const fmi1Integer order[],
                                                   const fmi1Real value[]) {
    return S(cw_core_set_input_derivatives(INST, "fmiSetRealInputDerivatives",
                                           vr, nvr, order, value));
}

EXPORT fmi1Status FMI1(fmiGetRealOutputDerivatives)(fmi1Component c,
                                                    const fmi1ValueReference vr[],
                                                    size_t nvr,
                                                    const fmi1Integer order[],
                                                    fmi1Real value[]) {
    return S(cw_core_get_output_derivatives(INST, "fmiGetRealOutputDerivatives",
                                            vr, nvr, order, value));
}

EXPORT fmi1Status FMI1(fmiDoStep)(fmi1Component c,
                                  fmi1Real currentCommunicationPoint,
                                  fmi1Real communicationStepSize,
                                  fmi1Boolean newStep) {
    static const char fn[] = "fmiDoStep";
    if (!cw_core_allowed(INST, fn, CW_STEP_COMPLETE)) return fmi1Error;
    if (newStep == fmi1False) {
        cw_log(INST, fmi2Error, "logStatusError",
               "%s: newStep = false asks to repeat a step, which %s cannot "
               "(canRejectSteps = false).",
               fn, INST->model->name);
        return fmi1Error;
    }
    INST->no_set_prior = 1; /* FMI 1.0 has no FMU state to set */
    if (communicationStepSize == 0.0) {
        /* FMI 1.0's iteration at a communication point: the importer asks
         * for the outputs of the inputs it set. The runtime's outputs
         * follow the inputs already; time does not move. */
        if (currentCommunicationPoint != INST->time) {
            cw_log(INST, fmi2Error, "logStatusError",
                   "%s: a zero step at %.17g, where the FMU stands at %.17g.", fn,
                   currentCommunicationPoint, INST->time);
            return fmi1Error;
        }
        return fmi1OK;
    }
    return S(cw_core_do_step(INST, fn, currentCommunicationPoint,
                             communicationStepSize));
}

EXPORT fmi1Status FMI1(fmiCancelStep)(fmi1Component c) {
    if (!c) return fmi1Error;
    cw_log(INST, fmi2Error, "logStatusError",
           "fmiCancelStep: steps are synchronous; there is nothing to cancel.");
    return fmi1Error;
}

#define STATUS_STATES (CW_STEP_COMPLETE | CW_STEP_FAILED | CW_TERMINATED)

/* The status a getter may report: 0 (logged) when it may not. */
static int status_query(cw_instance *inst, const char *fn, const void *value) {
    if (!cw_core_allowed(inst, fn, STATUS_STATES)) return 0;
    if (!value) {
        cw_log(inst, fmi2Error, "logStatusError", "%s: value is NULL.", fn);
        return 0;
    }
    return 1;
}

static fmi1Status not_provided(cw_instance *inst, const char *fn, int kind) {
    cw_log(inst, fmi2Error, "logStatusError", "%s: status kind %d is not provided.", fn, kind);
    return fmi1Error;
}

EXPORT fmi1Status FMI1(fmiGetStatus)(fmi1Component c, const fmi1StatusKind s,
                                     fmi1Status *value) {
    static const char fn[] = "fmiGetStatus";
    if (!status_query(INST, fn, value)) return fmi1Error;
    if (s != fmi1DoStepStatus) return not_provided(INST, fn, (int)s);
    *value = INST->state == CW_STEP_FAILED ? fmi1Discard : fmi1OK;
    return fmi1OK;
}

EXPORT fmi1Status FMI1(fmiGetRealStatus)(fmi1Component c, const fmi1StatusKind s,
                                         fmi1Real *value) {
    static const char fn[] = "fmiGetRealStatus";
    if (!status_query(INST, fn, value)) return fmi1Error;
    if (s != fmi1LastSuccessfulTime) return not_provided(INST, fn, (int)s);
    *value = INST->time;
    return fmi1OK;
}

EXPORT fmi1Status FMI1(fmiGetIntegerStatus)(fmi1Component c, const fmi1StatusKind s,
                                            fmi1Integer *value) {
    static const char fn[] = "fmiGetIntegerStatus";
    if (!status_query(INST, fn, value)) return fmi1Error;
    return not_provided(INST, fn, (int)s);
}

EXPORT fmi1Status FMI1(fmiGetBooleanStatus)(fmi1Component c, const fmi1StatusKind s,
                                            fmi1Boolean *value) {
    static const char fn[] = "fmiGetBooleanStatus";
    if (!status_query(INST, fn, value)) return fmi1Error;
    return not_provided(INST, fn, (int)s);
}

EXPORT fmi1Status FMI1(fmiGetStringStatus)(fmi1Component c, const fmi1StatusKind s,
                                           fmi1String *value) {
    static const char fn[] = "fmiGetStringStatus";
    if (!status_query(INST, fn, value)) return fmi1Error;
    return not_provided(INST, fn, (int)s);
}
