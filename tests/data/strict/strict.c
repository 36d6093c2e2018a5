/* A Co-Simulation FMU that enforces the call sequence of FMI 2.0 section
 * 4.2.4 and FMI 3.0's Step Mode: a get after a set without a step in
 * between returns an error (and logs why). Built for FMI 2.0 (default) or
 * FMI 3.0 (-DCW_FMI3) by tests/CMakeLists.txt (descriptions: tests/strict_fmu.py).
 *
 * Model: one direct-feedthrough output, as Reference-FMUs' Feedthrough,
 *     y = gain * u + offset + slope * time
 * (u: a Real input held over a step; time: the FMU's time). In
 * Initialization Mode sets and gets may alternate freely (algebraic loops
 * are solved there); in Step Mode a set marks the outputs stale until the
 * next step. The mark is part of the FMU state (fmi2GetFMUstate/
 * fmi3GetFMUState copy the whole instance): a state saved after a step
 * may be read again once it is set. All its state is in its instance. */
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef CW_FMI3
#include "fmi3Functions.h"
#else
#include "fmi2Functions.h"
#endif

enum { VR_TIME = 0, VR_U = 1, VR_Y = 2, VR_GAIN = 3, VR_OFFSET = 4, VR_SLOPE = 5 };
enum { INSTANTIATED, INITIALIZATION, STEPPING };

typedef struct {
    double time, u, gain, offset, slope;
    int mode;
    bool stale;            /* an input was set in Step Mode since the last step */
    long long refused;     /* gets refused (for the log) */
} Model;

typedef struct {
    Model m;
    char name[128];
#ifdef CW_FMI3
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
#else
    fmi2CallbackFunctions cb;
#endif
} Strict;

static void defaults(Model *m)
{
    memset(m, 0, sizeof *m);
    m->gain = 1.0;
}

static double output(const Model *m) { return m->gain * m->u + m->offset + m->slope * m->time; }

static void say(Strict *s, const char *text)
{
#ifdef CW_FMI3
    if (s->log)
        s->log(s->env, fmi3Error, "logStatusError", text);
#else
    if (s->cb.logger)
        s->cb.logger(s->cb.componentEnvironment, s->name, fmi2Error, "logStatusError", "%s", text);
#endif
}

/* 0: the get may go on; else the error was logged. */
static int check_get(Strict *s, const char *get, const char *set, const char *step)
{
    if (s->m.mode == STEPPING && s->m.stale) {
        char text[200];
        s->m.refused++;
        snprintf(text, sizeof text, "%s after %s without %s in between at t = %.17g s (Step Mode)", get, set,
                 step, s->m.time);
        say(s, text);
        return 1;
    }
    return 0;
}

static int set_value(Strict *s, unsigned vr, double v)
{
    switch (vr) {
    case VR_U: s->m.u = v; break;
    case VR_GAIN: s->m.gain = v; break;
    case VR_OFFSET: s->m.offset = v; break;
    case VR_SLOPE: s->m.slope = v; break;
    default: return 1;
    }
    if (s->m.mode == STEPPING)
        s->m.stale = true;
    return 0;
}

static int get_value(const Strict *s, unsigned vr, double *v)
{
    switch (vr) {
    case VR_TIME: *v = s->m.time; return 0;
    case VR_U: *v = s->m.u; return 0;
    case VR_Y: *v = output(&s->m); return 0;
    case VR_GAIN: *v = s->m.gain; return 0;
    case VR_OFFSET: *v = s->m.offset; return 0;
    case VR_SLOPE: *v = s->m.slope; return 0;
    default: return 1;
    }
}

