/* libFuzzer harness for a clockwork FMU: one generic harness, compiled
 * (by tools/fuzz.sh) against each model's runtime and model objects and its
 * generated cw_vars.h, with -fsanitize=fuzzer,address,undefined.
 *
 * The fuzz input is decoded into a random sequence of FMI calls: parameter,
 * input and input-derivative values including NaN, inf, huge and denormal
 * numbers; step sizes including 0, negative and denormal; communication
 * points that do not match; get/set/free of FMU states; serialization with
 * truncated, extended, bit-flipped or re-checksummed buffers; calls in the
 * wrong state; failing allocations; fresh instances.
 *
 * Pass = no crash, no sanitizer report, no hang (libFuzzer's -timeout), and
 * these invariants, checked after every call (abort() otherwise):
 *   - no Real variable is NaN/inf, no Boolean other than 0/1 and no String
 *     NULL, when fmi2GetReal/fmi2GetBoolean/fmi2GetString said fmi2OK (read
 *     after every call); Strings set from the input, or NULL, on models that
 *     have them (tests/models/TestTypes);
 *   - output derivatives returned with fmi2OK are finite;
 *   - every status is OK, Warning, Discard or Error, and every fmi2Error
 *     from a live instance came with a logged error message;
 *   - a state saved, serialized, deserialized and restored gives back the
 *     same values bit for bit, and a fresh twin instance restored from it
 *     steps to the same values bit for bit;
 *   - nothing the FMU allocated is left when the input is done. */
#include <float.h>

#include "fmi2Functions.h" /* the fmi2 functions, linked in */
#include "harness.h"

static fmi_api api;
static h_log LOG;
static fmi2CallbackFunctions CB;

#define FAIL(...)                                                            \
    do {                                                                     \
        fprintf(stderr, "fuzz_fmu (%s): ", CW_MODEL_NAME);                   \
        fprintf(stderr, __VA_ARGS__);                                        \
        fprintf(stderr, " (last message: %s)\n", LOG.last);                  \
        abort();                                                             \
    } while (0)

/* ------------------------------------------------------------------ */
/* Reading the fuzz input; past its end everything reads as zero. */

typedef struct {
    const uint8_t *p;
    size_t n;
} reader;

static uint8_t u8(reader *r) {
    if (!r->n) return 0;
    r->n--;
    return *r->p++;
}

static uint32_t u32(reader *r) {
    uint32_t x = 0;
    for (int b = 0; b < 4; b++) x |= (uint32_t)u8(r) << (8 * b);
    return x;
}

static uint64_t u64(reader *r) {
    return (uint64_t)u32(r) | (uint64_t)u32(r) << 32;
}

/* A double, biased towards the values that break numerical code. `v` (may
 * be NULL) gives the variable's start and range to stay near. */
static double fuzz_double(reader *r, const cw_var_info *v) {
    const uint8_t tag = u8(r);
    switch (tag % 20) {
    case 0: return NAN;
    case 1: return INFINITY;
    case 2: return -INFINITY;
    case 3: return 0.0;
    case 4: return -0.0;
    case 5: return DBL_MIN;
    case 6: return 4.9e-324; /* smallest denormal */
    case 7: return -4.9e-324;
    case 8: return DBL_MAX;
    case 9: return -DBL_MAX;
    case 10: return (tag & 0x80 ? -1 : 1) * 1e300;
    case 11: {
        uint64_t bits = u64(r);
        double x;
        memcpy(&x, &bits, 8);
        return x;
    }
    case 12: return (double)(int16_t)(u8(r) | u8(r) << 8) / 16.0;
    case 13:
    case 14:
        if (v && isfinite(v->min) && isfinite(v->max)) {
            const double f = (double)(u8(r) | u8(r) << 8) / 65535.0;
            return v->min + f * (v->max - v->min);
        }
        return ldexp((double)(int8_t)u8(r), (int)(u8(r) % 64) - 32);
    case 15:
        if (v) return tag & 0x80 ? nextafter(v->min, -INFINITY) : nextafter(v->max, INFINITY);
        return 1e-300;
    case 16: return v ? v->start * (1.0 + (double)(int8_t)u8(r) / 64.0) : 1.0;
    case 17: return (tag & 0x80 ? -1 : 1) * ldexp(1.0, (int)(u8(r) % 128) - 64);
    default: return v ? v->start : 0.0;
    }
}

