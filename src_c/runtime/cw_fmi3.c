/* The FMI 3.0 Co-Simulation face of the runtime: the fmi3 functions, each a
 * thin call into the same core as the fmi2 face (cw_runtime.c), plus what
 * FMI 3.0 adds: Event Mode, early return, scalar nValues checks and the
 * integer types of the new standard (Float64, Int32 and Boolean are the
 * models' Real, Integer and Boolean; the other types have no variables). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cw_core.h"
#include "fmi3Functions.h"

/* The runtime reports fmi2Status values; they are FMI 3.0's too. */
typedef char cw_status_values_agree[(fmi3OK == (int)fmi2OK &&
                                     fmi3Warning == (int)fmi2Warning &&
                                     fmi3Discard == (int)fmi2Discard &&
                                     fmi3Error == (int)fmi2Error &&
                                     fmi3Fatal == (int)fmi2Fatal)
                                        ? 1
                                        : -1];

static void emit3(const cw_instance *inst, fmi2Status status,
                  const char *category, const char *message) {
    fmi3LogMessageCallback logger = (fmi3LogMessageCallback)inst->env_logger;
    if (logger) logger(inst->env, (fmi3Status)status, category, message);
}

static void *calloc_mem(size_t n, size_t size) { return calloc(n, size); }

/* A model with Float64 inputs provides intermediate update (fmugen writes
 * providesIntermediateUpdate and intermediateUpdate on those inputs). */
static int has_real_inputs(const cw_model *model) {
    for (int k = 0; k < model->nvars; k++)
        if (model->vars[k].name && model->vars[k].type == CW_REAL &&
            model->vars[k].causality == CW_INPUT)
            return 1;
    return 0;
}

/* Inside fmi3DoStep, where the model reads its inputs at a new time (an
 * RK stage, the end of the step): Intermediate Update Mode, in which the
 * importer may set the inputs to their values at that time. */
static void intermediate_update(cw_instance *inst, double t) {
    fmi3IntermediateUpdateCallback callback =
        (fmi3IntermediateUpdateCallback)inst->env_intermediate_update;
    const cw_machine_state was = inst->state;
    fmi3Boolean early_requested = fmi3False;
    fmi3Float64 early_time = t;
    inst->intermediate_time = t;
    inst->state = CW_INTERMEDIATE_UPDATE;
    callback(inst->env, t, fmi3True, fmi3False, fmi3False, fmi3False,
             &early_requested, &early_time);
    /* A refused set left the instance in Error: fmi3DoStep reports it. */
    if (inst->state == CW_INTERMEDIATE_UPDATE) inst->state = was;
}

#define INST ((cw_instance *)instance)
#define S(x) ((fmi3Status)(x))

/* ------------------------------------------------------------------ */
/* Version, logging, instances                                        */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn,
                               size_t nCategories,
                               const fmi3String categories[]) {
    return S(cw_core_set_debug_logging(INST, "fmi3SetDebugLogging", loggingOn,
                                       nCategories, categories));
}

fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken,
    fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
    fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
    const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables,
    fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage,
    fmi3IntermediateUpdateCallback intermediateUpdate) {
    (void)resourcePath;
    (void)visible;
    (void)requiredIntermediateVariables;
    cw_instance proto;
    memset(&proto, 0, sizeof proto);
    proto.alloc_mem = calloc_mem;
    proto.free_mem = free;
    proto.emit = emit3;
    proto.env = instanceEnvironment;
    proto.env_logger = (void (*)(void))logMessage;
    proto.api = "fmi3";
    proto.model = &CW_MODEL;
    proto.instance_name = (char *)(instanceName ? instanceName : "?");
    proto.logging_on = loggingOn ? 1 : 0;
    proto.event_mode_used = eventModeUsed ? 1 : 0;
    proto.early_return_allowed = earlyReturnAllowed ? 1 : 0;
    if (intermediateUpdate && has_real_inputs(&CW_MODEL))
        proto.env_intermediate_update = (void (*)(void))intermediateUpdate;
    if (nRequiredIntermediateVariables > 0) {
        /* Its intermediate update serves inputs only: no output has
         * intermediateUpdate = true. */
        cw_log(&proto, fmi2Error, "logStatusError",
               "fmi3InstantiateCoSimulation: %s has no intermediate "
               "variables to get; %zu required intermediate variables cannot "
               "be served.",
               CW_MODEL.name, nRequiredIntermediateVariables);
        return NULL;
    }
    return cw_core_instantiate(&proto, "fmi3InstantiateCoSimulation",
                               instanceName, instantiationToken,
                               "instantiationToken");
}

