/* Linear: a small FMI 3.0 Co-Simulation FMU with array variables, for the
 * master's array tests (tests/fmi3_linear.py writes its modelDescription.xml).
 *
 *     dx/dt = A x + B u,   y = C x + D u,   x(0) = x0,   s = x[0] + ... + x[n-1] + w
 *
 * with n states (the structural parameter n, start 3), two inputs u and two
 * outputs y; A is n x n, B n x 2, C 2 x n, D 2 x 2 (row-major, as FMI 3.0
 * stores arrays). x is an output too; w a scalar input, s a scalar output.
 * The step is classic RK4 with internal steps of at most H_MAX, the input
 * held over the step.
 *
 * An Int32 array input k (3 values) is mirrored by the output kk.
 *
 * Faults for the tests of failed runs: from t >= t_nan on, y[0] is NaN; a
 * step that would end after t_fail returns fmi3Error (with a message).
 *
 * x and y offer their first and second time derivatives.
 *
 * Every get and set checks nValues against the sizes of the variables
 * named, so that a master that passes nValues wrong sees an error.
 */

#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"

#define N_MAX 4
#define N_IN 2
#define N_OUT 2
#define N_K 3
#define H_MAX 0.01

enum { VR_TIME, VR_N, VR_A, VR_B, VR_C, VR_D, VR_X0, VR_U, VR_Y, VR_X, VR_T_NAN, VR_T_FAIL, VR_K, VR_KK, VR_W,
       VR_S };
enum { INSTANTIATED, INITIALIZATION, STEPPING };

typedef struct {
    double time;
    int mode;
    uint64_t n;
    double A[N_MAX * N_MAX], B[N_MAX * N_IN], C[N_OUT * N_MAX], D[N_OUT * N_IN];
    double x0[N_MAX], u[N_IN], x[N_MAX], y[N_OUT];
    double t_nan, t_fail, w, s;
    int32_t k[N_K];
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
} Linear;

static fmi3Status fail(Linear *a, const char *message)
{
    if (a->log)
        a->log(a->env, fmi3Error, "logStatusError", message);
    return fmi3Error;
}

static void defaults(Linear *a)
{
    memset(a->A, 0, sizeof a->A);
    memset(a->B, 0, sizeof a->B);
    memset(a->C, 0, sizeof a->C);
    memset(a->D, 0, sizeof a->D);
    a->n = 3;
    a->A[0] = -1.0;               /* A = diag(-1, -2, -3) */
    a->A[4] = -2.0;
    a->A[8] = -3.0;
    a->B[0] = a->B[3] = 1.0;      /* B = [[1, 0], [0, 1], [0, 0]] */
    a->C[0] = a->C[4] = 1.0;      /* C = [[1, 0, 0], [0, 1, 0]] */
    a->x0[0] = a->x0[1] = a->x0[2] = 1.0;
    a->u[0] = a->u[1] = 0.0;
    a->w = 0.0;
    a->t_nan = a->t_fail = 1e300;
    memset(a->k, 0, sizeof a->k);
    memset(a->x, 0, sizeof a->x);
    a->time = 0.0;
    a->mode = INSTANTIATED;
}

/* y = C x + D u; y[0] is NaN from t_nan on. */
static void outputs(Linear *a)
{
    const size_t n = (size_t)a->n;
    for (size_t i = 0; i < N_OUT; i++) {
        double s = 0.0;
        for (size_t j = 0; j < n; j++)
            s += a->C[i * n + j] * a->x[j];
        for (size_t j = 0; j < N_IN; j++)
            s += a->D[i * N_IN + j] * a->u[j];
        a->y[i] = s;
    }
    if (a->time >= a->t_nan)
        a->y[0] = NAN;
    a->s = a->w;
    for (size_t j = 0; j < n; j++)
        a->s += a->x[j];
}

static void derivative(const Linear *a, const double *x, double *dx)
{
    const size_t n = (size_t)a->n;
    for (size_t i = 0; i < n; i++) {
        double s = 0.0;
        for (size_t j = 0; j < n; j++)
            s += a->A[i * n + j] * x[j];
        for (size_t j = 0; j < N_IN; j++)
            s += a->B[i * N_IN + j] * a->u[j];
        dx[i] = s;
    }
}

