/* C test driver for the FMI 1.0 Co-Simulation build of one clockwork FMU
 * (the runtime's fmi1 face, src_c/runtime/cw_fmi1.c), run by ctest.
 *
 *   fmu_driver1_<Model> path/to/fmi1/<Model>.so
 *
 * Loads the binary with dlopen and drives it through FMI 1.0's
 * <modelIdentifier>_fmi* functions: refused instantiations; the lifecycle
 * (start values, fmiInitializeSlave, steps, every variable of every type,
 * fmiBoolean as a char both ways, also more of them than the face converts
 * on its stack, the status functions, newStep = false refused, a step of
 * size 0 where the FMU stands (FMI 1.0's iteration) and nowhere else,
 * fmiResetSlave giving the first run's bits again); and a long random
 * sequence of calls in any order (every status OK, Discard or Error, and
 * every Error with a logged message). A counting allocator checks that
 * every block is freed. Built with CW_SANITIZE=ON it runs under
 * AddressSanitizer, UndefinedBehaviorSanitizer and LeakSanitizer. */
#include <dlfcn.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi1Functions.h"

/* The table only: CW_MODEL is defined by the model's own model.c. */
#define CW_VARS_TABLE_ONLY
#include "cw_vars.h"
#include "driver_checks.h"

/* A counting allocator: every block the FMU takes must come back. */
static long h_live_blocks;

static void *h_alloc(size_t nobj, size_t size) {
    void *p = calloc(nobj, size);
    if (p) h_live_blocks++;
    return p;
}

static void h_free(void *p) {
    if (p) h_live_blocks--;
    free(p);
}

#define FMI1_FUNCTIONS(X)                                                     \
    X(GetTypesPlatform) X(GetVersion) X(SetDebugLogging) X(InstantiateSlave)  \
    X(InitializeSlave) X(TerminateSlave) X(ResetSlave) X(FreeSlaveInstance)   \
    X(GetReal) X(GetInteger) X(GetBoolean) X(GetString) X(SetReal)            \
    X(SetInteger) X(SetBoolean) X(SetString) X(SetRealInputDerivatives)       \
    X(GetRealOutputDerivatives) X(CancelStep) X(DoStep) X(GetStatus)          \
    X(GetRealStatus) X(GetIntegerStatus) X(GetBooleanStatus)                  \
    X(GetStringStatus)

static struct {
#define FIELD(n) fmi1##n##TYPE *n;
    FMI1_FUNCTIONS(FIELD)
#undef FIELD
} api;

static fmi1Component current; /* the instance a logged message must name (NULL: any) */

/* FMI 1.0's logger gets the component (NULL while it is being made). */
static void logger(fmi1Component c, fmi1String instance, fmi1Status status, fmi1String category,
                   fmi1String message, ...) {
    if (!message || !category || !instance) abort();
    if (strchr(message, '%')) abort(); /* the importer takes it as a printf format */
    if (c && current && c != current) abort();
    n_messages++;
    if (status >= fmi1Error) n_errors++;
    snprintf(last, sizeof last, "%s", message);
}

static fmi1CallbackFunctions callbacks(void) {
    fmi1CallbackFunctions cb = {logger, h_alloc, h_free, NULL};
    return cb;
}

static fmi1Component instantiate(const char *name) {
    return api.InstantiateSlave(name, CW_MODEL_GUID, "file:///nowhere", "application/x-fmu-sharedlibrary",
                                0.0, fmi1False, fmi1False, callbacks(), fmi1False);
}

static void set_inputs(fmi1Component c, double t) {
    for (int k = 0; k < CW_NVARS; k++) {
        const cw_var_info *v = &CW_VARS[k];
        if (!v->name || v->causality != CW_INPUT || v->type != CW_REAL) continue;
        fmi1ValueReference vr = v->vr;
        double x = input_value(v, t);
        CHECK(api.SetReal(c, &vr, 1, &x) == fmi1OK, "set %s", v->name);
    }
}

/* Every variable's value (Strings by length), after a step. */
static int values(fmi1Component c, double *out) {
    int n = 0;
    for (int k = 0; k < CW_NVARS; k++) {
        const cw_var_info *v = &CW_VARS[k];
        if (!v->name) continue;
        fmi1ValueReference vr = v->vr;
        if (v->type == CW_REAL) {
            CHECK(api.GetReal(c, &vr, 1, &out[n]) == fmi1OK, "get %s", v->name);
        } else if (v->type == CW_INTEGER) {
            fmi1Integer i = 0;
            CHECK(api.GetInteger(c, &vr, 1, &i) == fmi1OK, "get %s", v->name);
            out[n] = i;
        } else if (v->type == CW_BOOLEAN) {
            fmi1Boolean b = 7;
            CHECK(api.GetBoolean(c, &vr, 1, &b) == fmi1OK, "get %s", v->name);
            CHECK(b == fmi1True || b == fmi1False, "%s is %d, neither fmi1True nor fmi1False", v->name, b);
            out[n] = b;
        } else {
            fmi1String s = NULL;
            CHECK(api.GetString(c, &vr, 1, &s) == fmi1OK && s, "get %s", v->name);
            out[n] = s ? (double)strlen(s) : -1;
        }
        n++;
    }
    return n;
}