/* Only Co-Simulation: the other interface types are refused. */
static fmi3Instance refuse_type(fmi3String instanceName,
                                fmi3InstanceEnvironment env,
                                fmi3LogMessageCallback logMessage,
                                const char *fn) {
    if (logMessage) {
        char buf[256];
        snprintf(buf, sizeof buf,
                 "%s: %s is a Co-Simulation FMU only (instance '%s').", fn,
                 CW_MODEL.name, instanceName ? instanceName : "?");
        logMessage(env, fmi3Error, "logStatusError", buf);
    }
    return NULL;
}

fmi3Instance fmi3InstantiateModelExchange(
    fmi3String instanceName, fmi3String instantiationToken,
    fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
    fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage) {
    (void)instantiationToken;
    (void)resourcePath;
    (void)visible;
    (void)loggingOn;
    return refuse_type(instanceName, instanceEnvironment, logMessage,
                       "fmi3InstantiateModelExchange");
}

fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken,
    fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
    fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
    fmi3LockPreemptionCallback lockPreemption,
    fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instantiationToken;
    (void)resourcePath;
    (void)visible;
    (void)loggingOn;
    (void)clockUpdate;
    (void)lockPreemption;
    (void)unlockPreemption;
    return refuse_type(instanceName, instanceEnvironment, logMessage,
                       "fmi3InstantiateScheduledExecution");
}

void fmi3FreeInstance(fmi3Instance instance) { cw_core_free_instance(INST); }

/* ------------------------------------------------------------------ */
/* Initialization, Event Mode, Step Mode, termination                 */

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance,
                                       fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance,
                                       fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined,
                                       fmi3Float64 stopTime) {
    static const char fn[] = "fmi3EnterInitializationMode";
    if (!cw_core_allowed(INST, fn, CW_INSTANTIATED)) return fmi3Error;
    /* Kept for models that integrate to it, as on FMI 2.0. */
    INST->tolerance_defined = toleranceDefined ? 1 : 0;
    INST->tolerance = toleranceDefined ? tolerance : 0.0;
    fmi2Status st = cw_core_setup(INST, fn, startTime, stopTimeDefined, stopTime);
    if (st != fmi2OK) return S(st);
    return S(cw_core_enter_initialization(INST, fn));
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    /* With Event Mode the importer settles the discrete states first. */
    cw_machine_state next =
        instance && INST->event_mode_used ? CW_EVENT_MODE : CW_STEP_COMPLETE;
    return S(cw_core_exit_initialization(INST, "fmi3ExitInitializationMode", next));
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    cw_instance *inst = INST;
    if (!cw_core_allowed(inst, "fmi3EnterEventMode", CW_STEP_COMPLETE))
        return fmi3Error;
    if (!inst->event_mode_used) {
        cw_log(inst, fmi2Error, "logStatusError",
               "fmi3EnterEventMode: the instance was made with eventModeUsed = "
               "false.");
        return fmi3Error;
    }
    inst->state = CW_EVENT_MODE;
    return fmi3OK;
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance,
                                    fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation,
                                    fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged,
                                    fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) {
    cw_instance *inst = INST;
    if (!cw_core_allowed(inst, "fmi3UpdateDiscreteStates", CW_EVENT_MODE))
        return fmi3Error;
    if (!discreteStatesNeedUpdate || !terminateSimulation ||
        !nominalsOfContinuousStatesChanged || !valuesOfContinuousStatesChanged ||
        !nextEventTimeDefined || !nextEventTime)
        return S(cw_core_fail(inst, "fmi3UpdateDiscreteStates: NULL argument."));
    /* The modes decided from the inputs at this instant become the state
     * (what fmi3DoStep would otherwise do at its start): one pass settles
     * them, and the FMU schedules no time events. */
    cw_core_commit(inst);
    *discreteStatesNeedUpdate = fmi3False;
    *terminateSimulation = fmi3False;
    *nominalsOfContinuousStatesChanged = fmi3False;
    *valuesOfContinuousStatesChanged = fmi3False;
    *nextEventTimeDefined = fmi3False;
    *nextEventTime = 0.0;
    return fmi3OK;
}

fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    if (!cw_core_allowed(INST, "fmi3EnterStepMode", CW_EVENT_MODE))
        return fmi3Error;
    INST->state = CW_STEP_COMPLETE;
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    return S(cw_core_terminate(INST, "fmi3Terminate"));
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    if (instance) INST->resume_valid = 0;
    return S(cw_core_reset(INST, "fmi3Reset"));
}

