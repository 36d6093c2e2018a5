/* Shared by the C test driver (tests/c/fmu_driver.c) and the fuzz harness
 * (fuzz/fuzz_fmu.c): a table of the fmi2 functions, a counting allocator
 * that can be told to fail, and a logger that records what the FMU says.
 *
 * Both are compiled once per model together with the model's generated
 * cw_vars.h, which provides the variable table (CW_VARS, CW_NVARS,
 * CW_MODEL_GUID, CW_MODEL_NAME) that they drive the FMU through. */
#ifndef CW_HARNESS_H
#define CW_HARNESS_H

#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2FunctionTypes.h" /* before cw_vars.h: its fmi2Status */

/* The table only: CW_MODEL is defined by the model's own model.c. */
#define CW_VARS_TABLE_ONLY
#include "cw_vars.h"

#define FMI_FUNCTIONS(X)                                                    \
    X(GetTypesPlatform) X(GetVersion) X(SetDebugLogging) X(Instantiate)      \
    X(FreeInstance) X(SetupExperiment) X(EnterInitializationMode)            \
    X(ExitInitializationMode) X(Terminate) X(Reset) X(GetReal) X(GetInteger) \
    X(GetBoolean) X(GetString) X(SetReal) X(SetInteger) X(SetBoolean)        \
    X(SetString) X(GetFMUstate) X(SetFMUstate) X(FreeFMUstate)               \
    X(SerializedFMUstateSize) X(SerializeFMUstate) X(DeSerializeFMUstate)    \
    X(GetDirectionalDerivative) X(SetRealInputDerivatives)                   \
    X(GetRealOutputDerivatives) X(DoStep) X(CancelStep) X(GetStatus)         \
    X(GetRealStatus) X(GetIntegerStatus) X(GetBooleanStatus)                 \
    X(GetStringStatus)

typedef struct {
#define H_FIELD(n) fmi2##n##TYPE *n;
    FMI_FUNCTIONS(H_FIELD)
#undef H_FIELD
} fmi_api;

/* ------------------------------------------------------------------ */
/* Counting allocator. Every block carries a header, so that a free of a
 * pointer the allocator never handed out, or a double free, is caught
 * even without AddressSanitizer. */

#define H_BLOCK_MAGIC 0x436c6f636b776f72ULL /* "Clockwor" */
#define H_BLOCK_DEAD 0x6465616462656566ULL

typedef struct {
    uint64_t magic;
    uint64_t size;
} h_block;

static long h_live_blocks;     /* allocated and not yet freed */
static long h_total_allocs;    /* successful allocations, ever */
static long h_fail_countdown = -1; /* >= 0: that many more succeed, then NULL */

static void h_abort(const char *why) {
    fprintf(stderr, "harness: %s\n", why);
    abort();
}

static void *h_alloc(size_t nobj, size_t size) {
    if (h_fail_countdown == 0) return NULL;
    if (h_fail_countdown > 0) h_fail_countdown--;
    if (size != 0 && nobj > (SIZE_MAX - sizeof(h_block)) / size)
        return NULL;
    size_t n = nobj * size;
    h_block *b = calloc(1, sizeof(h_block) + n);
    if (!b) return NULL;
    b->magic = H_BLOCK_MAGIC;
    b->size = n;
    h_live_blocks++;
    h_total_allocs++;
    return b + 1;
}

static void h_free(void *p) {
    if (!p) return; /* free(NULL) is allowed */
    h_block *b = (h_block *)p - 1;
    if (b->magic != H_BLOCK_MAGIC)
        h_abort(b->magic == H_BLOCK_DEAD ? "double free by the FMU"
                                         : "the FMU freed a pointer it was "
                                           "not given");
    b->magic = H_BLOCK_DEAD;
    h_live_blocks--;
    free(b);
}

/* ------------------------------------------------------------------ */
/* Logger */

typedef struct {
    long n_messages;
    long n_errors; /* messages with status >= fmi2Error */
    int last_status;
    char last[1100];
    int echo; /* print every message to stderr */
} h_log;