/* More Booleans than the face converts on its stack (64): the first
 * Boolean parameter or input, many times over. */
static void many_booleans(fmi1Component c) {
    for (int k = 0; k < CW_NVARS; k++) {
        const cw_var_info *v = &CW_VARS[k];
        if (!v->name || v->type != CW_BOOLEAN || (v->causality != CW_PARAMETER && v->causality != CW_INPUT))
            continue;
        enum { N = 200 };
        fmi1ValueReference vr[N];
        fmi1Boolean set[N], got[N];
        for (int j = 0; j < N; j++) {
            vr[j] = v->vr;
            set[j] = (fmi1Boolean)(j == N - 1 ? 2 : 0); /* any char but 0 is true; the last one wins */
        }
        CHECK(api.SetBoolean(c, vr, N, set) == fmi1OK, "set %d Booleans", N);
        CHECK(api.GetBoolean(c, vr, N, got) == fmi1OK, "get %d Booleans", N);
        for (int j = 0; j < N; j++) CHECK(got[j] == fmi1True, "Boolean %d read back as %d", j, got[j]);
        return;
    }
}

static void run(fmi1Component c, double *out, int *n) {
    double t = 0.0, h = 0.05;
    for (int k = 0; k < 100; k++) {
        set_inputs(c, t);
        CHECK(api.DoStep(c, t, h, fmi1True) == fmi1OK, "step at %g", t);
        t += h;
        fmi1Real last_t = -1;
        CHECK(api.GetRealStatus(c, fmi1LastSuccessfulTime, &last_t) == fmi1OK && last_t == t, "last time");
    }
    /* FMI 1.0's iteration: a step of size 0 where the FMU stands, nowhere else. */
    set_inputs(c, t);
    CHECK(api.DoStep(c, t, 0.0, fmi1True) == fmi1OK, "a zero step");
    REFUSED(api.DoStep(c, t + 1.0, 0.0, fmi1True), "a zero step elsewhere");
    *n = values(c, out);
}

static void lifecycle(void) {
    section = "lifecycle";
    fmi1Component c = instantiate("life");
    CHECK(c != NULL, "instantiate");
    if (!c) return;
    current = c;
    fmi1Real x = 0;
    fmi1ValueReference vr0 = 0;
    REFUSED(api.GetReal(c, &vr0, 1, &x), "get before fmiInitializeSlave");
    REFUSED(api.DoStep(c, 0.0, 0.1, fmi1True), "step before fmiInitializeSlave");
    many_booleans(c);
    CHECK(api.InitializeSlave(c, 0.0, fmi1True, 20.0) == fmi1OK, "initialize");
    REFUSED(api.InitializeSlave(c, 0.0, fmi1False, 0.0), "initialize twice");
    double a[CW_NVARS + 1], b[CW_NVARS + 1];
    int na = 0, nb = 0;
    run(c, a, &na);
    REFUSED(api.DoStep(c, 5.0, 0.05, fmi1False), "newStep = false: a repeated step");
    fmi1Status st = fmi1Error;
    CHECK(api.GetStatus(c, fmi1DoStepStatus, &st) == fmi1OK && st == fmi1OK, "do-step status");
    fmi1Integer i = 0;
    fmi1Boolean bb = 0;
    fmi1String s = NULL;
    REFUSED(api.GetIntegerStatus(c, fmi1DoStepStatus, &i), "no Integer status");
    REFUSED(api.GetBooleanStatus(c, fmi1DoStepStatus, &bb), "no Boolean status");
    REFUSED(api.GetStringStatus(c, fmi1PendingStatus, &s), "no String status");
    REFUSED(api.CancelStep(c), "nothing to cancel");
    CHECK(api.TerminateSlave(c) == fmi1OK, "terminate");
    REFUSED(api.TerminateSlave(c), "terminate twice");
    /* fmiResetSlave: the same start values, initialization and steps give the same bits. */
    CHECK(api.ResetSlave(c) == fmi1OK, "reset");
    CHECK(api.InitializeSlave(c, 0.0, fmi1False, 0.0) == fmi1OK, "initialize after the reset");
    run(c, b, &nb);
    CHECK(na == nb && memcmp(a, b, sizeof(double) * (size_t)na) == 0, "the bits of the first run");
    api.FreeSlaveInstance(c);
    current = NULL;
}

