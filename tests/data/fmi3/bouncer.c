/* Bouncer: a small FMI 3.0 Co-Simulation FMU for the master's FMI 3.0 tests.
 *
 * x moves at dx/dt = dir * v0 + u between 0 and 1 and turns at each wall
 * (a state event the FMU owns, located exactly: the motion is linear);
 * n counts time events at k * period; the FMU asks to end the simulation
 * when n reaches n_stop (> 0). z = x - threshold is an event indicator for
 * the master (clockwork vendor annotation). With eventModeUsed and
 * earlyReturnAllowed, fmi3DoStep returns early at each event and the
 * master handles it in event mode; otherwise the FMU handles it inside
 * the step. A wrong communication point or call sequence is an error, so
 * that the tests see a master's mistakes.
 */

#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"

enum { VR_TIME, VR_V0, VR_PERIOD, VR_THRESHOLD, VR_U, VR_X, VR_N, VR_BOUNCES, VR_Z, VR_N_STOP };
enum { INSTANTIATED, INITIALIZATION, EVENT, STEP, TERMINATED };

typedef struct {
    double time, x, n, bounces, v0, period, threshold, u, next_time_event;
    int dir, n_stop, mode, event_mode_used, early_return_allowed, pending, terminate;
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
} Bouncer;

static fmi3Status fail(Bouncer *b, const char *message)
{
    if (b->log)
        b->log(b->env, fmi3Error, "logStatusError", message);
    return fmi3Error;
}

static void defaults(Bouncer *b)
{
    b->time = 0.0; b->x = 0.0; b->n = 0.0; b->bounces = 0.0;
    b->v0 = 1.0; b->period = 0.25; b->threshold = 0.5; b->u = 0.0;
    b->dir = 1; b->n_stop = 0; b->pending = 0; b->terminate = 0;
    b->mode = INSTANTIATED;
}

static double rate(const Bouncer *b) { return b->dir * b->v0 + b->u; }

/* Apply the events due now; true when one was. */
static bool apply_events(Bouncer *b)
{
    bool any = false;
    if (b->dir > 0 && b->x >= 1.0) { b->x = 1.0; b->dir = -1; b->bounces += 1.0; any = true; }
    else if (b->dir < 0 && b->x <= 0.0) { b->x = 0.0; b->dir = 1; b->bounces += 1.0; any = true; }
    if (b->period > 0.0 && b->time >= b->next_time_event) {
        b->n += 1.0;
        b->next_time_event = (b->n + 1.0) * b->period;
        any = true;
        if (b->n_stop > 0 && b->n >= b->n_stop)
            b->terminate = 1;
    }
    b->pending = 0;
    return any;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
    fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate)
{
    (void)instanceName; (void)resourcePath; (void)visible; (void)loggingOn;
    (void)requiredIntermediateVariables; (void)intermediateUpdate;
    if (nRequiredIntermediateVariables || strcmp(instantiationToken, "{cw-fmi3-bouncer}") != 0)
        return NULL;
#ifdef CW_REFUSE_EVENT_MODE
    /* As Reference-FMUs' Roberts: hasEventMode declared, eventModeUsed refused. */
    if (eventModeUsed) {
        if (logMessage)
            logMessage(instanceEnvironment, fmi3Error, "logStatusError", "Event Mode is not supported.");
        return NULL;
    }
#endif
    Bouncer *b = calloc(1, sizeof *b);
    if (!b)
        return NULL;
    defaults(b);
    b->event_mode_used = eventModeUsed;
    b->early_return_allowed = earlyReturnAllowed;
    b->env = instanceEnvironment;
    b->log = logMessage;
    return b;
}

