/* libFuzzer harness for the FMI 3.0 face of a clockwork FMU: compiled (by
 * tools/fuzz.sh) against each model's runtime core, cw_fmi3.c and model
 * objects, with -fsanitize=fuzzer,address,undefined. fuzz_fmu.c covers the
 * core through the fmi2 face; this one covers what the fmi3 face adds and
 * routes: Event Mode and Step Mode in any order, instances with and without
 * eventModeUsed and earlyReturnAllowed, with and without an intermediate
 * update callback (fuzzed inputs, refused calls inside it), fmi3DoStep's
 * early return, the typed getters and setters with nValues, FMU states
 * (also corrupted), and the functions the FMU does not provide.
 *
 * Pass = no crash, no sanitizer report, no hang, and after every call:
 *   - every status is OK, Warning, Discard or Error, and every fmi3Error
 *     from a live instance came with a logged error message;
 *   - every Float64 is finite and every Boolean 0/1 when read with fmi3OK;
 *   - an early return ends strictly inside its step, is only made when
 *     allowed, and asks for Event Mode only when Event Mode is used;
 *   - a state saved, serialized, deserialized and restored gives back the
 *     same values bit for bit;
 *   - nothing is leaked (LeakSanitizer). */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"

#define CW_VARS_TABLE_ONLY
#include "cw_vars.h"

#define FAIL(...)                                                            \
    do {                                                                     \
        fprintf(stderr, "fuzz_fmu3 (%s): ", CW_MODEL_NAME);                  \
        fprintf(stderr, __VA_ARGS__);                                        \
        fprintf(stderr, " (last message: %s)\n", last);                      \
        abort();                                                             \
    } while (0)

static long n_errors;
static char last[1100];

static void logger(fmi3InstanceEnvironment env, fmi3Status status,
                   fmi3String category, fmi3String message) {
    (void)env;
    if (!message || !category) FAIL("logged a NULL message or category");
    if (status >= fmi3Error) n_errors++;
    snprintf(last, sizeof last, "%s", message);
}

typedef struct {
    const uint8_t *p;
    size_t n;
} reader;

static uint8_t u8(reader *r) {
    if (!r->n) return 0;
    r->n--;
    return *r->p++;
}

static double fuzz_double(reader *r, const cw_var_info *v) {
    const uint8_t tag = u8(r);
    switch (tag % 12) {
    case 0: return NAN;
    case 1: return INFINITY;
    case 2: return -DBL_MAX;
    case 3: return 0.0;
    case 4: return 4.9e-324;
    case 5: return (tag & 0x80 ? -1 : 1) * 1e300;
    case 6: {
        uint64_t bits = 0;
        for (int b = 0; b < 8; b++) bits |= (uint64_t)u8(r) << (8 * b);
        double x;
        memcpy(&x, &bits, 8);
        return x;
    }
    case 7:
    case 8:
        if (v && isfinite(v->min) && isfinite(v->max))
            return v->min + (double)u8(r) / 255.0 * (v->max - v->min);
        return ldexp((double)(int8_t)u8(r), (int)(u8(r) % 16) - 8);
    default: return v ? v->start : 0.0;
    }
}

static fmi3ValueReference fuzz_vr(reader *r) {
    const uint8_t x = u8(r);
    if (x < 240) return (fmi3ValueReference)(x % (CW_NVARS + 1)); /* + time */
    return (fmi3ValueReference)CW_NVARS + (x - 239);
}

static const cw_var_info *info(fmi3ValueReference vr) {
    return vr < (fmi3ValueReference)CW_NVARS && CW_VARS[vr].name ? &CW_VARS[vr] : NULL;
}

static double fuzz_step(reader *r) {
    static const double sane[] = {1e-3, 1e-2, 0.05, 0.1, 0.5, 1.0, 2.0, 10.0};
    const uint8_t tag = u8(r);
    return tag < 200 ? sane[tag % 8] : fuzz_double(r, NULL);
}