static void refused_instantiations(void) {
    section = "instantiation";
    long before = n_errors;
    CHECK(!api.InstantiateSlave("x", "{wrong}", "", "", 0, 0, 0, callbacks(), 0) && n_errors > before,
          "wrong GUID");
    before = n_errors;
    CHECK(!api.InstantiateSlave("", CW_MODEL_GUID, "", "", 0, 0, 0, callbacks(), 0) && n_errors > before,
          "empty name");
    fmi1CallbackFunctions none = {logger, NULL, NULL, NULL};
    CHECK(!api.InstantiateSlave("x", CW_MODEL_GUID, "", "", 0, 0, 0, none, 0), "no memory functions");
    fmi1CallbackFunctions quiet_cb = {NULL, h_alloc, h_free, NULL};
    fmi1Component quiet = api.InstantiateSlave("q", CW_MODEL_GUID, "", "", 0, 0, 0, quiet_cb, 0);
    CHECK(quiet != NULL, "an instance without a logger");
    if (quiet) {
        CHECK(api.DoStep(quiet, 0, 1, fmi1True) == fmi1Error, "silently refused");
        api.FreeSlaveInstance(quiet);
    }
    api.FreeSlaveInstance(NULL);
}

/* Any order: a long random walk over the state machine's functions. */
static void random_walk(void) {
    section = "random order";
    fmi1Component c = instantiate("walk");
    if (!c) return;
    current = c;
    uint64_t rng = 0x9E3779B97F4A7C15ull;
    double t = 0.0;
    for (int n = 0; n < 3000; n++) {
        rng ^= rng << 13, rng ^= rng >> 7, rng ^= rng << 17;
        int pick = (int)(rng % 10);
        long before = n_errors;
        fmi1Status st = fmi1OK;
        fmi1Real x = 1e-3;
        fmi1Boolean b = (fmi1Boolean)(rng >> 20);
        fmi1ValueReference vr = (fmi1ValueReference)((rng >> 8) % (CW_NVARS + 2));
        switch (pick) {
        case 0: st = api.InitializeSlave(c, t, fmi1False, 0.0); break;
        case 1: st = api.DoStep(c, t, 0.07, (rng >> 30) % 8 ? fmi1True : fmi1False);
                if (st == fmi1OK) t += 0.07;
                break;
        case 2: st = api.TerminateSlave(c); break;
        case 3: st = api.ResetSlave(c); if (st == fmi1OK) t = 0.0; break;
        case 4: st = api.GetReal(c, &vr, 1, &x); break;
        case 5: st = api.SetReal(c, &vr, 1, &x); break;
        case 6: st = api.GetBoolean(c, &vr, 1, &b); break;
        case 7: st = api.SetBoolean(c, &vr, 1, &b); break;
        case 8: st = api.GetRealOutputDerivatives(c, &vr, 1, (fmi1Integer[]){1}, &x); break;
        case 9: st = api.SetRealInputDerivatives(c, &vr, 1, (fmi1Integer[]){1}, &x); break;
        }
        CHECK(st == fmi1OK || st == fmi1Discard || st == fmi1Error, "status %d", (int)st);
        if (st == fmi1Error) CHECK(n_errors > before, "call %d refused without a message", pick);
    }
    api.FreeSlaveInstance(c);
    current = NULL;
}

int main(int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: %s path/to/fmi1/<Model>.so\n", argv[0]);
        return 2;
    }
    void *lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "dlopen: %s\n", dlerror());
        return 2;
    }
#define LOAD(n)                                                              \
    api.n = (fmi1##n##TYPE *)dlsym(lib, CW_MODEL_NAME "_fmi" #n);            \
    if (!api.n) {                                                            \
        fprintf(stderr, "missing %s_fmi" #n "\n", CW_MODEL_NAME);           \
        n_failures++;                                                        \
    }
    FMI1_FUNCTIONS(LOAD)
#undef LOAD
    if (n_failures) return 1;
    CHECK(strcmp(api.GetVersion(), "1.0") == 0, "version");
    CHECK(strcmp(api.GetTypesPlatform(), "standard32") == 0, "types platform");
    refused_instantiations();
    lifecycle();
    random_walk();
    CHECK(h_live_blocks == 0, "%ld blocks not freed", h_live_blocks);
    printf("%s (FMI 1.0): %ld checks, %ld failures, %ld messages\n", CW_MODEL_NAME, n_checks, n_failures,
           n_messages);
    dlclose(lib);
    return n_failures ? 1 : 0;
}
