/* C test driver for the FMI 3.0 build of one clockwork FMU, run by ctest.
 *
 *   fmu_driver3_<Model> path/to/fmi3/<Model>.so
 *
 * Loads the binary with dlopen and drives it through the FMI 3.0 API:
 * refused instantiations, the lifecycle with and without Event Mode and
 * early return, a long random sequence of calls in any order (every status
 * is OK, Discard or Error, and every Error comes with a logged message),
 * the functions the FMU does not provide, and the FMU state (restored bit
 * for bit, in the same and a fresh instance; a corrupt buffer refused).
 * Built with CW_SANITIZE=ON it runs under AddressSanitizer,
 * UndefinedBehaviorSanitizer and LeakSanitizer (the FMI 3.0 build
 * allocates with calloc/free, which they watch).
 *
 * Compiled once per model against the model's generated cw_vars.h, for the
 * variable table; nothing else here is model specific. */
#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3FunctionTypes.h"

#define CW_VARS_TABLE_ONLY
#include "cw_vars.h"
#include "driver_checks.h"

#define FMI3_FUNCTIONS(X)                                                     \
    X(GetVersion) X(SetDebugLogging) X(InstantiateModelExchange)              \
    X(InstantiateCoSimulation) X(InstantiateScheduledExecution)               \
    X(FreeInstance) X(EnterInitializationMode) X(ExitInitializationMode)      \
    X(EnterEventMode) X(Terminate) X(Reset) X(GetFloat32) X(GetFloat64)       \
    X(GetInt8) X(GetUInt8) X(GetInt16) X(GetUInt16) X(GetInt32) X(GetUInt32)  \
    X(GetInt64) X(GetUInt64) X(GetBoolean) X(GetString) X(GetBinary)          \
    X(GetClock) X(SetFloat32) X(SetFloat64) X(SetInt8) X(SetUInt8)            \
    X(SetInt16) X(SetUInt16) X(SetInt32) X(SetUInt32) X(SetInt64)             \
    X(SetUInt64) X(SetBoolean) X(SetString) X(SetBinary) X(SetClock)          \
    X(GetNumberOfVariableDependencies) X(GetVariableDependencies)             \
    X(GetFMUState) X(SetFMUState) X(FreeFMUState)                             \
    X(SerializedFMUStateSize) X(SerializeFMUState) X(DeserializeFMUState)     \
    X(GetDirectionalDerivative) X(GetAdjointDerivative)                       \
    X(EnterConfigurationMode) X(ExitConfigurationMode) X(GetIntervalDecimal)  \
    X(GetIntervalFraction) X(GetShiftDecimal) X(GetShiftFraction)             \
    X(SetIntervalDecimal) X(SetIntervalFraction) X(SetShiftDecimal)           \
    X(SetShiftFraction) X(EvaluateDiscreteStates) X(UpdateDiscreteStates)     \
    X(EnterContinuousTimeMode) X(CompletedIntegratorStep) X(SetTime)          \
    X(SetContinuousStates) X(GetContinuousStateDerivatives)                   \
    X(GetEventIndicators) X(GetContinuousStates)                              \
    X(GetNominalsOfContinuousStates) X(GetNumberOfEventIndicators)            \
    X(GetNumberOfContinuousStates) X(EnterStepMode) X(GetOutputDerivatives)   \
    X(DoStep) X(ActivateModelPartition)

static struct {
#define FIELD(n) fmi3##n##TYPE *n;
    FMI3_FUNCTIONS(FIELD)
#undef FIELD
} api;

static void logger(fmi3InstanceEnvironment env, fmi3Status status,
                   fmi3String category, fmi3String message) {
    if (env != &n_messages) {
        fprintf(stderr, "logger called without the instanceEnvironment\n");
        abort();
    }
    if (!message || !category) abort();
    n_messages++;
    if (status >= fmi3Error) n_errors++;
    snprintf(last, sizeof last, "%s", message);
}

static fmi3Instance instantiate(const char *name, int event_mode, int early) {
    return api.InstantiateCoSimulation(name, CW_MODEL_GUID, NULL, fmi3False,
                                       fmi3False, event_mode, early, NULL, 0,
                                       &n_messages, logger, NULL);
}