#ifdef CW_FMI3

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
    fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate)
{
    (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn; (void)eventModeUsed;
    (void)earlyReturnAllowed; (void)requiredIntermediateVariables; (void)nRequiredIntermediateVariables;
    (void)intermediateUpdate;
    Strict *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    defaults(&s->m);
    strncpy(s->name, instanceName ? instanceName : "", sizeof s->name - 1);
    s->env = instanceEnvironment;
    s->log = logMessage;
    return s;
}

void fmi3FreeInstance(fmi3Instance instance) { free(instance); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    Strict *s = instance;
    s->m.time = startTime;
    s->m.mode = INITIALIZATION;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    Strict *s = instance;
    s->m.mode = STEPPING;
    s->m.stale = false;
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance) { (void)instance; return fmi3OK; }
fmi3Status fmi3Reset(fmi3Instance instance) { defaults(&((Strict *)instance)->m); return fmi3OK; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean on, size_t n, const fmi3String categories[])
{
    (void)instance; (void)on; (void)n; (void)categories;
    return fmi3OK;
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    Strict *s = instance;
    *eventHandlingNeeded = false;
    *terminateSimulation = false;
    *earlyReturn = false;
    if (s->m.mode != STEPPING) {
        say(s, "fmi3DoStep: not in Step Mode");
        return fmi3Error;
    }
    s->m.time = currentCommunicationPoint + communicationStepSize;
    s->m.stale = false;
    *lastSuccessfulTime = s->m.time;
    return fmi3OK;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 values[],
                          size_t nValues)
{
    Strict *s = instance;
    if (nvr != nValues)
        return fmi3Error;
    if (check_get(s, "fmi3GetFloat64", "fmi3SetFloat64", "fmi3DoStep"))
        return fmi3Error;
    for (size_t k = 0; k < nvr; k++)
        if (get_value(s, vr[k], &values[k]))
            return fmi3Error;
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Float64 values[], size_t nValues)
{
    Strict *s = instance;
    if (nvr != nValues)
        return fmi3Error;
    for (size_t k = 0; k < nvr; k++)
        if (set_value(s, vr[k], values[k]))
            return fmi3Error;
    return fmi3OK;
}

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *state)
{
    Model *copy = *state ? *state : malloc(sizeof *copy);
    if (!copy)
        return fmi3Error;
    *copy = ((Strict *)instance)->m;
    *state = copy;
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState state)
{
    if (!state)
        return fmi3Error;
    ((Strict *)instance)->m = *(Model *)state;
    return fmi3OK;
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *state)
{
    (void)instance;
    free(*state);
    *state = NULL;
    return fmi3OK;
}

const char *fmi3GetVersion(void) { return fmi3Version; }

#else  /* FMI 2.0 */

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String guid,
                              fmi2String resources, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    (void)fmuType; (void)guid; (void)resources; (void)visible; (void)loggingOn;
    Strict *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    defaults(&s->m);
    s->cb = *functions;
    strncpy(s->name, instanceName ? instanceName : "", sizeof s->name - 1);
    return s;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stopDef, fmi2Real stop)
{
    (void)tolDef; (void)tol; (void)stopDef; (void)stop;
    ((Strict *)c)->m.time = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) { ((Strict *)c)->m.mode = INITIALIZATION; return fmi2OK; }

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    Strict *s = c;
    s->m.mode = STEPPING;
    s->m.stale = false;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) { defaults(&((Strict *)c)->m); return fmi2OK; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[])
{
    (void)c; (void)on; (void)n; (void)cats;
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[])
{
    Strict *s = c;
    if (check_get(s, "fmi2GetReal", "fmi2SetReal", "fmi2DoStep"))
        return fmi2Error;
    for (size_t k = 0; k < n; k++)
        if (get_value(s, vr[k], &value[k]))
            return fmi2Error;
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[])
{
    Strict *s = c;
    for (size_t k = 0; k < n; k++)
        if (set_value(s, vr[k], value[k]))
            return fmi2Error;
    return fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior)
{
    (void)noSetPrior;
    Strict *s = c;
    if (s->m.mode != STEPPING) {
        say(s, "fmi2DoStep: not in slaveInitialized");
        return fmi2Error;
    }
    s->m.time = t + h;
    s->m.stale = false;
    return fmi2OK;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    Model *copy = *state ? *state : malloc(sizeof *copy);
    if (!copy)
        return fmi2Error;
    *copy = ((Strict *)c)->m;
    *state = copy;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state)
{
    if (!state)
        return fmi2Error;
    ((Strict *)c)->m = *(Model *)state;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    (void)c;
    free(*state);
    *state = NULL;
    return fmi2OK;
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

#endif