/* ------------------------------------------------------------------ */

static fmi3Instance C;
static int event_mode, early_allowed;
static double T;

/* Every Float64, Int32 and Boolean variable's value, read with fmi3OK. */
typedef struct {
    double r[CW_NVARS + 1];
    int32_t i[CW_NVARS + 1];
    int ok;
} values;

static void read_all(fmi3Instance c, values *v) {
    memset(v, 0, sizeof *v);
    v->ok = 1;
    const long e = n_errors;
    for (int k = 0; k < CW_NVARS; k++) {
        const cw_var_info *x = &CW_VARS[k];
        if (!x->name) continue;
        fmi3ValueReference vr = (fmi3ValueReference)k;
        if (x->type == CW_REAL) {
            if (fmi3GetFloat64(c, &vr, 1, &v->r[k], 1) != fmi3OK) v->ok = 0;
            else if (!isfinite(v->r[k])) FAIL("%s = %g with fmi3OK", x->name, v->r[k]);
        } else if (x->type == CW_INTEGER) {
            if (fmi3GetInt32(c, &vr, 1, &v->i[k], 1) != fmi3OK) v->ok = 0;
        } else {
            fmi3Boolean b;
            if (fmi3GetBoolean(c, &vr, 1, &b, 1) != fmi3OK) v->ok = 0;
            else v->i[k] = b;
        }
    }
    n_errors = e; /* reads in a state that refuses them are not findings */
}

static fmi3Status checked(fmi3Status st, long before, const char *fn) {
    if (st < fmi3OK || st > fmi3Error) FAIL("%s returned status %d", fn, (int)st);
    if (st == fmi3Error && n_errors == before) FAIL("%s returned fmi3Error without logging why", fn);
    if (C) {
        values v;
        read_all(C, &v);
    }
    return st;
}

static long before;
#define CALL(fn, ...) (before = n_errors, checked(fmi3##fn(__VA_ARGS__), before, #fn))

/* Intermediate update: the callback, given the fuzz input as its
 * environment, sets the Float64 inputs to fuzzed values or tries what
 * Intermediate Update Mode refuses; it may only be called inside
 * fmi3DoStep, at a time inside the step. */
static int in_do_step;
static double step_tc, step_h;

static void intermediate(fmi3InstanceEnvironment env, fmi3Float64 t, fmi3Boolean set_requested,
                         fmi3Boolean get_allowed, fmi3Boolean step_finished, fmi3Boolean can_return_early,
                         fmi3Boolean *early_requested, fmi3Float64 *early_time) {
    reader *r = env;
    (void)step_finished;
    if (!in_do_step) FAIL("intermediate update outside fmi3DoStep");
    if (!(t >= step_tc && t <= step_tc + step_h))
        FAIL("intermediate update at %.17g outside [%.17g, %.17g]", t, step_tc, step_tc + step_h);
    if (!set_requested || get_allowed || can_return_early) FAIL("unexpected intermediate update flags");
    if (!early_requested || !early_time) FAIL("NULL early-return arguments");
    *early_requested = fmi3False;
    const uint8_t what = u8(r);
    const long e = n_errors;
    if (what % 8 == 7) { /* what the mode refuses: each must fail with a logged reason */
        fmi3Boolean a, b, c;
        double x;
        fmi3ValueReference vr = fuzz_vr(r);
        const cw_var_info *v = info(vr);
        if (fmi3DoStep(C, t, 0.1, fmi3False, &a, &b, &c, &x) != fmi3Error || n_errors == e)
            FAIL("fmi3DoStep in Intermediate Update Mode");
        if (fmi3GetFloat64(C, &vr, 1, &x, 1) != fmi3Error)
            FAIL("fmi3GetFloat64 in Intermediate Update Mode");
        x = 1.0;
        if ((!v || v->causality != CW_INPUT || v->type != CW_REAL) &&
            fmi3SetFloat64(C, &vr, 1, &x, 1) != fmi3Error)
            FAIL("fmi3SetFloat64 of %u (not a Float64 input) in Intermediate Update Mode", (unsigned)vr);
        n_errors = e;
        return;
    }
    for (int k = 0; k < CW_NVARS; k++) {
        const cw_var_info *v = &CW_VARS[k];
        if (!v->name || v->type != CW_REAL || v->causality != CW_INPUT || !(u8(r) & 1)) continue;
        fmi3ValueReference vr = (fmi3ValueReference)k;
        double x = fuzz_double(r, v);
        fmi3SetFloat64(C, &vr, 1, &x, 1); /* a bad value fails the step, with a reason */
    }
}