static void h_logger(fmi2ComponentEnvironment env, fmi2String instance,
                     fmi2Status status, fmi2String category,
                     fmi2String message, ...) {
    h_log *log = env;
    if (!log) h_abort("logger called without the componentEnvironment");
    if (!message) h_abort("logger called with a NULL message");
    if (!category) h_abort("logger called with a NULL category");
    /* Environments pass the message to printf as a format; with no
     * arguments a '%' in it would be undefined behaviour. */
    if (strchr(message, '%')) h_abort("logged message contains '%'");
    log->n_messages++;
    if (status >= fmi2Error) log->n_errors++;
    log->last_status = status;
    snprintf(log->last, sizeof log->last, "%s", message);
    if (log->echo)
        fprintf(stderr, "  [%s %d %s] %s\n", instance ? instance : "(null)",
                (int)status, category, message);
}

static fmi2CallbackFunctions h_callbacks(h_log *log) {
    fmi2CallbackFunctions cb;
    memset(&cb, 0, sizeof cb);
    cb.logger = h_logger;
    cb.allocateMemory = h_alloc;
    cb.freeMemory = h_free;
    cb.stepFinished = NULL;
    cb.componentEnvironment = log;
    return cb;
}

/* ------------------------------------------------------------------ */
/* The variable table */

static inline const cw_var_info *h_find(const char *name) {
    for (int k = 0; k < CW_NVARS; k++)
        if (CW_VARS[k].name && strcmp(CW_VARS[k].name, name) == 0)
            return &CW_VARS[k];
    return NULL;
}

/* Value references of all variables of a type, in table order. */
static int h_vrs_of_type(cw_type type, fmi2ValueReference *out) {
    int n = 0;
    for (int k = 0; k < CW_NVARS; k++)
        if (CW_VARS[k].name && CW_VARS[k].type == type)
            out[n++] = (fmi2ValueReference)k;
    return n;
}

/* A snapshot of every variable's value, for bitwise comparisons. */
typedef struct {
    fmi2Status st_real, st_int, st_bool, st_str;
    double r[CW_NVARS > 0 ? CW_NVARS : 1];
    int i[CW_NVARS > 0 ? CW_NVARS : 1];
    int b[CW_NVARS > 0 ? CW_NVARS : 1];
    int nr, ni, nb, ns;
    /* Strings: FNV-1a over each one's bytes and terminator (the pointers
     * live only until the FMU changes the variable); the first that came
     * back NULL with fmi2OK, or -1. */
    uint64_t s_hash;
    int s_null;
} h_values;

static void h_read_all(const fmi_api *api, fmi2Component c, h_values *v) {
    fmi2ValueReference vr[CW_NVARS > 0 ? CW_NVARS : 1];
    memset(v, 0, sizeof *v);
    v->nr = h_vrs_of_type(CW_REAL, vr);
    v->st_real = api->GetReal(c, vr, (size_t)v->nr, v->r);
    v->ni = h_vrs_of_type(CW_INTEGER, vr);
    v->st_int = api->GetInteger(c, vr, (size_t)v->ni, v->i);
    v->nb = h_vrs_of_type(CW_BOOLEAN, vr);
    v->st_bool = api->GetBoolean(c, vr, (size_t)v->nb, v->b);
    v->ns = h_vrs_of_type(CW_STRING, vr);
    v->s_null = -1;
    v->s_hash = 14695981039346656037ULL;
    if (v->ns == 0) return; /* models without Strings: no fmi2GetString call */
    fmi2String text[CW_NVARS > 0 ? CW_NVARS : 1];
    v->st_str = api->GetString(c, vr, (size_t)v->ns, text);
    if (v->st_str > fmi2Warning) return;
    for (int k = 0; k < v->ns; k++) {
        if (!text[k]) {
            if (v->s_null < 0) v->s_null = (int)vr[k];
            continue;
        }
        for (const unsigned char *p = (const unsigned char *)text[k];; p++) {
            v->s_hash = (v->s_hash ^ *p) * 1099511628211ULL;
            if (!*p) break;
        }
    }
}

