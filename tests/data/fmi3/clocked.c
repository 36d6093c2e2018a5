/* Clocked FMI 3.0 test FMUs for the master's clock engine (tests/CMakeLists.txt
 * builds each with -DMODEL_<name>):
 *
 * Ticker (Co-Simulation, Event Mode): an output clock `tick` that ticks every
 *   `period` s (announced as time events, unless `announce` is false: then it
 *   returns early at each tick); its clocked output `n` counts the ticks.
 * Counter (Co-Simulation, Event Mode): a triggered input clock `tooth`; at each
 *   tick the clocked input `step_by` is added to the clocked output `count`, and
 *   `last` is the tick's time; `total` (not clocked) follows `count`.
 * Sampler (Co-Simulation, Event Mode): a constant input clock `sample`
 *   (0.1 s, shift 0.05 s) counted in `samples`; at the third sample it sets
 *   the countdown clock `alarm` to 0.025 s, counted in `alarms`
 *   (`alarm_time`); `beat` is a changing clock: ticks at 0, then after
 *   0.2, 0.3, 0.4... s, counted in `beats`.
 * Partitions (Scheduled Execution): input clocks `fast` (0.1 s, priority 1)
 *   and `slow` (0.3 s, priority 2); `order` is the activation sequence
 *   (order * 10 + partition); every third `fast` activation ticks the output
 *   clock `every3` and sets the countdown clock `later` to 0.05 s, both
 *   through clockUpdate.
 *
 * Each refuses a wrong call sequence or a tick at a wrong time with an
 * error, so that the tests see a master's mistakes.
 */

#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"

enum { INSTANTIATED, INITIALIZATION, EVENT, STEP, ACTIVATION, TERMINATED };

typedef struct {
    int mode, event_mode_used, early_return_allowed;
    double time;
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
    fmi3ClockUpdateCallback clock_update;
    /* Ticker */
    double period, next_tick;
    int n, tick_active, announce;
    /* Counter */
    int tooth_active, applied, count, step_by;
    double last;
    /* Sampler */
    int sample_active, alarm_active, beat_active, samples, alarms, beats, alarm_qualifier, beat_qualifier;
    double alarm_interval, alarm_due, alarm_time, beat_interval, beat_due;
    /* Partitions */
    int order, fast_n, slow_n, later_n, every3, later_qualifier;
    double later_interval, later_due;
} M;

static fmi3Status fail(M *m, const char *message)
{
    if (m->log)
        m->log(m->env, fmi3Error, "logStatusError", message);
    return fmi3Error;
}

static bool same_time(double a, double b) { return fabs(a - b) <= 1e-9 * fmax(1.0, fabs(a)); }

static void defaults(M *m)
{
    memset(&m->period, 0, sizeof(M) - offsetof(M, period));
    m->period = 0.1;
    m->announce = 1;
    m->step_by = 1;
    m->alarm_due = m->later_due = -1.0;
    m->beat_interval = 0.2;
    m->beat_qualifier = fmi3IntervalChanged;
    m->mode = INSTANTIATED;
    m->time = 0.0;
}