void fmi3FreeInstance(fmi3Instance instance) { free(instance); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
    fmi3Float64 tolerance, fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    Bouncer *b = instance;
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    if (b->mode != INSTANTIATED)
        return fail(b, "fmi3EnterInitializationMode: illegal call sequence");
    b->time = startTime;
    b->mode = INITIALIZATION;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    Bouncer *b = instance;
    if (b->mode != INITIALIZATION)
        return fail(b, "fmi3ExitInitializationMode: illegal call sequence");
    b->next_time_event = b->period > 0.0 ? (b->n + 1.0) * b->period : INFINITY;
    b->mode = b->event_mode_used ? EVENT : STEP;
    return fmi3OK;
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance)
{
    Bouncer *b = instance;
    if (b->mode != STEP)
        return fail(b, "fmi3EnterEventMode: illegal call sequence");
    b->mode = EVENT;
    return fmi3OK;
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined, fmi3Float64 *nextEventTime)
{
    Bouncer *b = instance;
    if (b->mode != EVENT)
        return fail(b, "fmi3UpdateDiscreteStates: illegal call sequence");
    bool changed = apply_events(b);
    *discreteStatesNeedUpdate = false;
    *terminateSimulation = b->terminate;
    *nominalsOfContinuousStatesChanged = false;
    *valuesOfContinuousStatesChanged = changed;
    *nextEventTimeDefined = b->period > 0.0;
    *nextEventTime = b->next_time_event;
    return fmi3OK;
}

fmi3Status fmi3EnterStepMode(fmi3Instance instance)
{
    Bouncer *b = instance;
    if (b->mode != EVENT)
        return fail(b, "fmi3EnterStepMode: illegal call sequence");
    if (b->pending)
        return fail(b, "fmi3EnterStepMode: an event is still pending");
    b->mode = STEP;
    return fmi3OK;
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
    fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
    fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
    fmi3Float64 *lastSuccessfulTime)
{
    Bouncer *b = instance;
    (void)noSetFMUStatePriorToCurrentPoint;
    *eventHandlingNeeded = *terminateSimulation = *earlyReturn = false;
    *lastSuccessfulTime = b->time;
    if (b->mode != STEP)
        return fail(b, "fmi3DoStep: illegal call sequence (not in step mode)");
    if (b->pending)
        return fail(b, "fmi3DoStep: an event was not handled in event mode");
    if (fabs(currentCommunicationPoint - b->time) > 1e-12 * fmax(1.0, fabs(b->time)))
        return fail(b, "fmi3DoStep: currentCommunicationPoint is not the FMU's time");
    if (!(communicationStepSize > 0.0))
        return fail(b, "fmi3DoStep: communicationStepSize must be > 0");
    double end = currentCommunicationPoint + communicationStepSize;
    b->time = currentCommunicationPoint;
    while (b->time < end) {
        double r = rate(b), dt = end - b->time;
        double to_wall = r > 0.0 ? (1.0 - b->x) / r : r < 0.0 ? b->x / -r : INFINITY;
        int wall = 0, timed = 0;
        if (to_wall <= dt) { dt = to_wall; wall = 1; }
        if (b->next_time_event - b->time <= dt) { dt = b->next_time_event - b->time; timed = 1; wall = to_wall <= dt; }
        /* Land on an event exactly: a rounded landing would miss it. */
        b->x = wall ? (r > 0.0 ? 1.0 : 0.0) : b->x + r * dt;
        b->time = timed ? b->next_time_event : wall ? b->time + dt : end;
        if (!wall && !timed)
            break;
        if (b->time >= end)
            b->time = end;
        if (b->event_mode_used) {
            b->pending = 1;
            *eventHandlingNeeded = true;
            if (b->early_return_allowed || b->time >= end)
                break;
            return fail(b, "fmi3DoStep: an event inside the step needs early return in event mode");
        }
        apply_events(b);
        if (b->terminate)
            break;
    }
    *terminateSimulation = b->terminate;
    *earlyReturn = b->time < end;
    *lastSuccessfulTime = b->time;
    return fmi3OK;
}