static void set_inputs(fmi3Instance c, double t) {
    for (int k = 0; k < CW_NVARS; k++) {
        const cw_var_info *v = &CW_VARS[k];
        if (!v->name || v->causality != CW_INPUT || v->type != CW_REAL) continue;
        fmi3ValueReference vr = v->vr;
        double x = input_value(v, t);
        CHECK(api.SetFloat64(c, &vr, 1, &x, 1) == fmi3OK, "set %s", v->name);
    }
}

/* Every Float64 output, bit for bit comparable. */
static int outputs(fmi3Instance c, double *out) {
    int n = 0;
    for (int k = 0; k < CW_NVARS; k++) {
        const cw_var_info *v = &CW_VARS[k];
        if (!v->name || v->causality != CW_OUTPUT || v->type != CW_REAL) continue;
        fmi3ValueReference vr = v->vr;
        CHECK(api.GetFloat64(c, &vr, 1, &out[n], 1) == fmi3OK, "get %s", v->name);
        CHECK(isfinite(out[n]), "%s is not finite", v->name);
        n++;
    }
    return n;
}

static void settle(fmi3Instance c) {
    fmi3Boolean f[5];
    fmi3Float64 next;
    CHECK(api.UpdateDiscreteStates(c, &f[0], &f[1], &f[2], &f[3], &f[4], &next) == fmi3OK,
          "update");
    CHECK(!f[0] && !f[1] && !f[4], "one pass settles, no time event");
    CHECK(api.EnterStepMode(c) == fmi3OK, "enter step mode");
}

static void lifecycle(int event_mode, int early) {
    section = "lifecycle";
    fmi3Instance c = instantiate("life", event_mode, early);
    CHECK(c != NULL, "instantiate");
    if (!c) return;
    CHECK(api.EnterInitializationMode(c, fmi3False, 0, 0.0, fmi3True, 20.0) == fmi3OK, "enter init");
    set_inputs(c, 0.0);
    CHECK(api.ExitInitializationMode(c) == fmi3OK, "exit init");
    if (event_mode) settle(c);
    double t = 0.0, h = 0.05, a[CW_NVARS], b[CW_NVARS];
    fmi3FMUState saved = NULL;
    double t_saved = 0;
    int early_returns = 0;
    for (int n = 0; n < 200 && t < 19.0; n++) {
        if (n == 100) {
            CHECK(api.GetFMUState(c, &saved) == fmi3OK, "get state");
            t_saved = t;
        }
        set_inputs(c, t);
        fmi3Boolean event, terminate, returned;
        fmi3Float64 last_t;
        CHECK(api.DoStep(c, t, h, fmi3False, &event, &terminate, &returned, &last_t) == fmi3OK,
              "step at %g", t);
        CHECK(!terminate, "terminate");
        if (returned) {
            early_returns++;
            CHECK(early && last_t > t && last_t < t + h, "early return inside the step");
            CHECK(event == (event_mode != 0), "eventHandlingNeeded with Event Mode only");
        } else {
            CHECK(!event && last_t == t + h, "a full step");
        }
        t = last_t;
        if (event) {
            CHECK(api.EnterEventMode(c) == fmi3OK, "enter event mode");
            settle(c);
        }
        if (n == 150) outputs(c, a);
    }
    /* Back to the saved state: the same steps give the same bits. */
    if (saved) {
        CHECK(api.SetFMUState(c, saved) == fmi3OK, "set state");
        size_t size = 0;
        CHECK(api.SerializedFMUStateSize(c, saved, &size) == fmi3OK && size > 0, "size");
        fmi3Byte *buf = malloc(size);
        CHECK(api.SerializeFMUState(c, saved, buf, size) == fmi3OK, "serialize");
        fmi3Instance twin = instantiate("twin", event_mode, early);
        fmi3FMUState copy = NULL;
        CHECK(twin && api.DeserializeFMUState(twin, buf, size, &copy) == fmi3OK, "deserialize");
        buf[size / 2] ^= 0x10;
        fmi3FMUState bad = NULL;
        REFUSED(api.DeserializeFMUState(twin, buf, size, &bad), "a corrupt state");
        CHECK(bad == NULL, "nothing made of a corrupt state");
        CHECK(api.SetFMUState(twin, copy) == fmi3OK, "the twin takes the good one");
        fmi3Instance both[2] = {c, twin};
        for (int i = 0; i < 2; i++) {
            double tt = t_saved;
            for (int n = 100; n <= 150; n++) {
                set_inputs(both[i], tt);
                fmi3Boolean event, terminate, returned;
                fmi3Float64 last_t;
                api.DoStep(both[i], tt, h, fmi3False, &event, &terminate, &returned, &last_t);
                tt = last_t;
                if (event) {
                    api.EnterEventMode(both[i]);
                    settle(both[i]);
                }
            }
            if (!early) { /* with early returns the step count differs; compared above by fmpy */
                int m = outputs(both[i], b);
                CHECK(memcmp(a, b, sizeof(double) * (size_t)m) == 0, "same bits after restore (%d)", i);
            }
        }
        CHECK(api.FreeFMUState(c, &saved) == fmi3OK && saved == NULL, "free state");
        CHECK(api.FreeFMUState(twin, &copy) == fmi3OK, "free copy");
        api.FreeInstance(twin);
        free(buf);
    }
    if (!early) CHECK(early_returns == 0, "no early return unless allowed");
    CHECK(api.Terminate(c) == fmi3OK, "terminate");
    REFUSED(api.Terminate(c), "terminate twice");
    CHECK(api.Reset(c) == fmi3OK, "reset");
    api.FreeInstance(c);
}

static void refused_instantiations(void) {
    section = "instantiation";
    long before = n_errors;
    CHECK(!api.InstantiateCoSimulation("x", "{wrong}", NULL, 0, 0, 0, 0, NULL, 0,
                                       &n_messages, logger, NULL) && n_errors > before,
          "wrong token");
    before = n_errors;
    CHECK(!api.InstantiateCoSimulation("", CW_MODEL_GUID, NULL, 0, 0, 0, 0, NULL, 0,
                                       &n_messages, logger, NULL) && n_errors > before,
          "empty name");
    before = n_errors;
    fmi3ValueReference vr = 0;
    CHECK(!api.InstantiateCoSimulation("x", CW_MODEL_GUID, NULL, 0, 0, 0, 0, &vr, 1,
                                       &n_messages, logger, NULL) && n_errors > before,
          "intermediate variables");
    before = n_errors;
    CHECK(!api.InstantiateModelExchange("x", CW_MODEL_GUID, NULL, 0, 0, &n_messages, logger) &&
              n_errors > before,
          "Model Exchange");
    fmi3Instance quiet = api.InstantiateCoSimulation("q", CW_MODEL_GUID, NULL, 0, 0, 0, 0, NULL,
                                                     0, NULL, NULL, NULL);
    CHECK(quiet != NULL, "an instance without a logger");
    if (quiet) {
        CHECK(api.DoStep(quiet, 0, 1, 0, NULL, NULL, NULL, NULL) == fmi3Error, "silently refused");
        api.FreeInstance(quiet);
    }
    api.FreeInstance(NULL);
}

static void not_provided(void) {
    section = "not provided";
    fmi3Instance c = instantiate("np", 0, 0);
    if (!c) return;
    fmi3ValueReference vr = 0;
    fmi3UInt64 u = 0;
    fmi3Float64 d = 0;
    size_t n = 0;
    REFUSED(api.GetUInt64(c, &vr, 1, &u, 1), "GetUInt64");
    REFUSED(api.SetUInt64(c, &vr, 1, &u, 1), "SetUInt64");
    REFUSED(api.GetClock(c, &vr, 1, (fmi3Clock *)&u), "GetClock");
    REFUSED(api.EnterConfigurationMode(c), "EnterConfigurationMode");
    REFUSED(api.GetDirectionalDerivative(c, &vr, 1, &vr, 1, &d, 1, &d, 1), "directional");
    REFUSED(api.GetNumberOfEventIndicators(c, &n), "ME function");
    REFUSED(api.SetTime(c, 1.0), "SetTime");
    REFUSED(api.EnterEventMode(c), "no eventModeUsed");
    REFUSED(api.ExitInitializationMode(c), "exit without enter");
    REFUSED(api.GetFloat64(c, &vr, 1, &d, 1), "get in Instantiated");
    api.FreeInstance(c);
}