static void rk4(Linear *a, double h)
{
    const size_t n = (size_t)a->n;
    double k1[N_MAX], k2[N_MAX], k3[N_MAX], k4[N_MAX], tmp[N_MAX];
    derivative(a, a->x, k1);
    for (size_t i = 0; i < n; i++)
        tmp[i] = a->x[i] + 0.5 * h * k1[i];
    derivative(a, tmp, k2);
    for (size_t i = 0; i < n; i++)
        tmp[i] = a->x[i] + 0.5 * h * k2[i];
    derivative(a, tmp, k3);
    for (size_t i = 0; i < n; i++)
        tmp[i] = a->x[i] + h * k3[i];
    derivative(a, tmp, k4);
    for (size_t i = 0; i < n; i++)
        a->x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
}

/* The values of a Float64 variable and how many there are, or NULL. */
static double *float64_values(Linear *a, fmi3ValueReference vr, size_t *size)
{
    const size_t n = (size_t)a->n;
    switch (vr) {
    case VR_TIME: *size = 1; return &a->time;
    case VR_A: *size = n * n; return a->A;
    case VR_B: *size = n * N_IN; return a->B;
    case VR_C: *size = N_OUT * n; return a->C;
    case VR_D: *size = N_OUT * N_IN; return a->D;
    case VR_X0: *size = n; return a->x0;
    case VR_U: *size = N_IN; return a->u;
    case VR_Y: *size = N_OUT; return a->y;
    case VR_X: *size = n; return a->x;
    case VR_T_NAN: *size = 1; return &a->t_nan;
    case VR_T_FAIL: *size = 1; return &a->t_fail;
    case VR_W: *size = 1; return &a->w;
    case VR_S: *size = 1; return &a->s;
    default: return NULL;
    }
}

static bool is_parameter(fmi3ValueReference vr)
{
    return vr == VR_A || vr == VR_B || vr == VR_C || vr == VR_D || vr == VR_X0 || vr == VR_T_NAN
        || vr == VR_T_FAIL;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
    fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate)
{
    (void)instanceName; (void)resourcePath; (void)visible; (void)loggingOn; (void)eventModeUsed;
    (void)earlyReturnAllowed; (void)requiredIntermediateVariables; (void)intermediateUpdate;
    if (nRequiredIntermediateVariables || strcmp(instantiationToken, "{cw-fmi3-linear}") != 0)
        return NULL;
    Linear *a = calloc(1, sizeof *a);
    if (!a)
        return NULL;
    defaults(a);
    a->env = instanceEnvironment;
    a->log = logMessage;
    return a;
}

void fmi3FreeInstance(fmi3Instance instance) { free(instance); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    Linear *a = instance;
    a->time = startTime;
    a->mode = INITIALIZATION;
    memcpy(a->x, a->x0, sizeof a->x);
    outputs(a);
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    Linear *a = instance;
    memcpy(a->x, a->x0, sizeof a->x);
    a->mode = STEPPING;
    outputs(a);
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance) { (void)instance; return fmi3OK; }
fmi3Status fmi3Reset(fmi3Instance instance) { defaults(instance); return fmi3OK; }

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    Linear *a = instance;
    *eventHandlingNeeded = false;
    *terminateSimulation = false;
    *earlyReturn = false;
    *lastSuccessfulTime = a->time;
    if (a->mode != STEPPING)
        return fail(a, "fmi3DoStep: not in step mode");
    if (currentCommunicationPoint != a->time)
        return fail(a, "fmi3DoStep: the communication point is not the FMU's time");
    const double end = currentCommunicationPoint + communicationStepSize;
#ifdef CW_HOSTILE_LOG  /* tests/test_fmu_crash.py: unreadable strings and environments to the logger */
    if (a->log) {
        a->log((fmi3InstanceEnvironment)1, fmi3OK, (fmi3String)16, (fmi3String)24);
        a->log(NULL, fmi3OK, NULL, NULL);
    }
