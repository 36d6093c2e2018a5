/* An FMI 2.0 Co-Simulation FMU that breaks the rules on purpose, for the
 * master's tests (tests/fmi2_hostile.py describes it, tests/CMakeLists.txt builds it): x = time, and
 *
 * - it logs, in fmi2Instantiate and in every step, through the logger with
 *   componentEnvironment (void *)1, NULL and a pointer of its own, with
 *   its instance name, NULL and an unreadable one as the instance name,
 *   and with a NULL message, an unreadable one and formats that ask for
 *   arguments it does not pass (%s, %n);
 * - at t >= t_fault its doStep does what `fault` says: 1 dereferences NULL,
 *   2 raises SIGFPE, 3 calls abort(), 4 never returns (sleeps in a loop),
 *   5 logs an error through environment (void *)1 with its instance name
 *   and returns fmi2Error, 6 calls the stepFinished callback it was not
 *   given (NULL);
 * - built with -DCW_ABORT_IN_INSTANTIATE, fmi2Instantiate calls abort().
 *
 * All its state is in its instance (no globals). */
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2Functions.h"

typedef struct {
    fmi2CallbackFunctions cb;
    char name[128];
    double time, t_fault, fault;
    int volatile *nowhere;
} Inst;

static void hostile_logs(Inst *s, const char *where)
{
    fmi2CallbackLogger log = s->cb.logger;
    if (!log)
        return;
    log((fmi2ComponentEnvironment)1, s->name, fmi2OK, "logAll", "env 1 in %s at t=%g", where, s->time);
    log(NULL, s->name, fmi2OK, "logAll", "env NULL in %s", where);
    log((fmi2ComponentEnvironment)s, s->name, fmi2OK, "logAll", "own pointer in %s", where);
    log((fmi2ComponentEnvironment)1, NULL, fmi2OK, NULL, "no name in %s", where);
    log((fmi2ComponentEnvironment)1, (const char *)8, fmi2OK, (const char *)16, "bad name in %s", where);
    log(s->cb.componentEnvironment, s->name, fmi2OK, "logAll", NULL);
    log((fmi2ComponentEnvironment)1, s->name, fmi2OK, "logAll", (const char *)24);
    log((fmi2ComponentEnvironment)1, s->name, fmi2OK, "logAll", "missing args %s %s %s %n %d %.*s|%ls", where);
    log(s->cb.componentEnvironment, s->name, fmi2OK, "logAll", "string arg %s", (const char *)32);
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String guid,
                              fmi2String resources, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    (void)fmuType; (void)guid; (void)resources; (void)visible; (void)loggingOn;
#ifdef CW_ABORT_IN_INSTANTIATE
    abort();
#endif
    Inst *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    s->cb = *functions;
    strncpy(s->name, instanceName ? instanceName : "", sizeof s->name - 1);
    s->t_fault = 1e300;
    hostile_logs(s, "fmi2Instantiate");
    return s;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stopDef, fmi2Real stop)
{
    (void)tolDef; (void)tol; (void)stopDef; (void)stop;
    ((Inst *)c)->time = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) { ((Inst *)c)->time = 0; return fmi2OK; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[])
{
    (void)c; (void)on; (void)n; (void)cats;
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[])
{
    Inst *s = c;
    for (size_t k = 0; k < n; k++)
        value[k] = vr[k] == 0 ? s->time : vr[k] == 1 ? s->t_fault : s->fault;
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[])
{
    Inst *s = c;
    for (size_t k = 0; k < n; k++) {
        if (vr[k] == 1)
            s->t_fault = value[k];
        else if (vr[k] == 2)
            s->fault = value[k];
        else
            return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior)
{
    (void)noSetPrior;
    Inst *s = c;
    hostile_logs(s, "fmi2DoStep");
    if (t + h > s->t_fault + 1e-9) {
        switch ((int)s->fault) {
        case 1:
            return (fmi2Status)(*s->nowhere + 1);  /* NULL */
        case 2:
            raise(SIGFPE);
            break;
        case 3:
            abort();
        case 4:
            for (;;) {
                struct timespec nap = {0, 10000000};
                nanosleep(&nap, NULL);
            }
        case 6:  /* a callback the environment did not give (stepFinished is NULL) */
            s->cb.stepFinished(s->cb.componentEnvironment, fmi2OK);
            break;
        case 5:
            s->cb.logger((fmi2ComponentEnvironment)1, s->name, fmi2Error, "logStatusError",
                         "hostile failure at t=%g (%s)", t + h, "formatted");
            return fmi2Error;
        default:
            break;
        }
    }
    s->time = t + h;
    return fmi2OK;
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }
