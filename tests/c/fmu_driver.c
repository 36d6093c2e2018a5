/* C test driver for one clockwork FMU binary, run by ctest.
 *
 *   fmu_driver_<Model> path/to/<Model>.so
 *
 * Loads the binary with dlopen and drives it through the FMI 2.0 API with
 * its own logger and a counting allocator: lifecycle and refused
 * instantiations, calls in the wrong state, bad values, failed allocations,
 * and the FMU state (continuation bit for bit in a fresh instance, refusal
 * of truncated and corrupted buffers, every state freed). Built with
 * CW_SANITIZE=ON it runs under AddressSanitizer, UndefinedBehaviorSanitizer
 * and LeakSanitizer, so that a leak or memory error inside the FMU fails
 * the test as well.
 *
 * Compiled once per model against the model's generated cw_vars.h, which
 * provides the variable table; nothing else here is model specific. */
#include <dlfcn.h>
#include <float.h>

#include "harness.h"

static fmi_api api;
static h_log LOG;
static fmi2CallbackFunctions CB;
static long n_checks, n_failures;
static const char *section = "";

static void fail_at(int line, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

static void fail_at(int line, const char *fmt, ...) {
    va_list ap;
    n_failures++;
    fprintf(stderr, "FAIL [%s] line %d: ", section, line);
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fprintf(stderr, " (last message: %s)\n", LOG.last);
}

#define CHECK(cond, ...)                                                     \
    do {                                                                     \
        n_checks++;                                                          \
        if (!(cond)) fail_at(__LINE__, __VA_ARGS__);                         \
    } while (0)

/* A call refused with fmi2Error must say why through the logger. */
#define CHECK_REFUSED(call, ...)                                             \
    do {                                                                     \
        long errors_before_ = LOG.n_errors;                                  \
        fmi2Status st_ = (call);                                             \
        CHECK(st_ == fmi2Error, __VA_ARGS__);                                \
        if (st_ != fmi2Error) fprintf(stderr, "  -> not refused: %d\n", st_); \
        CHECK(LOG.n_errors > errors_before_, __VA_ARGS__);                   \
        if (LOG.n_errors == errors_before_)                                  \
            fprintf(stderr, "  -> refused without a logged error\n");        \
    } while (0)

#define CHECK_OK(call, ...)                                                  \
    do {                                                                     \
        fmi2Status st_ = (call);                                             \
        CHECK(st_ == fmi2OK, __VA_ARGS__);                                   \
        if (st_ != fmi2OK) fprintf(stderr, "  -> status %d\n", st_);         \
    } while (0)

static const double STEP = 0.01; /* communication step, s */

/* ------------------------------------------------------------------ */
/* Instances */

typedef struct {
    fmi2Component c;
    double t; /* the master's time */
} inst;

enum {
    ST_INSTANTIATED = 1 << 0,
    ST_INIT = 1 << 1,
    ST_STEP_COMPLETE = 1 << 2,
    ST_STEP_FAILED = 1 << 3,
    ST_TERMINATED = 1 << 4,
    ST_ERROR = 1 << 5,
    ST_ALL = 63
};

static const char *st_name(int s) {
    switch (s) {
    case ST_INSTANTIATED: return "Instantiated";
    case ST_INIT: return "InitializationMode";
    case ST_STEP_COMPLETE: return "StepComplete";
    case ST_STEP_FAILED: return "StepFailed";
    case ST_TERMINATED: return "Terminated";
    case ST_ERROR: return "Error";
    }
    return "?";
}

static fmi2Component instantiate(const char *name) {
    return api.Instantiate(name, fmi2CoSimulation, CW_MODEL_GUID,
                           "file:///nonexistent", &CB, fmi2False, fmi2False);
}

static fmi2Status set_real(fmi2Component c, unsigned vr, double x) {
    fmi2ValueReference v = vr;
    return api.SetReal(c, &v, 1, &x);
}

static double get_real(fmi2Component c, unsigned vr) {
    fmi2ValueReference v = vr;
    double x = NAN;
    api.GetReal(c, &v, 1, &x);
    return x;
}

/* Inputs follow smooth signals around their start values, given to the FMU
 * with first and second derivatives, so that the input polynomials are
 * part of every state. */
#define INPUT_AMPLITUDE 0.2

static void input_signal(int k, double t, double *u, double *d1, double *d2) {
    const double amp = INPUT_AMPLITUDE, w = 2.0 + 0.7 * k, ph = w * t + k;
    *u = amp * sin(ph);
    *d1 = amp * w * cos(ph);
    *d2 = -amp * w * w * sin(ph);
}

static fmi2Status drive_inputs(fmi2Component c, double t) {
    fmi2Status worst = fmi2OK;
    int k = 0;
    for (int vr = 0; vr < CW_NVARS; vr++) {
        const cw_var_info *v = &CW_VARS[vr];
        if (!v->name || v->type != CW_REAL || v->causality != CW_INPUT) continue;
        double u, d[2];
        input_signal(k++, t, &u, &d[0], &d[1]);
        /* Around the start value, moved inside [min, max] where the start
         * sits on a bound (the air's density starts at its minimum, 0). */
        const double center = fmin(fmax(v->start, v->min + INPUT_AMPLITUDE),
                                   v->max - INPUT_AMPLITUDE);
        fmi2Status st = set_real(c, (unsigned)vr, center + u);
        fmi2ValueReference vrs[2] = {(unsigned)vr, (unsigned)vr};
        fmi2Integer order[2] = {1, 2};
        if (st == fmi2OK) st = api.SetRealInputDerivatives(c, vrs, 2, order, d);
        if (st > worst) worst = st;
    }
    return worst;
}

/* Parameters that make a generic run exercise more of a model. */
static void interesting_parameters(fmi2Component c) {
    const cw_var_info *v = h_find("noise_rms");
    if (v) set_real(c, v->vr, 0.05); /* the RNG state becomes part of the state */
}

/* Fresh instance brought into machine state `s`; .c is NULL when this model
 * cannot reach it (StepFailed needs an integrator). */
static inst make(int s) {
    inst I = {NULL, 0.0};
    const cw_var_info *h_max = h_find("h_max");
    if (s == ST_STEP_FAILED && !h_max) return I;
    I.c = instantiate("driver");
    if (!I.c) h_abort("instantiate failed");
    if (s == ST_INSTANTIATED) return I;
    interesting_parameters(I.c);
    /* An internal step limit of 1e-300 s can never reach the next
     * communication point: the step is discarded. */
    if (s == ST_STEP_FAILED && set_real(I.c, h_max->vr, 1e-300) != fmi2OK)
        h_abort("cannot set h_max");
    if (api.SetupExperiment(I.c, fmi2False, 0.0, 0.0, fmi2False, 0.0) ||
        api.EnterInitializationMode(I.c))
        h_abort("cannot enter initialization mode");
    if (s == ST_INIT) return I;
    if (api.ExitInitializationMode(I.c)) h_abort("cannot initialize");
    if (s == ST_STEP_FAILED) {
        if (api.DoStep(I.c, 0.0, STEP, fmi2True) != fmi2Discard)
            h_abort("expected a discarded step");
        return I;
    }
    drive_inputs(I.c, 0.0);
    if (api.DoStep(I.c, 0.0, STEP, fmi2True)) h_abort("first step failed");
    I.t = STEP;
    if (s == ST_STEP_COMPLETE) return I;
    if (s == ST_TERMINATED) {
        if (api.Terminate(I.c)) h_abort("cannot terminate");
        return I;
    }
    /* Error: a refused value puts the instance into the error state. */
    for (int vr = 0; vr < CW_NVARS; vr++)
        if (CW_VARS[vr].name && CW_VARS[vr].causality == CW_INPUT &&
            CW_VARS[vr].type == CW_REAL) {
            if (set_real(I.c, (unsigned)vr, NAN) != fmi2Error)
                h_abort("NaN input accepted");
            return I;
        }
    h_abort("no Real input to provoke the error state");
    return I;
}

/* The machine state as recorded in a serialized state; ST_ERROR when the
 * FMU refuses to save its state (the runtime refuses only in Error). */
static int observed_state(fmi2Component c) {
    fmi2FMUstate s = NULL;
    long n = LOG.n_errors;
    if (api.GetFMUstate(c, &s) != fmi2OK) {
        LOG.n_errors = n;
        return ST_ERROR;
    }
    size_t size = 0;
    unsigned char buf[24] = {0};
    unsigned char *all = NULL;
    if (api.SerializedFMUstateSize(c, s, &size) == fmi2OK && size >= 24 &&
        (all = malloc(size)) != NULL &&
        api.SerializeFMUstate(c, s, (fmi2Byte *)all, size) == fmi2OK)
        memcpy(buf, all, 24);
    free(all);
    api.FreeFMUstate(c, &s);
    return (int)((uint32_t)buf[20] | (uint32_t)buf[21] << 8 |
                 (uint32_t)buf[22] << 16 | (uint32_t)buf[23] << 24);
}

/* One communication step with driven inputs; returns the DoStep status and
 * checks that a successful step left only fit values behind. */
static fmi2Status step(inst *I, h_values *after) {
    drive_inputs(I->c, I->t);
    fmi2Status st = api.DoStep(I->c, I->t, STEP, fmi2False);
    if (st <= fmi2Warning) {
        I->t += STEP;
        h_values v;
        h_read_all(&api, I->c, after ? after : &v);
        const char *bad = h_unfit_value(after ? after : &v);
        CHECK(!bad, "%s is not finite (or not a Boolean) after an OK step "
                    "at t = %g", bad, I->t);
    }
    return st;
}

static void free_inst(inst *I) {
    if (I->c) api.FreeInstance(I->c);
    I->c = NULL;
}

/* ------------------------------------------------------------------ */
/* Lifecycle */

static void test_lifecycle(void) {
    section = "lifecycle";
    CHECK(strcmp(api.GetVersion(), "2.0") == 0, "version %s", api.GetVersion());
    CHECK(strcmp(api.GetTypesPlatform(), "default") == 0, "types platform");

    long errors = LOG.n_errors;
    CHECK(api.Instantiate("x", fmi2CoSimulation, "{wrong}", "", &CB, 0, 0) == NULL,
          "wrong GUID accepted");
    CHECK(api.Instantiate("x", fmi2CoSimulation, NULL, "", &CB, 0, 0) == NULL,
          "NULL GUID accepted");
    CHECK(api.Instantiate("", fmi2CoSimulation, CW_MODEL_GUID, "", &CB, 0, 0) == NULL,
          "empty instance name accepted");
    CHECK(api.Instantiate(NULL, fmi2CoSimulation, CW_MODEL_GUID, "", &CB, 0, 0) == NULL,
          "NULL instance name accepted");
    CHECK(api.Instantiate("x", fmi2ModelExchange, CW_MODEL_GUID, "", &CB, 0, 0) == NULL,
          "Model Exchange accepted");
    CHECK(LOG.n_errors == errors + 5, "each refused instantiation logs an error");
    CHECK(api.Instantiate("x", fmi2CoSimulation, CW_MODEL_GUID, "", NULL, 0, 0) == NULL,
          "NULL callbacks accepted");
    fmi2CallbackFunctions no_alloc = CB;
    no_alloc.allocateMemory = NULL;
    CHECK(api.Instantiate("x", fmi2CoSimulation, CW_MODEL_GUID, "", &no_alloc, 0, 0) == NULL,
          "NULL allocateMemory accepted");
    /* A NULL logger is allowed: the FMU then stays silent. */
    fmi2CallbackFunctions no_logger = CB;
    no_logger.logger = NULL;
    fmi2Component quiet = api.Instantiate("quiet", fmi2CoSimulation, CW_MODEL_GUID,
                                          "", &no_logger, 0, 1);
    CHECK(quiet != NULL, "a NULL logger is allowed");
    if (quiet) {
        CHECK(set_real(quiet, 0xFFFFFFFFu, 1.0) == fmi2Error, "bad vr refused");
        api.FreeInstance(quiet);
    }
    CHECK(h_live_blocks == 0, "%ld blocks live after refused instantiations",
          h_live_blocks);

    /* Many instances alive at once, freed in a scrambled order. */
    enum { N = 40 };
    fmi2Component many[N];
    for (int k = 0; k < N; k++) many[k] = instantiate("many");
    for (int k = 0; k < N; k++) {
        fmi2Component c = many[(k * 7) % N];
        CHECK(c != NULL, "instance %d", k);
        if (c && k % 2 == 0) {
            api.SetupExperiment(c, 0, 0, 0, 0, 0);
            api.EnterInitializationMode(c);
            api.ExitInitializationMode(c);
            api.DoStep(c, 0.0, STEP, 1);
        }
        api.FreeInstance(c);
    }
    api.FreeInstance(NULL); /* must be harmless */
    CHECK(h_live_blocks == 0, "%ld blocks live after freeing %d instances",
          h_live_blocks, N);

    /* Reset brings an instance back to the start values. */
    inst I = make(ST_STEP_COMPLETE);
    for (int k = 0; k < 20; k++) step(&I, NULL);
    CHECK_OK(api.Reset(I.c), "reset");
    CHECK(observed_state(I.c) == ST_INSTANTIATED, "Reset -> Instantiated");
    CHECK_OK(api.SetupExperiment(I.c, 0, 0, 0, 0, 0), "setup after reset");
    CHECK_OK(api.EnterInitializationMode(I.c), "enter after reset");
    CHECK_OK(api.ExitInitializationMode(I.c), "exit after reset");
    h_values a, b;
    h_read_all(&api, I.c, &a);
    inst J = make(ST_INSTANTIATED);
    api.SetupExperiment(J.c, 0, 0, 0, 0, 0);
    api.EnterInitializationMode(J.c);
    interesting_parameters(J.c);
    api.ExitInitializationMode(J.c);
    h_read_all(&api, J.c, &b);
    /* The reset instance kept no parameter from before: noise_rms was set
     * in I before the reset and in J after, so compare only when absent. */
    if (!h_find("noise_rms"))
        CHECK(h_same_values(&a, &b), "reset instance equals a fresh one");
    free_inst(&I);
    free_inst(&J);
    CHECK(h_live_blocks == 0, "%ld blocks live", h_live_blocks);
}

/* ------------------------------------------------------------------ */
/* Calls in the wrong state: refused with fmi2Error and a logged reason,
 * and the machine state is unchanged. Calls the standard permits in a
 * state succeed. Masks after FMI 2.0.4, Sec. 4.2.4 (Co-Simulation). */

static unsigned first_var(cw_causality causality, int need_derivative) {
    for (int vr = 0; vr < CW_NVARS; vr++) {
        const cw_var_info *v = &CW_VARS[vr];
        if (v->name && v->type == CW_REAL && v->causality == causality &&
            (!need_derivative || v->max_derivative_order >= 1))
            return (unsigned)vr;
    }
    return 0xFFFFFFFFu;
}

typedef struct {
    const char *name;
    int permitted; /* machine states where the standard allows the call */
    fmi2Status (*call)(inst *I);
} state_case;

static fmi2Status c_setup(inst *I) {
    return api.SetupExperiment(I->c, 0, 0, I->t, 0, 0);
}
static fmi2Status c_enter(inst *I) { return api.EnterInitializationMode(I->c); }
static fmi2Status c_exit(inst *I) { return api.ExitInitializationMode(I->c); }
static fmi2Status c_terminate(inst *I) { return api.Terminate(I->c); }
static fmi2Status c_dostep(inst *I) {
    return api.DoStep(I->c, I->t, STEP, fmi2False);
}
static fmi2Status c_get_real(inst *I) {
    fmi2ValueReference vr = first_var(CW_OUTPUT, 0);
    double x;
    return api.GetReal(I->c, &vr, 1, &x);
}
static fmi2Status c_set_input(inst *I) {
    unsigned vr = first_var(CW_INPUT, 0);
    return set_real(I->c, vr, CW_VARS[vr].start);
}
static fmi2Status c_set_input_der(inst *I) {
    fmi2ValueReference vr = first_var(CW_INPUT, 0);
    fmi2Integer order = 1;
    double x = 0.0;
    return api.SetRealInputDerivatives(I->c, &vr, 1, &order, &x);
}
static fmi2Status c_get_output_der(inst *I) {
    fmi2ValueReference vr = first_var(CW_OUTPUT, 1);
    fmi2Integer order = 1;
    double x;
    return api.GetRealOutputDerivatives(I->c, &vr, 1, &order, &x);
}
static fmi2Status c_get_status(inst *I) {
    fmi2Status s;
    return api.GetStatus(I->c, fmi2DoStepStatus, &s);
}
static fmi2Status c_get_real_status(inst *I) {
    double t;
    return api.GetRealStatus(I->c, fmi2LastSuccessfulTime, &t);
}
static fmi2Status c_reset(inst *I) { return api.Reset(I->c); }
static fmi2Status c_debug(inst *I) {
    return api.SetDebugLogging(I->c, fmi2False, 0, NULL);
}
static fmi2Status c_state_cycle(inst *I) {
    fmi2FMUstate s = NULL;
    fmi2Status st = api.GetFMUstate(I->c, &s);
    if (st == fmi2OK) st = api.SetFMUstate(I->c, s);
    if (s) api.FreeFMUstate(I->c, &s);
    return st;
}

static void test_wrong_states(void) {
    section = "wrong state";
    const int OUT_READ = ST_INIT | ST_STEP_COMPLETE | ST_STEP_FAILED |
                         ST_TERMINATED | ST_ERROR;
    const int SETTABLE = ST_INSTANTIATED | ST_INIT | ST_STEP_COMPLETE;
    const int STATUS = ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED;
    state_case cases[] = {
        {"fmi2SetupExperiment", ST_INSTANTIATED, c_setup},
        {"fmi2EnterInitializationMode", ST_INSTANTIATED, c_enter},
        {"fmi2ExitInitializationMode", ST_INIT, c_exit},
        {"fmi2Terminate", ST_STEP_COMPLETE | ST_STEP_FAILED, c_terminate},
        {"fmi2DoStep", ST_STEP_COMPLETE, c_dostep},
        {"fmi2GetReal", OUT_READ, c_get_real},
        {"fmi2SetReal(input)", SETTABLE, c_set_input},
        {"fmi2SetRealInputDerivatives", SETTABLE, c_set_input_der},
        {"fmi2GetRealOutputDerivatives", OUT_READ & ~ST_INIT, c_get_output_der},
        {"fmi2GetStatus", STATUS, c_get_status},
        {"fmi2GetRealStatus", STATUS, c_get_real_status},
        {"fmi2Reset", ST_ALL, c_reset},
        {"fmi2SetDebugLogging", ST_ALL, c_debug},
        /* The standard also permits saving the state in Error; the runtime
         * refuses it there (an errored instance is no state to return to),
         * so Error is left out of both checks. */
        {"fmi2Get/SetFMUstate", ST_ALL & ~ST_ERROR, c_state_cycle},
    };
    const int states[] = {ST_INSTANTIATED, ST_INIT, ST_STEP_COMPLETE,
                          ST_STEP_FAILED, ST_TERMINATED, ST_ERROR};
    int has_output_der = first_var(CW_OUTPUT, 1) != 0xFFFFFFFFu;
    for (size_t k = 0; k < sizeof cases / sizeof *cases; k++) {
        const state_case *sc = &cases[k];
        if (sc->call == c_get_output_der && !has_output_der) continue;
        for (size_t j = 0; j < sizeof states / sizeof *states; j++) {
            const int s = states[j];
            if (sc->call == c_state_cycle && s == ST_ERROR) continue;
            inst I = make(s);
            if (!I.c) continue;
            if (sc->permitted & s) {
                fmi2Status st = sc->call(&I);
                /* Terminate after a failed step and a step are the only
                 * permitted calls whose status depends on the model. */
                CHECK(st <= fmi2Warning, "%s in %s is permitted, got %d",
                      sc->name, st_name(s), (int)st);
            } else {
                CHECK_REFUSED(sc->call(&I), "%s in %s", sc->name, st_name(s));
                CHECK(observed_state(I.c) == s, "%s in %s changed the state to %s",
                      sc->name, st_name(s), st_name(observed_state(I.c)));
            }
            free_inst(&I);
        }
    }
    /* Functions this FMU does not provide say so in every state. */
    inst I = make(ST_STEP_COMPLETE);
    fmi2ValueReference vr = 0;
    double x = 0, dx = 0;
    fmi2String str = NULL;
    fmi2Integer iv;
    fmi2Boolean bv;
    CHECK_REFUSED(api.GetDirectionalDerivative(I.c, &vr, 1, &vr, 1, &x, &dx),
                  "directional derivative");
    CHECK_REFUSED(api.CancelStep(I.c), "cancel step");
    CHECK_REFUSED(api.GetIntegerStatus(I.c, fmi2DoStepStatus, &iv), "integer status");
    /* fmi2Terminated is provided (false: these FMUs never end the run);
     * other Boolean status kinds and a NULL value are refused. */
    bv = fmi2True;
    CHECK(api.GetBooleanStatus(I.c, fmi2Terminated, &bv) == fmi2OK && bv == fmi2False,
          "fmi2GetBooleanStatus(fmi2Terminated) is fmi2OK and false");
    CHECK_REFUSED(api.GetBooleanStatus(I.c, fmi2DoStepStatus, &bv), "boolean status kind");
    CHECK_REFUSED(api.GetBooleanStatus(I.c, fmi2Terminated, NULL), "NULL boolean status");
    CHECK_REFUSED(api.GetStringStatus(I.c, fmi2PendingStatus, &str), "string status");
    CHECK_REFUSED(api.GetString(I.c, &vr, 1, &str), "strings");
    CHECK_REFUSED(api.SetString(I.c, &vr, 1, &str), "strings");
    CHECK_REFUSED(api.GetStatus(I.c, fmi2PendingStatus, (fmi2Status *)&iv),
                  "pending status");
    CHECK_REFUSED(api.GetStatus(I.c, fmi2DoStepStatus, NULL), "NULL status");
    CHECK_REFUSED(api.GetRealStatus(I.c, fmi2LastSuccessfulTime, NULL),
                  "NULL real status");
    CHECK(observed_state(I.c) == ST_STEP_COMPLETE, "refusals kept the state");
    free_inst(&I);
    CHECK(h_live_blocks == 0, "%ld blocks live", h_live_blocks);
}

/* ------------------------------------------------------------------ */
/* Bad values and arguments */

static void test_bad_values(void) {
    section = "bad values";
    for (int vr = 0; vr < CW_NVARS; vr++) {
        const cw_var_info *v = &CW_VARS[vr];
        if (!v->name || v->causality == CW_OUTPUT || v->causality == CW_LOCAL)
            continue;
        double bad[6];
        int n = 0;
        if (v->type == CW_REAL) {
            bad[n++] = NAN;
            bad[n++] = INFINITY;
            bad[n++] = -INFINITY;
        }
        if (isfinite(v->min)) bad[n++] = v->type == CW_REAL ? nextafter(v->min, -INFINITY) : v->min - 1;
        if (isfinite(v->max)) bad[n++] = v->type == CW_REAL ? nextafter(v->max, INFINITY) : v->max + 1;
        for (int k = 0; k < n; k++) {
            /* Refused before and, for inputs and tunables, after
             * initialization; the refusal puts the instance into Error and
             * leaves the value alone. */
            int states[2] = {ST_INSTANTIATED, ST_STEP_COMPLETE};
            int n_states = (v->causality == CW_INPUT || v->variability == CW_TUNABLE) ? 2 : 1;
            for (int j = 0; j < n_states; j++) {
                inst I = make(states[j]);
                fmi2ValueReference r = (fmi2ValueReference)vr;
                if (v->type == CW_REAL) {
                    double before = get_real(I.c, r);
                    CHECK_REFUSED(api.SetReal(I.c, &r, 1, &bad[k]), "%s = %g in %s",
                                  v->name, bad[k], st_name(states[j]));
                    double after = get_real(I.c, r);
                    if (states[j] != ST_INSTANTIATED)
                        CHECK(memcmp(&before, &after, 8) == 0, "refused %s changed it",
                              v->name);
                } else if (bad[k] >= INT32_MIN && bad[k] <= INT32_MAX) {
                    fmi2Integer x = (fmi2Integer)bad[k];
                    fmi2Status st = v->type == CW_INTEGER
                                        ? api.SetInteger(I.c, &r, 1, &x)
                                        : api.SetBoolean(I.c, &r, 1, &x);
                    CHECK(st == fmi2Error, "%s = %d accepted", v->name, (int)x);
                }
                free_inst(&I);
            }
        }
        /* A fixed parameter cannot change after initialization. */
        if (v->variability == CW_FIXED && v->type == CW_REAL) {
            inst I = make(ST_STEP_COMPLETE);
            CHECK_REFUSED(set_real(I.c, (unsigned)vr, v->start), "fixed %s after init",
                          v->name);
            free_inst(&I);
        }
    }

    inst I = make(ST_STEP_COMPLETE);
    fmi2ValueReference out = first_var(CW_OUTPUT, 0);
    fmi2ValueReference in = first_var(CW_INPUT, 0);
    double x = 0.0;
    fmi2Integer iv = 0;
    CHECK_REFUSED(api.SetReal(I.c, &out, 1, &x), "setting an output");
    fmi2ValueReference bogus[] = {(fmi2ValueReference)CW_NVARS, 0xFFFFFFFFu, 0x80000000u};
    for (size_t k = 0; k < 3; k++) {
        CHECK_REFUSED(api.GetReal(I.c, &bogus[k], 1, &x), "GetReal vr %u", bogus[k]);
        CHECK_REFUSED(api.SetReal(I.c, &bogus[k], 1, &x), "SetReal vr %u", bogus[k]);
        CHECK_REFUSED(api.GetInteger(I.c, &bogus[k], 1, &iv), "GetInteger vr %u", bogus[k]);
    }
    for (int vr = 0; vr < CW_NVARS; vr++)
        if (!CW_VARS[vr].name) { /* a hole in the table */
            fmi2ValueReference hole = (fmi2ValueReference)vr;
            CHECK_REFUSED(api.GetReal(I.c, &hole, 1, &x), "GetReal hole vr %d", vr);
            break;
        }
    CHECK_REFUSED(api.GetInteger(I.c, &out, 1, &iv), "GetInteger of a Real");
    CHECK_REFUSED(api.GetBoolean(I.c, &out, 1, &iv), "GetBoolean of a Real");
    CHECK_REFUSED(api.GetReal(I.c, NULL, 1, &x), "NULL vr");
    CHECK_REFUSED(api.GetReal(I.c, &out, 1, NULL), "NULL values");
    CHECK_REFUSED(api.SetReal(I.c, NULL, 1, &x), "NULL vr");
    CHECK_OK(api.GetReal(I.c, NULL, 0, NULL), "nvr = 0");
    CHECK_OK(api.SetReal(I.c, NULL, 0, NULL), "nvr = 0");

    fmi2Integer orders[] = {0, 3, -1};
    for (int k = 0; k < 3; k++)
        CHECK_REFUSED(api.SetRealInputDerivatives(I.c, &in, 1, &orders[k], &x),
                      "input derivative of order %d", (int)orders[k]);
    fmi2Integer one = 1;
    CHECK_REFUSED(api.SetRealInputDerivatives(I.c, &out, 1, &one, &x),
                  "input derivative of an output");
    CHECK_REFUSED(api.SetRealInputDerivatives(I.c, &in, 1, NULL, &x), "NULL order");
    fmi2ValueReference der_out = first_var(CW_OUTPUT, 1);
    if (der_out != 0xFFFFFFFFu) {
        fmi2Integer too_high = CW_VARS[der_out].max_derivative_order + 1;
        CHECK_REFUSED(api.GetRealOutputDerivatives(I.c, &der_out, 1, &too_high, &x),
                      "output derivative of order %d", (int)too_high);
        CHECK_REFUSED(api.GetRealOutputDerivatives(I.c, &der_out, 1, &orders[0], &x),
                      "output derivative of order 0");
    }
    CHECK(observed_state(I.c) == ST_STEP_COMPLETE, "argument errors kept the state");

    /* Communication steps: refused without changing the state. */
    const double bad_h[] = {0.0, -STEP, -0.0, NAN, INFINITY, -INFINITY};
    for (size_t k = 0; k < sizeof bad_h / sizeof *bad_h; k++)
        CHECK_REFUSED(api.DoStep(I.c, I.t, bad_h[k], fmi2False), "step size %g", bad_h[k]);
    const double bad_tc[] = {NAN, INFINITY, -1.0};
    for (size_t k = 0; k < 3; k++)
        CHECK_REFUSED(api.DoStep(I.c, bad_tc[k], STEP, fmi2False),
                      "communication point %g", bad_tc[k]);
    CHECK_REFUSED(api.DoStep(I.c, I.t + 1.0, STEP, fmi2False), "point ahead of the FMU");
    CHECK(observed_state(I.c) == ST_STEP_COMPLETE, "bad steps kept the state");
    CHECK(step(&I, NULL) == fmi2OK, "a good step after bad ones");
    /* A denormal step is a legal, if silly, step. */
    fmi2Status st = api.DoStep(I.c, I.t, 4.9e-324, fmi2False);
    CHECK(st == fmi2OK || st == fmi2Discard, "denormal step: %d", (int)st);
    free_inst(&I);

    /* Experiment setup. */
    I = make(ST_INSTANTIATED);
    CHECK_REFUSED(api.SetupExperiment(I.c, 0, 0, NAN, 0, 0), "start NaN");
    free_inst(&I);
    I = make(ST_INSTANTIATED);
    CHECK_REFUSED(api.SetupExperiment(I.c, 0, 0, 1.0, 1, 0.5), "stop < start");
    free_inst(&I);
    I = make(ST_INSTANTIATED);
    CHECK_OK(api.SetupExperiment(I.c, 0, 0, 0.0, 1, 2 * STEP), "stop time");
    api.EnterInitializationMode(I.c);
    api.ExitInitializationMode(I.c);
    CHECK(step(&I, NULL) == fmi2OK, "step inside the stop time");
    CHECK_REFUSED(api.DoStep(I.c, I.t, 2 * STEP, fmi2False), "step past the stop time");
    free_inst(&I);

    /* A step whose end overflows the time axis. */
    I = make(ST_INSTANTIATED);
    CHECK_OK(api.SetupExperiment(I.c, 0, 0, 1e308, 0, 0), "start at 1e308 s");
    api.EnterInitializationMode(I.c);
    api.ExitInitializationMode(I.c);
    CHECK_REFUSED(api.DoStep(I.c, 1e308, 1e308, fmi2False), "step to inf");
    free_inst(&I);

    /* Logging categories. */
    I = make(ST_INSTANTIATED);
    const fmi2String good[] = {"logEvents", "logStatusError", "logAll"};
    const fmi2String bad_cat[] = {"logEvents", "noSuchCategory"};
    const fmi2String null_cat[] = {NULL};
    CHECK_OK(api.SetDebugLogging(I.c, fmi2True, 3, good), "known categories");
    CHECK_REFUSED(api.SetDebugLogging(I.c, fmi2True, 2, bad_cat), "unknown category");
    CHECK_REFUSED(api.SetDebugLogging(I.c, fmi2True, 1, null_cat), "NULL category");
    CHECK_REFUSED(api.SetDebugLogging(I.c, fmi2True, 1, NULL), "NULL categories");
    free_inst(&I);
    CHECK(h_live_blocks == 0, "%ld blocks live", h_live_blocks);
}

/* ------------------------------------------------------------------ */
/* Extreme but accepted inputs: outputs that overflow are refused with
 * fmi2Error, never returned as inf/NaN with fmi2OK; input polynomials that
 * overflow within a step are refused. */

static void test_extreme_inputs(void) {
    section = "extreme inputs";
    const double extremes[] = {DBL_MAX, -DBL_MAX, 1e300, -1e300, 4.9e-324};
    for (size_t j = 0; j < sizeof extremes / sizeof *extremes; j++) {
        inst I = make(ST_STEP_COMPLETE);
        for (int vr = 0; vr < CW_NVARS; vr++) {
            const cw_var_info *v = &CW_VARS[vr];
            if (v->name && v->type == CW_REAL && v->causality == CW_INPUT &&
                extremes[j] >= v->min && extremes[j] <= v->max)
                set_real(I.c, (unsigned)vr, extremes[j]);
        }
        h_values vals;
        h_read_all(&api, I.c, &vals);
        const char *bad = h_unfit_value(&vals);
        CHECK(!bad, "inputs %g: %s is not finite with fmi2OK", extremes[j], bad);
        fmi2Status st = api.DoStep(I.c, I.t, STEP, fmi2False);
        h_read_all(&api, I.c, &vals);
        bad = h_unfit_value(&vals);
        CHECK(!bad, "inputs %g, step %d: %s is not finite with fmi2OK", extremes[j],
              (int)st, bad);
        free_inst(&I);
    }
    /* Derivatives that carry an input to inf within the step. */
    inst I = make(ST_STEP_COMPLETE);
    fmi2ValueReference in = first_var(CW_INPUT, 0);
    fmi2Integer one = 1;
    double d = 1e300;
    CHECK_OK(api.SetRealInputDerivatives(I.c, &in, 1, &one, &d), "huge derivative");
    CHECK_REFUSED(api.DoStep(I.c, I.t, 1e10, fmi2False), "input overflows in the step");
    free_inst(&I);
    CHECK(h_live_blocks == 0, "%ld blocks live", h_live_blocks);
}

/* ------------------------------------------------------------------ */
/* Out of memory: every allocation in turn fails; the FMU must refuse
 * cleanly and free what it had. */

static void test_out_of_memory(void) {
    section = "out of memory";
    int completed = 0;
    for (long k = 0; k < 200 && !completed; k++) {
        h_fail_countdown = k;
        fmi2Component c = instantiate("oom");
        if (c) {
            fmi2FMUstate s = NULL, s2 = NULL;
            api.SetupExperiment(c, 0, 0, 0, 0, 0);
            api.EnterInitializationMode(c);
            api.ExitInitializationMode(c);
            api.DoStep(c, 0.0, STEP, fmi2False);
            fmi2Status g = api.GetFMUstate(c, &s);
            size_t size = 0;
            unsigned char *buf = NULL;
            fmi2Status d = fmi2Error;
            if (g == fmi2OK && api.SerializedFMUstateSize(c, s, &size) == fmi2OK &&
                (buf = malloc(size)) != NULL &&
                api.SerializeFMUstate(c, s, (fmi2Byte *)buf, size) == fmi2OK)
                d = api.DeSerializeFMUstate(c, (fmi2Byte *)buf, size, &s2);
            free(buf);
            if (d == fmi2OK) {
                CHECK(s2 != NULL, "deserialized state");
                completed = h_fail_countdown != 0;
            } else {
                CHECK(s2 == NULL, "a failed deserialization returned a state");
            }
            if (s) api.FreeFMUstate(c, &s);
            if (s2) api.FreeFMUstate(c, &s2);
            api.FreeInstance(c);
        }
        h_fail_countdown = -1;
        CHECK(h_live_blocks == 0, "%ld blocks live after failing allocation %ld",
              h_live_blocks, k);
    }
    CHECK(completed, "a run without allocation failures was reached");
}

/* ------------------------------------------------------------------ */
/* FMU state */

typedef struct {
    int n;
    h_values v[150];
} trace;

static void run_trace(inst *I, trace *tr, int n) {
    tr->n = n;
    for (int k = 0; k < n; k++) {
        fmi2Status st = step(I, &tr->v[k]);
        CHECK(st == fmi2OK, "step %d at t = %g: %d", k, I->t, (int)st);
        if (st != fmi2OK) {
            tr->n = k;
            return;
        }
    }
}

static int same_trace(const trace *a, const trace *b) {
    if (a->n != b->n) return 0;
    for (int k = 0; k < a->n; k++)
        if (!h_same_values(&a->v[k], &b->v[k])) return 0;
    return 1;
}

/* Serialized state of I (caller frees). */
static unsigned char *serialize(fmi2Component c, size_t *size) {
    fmi2FMUstate s = NULL;
    unsigned char *buf = NULL;
    *size = 0;
    if (api.GetFMUstate(c, &s) == fmi2OK &&
        api.SerializedFMUstateSize(c, s, size) == fmi2OK &&
        (buf = malloc(*size)) != NULL &&
        api.SerializeFMUstate(c, s, (fmi2Byte *)buf, *size) != fmi2OK) {
        free(buf);
        buf = NULL;
    }
    if (s) api.FreeFMUstate(c, &s);
    return buf;
}

/* Deserialize and set; returns the deserialization status. */
static fmi2Status restore(fmi2Component c, const unsigned char *buf, size_t size) {
    fmi2FMUstate s = NULL;
    fmi2Status st = api.DeSerializeFMUstate(c, (const fmi2Byte *)buf, size, &s);
    if (st == fmi2OK) {
        CHECK_OK(api.SetFMUstate(c, s), "set a deserialized state");
        CHECK_OK(api.FreeFMUstate(c, &s), "free a deserialized state");
        CHECK(s == NULL, "FreeFMUstate sets the pointer to NULL");
    } else {
        CHECK(s == NULL, "a refused buffer returned a state");
    }
    return st;
}

static void expect_refused(fmi2Component c, const unsigned char *buf, size_t size,
                           const char *what, long detail) {
    fmi2FMUstate s = NULL;
    long errors = LOG.n_errors;
    fmi2Status st = api.DeSerializeFMUstate(c, (const fmi2Byte *)buf, size, &s);
    CHECK(st == fmi2Error, "%s (%ld) accepted", what, detail);
    CHECK(s == NULL, "%s (%ld) returned a state", what, detail);
    CHECK(LOG.n_errors > errors, "%s (%ld) refused without a logged reason", what,
          detail);
    if (s) api.FreeFMUstate(c, &s);
}

static void test_state(void) {
    section = "FMU state";
    static trace first, second, third;

    /* Continuation bit for bit in a fresh instance. */
    inst A = make(ST_STEP_COMPLETE);
    for (int k = 0; k < 137; k++) step(&A, NULL);
    size_t size;
    unsigned char *saved = serialize(A.c, &size);
    CHECK(saved != NULL, "serialize");
    if (!saved) return;
    const double t_saved = A.t;
    fmi2FMUstate mem = NULL;
    CHECK_OK(api.GetFMUstate(A.c, &mem), "get state");
    run_trace(&A, &first, 150);

    inst B = make(ST_INSTANTIATED); /* never initialized */
    CHECK(restore(B.c, saved, size) == fmi2OK, "restore into a fresh instance");
    CHECK(observed_state(B.c) == ST_STEP_COMPLETE, "restored machine state");
    B.t = t_saved;
    run_trace(&B, &second, 150);
    CHECK(same_trace(&first, &second),
          "a fresh instance continues bit for bit from a serialized state");

    /* And an instance that has run elsewhere, with other inputs. */
    inst C = make(ST_STEP_COMPLETE);
    for (int k = 0; k < 11; k++) step(&C, NULL);
    CHECK(restore(C.c, saved, size) == fmi2OK, "restore into a used instance");
    C.t = t_saved;
    run_trace(&C, &third, 150);
    CHECK(same_trace(&first, &third), "a used instance continues bit for bit");

    /* fmi2SetFMUstate rewinds the instance it came from. */
    CHECK_OK(api.SetFMUstate(A.c, mem), "rewind");
    double t_status = NAN;
    api.GetRealStatus(A.c, fmi2LastSuccessfulTime, &t_status);
    CHECK(t_status == t_saved, "last successful time after a rewind: %.17g vs %.17g",
          t_status, t_saved);
    A.t = t_saved;
    run_trace(&A, &second, 150);
    CHECK(same_trace(&first, &second), "get/set state rewinds bit for bit");
    /* GetFMUstate into an existing state reuses it. */
    fmi2FMUstate again = mem;
    long live = h_live_blocks;
    CHECK_OK(api.GetFMUstate(A.c, &again), "get state into an existing one");
    CHECK(again == mem && h_live_blocks == live, "the existing state was reused");
    mem = again;

    /* Truncated and overlong buffers. */
    unsigned char *buf = malloc(size + 64);
    for (size_t n = 0; n < size; n++) {
        memcpy(buf, saved, n);
        expect_refused(B.c, n ? buf : saved, n, "truncated to", (long)n);
    }
    memcpy(buf, saved, size);
    memset(buf + size, 0, 64);
    expect_refused(B.c, buf, size + 1, "one byte too long", (long)size + 1);
    expect_refused(B.c, buf, size + 64, "64 bytes too long", (long)size + 64);
    CHECK_REFUSED(api.DeSerializeFMUstate(B.c, NULL, size, &mem), "NULL buffer");
    CHECK_REFUSED(api.DeSerializeFMUstate(B.c, (fmi2Byte *)saved, size, NULL),
                  "NULL state pointer");

    /* Every single corrupted byte (the checksum covers them all). */
    for (size_t k = 0; k < size; k++)
        for (int b = 0; b < 8; b += 7) {
            memcpy(buf, saved, size);
            buf[k] ^= (unsigned char)(1u << b);
            expect_refused(B.c, buf, size, "bit flipped at byte", (long)k);
        }

    /* Corrupted content under a valid checksum: the decoded values are
     * checked too. */
    const size_t t_off = 24;
    const double nonfinite[] = {NAN, INFINITY, -INFINITY};
    for (int j = 0; j < 3; j++) {
        memcpy(buf, saved, size);
        h_put_f64(buf + t_off, nonfinite[j]);
        h_fix_checksum(buf, size);
        expect_refused(B.c, buf, size, "non-finite time", j);
    }
    const uint32_t machine[] = {0, 3, 6, 32, 64, 0xFFFFFFFFu};
    for (int j = 0; j < 6; j++) {
        memcpy(buf, saved, size);
        h_put_u32(buf + 20, machine[j]);
        h_fix_checksum(buf, size);
        expect_refused(B.c, buf, size, "machine state", (long)machine[j]);
    }
    for (int field = 0; field < 4; field++) { /* magic, version, GUID, size */
        const size_t off[] = {0, 4, 8, 16};
        memcpy(buf, saved, size);
        buf[off[field]] ^= 0x10;
        h_fix_checksum(buf, size);
        expect_refused(B.c, buf, size, "header field", field);
    }
    for (int vr = 0; vr < CW_NVARS; vr++) {
        const cw_var_info *v = &CW_VARS[vr];
        if (!v->name) continue;
        const size_t off = h_value_offset((unsigned)vr);
        if (v->type == CW_REAL) {
            for (int j = 0; j < 3; j++) {
                memcpy(buf, saved, size);
                h_put_f64(buf + off, nonfinite[j]);
                h_fix_checksum(buf, size);
                expect_refused(B.c, buf, size, v->name, j);
                if (v->causality == CW_INPUT)
                    for (int d = 1; d <= 3; d++) { /* d1, d2, t_ref */
                        memcpy(buf, saved, size);
                        h_put_f64(buf + off + 8 * d, nonfinite[j]);
                        h_fix_checksum(buf, size);
                        expect_refused(B.c, buf, size, "input polynomial", d);
                    }
            }
        }
        if (v->causality != CW_PARAMETER && v->causality != CW_INPUT) continue;
        double outside[2];
        int n = 0;
        if (isfinite(v->min))
            outside[n++] = v->type == CW_REAL ? nextafter(v->min, -INFINITY) : v->min - 1;
        if (isfinite(v->max))
            outside[n++] = v->type == CW_REAL ? nextafter(v->max, INFINITY) : v->max + 1;
        for (int j = 0; j < n; j++) {
            memcpy(buf, saved, size);
            if (v->type == CW_REAL)
                h_put_f64(buf + off, outside[j]);
            else
                h_put_u32(buf + off, (uint32_t)(int32_t)outside[j]);
            h_fix_checksum(buf, size);
            expect_refused(B.c, buf, size, v->name, (long)outside[j]);
        }
    }
    const size_t ms = h_model_state_offset();
    memcpy(buf, saved, size);
    h_put_u32(buf + ms, (uint32_t)(buf[ms] + 1u));
    h_fix_checksum(buf, size);
    expect_refused(B.c, buf, size, "model state count", 0);
    const uint32_t n_real = (uint32_t)saved[ms];
    for (uint32_t k = 0; k < n_real; k++)
        for (int j = 0; j < 3; j++) {
            memcpy(buf, saved, size);
            h_put_f64(buf + ms + 4 + 8 * k, nonfinite[j]);
            h_fix_checksum(buf, size);
            expect_refused(B.c, buf, size, "non-finite model state", (long)k);
        }
    const size_t us = ms + 4 + 8 * n_real;
    memcpy(buf, saved, size);
    h_put_u32(buf + us, (uint32_t)(buf[us] + 1u));
    h_fix_checksum(buf, size);
    expect_refused(B.c, buf, size, "counter count", 0);

    /* The refusals left B in Error; the good state recovers it. */
    CHECK(restore(B.c, saved, size) == fmi2OK, "recover with a good state");
    B.t = t_saved;
    run_trace(&B, &second, 150);
    CHECK(same_trace(&first, &second), "recovered instance continues bit for bit");

    /* Deserializing over an existing state replaces (and frees) it. */
    fmi2FMUstate s = NULL;
    CHECK_OK(api.DeSerializeFMUstate(B.c, (fmi2Byte *)saved, size, &s), "deserialize");
    live = h_live_blocks;
    CHECK_OK(api.DeSerializeFMUstate(B.c, (fmi2Byte *)saved, size, &s), "deserialize over");
    CHECK(h_live_blocks == live, "the replaced state was freed (%ld -> %ld blocks)",
          live, h_live_blocks);
    size_t got = 0;
    CHECK_OK(api.SerializedFMUstateSize(B.c, s, &got), "size");
    CHECK(got == size, "size %zu vs %zu", got, size);
    CHECK_REFUSED(api.SerializeFMUstate(B.c, s, (fmi2Byte *)buf, size - 1),
                  "serialize into a short buffer");
    CHECK_REFUSED(api.SerializedFMUstateSize(B.c, s, NULL), "NULL size");
    CHECK_OK(api.FreeFMUstate(B.c, &s), "free");
    s = NULL;
    CHECK_OK(api.FreeFMUstate(B.c, &s), "freeing a NULL state is harmless");

    /* States saved in initialization mode restore that mode. */
    inst D = make(ST_INIT);
    size_t init_size;
    unsigned char *init_state = serialize(D.c, &init_size);
    inst E = make(ST_STEP_COMPLETE);
    CHECK(init_state && restore(E.c, init_state, init_size) == fmi2OK,
          "restore an initialization-mode state");
    CHECK(observed_state(E.c) == ST_INIT, "restored into initialization mode");
    CHECK_OK(api.ExitInitializationMode(E.c), "exit after restore");
    free(init_state);

    /* Many get/free cycles leave nothing behind. */
    live = h_live_blocks;
    for (int k = 0; k < 2000; k++) {
        fmi2FMUstate x = NULL;
        api.GetFMUstate(A.c, &x);
        api.FreeFMUstate(A.c, &x);
    }
    CHECK(h_live_blocks == live, "get/free cycles leaked %ld blocks",
          h_live_blocks - live);

    api.FreeFMUstate(A.c, &mem);
    free(buf);
    free(saved);
    free_inst(&A);
    free_inst(&B);
    free_inst(&C);
    free_inst(&D);
    free_inst(&E);
    CHECK(h_live_blocks == 0, "%ld blocks live at the end", h_live_blocks);
}

/* ------------------------------------------------------------------ */

int main(int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: %s path/to/%s.so\n", argv[0], CW_MODEL_NAME);
        return 2;
    }
    /* RTLD_NODELETE keeps the code mapped for LeakSanitizer's report. */
    void *so = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL | RTLD_NODELETE);
    if (!so) {
        fprintf(stderr, "dlopen %s: %s\n", argv[1], dlerror());
        return 2;
    }
#define H_BIND(n)                                                            \
    *(void **)(&api.n) = dlsym(so, "fmi2" #n);                               \
    if (!api.n) {                                                            \
        fprintf(stderr, "%s does not export fmi2" #n "\n", argv[1]);         \
        return 2;                                                            \
    }
    FMI_FUNCTIONS(H_BIND)
#undef H_BIND
    LOG.echo = getenv("CW_DRIVER_ECHO") != NULL;
    CB = h_callbacks(&LOG);

    test_lifecycle();
    test_wrong_states();
    test_bad_values();
    test_extreme_inputs();
    test_out_of_memory();
    test_state();

    dlclose(so);
    printf("%s: %ld checks, %ld failed; %ld allocations, %ld blocks live\n",
           CW_MODEL_NAME, n_checks, n_failures, h_total_allocs, h_live_blocks);
    return n_failures || h_live_blocks ? 1 : 0;
}