static fmi3Instance instantiate(reader *r) {
    const uint8_t f = u8(r);
    event_mode = f & 1;
    early_allowed = (f >> 1) & 1;
    return fmi3InstantiateCoSimulation("fuzz3", CW_MODEL_GUID, NULL, fmi3False, (f >> 2) & 1,
                                       event_mode, early_allowed, NULL, 0, r, logger,
                                       (f >> 3) & 1 ? intermediate : NULL);
}

static void sync_time(void) {
    fmi3ValueReference tv = CW_NVARS;
    double t;
    const long e = n_errors;
    if (fmi3GetFloat64(C, &tv, 1, &t, 1) == fmi3OK) T = t;
    n_errors = e;
}

enum { SLOTS = 2 };
static fmi3FMUState slot[SLOTS];

static void round_trip(reader *r) {
    fmi3FMUState s = NULL, s2 = NULL;
    values a, b;
    if (CALL(GetFMUState, C, &s) != fmi3OK) return;
    read_all(C, &a);
    size_t size = 0;
    CALL(SerializedFMUStateSize, C, s, &size);
    uint8_t *buf = malloc(size ? size : 1);
    if (CALL(SerializeFMUState, C, s, buf, size) != fmi3OK) FAIL("serialize");
    CALL(FreeFMUState, C, &s);
    if (u8(r) & 1) buf[u8(r) % size] ^= (uint8_t)(1u << (u8(r) % 8));
    else if (CALL(DeserializeFMUState, C, buf, size, &s2) != fmi3OK)
        FAIL("an own state was refused");
    if (s2) {
        if (CALL(SetFMUState, C, s2) != fmi3OK) FAIL("restoring an own state");
        CALL(FreeFMUState, C, &s2);
        read_all(C, &b);
        if (a.ok && (memcmp(a.r, b.r, sizeof a.r) || memcmp(a.i, b.i, sizeof a.i)))
            FAIL("values differ after a state round trip");
    } else if (CALL(DeserializeFMUState, C, buf, size, &s2) == fmi3OK) {
        /* a flipped bit the checksum cannot see would be a finding */
        FAIL("a corrupted state was accepted");
    }
    free(buf);
}