static M *make(fmi3String token, fmi3InstanceEnvironment env, fmi3LogMessageCallback log)
{
    if (strcmp(token, "{cw-clocked-" MODEL_NAME "}") != 0)
        return NULL;
    M *m = calloc(1, sizeof(M));
    if (!m)
        return NULL;
    m->env = env;
    m->log = log;
    defaults(m);
    return m;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
    fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate)
{
    (void)instanceName; (void)resourcePath; (void)visible; (void)loggingOn;
    (void)requiredIntermediateVariables; (void)nRequiredIntermediateVariables; (void)intermediateUpdate;
#ifdef MODEL_Partitions
    (void)instantiationToken; (void)eventModeUsed; (void)earlyReturnAllowed; (void)instanceEnvironment;
    (void)logMessage;
    return NULL;
#else
    if (!eventModeUsed)
        return NULL; /* clocks need Event Mode */
    M *m = make(instantiationToken, instanceEnvironment, logMessage);
    if (m) {
        m->event_mode_used = 1;
        m->early_return_allowed = earlyReturnAllowed;
    }
    return m;
#endif
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
    fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
    fmi3LockPreemptionCallback lockPreemption, fmi3UnlockPreemptionCallback unlockPreemption)
{
    (void)instanceName; (void)resourcePath; (void)visible; (void)loggingOn; (void)lockPreemption;
    (void)unlockPreemption;
#ifdef MODEL_Partitions
    M *m = make(instantiationToken, instanceEnvironment, logMessage);
    if (m)
        m->clock_update = clockUpdate;
    return m;
#else
    (void)instantiationToken; (void)instanceEnvironment; (void)logMessage; (void)clockUpdate;
    return NULL;
#endif
}

void fmi3FreeInstance(fmi3Instance instance) { free(instance); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
    fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    M *m = instance;
    if (m->mode != INSTANTIATED)
        return fail(m, "fmi3EnterInitializationMode: illegal call sequence");
    m->time = startTime;
    m->mode = INITIALIZATION;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    M *m = instance;
    if (m->mode != INITIALIZATION)
        return fail(m, "fmi3ExitInitializationMode: illegal call sequence");
    m->next_tick = m->time + m->period;
#ifdef MODEL_Partitions
    m->mode = ACTIVATION;
#else
    m->mode = EVENT;
#endif
    return fmi3OK;
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance)
{
    M *m = instance;
    if (m->mode != STEP)
        return fail(m, "fmi3EnterEventMode: not in Step Mode");
    m->mode = EVENT;
#ifdef MODEL_Ticker
    if (same_time(m->time, m->next_tick)) {
        m->tick_active = 1;
        m->n += 1;
    }
#endif
    return fmi3OK;
}

/* The clocked outputs of the active clocks (computed once per tick). */
static void apply(M *m)
{
    if (m->applied)
        return;
    m->applied = 1;
#ifdef MODEL_Counter
    if (m->tooth_active) {
        m->count += m->step_by;
        m->last = m->time;
    }
#endif
#ifdef MODEL_Sampler
    if (m->sample_active) {
        m->samples += 1;
        if (m->samples == 3) {
            m->alarm_interval = 0.025;
            m->alarm_qualifier = fmi3IntervalChanged;
            m->alarm_due = m->time + 0.025;
        }
    }
    if (m->alarm_active) {
        m->alarms += 1;
        m->alarm_time = m->time;
    }
    if (m->beat_active) {
        m->beats += 1;
        m->beat_interval = 0.1 * (m->beats + 1);
        m->beat_qualifier = fmi3IntervalChanged;
        m->beat_due = m->time + m->beat_interval;
    }
#endif
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined, fmi3Float64 *nextEventTime)
{
    M *m = instance;
    if (m->mode != EVENT)
        return fail(m, "fmi3UpdateDiscreteStates: not in Event Mode");
    apply(m);
    *discreteStatesNeedUpdate = fmi3False;
    *terminateSimulation = fmi3False;
    *nominalsOfContinuousStatesChanged = fmi3False;
    *valuesOfContinuousStatesChanged = fmi3False;
    *nextEventTimeDefined = fmi3False;
    *nextEventTime = 0.0;
#ifdef MODEL_Ticker
    if (m->tick_active || m->time >= m->next_tick)
        m->next_tick = (m->n + 1) * m->period;
    m->tick_active = 0;
    *nextEventTimeDefined = m->announce ? fmi3True : fmi3False;
    *nextEventTime = m->announce ? m->next_tick : 0.0;
#endif
    m->tooth_active = m->sample_active = m->alarm_active = m->beat_active = 0;
    m->applied = 0;
    return fmi3OK;
}

