/* AllTypes: a small FMI 3.0 Co-Simulation FMU with a variable of every
 * FMI 3.0 type the master exchanges, for the master's type tests.
 *
 * For each type T (in the order of TYPES below, index k) there are three
 * variables: a parameter p_T (value reference 1 + 3k), an input u_T
 * (2 + 3k) and an output y_T (3 + 3k) that mirrors u_T. A get or set of a
 * value reference through the function of another type is an error, so
 * that the tests see a master that uses the wrong fmi3Get/Set function.
 */

#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"

enum { F32, F64, I8, U8, I16, U16, I32, U32, I64, U64, BOOL, STR, BIN, ENUM, NTYPES };
enum { PARAMETER, INPUT, OUTPUT };
#define NVARS (1 + 3 * NTYPES)
#define TEXT_MAX 256

typedef struct {
    double f64;
    float f32;
    int64_t i64;
    uint64_t u64;  /* UInt8..UInt64 */
    bool b;
    char text[TEXT_MAX];
    size_t size;   /* Binary: bytes in text */
} Value;

typedef struct {
    double time;
    Value v[NVARS];  /* by value reference; an output's own slot is unused */
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
} AllTypes;

static fmi3Status fail(AllTypes *a, const char *message)
{
    if (a->log)
        a->log(a->env, fmi3Error, "logStatusError", message);
    return fmi3Error;
}

/* The slot a value reference of type `type` reads (an output reads its
 * input), or NULL when the reference is not of that type. */
static Value *slot(AllTypes *a, fmi3ValueReference vr, int type, bool writing)
{
    if (vr < 1 || vr >= NVARS || (int)((vr - 1) / 3) != type)
        return NULL;
    int role = (int)((vr - 1) % 3);
    if (writing && role == OUTPUT)
        return NULL;
    return &a->v[role == OUTPUT ? vr - 1 : vr];
}

static void defaults(AllTypes *a)
{
    memset(a->v, 0, sizeof a->v);
    a->time = 0.0;
    for (int role = PARAMETER; role <= INPUT; role++) {
        strcpy(a->v[1 + 3 * STR + role].text, "start");
        a->v[1 + 3 * ENUM + role].i64 = 1;
    }
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
    fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate)
{
    (void)instanceName; (void)resourcePath; (void)visible; (void)loggingOn; (void)eventModeUsed;
    (void)earlyReturnAllowed; (void)requiredIntermediateVariables; (void)intermediateUpdate;
    if (nRequiredIntermediateVariables || strcmp(instantiationToken, "{cw-fmi3-alltypes}") != 0)
        return NULL;
    AllTypes *a = calloc(1, sizeof *a);
    if (!a)
        return NULL;
    defaults(a);
    a->env = instanceEnvironment;
    a->log = logMessage;
    return a;
}

void fmi3FreeInstance(fmi3Instance instance) { free(instance); }
const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[])
{
    (void)instance; (void)loggingOn; (void)nCategories; (void)categories;
    return fmi3OK;
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    ((AllTypes *)instance)->time = startTime;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) { (void)instance; return fmi3OK; }
fmi3Status fmi3Terminate(fmi3Instance instance) { (void)instance; return fmi3OK; }
fmi3Status fmi3Reset(fmi3Instance instance) { defaults(instance); return fmi3OK; }

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    AllTypes *a = instance;
    if (currentCommunicationPoint != a->time)
        return fail(a, "fmi3DoStep: the communication point is not the FMU's time");
    a->time = currentCommunicationPoint + communicationStepSize;
    *eventHandlingNeeded = false;
    *terminateSimulation = false;
    *earlyReturn = false;
    *lastSuccessfulTime = a->time;
    return fmi3OK;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 values[],
                          size_t nValues)
{
    AllTypes *a = instance;
    if (nvr != nValues)
        return fail(a, "fmi3GetFloat64: nValues != nValueReferences");
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] == 0) { values[i] = a->time; continue; }
        Value *s = slot(a, vr[i], F64, false);
        if (!s)
            return fail(a, "fmi3GetFloat64: not a Float64 variable");
        values[i] = s->f64;
    }
    return fmi3OK;
}