static void free_all(void) {
    for (int k = 0; k < SLOTS; k++)
        if (slot[k]) fmi3FreeFMUState(C, &slot[k]);
    if (C) fmi3FreeInstance(C);
    C = NULL;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    reader rd = {data, size}, *r = &rd;
    memset(slot, 0, sizeof slot);
    T = 0.0;
    C = instantiate(r);
    if (!C) FAIL("plain instantiation failed");
    if (u8(r) & 1) {
        CALL(EnterInitializationMode, C, fmi3False, 0.0, 0.0, fmi3False, 0.0);
        CALL(ExitInitializationMode, C);
    }
    int steps = 0;
    while (rd.n > 0) {
        const uint8_t op = u8(r);
        if (!C) {
            C = instantiate(r);
            T = 0.0;
            continue;
        }
        fmi3Boolean f[5];
        double x = 0.0;
        switch (op % 20) {
        case 0:
        case 1: {
            fmi3ValueReference vr = fuzz_vr(r);
            x = fuzz_double(r, info(vr));
            CALL(SetFloat64, C, &vr, 1, &x, (op & 0x80) ? 2 : 1);
            break;
        }
        case 2: {
            fmi3ValueReference vr = fuzz_vr(r);
            int32_t i = (int32_t)(u8(r) % 5) - 2;
            fmi3Boolean b = i != 0;
            if (op & 0x80) CALL(SetBoolean, C, &vr, 1, &b, 1);
            else CALL(SetInt32, C, &vr, 1, &i, 1);
            break;
        }
        case 3:
        case 4:
        case 5: {
            if (++steps > 64) break;
            const double h = fuzz_step(r);
            const double tc = u8(r) % 8 ? T : fuzz_double(r, NULL);
            fmi3Boolean event = 1, term = 1, early = 1;
            double t_last = NAN;
            in_do_step = 1, step_tc = tc, step_h = h;
            fmi3Status st = CALL(DoStep, C, tc, h, fmi3False, &event, &term, &early, &t_last);
            in_do_step = 0;
            if (st <= fmi3Warning) {
                if (early && !early_allowed) FAIL("an early return that was not allowed");
                if (early && !(t_last > tc && t_last < tc + h))
                    FAIL("early return at %.17g outside (%.17g, %.17g)", t_last, tc, tc + h);
                if (!early && t_last != tc + h) FAIL("a full step ended at %.17g", t_last);
                if (event && !(event_mode && early)) FAIL("eventHandlingNeeded without its event");
                if (term) FAIL("terminateSimulation");
                T = t_last;
            }
            break;
        }
        case 6: CALL(EnterEventMode, C); break;
        case 7: CALL(UpdateDiscreteStates, C, &f[0], &f[1], &f[2], &f[3], &f[4], &x); break;
        case 8: CALL(EnterStepMode, C); break;
        case 9:
            CALL(EnterInitializationMode, C, fmi3False, 0.0, fuzz_double(r, NULL), u8(r) & 1,
                 fuzz_double(r, NULL));
            sync_time();
            break;
        case 10: CALL(ExitInitializationMode, C); break;
        case 11: CALL(Terminate, C); break;
        case 12: if (CALL(Reset, C) == fmi3OK) T = 0.0; break;
        case 13: CALL(GetFMUState, C, &slot[u8(r) % SLOTS]); break;
        case 14: {
            const int k = u8(r) % SLOTS;
            if (slot[k] && CALL(SetFMUState, C, slot[k]) == fmi3OK) sync_time();
            break;
        }
        case 15: round_trip(r); break;
        case 16: {
            fmi3ValueReference vr = fuzz_vr(r);
            fmi3Int32 order = (fmi3Int32)(u8(r) % 4) - 1;
            if (CALL(GetOutputDerivatives, C, &vr, 1, &order, &x, 1) == fmi3OK && !isfinite(x))
                FAIL("output derivative = %g with fmi3OK", x);
            break;
        }
        case 17: { /* what the FMU does not provide */
            fmi3ValueReference vr = fuzz_vr(r);
            uint64_t u = 0;
            switch (u8(r) % 4) {
            case 0: CALL(GetUInt64, C, &vr, 1, &u, 1); break;
            case 1: CALL(EnterConfigurationMode, C); break;
            case 2: CALL(GetClock, C, &vr, 1, (fmi3Clock *)&f[0]); break;
            default: CALL(EvaluateDiscreteStates, C); break;
            }
            break;
        }
        case 18: {
            static const fmi3String cats[] = {"logEvents", "logAll", "bogus"};
            CALL(SetDebugLogging, C, op >> 7, u8(r) % 4, cats);
            break;
        }
        default:
            free_all();
            C = instantiate(r);
            T = 0.0;
            break;
        }
    }
    free_all();
    return 0;
}