static int32_t fuzz_int(reader *r, const cw_var_info *v) {
    switch (u8(r) % 8) {
    case 0: return 0;
    case 1: return 1;
    case 2: return -1;
    case 3: return INT32_MIN;
    case 4: return INT32_MAX;
    case 5: return v && isfinite(v->min) && v->min > INT32_MIN ? (int32_t)v->min - 1 : 7;
    case 6: return v && isfinite(v->max) && v->max < INT32_MAX ? (int32_t)v->max + 1 : -7;
    default: return (int32_t)u32(r);
    }
}

/* Whether the model has String variables: only then does the input choose
 * fmi2SetString (the other models' inputs keep their meaning). */
static int has_strings(void) {
    for (int k = 0; k < CW_NVARS; k++)
        if (CW_VARS[k].name && CW_VARS[k].type == CW_STRING) return 1;
    return 0;
}
#define HAS_STRINGS has_strings()

/* A value reference: mostly real variables, sometimes holes and junk. */
static fmi2ValueReference fuzz_vr(reader *r) {
    const uint8_t x = u8(r);
    if (x < 240) return (fmi2ValueReference)(x % (CW_NVARS > 0 ? CW_NVARS : 1));
    if (x < 250) return (fmi2ValueReference)CW_NVARS + (x - 240);
    return 0xFFFFFFFFu - (x - 250);
}

static const cw_var_info *info(fmi2ValueReference vr) {
    return vr < (fmi2ValueReference)CW_NVARS && CW_VARS[vr].name ? &CW_VARS[vr] : NULL;
}

/* A step size: usually sensible, sometimes not. Large steps are bounded
 * by the integrators' per-call step limit (CW_RK_MAX_STEPS). */
static double fuzz_step(reader *r) {
    const uint8_t tag = u8(r);
    static const double sane[] = {1e-3, 1e-2, 0.05, 0.1, 0.5, 1.0, 2.0, 10.0};
    if (tag < 160) return sane[tag % 8];
    if (tag < 176) return ldexp(1.0, (int)(u8(r) % 80) - 60);
    return fuzz_double(r, NULL);
}

/* ------------------------------------------------------------------ */
/* Checks */

static fmi2Component C; /* the instance under test, or NULL */
static double T;        /* the master's idea of the FMU's time */

/* C's experiment setup. Start and stop time belong to the instance, not to
 * the FMU state (docs/design.md's layout has neither), so a twin restored
 * from serialized bytes gets the same setup first. */
static struct {
    int set;
    double t0, stop;
    fmi2Boolean has_stop;
} EXP;

static void check_values(fmi2Component c, h_values *out) {
    h_values v;
    h_read_all(&api, c, &v);
    const char *bad = h_unfit_value(&v);
    if (bad) FAIL("%s is not finite (or not a Boolean 0/1, or a NULL String) with fmi2OK", bad);
    if (out) *out = v;
}

/* Every call goes through here: status sanity and the error-log rule. */
static int trace; /* CW_FUZZ_TRACE=1: print every call, to replay a finding */

static fmi2Status checked(fmi2Status st, long errors_before, const char *fn) {
    if (trace) fprintf(stderr, "%s -> %d\n", fn, (int)st);
    if (st < fmi2OK || st > fmi2Error)
        FAIL("%s returned status %d", fn, (int)st);
    if (st == fmi2Error && LOG.n_errors == errors_before)
        FAIL("%s returned fmi2Error without logging why", fn);
    if (C) check_values(C, NULL);
    return st;
}