fmi3Status fmi3EnterStepMode(fmi3Instance instance)
{
    M *m = instance;
    if (m->mode != EVENT)
        return fail(m, "fmi3EnterStepMode: not in Event Mode");
    m->mode = STEP;
    return fmi3OK;
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
    fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
    fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
    fmi3Float64 *lastSuccessfulTime)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    M *m = instance;
    if (m->mode != STEP)
        return fail(m, "fmi3DoStep: not in Step Mode");
    if (!same_time(currentCommunicationPoint, m->time))
        return fail(m, "fmi3DoStep: the communication point is not the FMU's time");
    double end = currentCommunicationPoint + communicationStepSize;
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
#ifdef MODEL_Ticker
    if (end > m->next_tick && !same_time(end, m->next_tick)) {
        if (!m->early_return_allowed)
            return fail(m, "fmi3DoStep: the step passes a tick of the output clock");
        end = m->next_tick;
        *earlyReturn = fmi3True;
    }
    if (same_time(end, m->next_tick))
        *eventHandlingNeeded = fmi3True;
#endif
#ifdef MODEL_Sampler
    double due[3] = {0.05 + 0.1 * floor((m->time - 0.05) / 0.1 + 1.0 + 1e-9), m->alarm_due, m->beat_due};
    for (int k = 0; k < 3; k++)
        if (due[k] > m->time && !same_time(due[k], m->time) && end > due[k] && !same_time(end, due[k]))
            return fail(m, "fmi3DoStep: the step passes a tick of an input clock");