/* Any order: a long random walk over the state machine's functions. */
static void random_walk(int event_mode) {
    section = "random order";
    fmi3Instance c = instantiate("walk", event_mode, 1);
    if (!c) return;
    uint64_t rng = 0x9E3779B97F4A7C15ull ^ (uint64_t)event_mode;
    double t = 0.0;
    fmi3FMUState state = NULL;
    for (int n = 0; n < 3000; n++) {
        rng ^= rng << 13, rng ^= rng >> 7, rng ^= rng << 17;
        int pick = (int)(rng % 13);
        long before = n_errors;
        fmi3Status st = fmi3OK;
        fmi3Boolean f[5];
        fmi3Float64 x = 0.0;
        fmi3ValueReference vr = (fmi3ValueReference)((rng >> 8) % (CW_NVARS + 2));
        switch (pick) {
        case 0: st = api.EnterInitializationMode(c, 0, 0, t, 0, 0); break;
        case 1: st = api.ExitInitializationMode(c); break;
        case 2: st = api.EnterEventMode(c); break;
        case 3: st = api.UpdateDiscreteStates(c, &f[0], &f[1], &f[2], &f[3], &f[4], &x); break;
        case 4: st = api.EnterStepMode(c); break;
        case 5: st = api.DoStep(c, t, 0.07, 0, &f[0], &f[1], &f[2], &x);
                if (st == fmi3OK) t = x;
                break;
        case 6: st = api.Terminate(c); break;
        case 7: st = api.Reset(c); if (st == fmi3OK) t = 0.0; break;
        case 8: st = api.GetFloat64(c, &vr, 1, &x, 1); break;
        case 9: x = 1e-3; st = api.SetFloat64(c, &vr, 1, &x, 1); break;
        case 10: st = api.GetFMUState(c, &state); break;
        case 11: st = state ? api.SetFMUState(c, state) : fmi3OK; break;
        case 12: st = api.GetOutputDerivatives(c, &vr, 1, (fmi3Int32[]){1}, &x, 1); break;
        }
        CHECK(st == fmi3OK || st == fmi3Discard || st == fmi3Error, "status %d", (int)st);
        if (st == fmi3Error) CHECK(n_errors > before, "call %d refused without a message", pick);
        if (pick == 11 && st == fmi3OK) { /* the restored state's time */
            fmi3ValueReference tv = CW_NVARS;
            api.GetFloat64(c, &tv, 1, &t, 1);
        }
    }
    if (state) api.FreeFMUState(c, &state);
    api.FreeInstance(c);
}

int main(int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: %s path/to/fmi3/<Model>.so\n", argv[0]);
        return 2;
    }
    void *lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "dlopen: %s\n", dlerror());
        return 2;
    }
#define LOAD(n)                                                              \
    api.n = (fmi3##n##TYPE *)dlsym(lib, "fmi3" #n);                          \
    if (!api.n) {                                                            \
        fprintf(stderr, "missing fmi3" #n "\n");                             \
        n_failures++;                                                        \
    }
    FMI3_FUNCTIONS(LOAD)
#undef LOAD
    if (n_failures) return 1;
    CHECK(strcmp(api.GetVersion(), "3.0") == 0, "version");
    refused_instantiations();
    not_provided();
    for (int e = 0; e < 2; e++)
        for (int r = 0; r < 2; r++) lifecycle(e, r);
    random_walk(0);
    random_walk(1);
    printf("%s (FMI 3.0): %ld checks, %ld failures, %ld messages\n", CW_MODEL_NAME, n_checks,
           n_failures, n_messages);
    dlclose(lib);
    return n_failures ? 1 : 0;
}