static long errors_before;
#define CALL(fn, ...)                                                        \
    (errors_before = LOG.n_errors,                                           \
     checked(api.fn(__VA_ARGS__), errors_before, #fn))

static void sync_time(void) {
    double t;
    long e = LOG.n_errors;
    if (C && api.GetRealStatus(C, fmi2LastSuccessfulTime, &t) == fmi2OK) T = t;
    LOG.n_errors = e; /* a refused status query is not the FMU's fault */
}

/* ------------------------------------------------------------------ */
/* FMU states */

enum { SLOTS = 3 };
static fmi2FMUstate slot[SLOTS];

static unsigned char *serialize(fmi2Component c, fmi2FMUstate s, size_t *size) {
    *size = 0;
    if (!s) return NULL;
    if (CALL(SerializedFMUstateSize, c, s, size) != fmi2OK) return NULL;
    if (*size > (1u << 20)) FAIL("serialized state of %zu bytes", *size);
    unsigned char *buf = malloc(*size ? *size : 1);
    if (CALL(SerializeFMUstate, c, s, (fmi2Byte *)buf, *size) != fmi2OK) {
        free(buf);
        return NULL;
    }
    return buf;
}

static fmi2Component instantiate(reader *r) {
    const uint8_t flags = u8(r);
    return api.Instantiate("fuzz", fmi2CoSimulation, CW_MODEL_GUID, "",
                           &CB, fmi2False, flags & 1 ? fmi2True : fmi2False);
}

static void free_all(void) {
    for (int k = 0; k < SLOTS; k++)
        if (slot[k]) {
            if (!C) FAIL("a state outlived its instance");
            api.FreeFMUstate(C, &slot[k]);
            if (slot[k]) FAIL("FreeFMUstate left the pointer set");
        }
    if (C) api.FreeInstance(C);
    C = NULL;
}

/* The state round trip: save, serialize, deserialize, restore. Values are
 * unchanged bit for bit, and a fresh twin restored from the bytes steps to
 * the same values as the original. */
static void round_trip(reader *r) {
    fmi2FMUstate s = NULL, s2 = NULL;
    h_values before, after;
    if (CALL(GetFMUstate, C, &s) != fmi2OK) return;
    check_values(C, &before);
    size_t size;
    unsigned char *buf = serialize(C, s, &size);
    api.FreeFMUstate(C, &s);
    if (!buf) return;
    if (CALL(DeSerializeFMUstate, C, (fmi2Byte *)buf, size, &s2) != fmi2OK) {
        if (h_fail_countdown < 0)
            FAIL("a state the FMU serialized itself was refused");
        free(buf); /* out of memory, as the fuzzer asked */
        return;
    }
    if (CALL(SetFMUstate, C, s2) != fmi2OK) {
        /* A rollback allocates nothing, except the copies of a model's Strings. */
        if (!(HAS_STRINGS && h_fail_countdown >= 0)) FAIL("restoring an own state failed");
        api.FreeFMUstate(C, &s2);
        free(buf);
        return;
    }
    api.FreeFMUstate(C, &s2);
    check_values(C, &after);
    if (!h_same_values(&before, &after))
        FAIL("values differ after a serialize/deserialize round trip");

    if (u8(r) & 1) {
        fmi2Component twin = instantiate(r);
        if (!twin) {
            free(buf);
            return;
        }
        fmi2FMUstate t = NULL;
        if (EXP.set)
            api.SetupExperiment(twin, fmi2False, 0.0, EXP.t0, EXP.has_stop, EXP.stop);
        if (api.DeSerializeFMUstate(twin, (fmi2Byte *)buf, size, &t) != fmi2OK) {
            if (h_fail_countdown < 0)
                FAIL("a fresh instance refused a serialized state");
            api.FreeInstance(twin);
            free(buf);
            return;
        }
        if (api.SetFMUstate(twin, t) != fmi2OK) {
            if (!(HAS_STRINGS && h_fail_countdown >= 0)) FAIL("a fresh instance refused a state");
            api.FreeFMUstate(twin, &t);
            api.FreeInstance(twin);
            free(buf);
            return;
        }
        api.FreeFMUstate(twin, &t);
        sync_time();
        const double h = fuzz_step(r);
        fmi2Status a = api.DoStep(C, T, h, fmi2False);
        fmi2Status b = api.DoStep(twin, T, h, fmi2False);
        h_values va, vb;
        h_read_all(&api, C, &va);
        h_read_all(&api, twin, &vb);
        if (a != b || !h_same_values(&va, &vb))
            FAIL("a twin restored from serialized bytes stepped differently "
                 "(status %d vs %d, h = %g)", (int)a, (int)b, h);
        api.FreeInstance(twin);
        sync_time();
    }
    free(buf);
}

/* A corrupted serialized state must be refused, or (when the corruption
 * happens to produce valid content) accepted as a usable state. */
static void corrupt_and_restore(reader *r) {
    const int k = u8(r) % SLOTS;
    size_t size;
    unsigned char *buf = serialize(C, slot[k], &size);
    if (!buf) return;
    size_t n = size;
    unsigned char *bad = malloc(size + 64);
    memcpy(bad, buf, size);
    memset(bad + size, 0, 64);
    free(buf);
    const uint8_t mode = u8(r) % 7;
    switch (mode) {
    case 0: n = u32(r) % (size + 1); break;             /* truncate */
    case 1: n = size + 1 + u8(r) % 63; break;           /* extend */
    case 2: bad[u32(r) % size] ^= (uint8_t)(1u << (u8(r) % 8)); break;
    case 3:                                             /* rewrite, re-checksum */
        for (int j = u8(r) % 4; j >= 0; j--) bad[u32(r) % size] = u8(r);
        h_fix_checksum(bad, size);
        break;
    case 4: {                                           /* a value, re-checksum */
        const fmi2ValueReference vr = fuzz_vr(r);
        const cw_var_info *v = info(vr);
        if (v) {
            const size_t off = h_value_offset(vr);
            if (v->type == CW_REAL)
                h_put_f64(bad + off, fuzz_double(r, v));
            else
                h_put_u32(bad + off, (uint32_t)fuzz_int(r, v));
        }
        h_fix_checksum(bad, size);
        break;
    }
    case 5: {                                           /* model state word */
        const size_t ms = h_model_state_offset();
        const size_t words = (size - 8 - ms - 8) / 8;   /* both blocks */
        if (words) h_put_f64(bad + ms + 4 + 8 * (u8(r) % words), fuzz_double(r, NULL));
        h_fix_checksum(bad, size);
        break;
    }
    default: h_put_u32(bad + 20, u32(r)); h_fix_checksum(bad, size); break;
    }
    fmi2FMUstate s = NULL;
    fmi2Status st = CALL(DeSerializeFMUstate, C, (fmi2Byte *)bad, n, &s);
    if (st == fmi2OK) {
        if (!s) FAIL("DeSerializeFMUstate said OK without a state");
        if (u8(r) & 1) {
            CALL(SetFMUstate, C, s);
            sync_time();
        }
        CALL(FreeFMUstate, C, &s);
    } else if (s) {
        FAIL("a refused buffer returned a state");
    }
    free(bad);
}

/* ------------------------------------------------------------------ */

static int ready;

static void bind_api(void) {
#define H_BIND(n) api.n = fmi2##n;
    FMI_FUNCTIONS(H_BIND)
#undef H_BIND
    CB = h_callbacks(&LOG);
    trace = getenv("CW_FUZZ_TRACE") != NULL;
    LOG.echo = trace;
    ready = 1;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    if (!ready) bind_api();
    reader rd = {data, size}, *r = &rd;
    const long live_at_start = h_live_blocks;
    memset(slot, 0, sizeof slot);
    T = 0.0;
    EXP.set = 0;
    C = instantiate(r);
    if (!C) FAIL("plain instantiation failed");
    const uint8_t start = u8(r);
    if (start & 1) { /* most sequences want an initialized instance */
        if (CALL(SetupExperiment, C, fmi2False, 0.0, 0.0, fmi2False, 0.0) == fmi2OK)
            EXP.set = 1, EXP.t0 = 0.0, EXP.has_stop = fmi2False, EXP.stop = 0.0;
        CALL(EnterInitializationMode, C);
        CALL(ExitInitializationMode, C);
    }
    int steps = 0;
    while (rd.n > 0) {
        const uint8_t op = u8(r);
        if (!C) { /* only a new instance can follow a failed instantiation */
            C = instantiate(r);
            EXP.set = 0;
            continue;
        }
        switch (op % 24) {
        case 0:
        case 1: { /* one Real */
            fmi2ValueReference vr = fuzz_vr(r);
            double x = fuzz_double(r, info(vr));
            if (trace) fprintf(stderr, "SetReal vr %u = %.17g\n", (unsigned)vr, x);
            CALL(SetReal, C, &vr, 1, &x);
            break;
        }
        case 2: { /* several Reals in one call */
            fmi2ValueReference vr[4];
            double x[4];
            const size_t n = u8(r) % 5;
            for (size_t k = 0; k < n; k++) {
                vr[k] = fuzz_vr(r);
                x[k] = fuzz_double(r, info(vr[k]));
                if (trace) fprintf(stderr, "SetReal vr %u = %.17g\n", (unsigned)vr[k], x[k]);
            }
            CALL(SetReal, C, vr, n, x);
            break;
        }
        case 3: {
            fmi2ValueReference vr = fuzz_vr(r);
            if (HAS_STRINGS && (op & 0x40)) { /* a String: text from the input, or NULL */
                char text[49];
                const size_t n = u8(r) % 49;
                for (size_t k = 0; k < n; k++) text[k] = (char)u8(r);
                text[n < 48 ? n : 48] = '\0';
                fmi2String value = op & 0x80 ? NULL : text;
                if (trace) fprintf(stderr, "SetString vr %u = %s\n", (unsigned)vr, value ? value : "(NULL)");
                CALL(SetString, C, &vr, 1, &value);
                break;
            }
            fmi2Integer x = fuzz_int(r, info(vr));
            if (op & 0x80)
                CALL(SetBoolean, C, &vr, 1, &x);
            else
                CALL(SetInteger, C, &vr, 1, &x);
            break;
        }
        case 4:
        case 5: { /* input derivatives */
            fmi2ValueReference vr = fuzz_vr(r);
            fmi2Integer order = (fmi2Integer)(u8(r) % 5) - 1;
            double x = fuzz_double(r, NULL);
            if (trace) fprintf(stderr, "input derivative vr %u order %d = %.17g\n", (unsigned)vr, (int)order, x);
            CALL(SetRealInputDerivatives, C, &vr, 1, &order, &x);
            break;
        }
        case 6:
        case 7:
        case 8: { /* steps, at the right or a fuzzed point */
            if (++steps > 64) break;
            double h = fuzz_step(r);
            double tc = T;
            if (u8(r) % 8 == 0) tc = fuzz_double(r, NULL);
            if (trace) fprintf(stderr, "DoStep(%.17g, %.17g)\n", tc, h);
            fmi2Status st = CALL(DoStep, C, tc, h, (fmi2Boolean)(op & 1));
            if (st <= fmi2Warning) T = tc + h;
            break;
        }
        case 9: { /* a run of steps */
            const double h = fuzz_step(r);
            if (trace) fprintf(stderr, "run of steps of %.17g from %.17g\n", h, T);
            for (int k = u8(r) % 32; k > 0 && steps < 64; k--, steps++) {
                if (CALL(DoStep, C, T, h, fmi2True) > fmi2Warning) break;
                T += h;
            }
            break;
        }
        case 10: {
            fmi2ValueReference vr = fuzz_vr(r);
            fmi2Integer order = (fmi2Integer)(u8(r) % 5) - 1;
            double x = 0.0;
            if (CALL(GetRealOutputDerivatives, C, &vr, 1, &order, &x) == fmi2OK &&
                !isfinite(x))
                FAIL("output derivative of vr %u, order %d = %g with fmi2OK",
                     (unsigned)vr, (int)order, x);
            break;
        }
        case 11: CALL(GetFMUstate, C, &slot[u8(r) % SLOTS]); break;
        case 12: {
            const int k = u8(r) % SLOTS;
            if (slot[k]) {
                CALL(SetFMUstate, C, slot[k]);
                sync_time();
            }
            break;
        }
        case 13: CALL(FreeFMUstate, C, &slot[u8(r) % SLOTS]); break;
        case 14: corrupt_and_restore(r); break;
        case 15: round_trip(r); break;
        case 16: { /* raw bytes from the input as a serialized state */
            const size_t n = u8(r) % 1024;
            unsigned char *buf = malloc(n ? n : 1);
            for (size_t k = 0; k < n; k++) buf[k] = u8(r);
            fmi2FMUstate s = NULL;
            if (CALL(DeSerializeFMUstate, C, (fmi2Byte *)buf, n, &s) == fmi2OK)
                CALL(FreeFMUstate, C, &s);
            free(buf);
            break;
        }
        case 17:
            if (CALL(Reset, C) == fmi2OK) EXP.set = 0;
            T = 0.0;
            break;
        case 18: CALL(Terminate, C); break;
        case 19: {
            const double t0 = u8(r) & 1 ? fuzz_double(r, NULL) : 0.0;
            const fmi2Boolean has_stop = u8(r) & 1;
            const double stop = fuzz_double(r, NULL);
            if (CALL(SetupExperiment, C, fmi2False, 0.0, t0, has_stop, stop) == fmi2OK) {
                T = t0;
                EXP.set = 1, EXP.t0 = t0, EXP.has_stop = has_stop, EXP.stop = stop;
            }
            break;
        }
        case 20:
            if (op & 0x80)
                CALL(EnterInitializationMode, C);
            else
                CALL(ExitInitializationMode, C);
            break;
        case 21: {
            fmi2Status s;
            double t;
            CALL(GetStatus, C, (fmi2StatusKind)(u8(r) % 5), &s);
            CALL(GetRealStatus, C, (fmi2StatusKind)(u8(r) % 5), &t);
            static const fmi2String cats[] = {"logEvents", "logAll", "bogus"};
            CALL(SetDebugLogging, C, (fmi2Boolean)(op >> 7), u8(r) % 4, cats);
            break;
        }
        case 22: { /* failing allocations for the next call */
            h_fail_countdown = u8(r) % 4;
            switch (u8(r) % 3) {
            case 0: CALL(GetFMUstate, C, &slot[0]); break;
            case 1: round_trip(r); break;
            default: {
                fmi2Component extra = instantiate(r);
                if (extra) api.FreeInstance(extra);
            }
            }
            h_fail_countdown = -1;
            break;
        }
        default: /* a fresh instance */
            free_all();
            C = instantiate(r);
            T = 0.0;
            EXP.set = 0;
            break;
        }
    }
    free_all();
    h_fail_countdown = -1;
    if (h_live_blocks != live_at_start)
        FAIL("%ld blocks allocated by the FMU were not freed",
             h_live_blocks - live_at_start);
    return 0;
}