/* ------------------------------------------------------------------ */
/* Getting and setting variable values                                */

/* Every variable is a scalar: nValues must equal nValueReferences. */
static int scalars(cw_instance *inst, const char *fn, size_t nvr,
                   size_t nValues) {
    if (!inst) return 0;
    if (nValues == nvr) return 1;
    cw_log(inst, fmi2Error, "logStatusError",
           "%s: nValues = %zu for %zu value references; every variable of %s "
           "is a scalar.",
           fn, nValues, nvr, inst->model->name);
    return 0;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance,
                          const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Float64 values[],
                          size_t nValues) {
    static const char fn[] = "fmi3GetFloat64";
    if (!scalars(INST, fn, nValueReferences, nValues)) return fmi3Error;
    return S(cw_core_get_real(INST, fn, valueReferences, nValueReferences, values));
}

fmi3Status fmi3SetFloat64(fmi3Instance instance,
                          const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Float64 values[],
                          size_t nValues) {
    static const char fn[] = "fmi3SetFloat64";
    cw_instance *inst = INST;
    if (!scalars(inst, fn, nValueReferences, nValues)) return fmi3Error;
    if (inst->state != CW_INTERMEDIATE_UPDATE) {
        inst->resume_valid = 0;
        return S(cw_core_set_real(inst, fn, valueReferences, nValueReferences,
                                  values));
    }
    /* Intermediate Update Mode: only the inputs (all intermediateUpdate =
     * true), set as in Step Mode; the model reads them at this time. */
    for (size_t k = 0; k < nValueReferences; k++) {
        const unsigned vr = valueReferences ? valueReferences[k] : 0;
        const cw_var_info *v =
            vr < (unsigned)inst->model->nvars ? &inst->model->vars[vr] : NULL;
        if (!valueReferences || !v || !v->name || v->type != CW_REAL ||
            v->causality != CW_INPUT) {
            cw_log(inst, fmi2Error, "logStatusError",
                   "%s: in IntermediateUpdateMode only the Float64 inputs of "
                   "%s may be set; value reference %u is not one.",
                   fn, inst->model->name, vr);
            return fmi3Error;
        }
    }
    inst->state = CW_STEP_COMPLETE;
    const fmi2Status st =
        cw_core_set_real(inst, fn, valueReferences, nValueReferences, values);
    if (inst->state == CW_STEP_COMPLETE) inst->state = CW_INTERMEDIATE_UPDATE;
    return S(st);
}

fmi3Status fmi3GetInt32(fmi3Instance instance,
                        const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Int32 values[],
                        size_t nValues) {
    static const char fn[] = "fmi3GetInt32";
    if (!scalars(INST, fn, nValueReferences, nValues)) return fmi3Error;
    return S(cw_core_get_int(INST, fn, CW_INTEGER, valueReferences,
                             nValueReferences, values, 0));
}

fmi3Status fmi3SetInt32(fmi3Instance instance,
                        const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Int32 values[],
                        size_t nValues) {
    static const char fn[] = "fmi3SetInt32";
    if (!scalars(INST, fn, nValueReferences, nValues)) return fmi3Error;
    INST->resume_valid = 0;
    return S(cw_core_set_int(INST, fn, CW_INTEGER, valueReferences,
                             nValueReferences, values, 0));
}

fmi3Status fmi3GetBoolean(fmi3Instance instance,
                          const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Boolean values[],
                          size_t nValues) {
    static const char fn[] = "fmi3GetBoolean";
    if (!scalars(INST, fn, nValueReferences, nValues)) return fmi3Error;
    return S(cw_core_get_int(INST, fn, CW_BOOLEAN, valueReferences,
                             nValueReferences, values, 1));
}

fmi3Status fmi3SetBoolean(fmi3Instance instance,
                          const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Boolean values[],
                          size_t nValues) {
    static const char fn[] = "fmi3SetBoolean";
    if (!scalars(INST, fn, nValueReferences, nValues)) return fmi3Error;
    INST->resume_valid = 0;
    return S(cw_core_set_int(INST, fn, CW_BOOLEAN, valueReferences,
                             nValueReferences, values, 1));
}