static double *real_of(Bouncer *b, fmi3ValueReference vr)
{
    switch (vr) {
    case VR_TIME: return &b->time;
    case VR_V0: return &b->v0;
    case VR_PERIOD: return &b->period;
    case VR_THRESHOLD: return &b->threshold;
    case VR_U: return &b->u;
    case VR_X: return &b->x;
    case VR_N: return &b->n;
    case VR_BOUNCES: return &b->bounces;
    default: return NULL;
    }
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
    fmi3Float64 values[], size_t nValues)
{
    Bouncer *b = instance;
    if (nValues != nvr)
        return fail(b, "fmi3GetFloat64: nValues differs from nValueReferences");
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] == VR_Z) { values[i] = b->x - b->threshold; continue; }
        double *p = real_of(b, vr[i]);
        if (!p)
            return fail(b, "fmi3GetFloat64: unknown value reference");
        values[i] = *p;
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
    const fmi3Float64 values[], size_t nValues)
{
    Bouncer *b = instance;
    if (nValues != nvr)
        return fail(b, "fmi3SetFloat64: nValues differs from nValueReferences");
    for (size_t i = 0; i < nvr; i++) {
        bool parameter = vr[i] == VR_V0 || vr[i] == VR_PERIOD || vr[i] == VR_THRESHOLD;
        if (!(vr[i] == VR_U || (parameter && b->mode <= INITIALIZATION)))
            return fail(b, "fmi3SetFloat64: not settable now");
        *real_of(b, vr[i]) = values[i];
    }
    return fmi3OK;
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
    fmi3Int32 values[], size_t nValues)
{
    Bouncer *b = instance;
    for (size_t i = 0; i < nvr && i < nValues; i++) {
        if (vr[i] != VR_N_STOP)
            return fail(b, "fmi3GetInt32: unknown value reference");
        values[i] = b->n_stop;
    }
    return fmi3OK;
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
    const fmi3Int32 values[], size_t nValues)
{
    Bouncer *b = instance;
    for (size_t i = 0; i < nvr && i < nValues; i++) {
        if (vr[i] != VR_N_STOP || b->mode > INITIALIZATION)
            return fail(b, "fmi3SetInt32: not settable now");
        b->n_stop = values[i];
    }
    return fmi3OK;
}

fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
    fmi3Boolean values[], size_t nValues)
{
    (void)vr; (void)values; (void)nValues;
    return nvr ? fail(instance, "fmi3GetBoolean: no Boolean variables") : fmi3OK;
}

fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
    const fmi3Boolean values[], size_t nValues)
{
    (void)vr; (void)values; (void)nValues;
    return nvr ? fail(instance, "fmi3SetBoolean: no Boolean variables") : fmi3OK;
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
    const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues)
{
    Bouncer *b = instance;
    if (nValues != nvr)
        return fail(b, "fmi3GetOutputDerivatives: nValues differs from nValueReferences");
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] != VR_X && vr[i] != VR_Z)
            return fail(b, "fmi3GetOutputDerivatives: only x and z have derivatives");
        values[i] = orders[i] == 1 ? rate(b) : 0.0;
    }
    return fmi3OK;
}

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *state)
{
    Bouncer *b = instance;
    if (!*state && !(*state = malloc(sizeof *b)))
        return fail(b, "fmi3GetFMUState: out of memory");
    memcpy(*state, b, sizeof *b);
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState state)
{
    if (!state)
        return fail(instance, "fmi3SetFMUState: no state");
    memcpy(instance, state, sizeof(Bouncer));
    return fmi3OK;
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *state)
{
    (void)instance;
    free(*state);
    *state = NULL;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance)
{
    Bouncer *b = instance;
    int event_mode_used = b->event_mode_used, early = b->early_return_allowed;
    defaults(b);
    b->event_mode_used = event_mode_used;
    b->early_return_allowed = early;
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance)
{
    ((Bouncer *)instance)->mode = TERMINATED;
    return fmi3OK;
}