#endif
    m->time = end;
    *lastSuccessfulTime = end;
    return fmi3OK;
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
    fmi3Float64 activationTime)
{
    M *m = instance;
#ifdef MODEL_Partitions
    if (m->mode != ACTIVATION)
        return fail(m, "fmi3ActivateModelPartition: not in Clock Activation Mode");
    if (activationTime < m->time && !same_time(activationTime, m->time))
        return fail(m, "fmi3ActivateModelPartition: time runs backwards");
    m->time = activationTime;
    switch (clockReference) {
    case 1: /* fast */
        if (!same_time(activationTime, 0.1 * m->fast_n))
            return fail(m, "fmi3ActivateModelPartition: fast activated off its period");
        m->fast_n += 1;
        m->order = (m->order * 10 + 1) % 100000000;
        if (m->fast_n % 3 == 0) {
            m->every3 = 1;
            m->later_interval = 0.05;
            m->later_qualifier = fmi3IntervalChanged;
            m->later_due = activationTime + 0.05;
            if (m->clock_update)
                m->clock_update(m->env);
        }
        return fmi3OK;
    case 2: /* slow */
        if (!same_time(activationTime, 0.3 * m->slow_n))
            return fail(m, "fmi3ActivateModelPartition: slow activated off its period");
        m->slow_n += 1;
        m->order = (m->order * 10 + 2) % 100000000;
        return fmi3OK;
    case 3: /* later */
        if (m->later_due < 0.0 || !same_time(activationTime, m->later_due))
            return fail(m, "fmi3ActivateModelPartition: later activated when no countdown ran out");
        m->later_due = -1.0;
        m->later_n += 1;
        m->order = (m->order * 10 + 3) % 100000000;
        return fmi3OK;
    default:
        return fail(m, "fmi3ActivateModelPartition: not an input clock");
    }
#else
    (void)clockReference; (void)activationTime;
    return fail(m, "fmi3ActivateModelPartition: not a Scheduled Execution FMU");
#endif
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, const fmi3Clock values[])
{
    M *m = instance;
    if (m->mode != EVENT)
        return fail(m, "fmi3SetClock: not in Event Mode");
    for (size_t k = 0; k < n; k++) {
        if (!values[k])
            continue;
#ifdef MODEL_Counter
        if (vr[k] == 1) { m->tooth_active = 1; continue; }
#endif
#ifdef MODEL_Sampler
        if (vr[k] == 1) {
            double r = (m->time - 0.05) / 0.1;
            if (fabs(r - floor(r + 0.5)) > 1e-6 || r < -1e-9)
                return fail(m, "fmi3SetClock: sample ticked off its period");
            m->sample_active = 1;
            continue;
        }
        if (vr[k] == 2) {
            if (m->alarm_due < 0.0 || !same_time(m->time, m->alarm_due))
                return fail(m, "fmi3SetClock: alarm ticked when no countdown ran out");
            m->alarm_due = -1.0;
            m->alarm_active = 1;
            continue;
        }
        if (vr[k] == 3) {
            if (m->beats > 0 && !same_time(m->time, m->beat_due))
                return fail(m, "fmi3SetClock: beat ticked off its interval");
            m->beat_active = 1;
            continue;
        }
#endif
        return fail(m, "fmi3SetClock: not an input clock");
    }
    return fmi3OK;
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3Clock values[])
{
    M *m = instance;
    for (size_t k = 0; k < n; k++) {
#ifdef MODEL_Ticker
        if (vr[k] == 1) {
            if (m->mode != EVENT)
                return fail(m, "fmi3GetClock: not in Event Mode");
            values[k] = m->tick_active;
            continue;
        }
#endif
#ifdef MODEL_Partitions
        if (vr[k] == 4) {
            values[k] = m->every3;
            m->every3 = 0;
            continue;
        }
#endif
        return fail(m, "fmi3GetClock: not an output clock");
    }
    return fmi3OK;
}

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
    fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[])
{
    M *m = instance;
    for (size_t k = 0; k < n; k++) {
        int *q = NULL;
        double value = 0.0;
#ifdef MODEL_Sampler
        if (vr[k] == 1) { intervals[k] = 0.1; qualifiers[k] = fmi3IntervalUnchanged; continue; }
        if (vr[k] == 2) { q = &m->alarm_qualifier; value = m->alarm_interval; }
        if (vr[k] == 3) { q = &m->beat_qualifier; value = m->beat_interval; }
#endif
#ifdef MODEL_Partitions
        if (vr[k] == 1) { intervals[k] = 0.1; qualifiers[k] = fmi3IntervalUnchanged; continue; }
        if (vr[k] == 2) { intervals[k] = 0.3; qualifiers[k] = fmi3IntervalUnchanged; continue; }
        if (vr[k] == 3) { q = &m->later_qualifier; value = m->later_interval; }
#endif
        if (!q)
            return fail(m, "fmi3GetIntervalDecimal: not a clock with an interval");
        qualifiers[k] = *q;
        intervals[k] = value;
        if (*q == fmi3IntervalChanged)
            *q = fmi3IntervalUnchanged;
    }
    return fmi3OK;
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3Float64 shifts[])
{
    (void)instance; (void)vr;
    for (size_t k = 0; k < n; k++)
        shifts[k] = 0.0;
    return fmi3OK;
}

