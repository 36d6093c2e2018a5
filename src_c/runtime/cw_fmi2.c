/* The FMI 2.0 Co-Simulation face of the runtime: the fmi2 functions, each a
 * thin call into the core (cw_runtime.c) under its own name. */
#include "fmi2Functions.h" /* first: cw_runtime.h takes fmi2Status from it */
#include "cw_core.h"

#include <string.h>

/* The environment's logger takes the message as a printf format. */
static void emit2(const cw_instance *inst, fmi2Status status,
                  const char *category, const char *message) {
    char buf[1024];
    cw_core_plain_text(buf, sizeof buf, message);
    fmi2CallbackLogger logger = (fmi2CallbackLogger)inst->env_logger;
    if (logger) logger(inst->env, inst->instance_name, status, category, buf);
}

#define INST ((cw_instance *)c)

/* ------------------------------------------------------------------ */
/* Inquire version numbers and setting logging status                 */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn,
                               size_t nCategories,
                               const fmi2String categories[]) {
    return cw_core_set_debug_logging(INST, "fmi2SetDebugLogging", loggingOn,
                                     nCategories, categories);
}

/* ------------------------------------------------------------------ */
/* Creation and destruction of instances                              */

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType,
                              fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)fmuResourceLocation;
    (void)visible;
    if (!functions || !functions->allocateMemory || !functions->freeMemory)
        return NULL; /* nobody to tell: the standard requires these */
    cw_instance proto;
    memset(&proto, 0, sizeof proto);
    proto.alloc_mem = functions->allocateMemory;
    proto.free_mem = functions->freeMemory;
    proto.emit = emit2;
    proto.env = functions->componentEnvironment;
    proto.env_logger = (void (*)(void))functions->logger;
    proto.api = "fmi2";
    proto.model = &CW_MODEL;
    proto.instance_name = (char *)(instanceName ? instanceName : "?");
    proto.logging_on = loggingOn ? 1 : 0;
    if (instanceName && *instanceName && fmuType != fmi2CoSimulation) {
        cw_log(&proto, fmi2Error, "logStatusError",
               "fmi2Instantiate: %s supports only fmi2CoSimulation.",
               CW_MODEL.name);
        return NULL;
    }
    return cw_core_instantiate(&proto, "fmi2Instantiate", instanceName, fmuGUID,
                               "GUID");
}

void fmi2FreeInstance(fmi2Component c) { cw_core_free_instance(INST); }

/* ------------------------------------------------------------------ */
/* Initialization                                                     */

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined,
                               fmi2Real stopTime) {
    if (!cw_core_allowed(INST, "fmi2SetupExperiment", CW_INSTANTIATED))
        return fmi2Error;
    /* Kept for models that integrate to it; the clock's models take their
     * tolerances as parameters. */
    INST->tolerance_defined = toleranceDefined ? 1 : 0;
    INST->tolerance = toleranceDefined ? tolerance : 0.0;
    return cw_core_setup(INST, "fmi2SetupExperiment", startTime,
                         stopTimeDefined, stopTime);
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    if (!cw_core_allowed(INST, "fmi2EnterInitializationMode", CW_INSTANTIATED))
        return fmi2Error;
    return cw_core_enter_initialization(INST, "fmi2EnterInitializationMode");
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    return cw_core_exit_initialization(INST, "fmi2ExitInitializationMode",
                                       CW_STEP_COMPLETE);
}

fmi2Status fmi2Terminate(fmi2Component c) {
    return cw_core_terminate(INST, "fmi2Terminate");
}

fmi2Status fmi2Reset(fmi2Component c) {
    return cw_core_reset(INST, "fmi2Reset");
}

/* ------------------------------------------------------------------ */
/* Getting and setting variable values                                */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[],
                       size_t nvr, fmi2Real value[]) {
    return cw_core_get_real(INST, "fmi2GetReal", vr, nvr, value);
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[],
                          size_t nvr, fmi2Integer value[]) {
    return cw_core_get_int(INST, "fmi2GetInteger", CW_INTEGER, vr, nvr, value, 0);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[],
                          size_t nvr, fmi2Boolean value[]) {
    return cw_core_get_int(INST, "fmi2GetBoolean", CW_BOOLEAN, vr, nvr, value, 0);
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[],
                         size_t nvr, fmi2String value[]) {
    return cw_core_get_string(INST, "fmi2GetString", vr, nvr, value);
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[],
                       size_t nvr, const fmi2Real value[]) {
    return cw_core_set_real(INST, "fmi2SetReal", vr, nvr, value);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[],
                          size_t nvr, const fmi2Integer value[]) {
    return cw_core_set_int(INST, "fmi2SetInteger", CW_INTEGER, vr, nvr, value, 0);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[],
                          size_t nvr, const fmi2Boolean value[]) {
    return cw_core_set_int(INST, "fmi2SetBoolean", CW_BOOLEAN, vr, nvr, value, 0);
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[],
                         size_t nvr, const fmi2String value[]) {
    return cw_core_set_string(INST, "fmi2SetString", vr, nvr, value);
}