/* Name of the first variable whose value is unfit although the FMU said
 * fmi2OK/fmi2Warning: a non-finite Real or a Boolean other than 0/1. */
static const char *h_unfit_value(const h_values *v) {
    fmi2ValueReference vr[CW_NVARS > 0 ? CW_NVARS : 1];
    if (v->st_real <= fmi2Warning) {
        h_vrs_of_type(CW_REAL, vr);
        for (int k = 0; k < v->nr; k++)
            if (!isfinite(v->r[k])) return CW_VARS[vr[k]].name;
    }
    if (v->ns && v->st_str <= fmi2Warning && v->s_null >= 0) return CW_VARS[v->s_null].name;
    if (v->st_bool <= fmi2Warning) {
        h_vrs_of_type(CW_BOOLEAN, vr);
        for (int k = 0; k < v->nb; k++)
            if (v->b[k] != fmi2False && v->b[k] != fmi2True)
                return CW_VARS[vr[k]].name;
    }
    return NULL;
}

static int h_same_values(const h_values *a, const h_values *b) {
    return a->st_real == b->st_real && a->st_int == b->st_int &&
           a->st_bool == b->st_bool && a->nr == b->nr &&
           a->st_str == b->st_str && a->s_hash == b->s_hash &&
           memcmp(a->r, b->r, sizeof(double) * (size_t)a->nr) == 0 &&
           memcmp(a->i, b->i, sizeof(int) * (size_t)a->ni) == 0 &&
           memcmp(a->b, b->b, sizeof(int) * (size_t)a->nb) == 0;
}

/* ------------------------------------------------------------------ */
/* The serialized state layout of docs/design.md, for crafting buffers
 * whose checksum is valid but whose content is not. */

/* The state's checksum (layout version 2): FNV-1a over little-endian
 * 64-bit words, the tail byte by byte. */
static uint64_t h_state_checksum(const unsigned char *p, size_t n) {
    uint64_t h = 14695981039346656037ULL;
    size_t k = 0;
    for (; k + 8 <= n; k += 8) {
        uint64_t w = 0;
        for (int b = 0; b < 8; b++) w |= (uint64_t)p[k + b] << (8 * b);
        h ^= w;
        h *= 1099511628211ULL;
    }
    for (; k < n; k++) {
        h ^= p[k];
        h *= 1099511628211ULL;
    }
    return h;
}

static void h_put_u64(unsigned char *p, uint64_t x) {
    for (int b = 0; b < 8; b++) p[b] = (unsigned char)(x >> (8 * b));
}

static void h_put_f64(unsigned char *p, double x) {
    uint64_t u;
    memcpy(&u, &x, 8);
    h_put_u64(p, u);
}

static void h_put_u32(unsigned char *p, uint32_t x) {
    for (int b = 0; b < 4; b++) p[b] = (unsigned char)(x >> (8 * b));
}

static void h_fix_checksum(unsigned char *buf, size_t size) {
    if (size >= 8) h_put_u64(buf + size - 8, h_state_checksum(buf, size - 8));
}

/* Byte offset of variable vr's value in a serialized state. */
static size_t h_value_offset(unsigned vr) {
    size_t off = 4 + 4 + 8 + 4 + 4 + 8;
    for (int k = 0; k < CW_NVARS && (unsigned)k < vr; k++) {
        const cw_var_info *v = &CW_VARS[k];
        if (!v->name || v->type == CW_STRING) continue; /* Strings: after the counters */
        off += v->type == CW_REAL ? 8 : 4;
        if (v->type == CW_REAL && v->causality == CW_INPUT) off += 24;
    }
    return off;
}

/* Offset of the model-state block (its u32 count) in a serialized state. */
static size_t h_model_state_offset(void) { return h_value_offset(CW_NVARS); }

#endif