/* Getters and setters of the number types: one per type, same shape. */
#define NUMBER_ACCESS(Name, ctype, type, field)                                                               \
    fmi3Status fmi3Get##Name(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, ctype values[], \
                             size_t nValues)                                                                  \
    {                                                                                                         \
        AllTypes *a = instance;                                                                               \
        if (nvr != nValues)                                                                                   \
            return fail(a, "fmi3Get" #Name ": nValues != nValueReferences");                                  \
        for (size_t i = 0; i < nvr; i++) {                                                                    \
            Value *s = slot(a, vr[i], type, false);                                                           \
            if (!s)                                                                                           \
                return fail(a, "fmi3Get" #Name ": not a variable of this type");                              \
            values[i] = (ctype)s->field;                                                                      \
        }                                                                                                     \
        return fmi3OK;                                                                                        \
    }                                                                                                         \
    fmi3Status fmi3Set##Name(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,                \
                             const ctype values[], size_t nValues)                                            \
    {                                                                                                         \
        AllTypes *a = instance;                                                                               \
        if (nvr != nValues)                                                                                   \
            return fail(a, "fmi3Set" #Name ": nValues != nValueReferences");                                  \
        for (size_t i = 0; i < nvr; i++) {                                                                    \
            Value *s = slot(a, vr[i], type, true);                                                            \
            if (!s)                                                                                           \
                return fail(a, "fmi3Set" #Name ": not a settable variable of this type");                     \
            s->field = values[i];                                                                             \
        }                                                                                                     \
        return fmi3OK;                                                                                        \
    }

NUMBER_ACCESS(Float32, fmi3Float32, F32, f32)
NUMBER_ACCESS(Int8, fmi3Int8, I8, i64)
NUMBER_ACCESS(UInt8, fmi3UInt8, U8, u64)
NUMBER_ACCESS(Int16, fmi3Int16, I16, i64)
NUMBER_ACCESS(UInt16, fmi3UInt16, U16, u64)
NUMBER_ACCESS(Int32, fmi3Int32, I32, i64)
NUMBER_ACCESS(UInt32, fmi3UInt32, U32, u64)
NUMBER_ACCESS(UInt64, fmi3UInt64, U64, u64)
NUMBER_ACCESS(Boolean, fmi3Boolean, BOOL, b)

/* Int64 serves both Int64 and Enumeration variables. */
fmi3Status fmi3GetInt64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Int64 values[],
                        size_t nValues)
{
    AllTypes *a = instance;
    if (nvr != nValues)
        return fail(a, "fmi3GetInt64: nValues != nValueReferences");
    for (size_t i = 0; i < nvr; i++) {
        Value *s = slot(a, vr[i], I64, false);
        if (!s)
            s = slot(a, vr[i], ENUM, false);
        if (!s)
            return fail(a, "fmi3GetInt64: not an Int64 or Enumeration variable");
        values[i] = s->i64;
    }
    return fmi3OK;
}

fmi3Status fmi3SetInt64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Int64 values[],
                        size_t nValues)
{
    AllTypes *a = instance;
    if (nvr != nValues)
        return fail(a, "fmi3SetInt64: nValues != nValueReferences");
    for (size_t i = 0; i < nvr; i++) {
        Value *s = slot(a, vr[i], I64, true);
        if (!s) {
            s = slot(a, vr[i], ENUM, true);
            if (s && (values[i] < 1 || values[i] > 3))
                return fail(a, "fmi3SetInt64: not an item of the Enumeration (1, 2, 3)");
        }
        if (!s)
            return fail(a, "fmi3SetInt64: not a settable Int64 or Enumeration variable");
        s->i64 = values[i];
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Float64 values[], size_t nValues)
{
    AllTypes *a = instance;
    if (nvr != nValues)
        return fail(a, "fmi3SetFloat64: nValues != nValueReferences");
    for (size_t i = 0; i < nvr; i++) {
        Value *s = slot(a, vr[i], F64, true);
        if (!s)
            return fail(a, "fmi3SetFloat64: not a settable Float64 variable");
        s->f64 = values[i];
    }
    return fmi3OK;
}

fmi3Status fmi3GetString(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3String values[],
                         size_t nValues)
{
    AllTypes *a = instance;
    if (nvr != nValues)
        return fail(a, "fmi3GetString: nValues != nValueReferences");
    for (size_t i = 0; i < nvr; i++) {
        Value *s = slot(a, vr[i], STR, false);
        if (!s)
            return fail(a, "fmi3GetString: not a String variable");
        values[i] = s->text;
    }
    return fmi3OK;
}

fmi3Status fmi3SetString(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                         const fmi3String values[], size_t nValues)
{
    AllTypes *a = instance;
    if (nvr != nValues)
        return fail(a, "fmi3SetString: nValues != nValueReferences");
    for (size_t i = 0; i < nvr; i++) {
        Value *s = slot(a, vr[i], STR, true);
        if (!s || !values[i] || strlen(values[i]) >= TEXT_MAX)
            return fail(a, "fmi3SetString: not a settable String variable, or NULL, or too long");
        strcpy(s->text, values[i]);
    }
    return fmi3OK;
}

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, size_t valueSizes[],
                         fmi3Binary values[], size_t nValues)
{
    AllTypes *a = instance;
    if (nvr != nValues)
        return fail(a, "fmi3GetBinary: nValues != nValueReferences");
    for (size_t i = 0; i < nvr; i++) {
        Value *s = slot(a, vr[i], BIN, false);
        if (!s)
            return fail(a, "fmi3GetBinary: not a Binary variable");
        valueSizes[i] = s->size;
        values[i] = (fmi3Binary)s->text;
    }
    return fmi3OK;
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues)
{
    AllTypes *a = instance;
    if (nvr != nValues)
        return fail(a, "fmi3SetBinary: nValues != nValueReferences");
    for (size_t i = 0; i < nvr; i++) {
        Value *s = slot(a, vr[i], BIN, true);
        if (!s || valueSizes[i] > TEXT_MAX || (valueSizes[i] && !values[i]))
            return fail(a, "fmi3SetBinary: not a settable Binary variable, or too long");
        memcpy(s->text, values[i], valueSizes[i]);
        s->size = valueSizes[i];
    }
    return fmi3OK;
}