/* ------------------------------------------------------------------ */
/* FMU state                                                          */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    return cw_core_get_state(INST, "fmi2GetFMUstate", FMUstate);
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    return cw_core_set_state(INST, "fmi2SetFMUstate", FMUstate);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    return cw_core_free_state(INST, "fmi2FreeFMUstate", FMUstate);
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate,
                                      size_t *size) {
    return cw_core_state_size(INST, "fmi2SerializedFMUstateSize", FMUstate, size);
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate,
                                 fmi2Byte serializedState[], size_t size) {
    return cw_core_serialize(INST, "fmi2SerializeFMUstate", FMUstate,
                             (unsigned char *)serializedState, size);
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c,
                                   const fmi2Byte serializedState[],
                                   size_t size, fmi2FMUstate *FMUstate) {
    return cw_core_deserialize(INST, "fmi2DeSerializeFMUstate",
                               (const unsigned char *)serializedState, size,
                               FMUstate);
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c,
                                        const fmi2ValueReference vUnknown[],
                                        size_t nUnknown,
                                        const fmi2ValueReference vKnown[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[]) {
    (void)vUnknown;
    (void)nUnknown;
    (void)vKnown;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    return cw_core_unsupported(INST, "fmi2GetDirectionalDerivative",
                               "does not provide directional derivatives "
                               "(providesDirectionalDerivative=false)");
}

/* ------------------------------------------------------------------ */
/* Co-Simulation                                                      */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c,
                                       const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[]) {
    return cw_core_set_input_derivatives(INST, "fmi2SetRealInputDerivatives",
                                         vr, nvr, order, value);
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c,
                                        const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    return cw_core_get_output_derivatives(INST, "fmi2GetRealOutputDerivatives",
                                          vr, nvr, order, value);
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    if (c) INST->no_set_prior = noSetFMUStatePriorToCurrentPoint ? 1 : 0;
    return cw_core_do_step(INST, "fmi2DoStep", currentCommunicationPoint,
                           communicationStepSize);
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    if (!c) return fmi2Error;
    cw_log(INST, fmi2Error, "logStatusError",
           "fmi2CancelStep: steps are synchronous; there is nothing to cancel.");
    return fmi2Error;
}

#define STATUS_STATES (CW_STEP_COMPLETE | CW_STEP_FAILED | CW_TERMINATED)

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s,
                         fmi2Status *value) {
    cw_instance *inst = INST;
    if (!cw_core_allowed(inst, "fmi2GetStatus", STATUS_STATES)) return fmi2Error;
    if (!value) {
        cw_log(inst, fmi2Error, "logStatusError", "fmi2GetStatus: value is NULL.");
        return fmi2Error;
    }
    if (s == fmi2DoStepStatus) {
        *value = inst->state == CW_STEP_FAILED ? fmi2Discard : fmi2OK;
        return fmi2OK;
    }
    cw_log(inst, fmi2Error, "logStatusError",
           "fmi2GetStatus: status kind %d is not provided.", (int)s);
    return fmi2Error;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s,
                             fmi2Real *value) {
    cw_instance *inst = INST;
    if (!cw_core_allowed(inst, "fmi2GetRealStatus", STATUS_STATES))
        return fmi2Error;
    if (!value) {
        cw_log(inst, fmi2Error, "logStatusError",
               "fmi2GetRealStatus: value is NULL.");
        return fmi2Error;
    }
    if (s == fmi2LastSuccessfulTime) {
        *value = inst->time;
        return fmi2OK;
    }
    cw_log(inst, fmi2Error, "logStatusError",
           "fmi2GetRealStatus: status kind %d is not provided.", (int)s);
    return fmi2Error;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s,
                                fmi2Integer *value) {
    (void)s;
    (void)value;
    if (!c) return fmi2Error;
    cw_log(INST, fmi2Error, "logStatusError",
           "fmi2GetIntegerStatus: no Integer status is provided.");
    return fmi2Error;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s,
                                fmi2Boolean *value) {
    if (!cw_core_allowed(INST, "fmi2GetBooleanStatus",
                         CW_STEP_COMPLETE | CW_STEP_FAILED | CW_TERMINATED))
        return fmi2Error;
    if (!value) {
        cw_log(INST, fmi2Error, "logStatusError",
               "fmi2GetBooleanStatus: value is NULL.");
        return fmi2Error;
    }
    if (s == fmi2Terminated) {
        *value = INST->terminate_requested ? fmi2True : fmi2False;
        return fmi2OK;
    }
    cw_log(INST, fmi2Error, "logStatusError",
           "fmi2GetBooleanStatus: status kind %d is not provided.", (int)s);
    return fmi2Error;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s,
                               fmi2String *value) {
    (void)s;
    (void)value;
    if (!c) return fmi2Error;
    cw_log(INST, fmi2Error, "logStatusError",
           "fmi2GetStringStatus: no String status is provided.");
    return fmi2Error;
}