/* The types no model has a variable of. */
#define NO_SUCH_TYPE(Type, CType)                                             \
    fmi3Status fmi3Get##Type(fmi3Instance instance,                           \
                             const fmi3ValueReference valueReferences[],      \
                             size_t nValueReferences, CType values[],         \
                             size_t nValues) {                                \
        (void)values;                                                         \
        (void)nValues;                                                        \
        return S(cw_core_no_such_type(INST, "fmi3Get" #Type, #Type,           \
                                      valueReferences, nValueReferences, 0)); \
    }                                                                         \
    fmi3Status fmi3Set##Type(fmi3Instance instance,                           \
                             const fmi3ValueReference valueReferences[],      \
                             size_t nValueReferences, const CType values[],   \
                             size_t nValues) {                                \
        (void)values;                                                         \
        (void)nValues;                                                        \
        return S(cw_core_no_such_type(INST, "fmi3Set" #Type, #Type,           \
                                      valueReferences, nValueReferences, 1)); \
    }
NO_SUCH_TYPE(Float32, fmi3Float32)
NO_SUCH_TYPE(Int8, fmi3Int8)
NO_SUCH_TYPE(UInt8, fmi3UInt8)
NO_SUCH_TYPE(Int16, fmi3Int16)
NO_SUCH_TYPE(UInt16, fmi3UInt16)
NO_SUCH_TYPE(UInt32, fmi3UInt32)
NO_SUCH_TYPE(Int64, fmi3Int64)
NO_SUCH_TYPE(UInt64, fmi3UInt64)
NO_SUCH_TYPE(String, fmi3String)

fmi3Status fmi3GetBinary(fmi3Instance instance,
                         const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, size_t valueSizes[],
                         fmi3Binary values[], size_t nValues) {
    (void)valueSizes;
    (void)values;
    (void)nValues;
    return S(cw_core_no_such_type(INST, "fmi3GetBinary", "Binary",
                                  valueReferences, nValueReferences, 0));
}

fmi3Status fmi3SetBinary(fmi3Instance instance,
                         const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, const size_t valueSizes[],
                         const fmi3Binary values[], size_t nValues) {
    (void)valueSizes;
    (void)values;
    (void)nValues;
    return S(cw_core_no_such_type(INST, "fmi3SetBinary", "Binary",
                                  valueReferences, nValueReferences, 1));
}

fmi3Status fmi3GetClock(fmi3Instance instance,
                        const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Clock values[]) {
    cw_instance *inst = INST;
    /* A model's output clock ([model] output_clock): read in Event Mode,
     * where it ticks when the model's clock_ticks says so. */
    if (inst && inst->model->clock_ticks && nValueReferences > 0 && valueReferences &&
        values) {
        size_t k;
        for (k = 0; k < nValueReferences; k++)
            if (valueReferences[k] != inst->model->output_clock_vr) break;
        if (k == nValueReferences) {
            if (!cw_core_allowed(inst, "fmi3GetClock", CW_EVENT_MODE)) return fmi3Error;
            const fmi3Clock ticks = inst->model->clock_ticks(inst) ? fmi3True : fmi3False;
            for (k = 0; k < nValueReferences; k++) values[k] = ticks;
            return fmi3OK;
        }
    }
    return S(cw_core_no_such_type(inst, "fmi3GetClock", "Clock",
                                  valueReferences, nValueReferences, 0));
}

fmi3Status fmi3SetClock(fmi3Instance instance,
                        const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Clock values[]) {
    (void)values;
    return S(cw_core_no_such_type(INST, "fmi3SetClock", "Clock",
                                  valueReferences, nValueReferences, 1));
}

/* ------------------------------------------------------------------ */
/* FMU state                                                          */

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    return S(cw_core_get_state(INST, "fmi3GetFMUState", FMUState));
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    if (instance) INST->resume_valid = 0;
    return S(cw_core_set_state(INST, "fmi3SetFMUState", FMUState));
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    return S(cw_core_free_state(INST, "fmi3FreeFMUState", FMUState));
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance,
                                      fmi3FMUState FMUState, size_t *size) {
    return S(cw_core_state_size(INST, "fmi3SerializedFMUStateSize", FMUState, size));
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState,
                                 fmi3Byte serializedState[], size_t size) {
    return S(cw_core_serialize(INST, "fmi3SerializeFMUState", FMUState,
                               serializedState, size));
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance,
                                   const fmi3Byte serializedState[],
                                   size_t size, fmi3FMUState *FMUState) {
    return S(cw_core_deserialize(INST, "fmi3DeserializeFMUState",
                                 serializedState, size, FMUState));
}