/* Values: clocked ones only while their clock ticks (Event Mode). */
static fmi3Status clocked(M *m, int active, const char *what)
{
    if (m->mode == ACTIVATION || m->mode == INITIALIZATION)
        return fmi3OK;
    if (m->mode != EVENT || !active)
        return fail(m, what);
    apply(m);
    return fmi3OK;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 values[],
    size_t nValues)
{
    (void)nValues;
    M *m = instance;
    for (size_t k = 0; k < nvr; k++) {
        switch (vr[k]) {
        case 0: values[k] = m->time; break;
#ifdef MODEL_Ticker
        case 10: values[k] = m->period; break;
        case 11: values[k] = m->time; break;
        case 12: values[k] = m->announce; break;
#endif
#ifdef MODEL_Counter
        case 12:
            if (clocked(m, m->tooth_active, "fmi3GetFloat64: last outside a tick of tooth"))
                return fmi3Error;
            values[k] = m->last;
            break;
        case 13: values[k] = m->count; break;
#endif
#ifdef MODEL_Sampler
        case 12:
            if (clocked(m, m->alarm_active, "fmi3GetFloat64: alarm_time outside a tick of alarm"))
                return fmi3Error;
            values[k] = m->alarm_time;
            break;
#endif
        default: return fail(m, "fmi3GetFloat64: no such Float64 variable");
        }
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
    const fmi3Float64 values[], size_t nValues)
{
    (void)nValues;
    M *m = instance;
    for (size_t k = 0; k < nvr; k++) {
#ifdef MODEL_Ticker
        if (vr[k] == 12 && (m->mode == INSTANTIATED || m->mode == INITIALIZATION)) {
            m->announce = values[k] != 0.0;
            continue;
        }
        if (vr[k] == 10 && (m->mode == INSTANTIATED || m->mode == INITIALIZATION) && values[k] > 0.0) {
            m->period = values[k];
            continue;
        }
#endif
        (void)values;
        return fail(m, "fmi3SetFloat64: not settable now");
    }
    return fmi3OK;
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Int32 values[],
    size_t nValues)
{
    (void)nValues;
    M *m = instance;
    for (size_t k = 0; k < nvr; k++) {
        switch (vr[k]) {
#ifdef MODEL_Ticker
        case 20:
            if (clocked(m, m->tick_active, "fmi3GetInt32: n outside a tick"))
                return fmi3Error;
            values[k] = m->n;
            break;
#endif
#ifdef MODEL_Counter
        case 20:
            if (clocked(m, m->tooth_active, "fmi3GetInt32: count outside a tick of tooth"))
                return fmi3Error;
            values[k] = m->count;
            break;
        case 21: values[k] = m->step_by; break;
#endif
#ifdef MODEL_Sampler
        case 20:
            if (clocked(m, m->sample_active, "fmi3GetInt32: samples outside a tick of sample"))
                return fmi3Error;
            values[k] = m->samples;
            break;
        case 21:
            if (clocked(m, m->alarm_active, "fmi3GetInt32: alarms outside a tick of alarm"))
                return fmi3Error;
            values[k] = m->alarms;
            break;
        case 22:
            if (clocked(m, m->beat_active, "fmi3GetInt32: beats outside a tick of beat"))
                return fmi3Error;
            values[k] = m->beats;
            break;
#endif
#ifdef MODEL_Partitions
        case 20: values[k] = m->order; break;
        case 21: values[k] = m->fast_n; break;
        case 22: values[k] = m->slow_n; break;
        case 23: values[k] = m->later_n; break;
#endif
        default: return fail(m, "fmi3GetInt32: no such Int32 variable");
        }
    }
    return fmi3OK;
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Int32 values[],
    size_t nValues)
{
    (void)nValues;
    M *m = instance;
    for (size_t k = 0; k < nvr; k++) {
#ifdef MODEL_Counter
        if (vr[k] == 21) {
            if (m->mode != INSTANTIATED && m->mode != INITIALIZATION && !(m->mode == EVENT && m->tooth_active))
                return fail(m, "fmi3SetInt32: step_by outside a tick of tooth");
            m->step_by = values[k];
            continue;
        }
#endif
        (void)values;
        return fail(m, "fmi3SetInt32: no such input");
    }
    return fmi3OK;
}

/* FMU state: the whole instance (its callbacks are the same). */
fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *state)
{
    M *copy = *state ? (M *)*state : malloc(sizeof(M));
    if (!copy)
        return fail(instance, "fmi3GetFMUState: out of memory");
    *copy = *(M *)instance;
    *state = copy;
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState state)
{
    if (!state)
        return fail(instance, "fmi3SetFMUState: no state");
    *(M *)instance = *(M *)state;
    return fmi3OK;
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *state)
{
    (void)instance;
    if (state) {
        free(*state);
        *state = NULL;
    }
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance)
{
    M *m = instance;
    m->mode = TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance)
{
    defaults(instance);
    return fmi3OK;
}