#endif
    if (end > a->t_fail) {
#ifdef CW_CRASH_AFTER_T_FAIL  /* tests/test_fmu_crash.py: a NULL dereference instead */
        *(volatile int *)(a->t_fail > 0 ? NULL : a) = 1;
#endif
        char text[120];
        snprintf(text, sizeof text, "the model fails after t_fail = %.17g s", a->t_fail);
        return fail(a, text);
    }
    while (a->time < end) {
        const double h = fmin(H_MAX, end - a->time);
        const bool last = h == end - a->time;
        rk4(a, h);
        a->time = last ? end : a->time + h;
    }
    *lastSuccessfulTime = a->time;
    outputs(a);
    return fmi3OK;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 values[],
                          size_t nValues)
{
    Linear *a = instance;
    size_t at = 0, size;
    for (size_t i = 0; i < nvr; i++) {
        const double *v = float64_values(a, vr[i], &size);
        if (!v)
            return fail(a, "fmi3GetFloat64: not a Float64 variable");
        if (at + size > nValues)
            return fail(a, "fmi3GetFloat64: nValues is less than the sizes of the variables");
        memcpy(values + at, v, size * sizeof *v);
        at += size;
    }
    if (at != nValues)
        return fail(a, "fmi3GetFloat64: nValues is more than the sizes of the variables");
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Float64 values[], size_t nValues)
{
    Linear *a = instance;
    size_t at = 0, size;
    for (size_t i = 0; i < nvr; i++) {
        double *v = float64_values(a, vr[i], &size);
        if (!v || !(vr[i] == VR_U || vr[i] == VR_W || (is_parameter(vr[i]) && a->mode != STEPPING)))
            return fail(a, "fmi3SetFloat64: not a variable that can be set now");
        if (at + size > nValues)
            return fail(a, "fmi3SetFloat64: nValues is less than the sizes of the variables");
        memcpy(v, values + at, size * sizeof *v);
        at += size;
    }
    if (at != nValues)
        return fail(a, "fmi3SetFloat64: nValues is more than the sizes of the variables");
    outputs(a);
    return fmi3OK;
}

/* d^order x/dt^order (order 1 or 2, the input held): dx = A x + B u, ddx = A dx. */
static void state_derivative(const Linear *a, int order, double *out)
{
    const size_t n = (size_t)a->n;
    double dx[N_MAX];
    derivative(a, a->x, dx);
    for (size_t i = 0; i < n; i++) {
        double s = dx[i];
        if (order == 2) {
            s = 0.0;
            for (size_t j = 0; j < n; j++)
                s += a->A[i * n + j] * dx[j];
        }
        out[i] = s;
    }
}

/* Derivatives of x and of y = C x + D u (orders 1 and 2); checks nValues as the getters do. */
fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues)
{
    Linear *a = instance;
    const size_t n = (size_t)a->n;
    size_t at = 0;
    for (size_t i = 0; i < nvr; i++) {
        double d[N_MAX];
        if ((vr[i] != VR_X && vr[i] != VR_Y) || orders[i] < 1 || orders[i] > 2)
            return fail(a, "fmi3GetOutputDerivatives: only x and y, of order 1 or 2");
        const size_t size = vr[i] == VR_X ? n : N_OUT;
        if (at + size > nValues)
            return fail(a, "fmi3GetOutputDerivatives: nValues is less than the sizes of the variables");
        state_derivative(a, orders[i], d);
        for (size_t k = 0; k < size; k++) {
            double s = d[k];
            if (vr[i] == VR_Y) {
                s = 0.0;
                for (size_t j = 0; j < n; j++)
                    s += a->C[k * n + j] * d[j];
            }
            values[at + k] = s;
        }
        at += size;
    }
    if (at != nValues)
        return fail(a, "fmi3GetOutputDerivatives: nValues is more than the sizes of the variables");
    return fmi3OK;
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Int32 values[],
                        size_t nValues)
{
    Linear *a = instance;
    if (nValues != N_K * nvr)
        return fail(a, "fmi3GetInt32: nValues is not the sizes of the variables");
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] != VR_K && vr[i] != VR_KK)
            return fail(a, "fmi3GetInt32: not an Int32 variable");
        memcpy(values + N_K * i, a->k, sizeof a->k);  /* kk mirrors k */
    }
    return fmi3OK;
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Int32 values[],
                        size_t nValues)
{
    Linear *a = instance;
    if (nvr != 1 || vr[0] != VR_K || nValues != N_K)
        return fail(a, "fmi3SetInt32: only the input k (3 values) can be set");
    memcpy(a->k, values, sizeof a->k);
    return fmi3OK;
}

fmi3Status fmi3GetUInt64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3UInt64 values[],
                         size_t nValues)
{
    Linear *a = instance;
    if (nvr != nValues)
        return fail(a, "fmi3GetUInt64: nValues != nValueReferences");
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] != VR_N)
            return fail(a, "fmi3GetUInt64: not a UInt64 variable");
        values[i] = a->n;
    }
    return fmi3OK;
}

fmi3Status fmi3SetUInt64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                         const fmi3UInt64 values[], size_t nValues)
{
    (void)vr; (void)nvr; (void)values; (void)nValues;
    return fail(instance, "fmi3SetUInt64: the structural parameter n is set in configuration mode only");
}