/* ------------------------------------------------------------------ */
/* Co-Simulation                                                      */

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance,
                                    const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences,
                                    const fmi3Int32 orders[],
                                    fmi3Float64 values[], size_t nValues) {
    static const char fn[] = "fmi3GetOutputDerivatives";
    if (!scalars(INST, fn, nValueReferences, nValues)) return fmi3Error;
    return S(cw_core_get_output_derivatives(INST, fn, valueReferences,
                                            nValueReferences, orders, values));
}

fmi3Status fmi3DoStep(fmi3Instance instance,
                      fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded,
                      fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime) {
    static const char fn[] = "fmi3DoStep";
    cw_instance *inst = INST;
    if (!cw_core_allowed(inst, fn, CW_STEP_COMPLETE)) return fmi3Error;
    inst->no_set_prior = noSetFMUStatePriorToCurrentPoint ? 1 : 0;
    if (!eventHandlingNeeded || !terminateSimulation || !earlyReturn ||
        !lastSuccessfulTime) {
        cw_log(inst, fmi2Error, "logStatusError", "%s: NULL argument.", fn);
        return fmi3Error;
    }
    if (inst->env_intermediate_update) {
        inst->intermediate_update = intermediate_update;
        inst->intermediate_time = NAN;
    }
    fmi2Status st = cw_core_do_step(inst, fn, currentCommunicationPoint,
                                    communicationStepSize);
    if (inst->intermediate_update && st <= fmi2Warning &&
        inst->state == CW_STEP_COMPLETE && inst->intermediate_time != inst->time)
        intermediate_update(inst, inst->time); /* the outputs' inputs */
    inst->intermediate_update = NULL;
    if (inst->state == CW_ERROR) return fmi3Error; /* a refused intermediate set */
    const int early = st <= fmi2Warning && inst->returned_early;
    /* The model's own event ends the step; the importer handles it in Event
     * Mode when it uses Event Mode. */
    *eventHandlingNeeded = early && inst->event_mode_used;
    *earlyReturn = early;
    *lastSuccessfulTime = inst->time;
    if (st == fmi2Discard && inst->terminate_requested) {
        /* The model ends the simulation (what fmi2GetBooleanStatus(
         * fmi2Terminated) says on FMI 2.0): the step stops at
         * lastSuccessfulTime and the importer terminates. */
        *terminateSimulation = fmi3True;
        return fmi3OK;
    }
    *terminateSimulation = fmi3False;
    return S(st);
}

/* ------------------------------------------------------------------ */
/* What a Co-Simulation FMU without these capabilities refuses        */

#define REFUSE(fn, why) return S(cw_core_unsupported(INST, fn, why))

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance,
                                               fmi3ValueReference valueReference,
                                               size_t *nDependencies) {
    (void)valueReference;
    (void)nDependencies;
    REFUSE("fmi3GetNumberOfVariableDependencies",
           "declares its dependencies in modelDescription.xml only");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance,
                                       fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[],
                                       fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[],
                                       fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies) {
    (void)dependent;
    (void)elementIndicesOfDependent;
    (void)independents;
    (void)elementIndicesOfIndependents;
    (void)dependencyKinds;
    (void)nDependencies;
    REFUSE("fmi3GetVariableDependencies",
           "declares its dependencies in modelDescription.xml only");
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance,
                                        const fmi3ValueReference unknowns[],
                                        size_t nUnknowns,
                                        const fmi3ValueReference knowns[],
                                        size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[],
                                        size_t nSensitivity) {
    (void)unknowns, (void)nUnknowns, (void)knowns, (void)nKnowns, (void)seed;
    (void)nSeed, (void)sensitivity, (void)nSensitivity;
    REFUSE("fmi3GetDirectionalDerivative",
           "does not provide directional derivatives "
           "(providesDirectionalDerivatives=false)");
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance,
                                    const fmi3ValueReference unknowns[],
                                    size_t nUnknowns,
                                    const fmi3ValueReference knowns[],
                                    size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[],
                                    size_t nSensitivity) {
    (void)unknowns, (void)nUnknowns, (void)knowns, (void)nKnowns, (void)seed;
    (void)nSeed, (void)sensitivity, (void)nSensitivity;
    REFUSE("fmi3GetAdjointDerivative",
           "does not provide adjoint derivatives "
           "(providesAdjointDerivatives=false)");
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) {
    REFUSE("fmi3EnterConfigurationMode", "has no structural parameters");
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) {
    REFUSE("fmi3ExitConfigurationMode", "has no structural parameters");
}

#define NO_CLOCKS "has no clocks"

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance,
                                  const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences,
                                  fmi3Float64 intervals[],
                                  fmi3IntervalQualifier qualifiers[]) {
    (void)valueReferences, (void)nValueReferences, (void)intervals, (void)qualifiers;
    REFUSE("fmi3GetIntervalDecimal", NO_CLOCKS);
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance,
                                   const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences,
                                   fmi3UInt64 counters[],
                                   fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[]) {
    (void)valueReferences, (void)nValueReferences, (void)counters;
    (void)resolutions, (void)qualifiers;
    REFUSE("fmi3GetIntervalFraction", NO_CLOCKS);
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance,
                               const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, fmi3Float64 shifts[]) {
    (void)valueReferences, (void)nValueReferences, (void)shifts;
    REFUSE("fmi3GetShiftDecimal", NO_CLOCKS);
}

fmi3Status fmi3GetShiftFraction(fmi3Instance instance,
                                const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, fmi3UInt64 counters[],
                                fmi3UInt64 resolutions[]) {
    (void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions;
    REFUSE("fmi3GetShiftFraction", NO_CLOCKS);
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance,
                                  const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences,
                                  const fmi3Float64 intervals[]) {
    (void)valueReferences, (void)nValueReferences, (void)intervals;
    REFUSE("fmi3SetIntervalDecimal", NO_CLOCKS);
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance,
                                   const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences,
                                   const fmi3UInt64 counters[],
                                   const fmi3UInt64 resolutions[]) {
    (void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions;
    REFUSE("fmi3SetIntervalFraction", NO_CLOCKS);
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance,
                               const fmi3ValueReference valueReferences[],
                               size_t nValueReferences,
                               const fmi3Float64 shifts[]) {
    (void)valueReferences, (void)nValueReferences, (void)shifts;
    REFUSE("fmi3SetShiftDecimal", NO_CLOCKS);
}

fmi3Status fmi3SetShiftFraction(fmi3Instance instance,
                                const fmi3ValueReference valueReferences[],
                                size_t nValueReferences,
                                const fmi3UInt64 counters[],
                                const fmi3UInt64 resolutions[]) {
    (void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions;
    REFUSE("fmi3SetShiftFraction", NO_CLOCKS);
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) {
    REFUSE("fmi3EvaluateDiscreteStates",
           "does not provide it (providesEvaluateDiscreteStates=false)");
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance,
                                      fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    (void)clockReference, (void)activationTime;
    REFUSE("fmi3ActivateModelPartition", "is not a Scheduled Execution FMU");
}

/* Model Exchange functions: this is a Co-Simulation FMU only. */
#define NOT_ME "is not a Model Exchange FMU"

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {
    REFUSE("fmi3EnterContinuousTimeMode", NOT_ME);
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance,
                                       fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode,
                                       fmi3Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint, (void)enterEventMode;
    (void)terminateSimulation;
    REFUSE("fmi3CompletedIntegratorStep", NOT_ME);
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
    (void)time;
    REFUSE("fmi3SetTime", NOT_ME);
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance,
                                   const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    (void)continuousStates, (void)nContinuousStates;
    REFUSE("fmi3SetContinuousStates", NOT_ME);
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance,
                                             fmi3Float64 derivatives[],
                                             size_t nContinuousStates) {
    (void)derivatives, (void)nContinuousStates;
    REFUSE("fmi3GetContinuousStateDerivatives", NOT_ME);
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance,
                                  fmi3Float64 eventIndicators[],
                                  size_t nEventIndicators) {
    (void)eventIndicators, (void)nEventIndicators;
    REFUSE("fmi3GetEventIndicators", NOT_ME);
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance,
                                   fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    (void)continuousStates, (void)nContinuousStates;
    REFUSE("fmi3GetContinuousStates", NOT_ME);
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance,
                                             fmi3Float64 nominals[],
                                             size_t nContinuousStates) {
    (void)nominals, (void)nContinuousStates;
    REFUSE("fmi3GetNominalsOfContinuousStates", NOT_ME);
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance,
                                          size_t *nEventIndicators) {
    (void)nEventIndicators;
    REFUSE("fmi3GetNumberOfEventIndicators", NOT_ME);
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance,
                                           size_t *nContinuousStates) {
    (void)nContinuousStates;
    REFUSE("fmi3GetNumberOfContinuousStates", NOT_ME);
}
