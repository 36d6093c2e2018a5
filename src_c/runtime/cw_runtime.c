/* The runtime's core, shared by every model and by both faces (cw_fmi2.c,
 * cw_fmi3.c): the Co-Simulation state machine (FMI 2.0.4 Sec. 4.2.4, FMI
 * 3.0 Step and Event Mode), argument and range checks driven by the
 * generated variable table, logging through the face, per-instance
 * storage, input polynomials, and the versioned FMU state layout described
 * in docs/design.md. Model independent. */
#include "cw_core.h"
#include "cw_rk.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#define STATE_MAGIC 0x31535743u /* "CWS1" little endian */
#define STATE_LAYOUT_VERSION 2u  /* 2: the checksum runs over 64-bit words */

#define ANY_OPEN_STATE CW_ANY_OPEN_STATE
#define READABLE_STATES                                                     \
    (CW_INIT_MODE | CW_STEP_COMPLETE | CW_STEP_FAILED | CW_TERMINATED |     \
     CW_ERROR | CW_EVENT_MODE)
/* Where inputs and tunable parameters may be set. */
#define SETTABLE_STATES                                                     \
    (CW_INSTANTIATED | CW_INIT_MODE | CW_STEP_COMPLETE | CW_EVENT_MODE)
/* After initialization: where tunable parameters are checked together. */
#define RUNNING_STATES (CW_STEP_COMPLETE | CW_EVENT_MODE)

static const char *state_name(const cw_instance *inst, cw_machine_state s) {
    const int v3 = inst->api[3] == '3';
    switch (s) {
    case CW_INSTANTIATED: return "Instantiated";
    case CW_INIT_MODE: return "InitializationMode";
    case CW_STEP_COMPLETE: return v3 ? "StepMode" : "StepComplete";
    case CW_STEP_FAILED: return v3 ? "StepMode after a discarded step" : "StepFailed";
    case CW_TERMINATED: return "Terminated";
    case CW_ERROR: return "Error";
    case CW_EVENT_MODE: return "EventMode";
    case CW_INTERMEDIATE_UPDATE: return "IntermediateUpdateMode";
    }
    return "?";
}

static const char *status_category(fmi2Status status) {
    switch (status) {
    case fmi2OK: return "logAll";
    case fmi2Warning: return "logStatusWarning";
    case fmi2Discard: return "logStatusDiscard";
    case fmi2Error: return "logStatusError";
    case fmi2Fatal: return "logStatusFatal";
    default: return "logAll";
    }
}


void cw_log(cw_instance *inst, fmi2Status status, const char *category,
            const char *fmt, ...) {
    if (!inst || !inst->emit) return;
    /* Problems are always reported; chatter only when asked for. */
    if (status == fmi2OK && !inst->logging_on) return;
    char buf[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    inst->emit(inst, status, category ? category : status_category(status), buf);
}

void cw_core_plain_text(char *buf, size_t size, const char *message) {
    size_t n = strlen(message);
    if (n >= size) n = size - 1;
    memcpy(buf, message, n);
    buf[n] = 0;
    for (char *p = buf; *p; p++)
        if (*p == '%') *p = ' ';
}

fmi2Status cw_refuse(cw_instance *inst, const char *var, double value,
                     const char *expected) {
    cw_log(inst, fmi2Error, "logStatusError",
           "%s = %.17g is not allowed: expected %s.", var, value, expected);
    return fmi2Error;
}

fmi2Status cw_core_fail(cw_instance *inst, const char *fmt, ...) {
    char buf[900];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    cw_log(inst, fmi2Error, "logStatusError", "%s", buf);
    inst->state = CW_ERROR;
    return fmi2Error;
}
#define fail cw_core_fail

/* Refuse a call made in the wrong state without changing the state: the
 * instance itself is still consistent, the caller is not. */
int cw_core_allowed(cw_instance *inst, const char *fn, int mask) {
    if (!inst) return 0;
    if (inst->state & mask) return 1;
    cw_log(inst, fmi2Error, "logStatusError",
           "%s may not be called in state %s.", fn, state_name(inst, inst->state));
    return 0;
}
#define allowed cw_core_allowed

double cw_input_rate(const cw_instance *inst, unsigned vr, double t) {
    return inst->in_d1[vr] + (t - inst->in_tref[vr]) * inst->in_d2[vr];
}


int cw_may_return_early(const cw_instance *inst) {
    return inst->early_return_allowed;
}

void cw_return_early(cw_instance *inst, double t) {
    inst->returned_early = 1;
    inst->early_time = t;
}

static const cw_var_info *var(cw_instance *inst, unsigned vr) {
    if (vr >= (unsigned)inst->model->nvars) return NULL;
    const cw_var_info *v = &inst->model->vars[vr];
    return v->name ? v : NULL;
}

static void *alloc(cw_instance *inst, size_t n, size_t size) {
    if (n == 0) n = 1;
    return inst->alloc_mem(n, size);
}

/* A fresh copy of head + tail (tail may be NULL), or NULL. */
static char *join(cw_instance *inst, const char *head, const char *tail) {
    const size_t a = strlen(head), b = tail ? strlen(tail) : 0;
    char *s = inst->alloc_mem(a + b + 1, 1);
    if (!s) return NULL;
    memcpy(s, head, a);
    if (b) memcpy(s + a, tail, b);
    s[a + b] = '\0';
    return s;
}

int cw_set_string(cw_instance *inst, unsigned vr, const char *head,
                  const char *tail) {
    char *s = join(inst, head ? head : "", tail);
    if (!s) {
        cw_log(inst, fmi2Error, "logStatusError",
               "%s: out of memory for the String %s.", inst->model->name,
               inst->model->vars[vr].name);
        return 0;
    }
    if (inst->str[vr]) inst->free_mem(inst->str[vr]);
    inst->str[vr] = s;
    return 1;
}

/* Start values; 0 when a String's copy could not be made (logged). */
static int set_start_values(cw_instance *inst) {
    const cw_model *m = inst->model;
    int ok = 1;
    for (int k = 0; k < m->nvars; k++) {
        const cw_var_info *v = &m->vars[k];
        if (!v->name) continue;
        if (v->type == CW_REAL)
            inst->r[k] = v->start;
        else if (v->type == CW_STRING)
            ok &= cw_set_string(inst, (unsigned)k, v->start_string, NULL);
        else
            inst->i[k] = (int32_t)v->start;
        inst->in_d1[k] = inst->in_d2[k] = 0.0;
        inst->in_tref[k] = 0.0;
    }
    memset(inst->s, 0, sizeof(double) * (m->n_real_state ? m->n_real_state : 1));
    inst->state_pending = 0;
    inst->values_epoch += 1;
    memset(inst->u, 0, sizeof(uint64_t) * (m->n_uint_state ? m->n_uint_state : 1));
    inst->time = 0.0;
    inst->start_time = 0.0;
    inst->stop_time = 0.0;
    inst->stop_time_defined = 0;
    inst->outputs_dirty = 1;
    inst->terminate_requested = 0;
    return ok;
}

static void refresh_outputs(cw_instance *inst) {
    cw_settle(inst);
    if (inst->outputs_dirty) {
        if (inst->model->calc_outputs) inst->model->calc_outputs(inst);
        inst->outputs_checked = 0; /* whatever set outputs_dirty may have changed them */
    }
    inst->outputs_dirty = 0;
}

/* Refresh the outputs and refuse to hand out a non-finite one: inputs and
 * parameters inside their ranges can still overflow a model's arithmetic
 * (found by fuzz/fuzz_fmu.c), and a NaN or inf must never reach the master
 * with fmi2OK. */
static int outputs_finite(cw_instance *inst, const char *fn) {
    refresh_outputs(inst);
    if (inst->outputs_checked) return 1;
    const cw_model *m = inst->model;
    const int *outputs = inst->real_io + inst->n_real_in;
    for (int a = 0; a < inst->n_real_out; a++) {
        const int k = outputs[a];
        const cw_var_info *v = &m->vars[k];
        if (!isfinite(inst->r[k])) {
            fail(inst,
                 "%s: output %s = %g at t = %.17g is not finite: the inputs "
                 "or parameters are beyond what %s can represent.",
                 fn, v->name, inst->r[k], inst->time, m->name);
            return 0;
        }
    }
    inst->outputs_checked = 1;
    return 1;
}

/* ------------------------------------------------------------------ */
/* Inquire version numbers and setting logging status                 */
/* ------------------------------------------------------------------ */
/* Logging, creation and destruction of instances                     */

fmi2Status cw_core_set_debug_logging(cw_instance *inst, const char *fn,
                                     int logging_on, size_t n,
                                     const char *const categories[]) {
    if (!allowed(inst, fn, ANY_OPEN_STATE)) return fmi2Error;
    static const char *known[] = {"logEvents", "logStatusWarning",
                                  "logStatusDiscard", "logStatusError",
                                  "logStatusFatal", "logAll"};
    if (n > 0 && !categories) {
        cw_log(inst, fmi2Error, "logStatusError",
               "%s: categories is NULL but nCategories = %zu.", fn, n);
        return fmi2Error;
    }
    for (size_t k = 0; k < n; k++) {
        int found = 0;
        for (size_t j = 0; j < sizeof known / sizeof *known; j++)
            if (categories[k] && strcmp(categories[k], known[j]) == 0) found = 1;
        if (!found) {
            cw_log(inst, fmi2Error, "logStatusError",
                   "%s: unknown log category '%s'.", fn,
                   categories[k] ? categories[k] : "(null)");
            return fmi2Error;
        }
    }
    inst->logging_on = logging_on ? 1 : 0;
    return fmi2OK;
}

/* The FMU state's layout (defined with the state below). */
#define FNV_SEED 14695981039346656037ULL
static uint64_t fnv1a(const unsigned char *p, size_t n, uint64_t h);
static int has_strings(const cw_model *m);
static size_t fixed_state_size(const cw_model *m);

cw_instance *cw_core_instantiate(const cw_instance *proto, const char *fn,
                                 const char *instance_name, const char *token,
                                 const char *token_name) {
    cw_instance tmp = *proto;
    tmp.instance_name = (char *)(instance_name ? instance_name : "?");
    tmp.model = &CW_MODEL;
    if (!instance_name || !*instance_name) {
        cw_log(&tmp, fmi2Error, "logStatusError",
               "%s: instanceName must be a non-empty string.", fn);
        return NULL;
    }
    if (!token || strcmp(token, CW_MODEL.guid) != 0) {
        cw_log(&tmp, fmi2Error, "logStatusError",
               "%s: %s '%s' does not match %s's '%s'.", fn, token_name,
               token ? token : "(null)", CW_MODEL.name, CW_MODEL.guid);
        return NULL;
    }
    cw_instance *inst = tmp.alloc_mem(1, sizeof(cw_instance));
    if (!inst) return NULL;
    *inst = tmp;
    size_t len = strlen(instance_name) + 1;
    inst->instance_name = tmp.alloc_mem(len, 1);
    int nv = CW_MODEL.nvars;
    inst->r = alloc(inst, nv, sizeof(double));
    inst->i = alloc(inst, nv, sizeof(int32_t));
    inst->in_d1 = alloc(inst, nv, sizeof(double));
    inst->in_d2 = alloc(inst, nv, sizeof(double));
    inst->in_tref = alloc(inst, nv, sizeof(double));
    inst->s = alloc(inst, CW_MODEL.n_real_state, sizeof(double));
    inst->u = alloc(inst, CW_MODEL.n_uint_state, sizeof(uint64_t));
    inst->str = alloc(inst, nv, sizeof(char *));
    if (inst->str)
        for (int k = 0; k < nv; k++) inst->str[k] = NULL;
    inst->real_io = alloc(inst, nv, sizeof(int));
    if (inst->real_io) {
        int n = 0;
        for (int pass = 0; pass < 2; pass++) {
            const cw_causality wanted = pass ? CW_OUTPUT : CW_INPUT;
            for (int k = 0; k < nv; k++) {
                const cw_var_info *v = &CW_MODEL.vars[k];
                if (v->name && v->type == CW_REAL && v->causality == wanted)
                    inst->real_io[n++] = k;
            }
            if (!pass) inst->n_real_in = n;
        }
        inst->n_real_out = n - inst->n_real_in;
    }
    if (!inst->instance_name || !inst->r || !inst->i || !inst->in_d1 ||
        !inst->in_d2 || !inst->in_tref || !inst->s || !inst->u || !inst->str ||
        !inst->real_io) {
        cw_log(&tmp, fmi2Error, "logStatusError", "%s: out of memory.", fn);
        cw_core_free_instance(inst);
        return NULL;
    }
    memcpy(inst->instance_name, instance_name, len);
    inst->state_fixed = fixed_state_size(&CW_MODEL);
    inst->state_strings = has_strings(&CW_MODEL);
    inst->guid_hash = fnv1a((const unsigned char *)CW_MODEL.guid, strlen(CW_MODEL.guid), FNV_SEED);
    inst->state = CW_INSTANTIATED;
    if (!set_start_values(inst)) {
        cw_core_free_instance(inst);
        return NULL;
    }
    return inst;
}

void cw_core_free_instance(cw_instance *inst) {
    if (!inst) return;
    void (*free_mem)(void *) = inst->free_mem;
    if (inst->str)
        for (int k = 0; k < inst->model->nvars; k++)
            if (inst->str[k]) free_mem(inst->str[k]);
    void *blocks[] = {inst->str, inst->r,     inst->i,       inst->in_d1, inst->in_d2,
                      inst->in_tref, inst->s,     inst->u,
                      inst->instance_name, inst->scratch, inst->real_io};
    for (size_t k = 0; k < sizeof blocks / sizeof *blocks; k++)
        if (blocks[k]) free_mem(blocks[k]);
    free_mem(inst);
}

/* ------------------------------------------------------------------ */
/* Initialization, termination, reset                                 */

fmi2Status cw_core_setup(cw_instance *inst, const char *fn, double start_time,
                         int stop_time_defined, double stop_time) {
    if (!isfinite(start_time))
        return fail(inst, "%s: startTime = %g must be finite.", fn, start_time);
    if (stop_time_defined && !(isfinite(stop_time) && stop_time >= start_time))
        return fail(inst,
                    "%s: stopTime = %g must be finite and >= startTime = %g.",
                    fn, stop_time, start_time);
    inst->start_time = start_time;
    inst->time = start_time;
    inst->stop_time = stop_time;
    inst->stop_time_defined = stop_time_defined ? 1 : 0;
    for (int k = 0; k < inst->model->nvars; k++) inst->in_tref[k] = start_time;
    return fmi2OK;
}

fmi2Status cw_core_enter_initialization(cw_instance *inst, const char *fn) {
    (void)fn;
    inst->state = CW_INIT_MODE;
    inst->outputs_dirty = 1;
    return fmi2OK;
}

static fmi2Status validate_and_initialize(cw_instance *inst) {
    if (inst->model->validate) {
        fmi2Status st = inst->model->validate(inst);
        if (st > fmi2Warning) {
            inst->state = CW_ERROR;
            return st;
        }
    }
    if (inst->model->initialize) inst->model->initialize(inst);
    inst->outputs_dirty = 1;
    return fmi2OK;
}

fmi2Status cw_core_exit_initialization(cw_instance *inst, const char *fn,
                                       cw_machine_state next) {
    if (!allowed(inst, fn, CW_INIT_MODE)) return fmi2Error;
    fmi2Status st = validate_and_initialize(inst);
    if (st > fmi2Warning) return st;
    if (!outputs_finite(inst, fn)) return fmi2Error;
    inst->state = next;
    return fmi2OK;
}

fmi2Status cw_core_terminate(cw_instance *inst, const char *fn) {
    if (!allowed(inst, fn, CW_STEP_COMPLETE | CW_STEP_FAILED | CW_EVENT_MODE))
        return fmi2Error;
    inst->state = CW_TERMINATED;
    return fmi2OK;
}

fmi2Status cw_core_reset(cw_instance *inst, const char *fn) {
    if (!allowed(inst, fn, ANY_OPEN_STATE)) return fmi2Error;
    if (!set_start_values(inst)) {
        inst->state = CW_ERROR;
        return fmi2Error;
    }
    inst->state = CW_INSTANTIATED;
    return fmi2OK;
}

void cw_core_commit(cw_instance *inst) {
    if (inst->model->commit) {
        cw_settle(inst);
        inst->model->commit(inst);
    }
    inst->outputs_dirty = 1;
}

/* ------------------------------------------------------------------ */
/* Getting and setting variable values                                */

static int arrays_given(cw_instance *inst, const char *fn, const unsigned vr[],
                        size_t nvr, const void *value) {
    if (nvr > 0 && (!vr || !value)) {
        cw_log(inst, fmi2Error, "logStatusError",
               "%s: vr or value is NULL with nvr = %zu.", fn, nvr);
        return 0;
    }
    return 1;
}

/* What every setter checks first: the state allows setting, the arrays are
   given. 0: refused (logged). */
static int writable(cw_instance *inst, const char *fn, const unsigned vr[],
                    size_t nvr, const void *value) {
    if (!allowed(inst, fn, SETTABLE_STATES) ||
        !arrays_given(inst, fn, vr, nvr, value))
        return 0;
    cw_settle(inst); /* with the inputs it was reached with */
    inst->values_epoch += 1;
    return 1;
}

/* The variable of value reference vr if it is of the type the getter or
   setter handles; NULL (logged) if not. */
static const cw_var_info *typed_var(cw_instance *inst, const char *fn,
                                    unsigned vr, cw_type type) {
    const cw_var_info *v = var(inst, vr);
    if (v && v->type == type) return v;
    const int fmi3 = inst->api[3] == '3';
    const char *a_type = type == CW_REAL      ? (fmi3 ? " Float64" : " Real")
                         : type == CW_BOOLEAN ? " Boolean"
                         : type == CW_STRING  ? " String"
                                              : (fmi3 ? "n Int32" : "n Integer");
    cw_log(inst, fmi2Error, "logStatusError",
           "%s: %u is not the value reference of a%s variable of %s.", fn, vr,
           a_type, inst->model->name);
    return NULL;
}

/* What every getter checks first: the state allows reading, the arrays are
   given, and in Initialization Mode the outputs follow the current
   parameters; then that the outputs are finite. 0: refused (logged). */
static int readable(cw_instance *inst, const char *fn, const unsigned vr[],
                    size_t nvr, const void *value) {
    if (!allowed(inst, fn, READABLE_STATES) ||
        !arrays_given(inst, fn, vr, nvr, value))
        return 0;
    if (inst->state == CW_INIT_MODE && inst->outputs_dirty &&
        inst->model->initialize)
        inst->model->initialize(inst); /* outputs from the current parameters */
    return outputs_finite(inst, fn);
}

fmi2Status cw_core_get_real(cw_instance *inst, const char *fn,
                            const unsigned vr[], size_t nvr, double value[]) {
    if (!readable(inst, fn, vr, nvr, value)) return fmi2Error;
    for (size_t k = 0; k < nvr; k++) {
        if (inst->api[3] == '3' && vr[k] == (unsigned)inst->model->nvars) {
            value[k] = inst->time; /* FMI 3.0's independent variable */
            continue;
        }
        const cw_var_info *v = typed_var(inst, fn, vr[k], CW_REAL);
        if (!v) return fmi2Error;
        value[k] = inst->r[vr[k]];
    }
    return fmi2OK;
}

fmi2Status cw_core_get_int(cw_instance *inst, const char *fn, cw_type type,
                           const unsigned vr[], size_t nvr, void *value,
                           int as_bool) {
    if (!readable(inst, fn, vr, nvr, value)) return fmi2Error;
    for (size_t k = 0; k < nvr; k++) {
        const cw_var_info *v = typed_var(inst, fn, vr[k], type);
        if (!v) return fmi2Error;
        if (as_bool)
            ((bool *)value)[k] = inst->i[vr[k]] != 0;
        else
            ((int32_t *)value)[k] = inst->i[vr[k]];
    }
    return fmi2OK;
}

fmi2Status cw_core_no_such_type(cw_instance *inst, const char *fn,
                                const char *type, const unsigned vr[],
                                size_t nvr, int setter) {
    if (!allowed(inst, fn, setter ? SETTABLE_STATES : READABLE_STATES))
        return fmi2Error;
    if (nvr == 0) return fmi2OK;
    cw_log(inst, fmi2Error, "logStatusError",
           "%s: %s has no %s variables (vr %u).", fn, inst->model->name, type,
           vr ? (unsigned)vr[0] : 0u);
    return fmi2Error;
}

/* May variable v be set in the instance's current state? */
static int settable(cw_instance *inst, const cw_var_info *v, const char *fn) {
    int ok;
    switch (v->causality) {
    case CW_INPUT:
        ok = inst->state & SETTABLE_STATES;
        break;
    case CW_PARAMETER:
        ok = v->variability == CW_TUNABLE
                 ? inst->state & SETTABLE_STATES
                 : inst->state & (CW_INSTANTIATED | CW_INIT_MODE);
        break;
    default: ok = 0;
    }
    if (!ok) {
        const char *why =
            v->causality == CW_OUTPUT || v->causality == CW_LOCAL
                ? "it is not a parameter or an input"
                : v->variability == CW_FIXED
                      ? "a fixed parameter can be set only before "
                      : "not in this state";
        cw_log(inst, fmi2Error, "logStatusError",
               "%s: cannot set '%s' in state %s: %s%s.", fn, v->name,
               state_name(inst, inst->state), why,
               v->variability == CW_FIXED && v->causality == CW_PARAMETER
                   ? (inst->api[3] == '3'   ? "fmi3ExitInitializationMode"
                      : inst->api[3] == '1' ? "fmiInitializeSlave"
                                            : "fmi2ExitInitializationMode")
                   : "");
    }
    return ok;
}

/* Value checks: finite, and inside [min, max] from the table. */
static int acceptable(cw_instance *inst, const cw_var_info *v, double x,
                      const char *fn) {
    if (!isfinite(x)) {
        cw_log(inst, fmi2Error, "logStatusError",
               "%s: %s = %g is not allowed: expected a finite number.", fn,
               v->name, x);
        return 0;
    }
    if (x < v->min || x > v->max) {
        cw_log(inst, fmi2Error, "logStatusError",
               "%s: %s = %.17g is not allowed: expected a value in [%.17g, "
               "%.17g].",
               fn, v->name, x, v->min, v->max);
        return 0;
    }
    return 1;
}

static fmi2Status after_set(cw_instance *inst, int tunable_changed) {
    inst->outputs_dirty = 1;
    if (tunable_changed && (inst->state & RUNNING_STATES) &&
        inst->model->validate) {
        fmi2Status st = inst->model->validate(inst);
        if (st > fmi2Warning) {
            inst->state = CW_ERROR;
            return st;
        }
    }
    return fmi2OK;
}


fmi2Status cw_core_set_real(cw_instance *inst, const char *fn,
                            const unsigned vr[], size_t nvr,
                            const double value[]) {
    if (!writable(inst, fn, vr, nvr, value)) return fmi2Error;
    /* Check everything first so that a refused call changes nothing. */
    for (size_t k = 0; k < nvr; k++) {
        const cw_var_info *v = typed_var(inst, fn, vr[k], CW_REAL);
        if (!v) return fmi2Error;
        if (!settable(inst, v, fn)) return fmi2Error;
        if (!acceptable(inst, v, value[k], fn)) {
            inst->state = CW_ERROR;
            return fmi2Error;
        }
    }
    int tunable = 0;
    for (size_t k = 0; k < nvr; k++) {
        const cw_var_info *v = &inst->model->vars[vr[k]];
        inst->r[vr[k]] = value[k];
        if (v->causality == CW_INPUT) {
            /* A new value without derivatives means: hold it. */
            inst->in_d1[vr[k]] = inst->in_d2[vr[k]] = 0.0;
            inst->in_tref[vr[k]] = inst->time;
        } else {
            tunable = 1;
        }
    }
    return after_set(inst, tunable);
}

fmi2Status cw_core_set_int(cw_instance *inst, const char *fn, cw_type type,
                           const unsigned vr[], size_t nvr, const void *value,
                           int as_bool) {
    if (!writable(inst, fn, vr, nvr, value)) return fmi2Error;
    for (size_t k = 0; k < nvr; k++) {
        const cw_var_info *v = typed_var(inst, fn, vr[k], type);
        if (!v) return fmi2Error;
        if (!settable(inst, v, fn)) return fmi2Error;
        const int32_t given = as_bool ? (int32_t)((const bool *)value)[k]
                                      : ((const int32_t *)value)[k];
        double x = type == CW_BOOLEAN ? (given != 0) : (double)given;
        if (!acceptable(inst, v, x, fn)) {
            inst->state = CW_ERROR;
            return fmi2Error;
        }
    }
    int tunable = 0;
    for (size_t k = 0; k < nvr; k++) {
        const cw_var_info *v = &inst->model->vars[vr[k]];
        const int32_t given = as_bool ? (int32_t)((const bool *)value)[k]
                                      : ((const int32_t *)value)[k];
        inst->i[vr[k]] = type == CW_BOOLEAN ? (given != 0) : given;
        if (v->causality != CW_INPUT) tunable = 1;
    }
    return after_set(inst, tunable);
}


fmi2Status cw_core_get_string(cw_instance *inst, const char *fn,
                              const unsigned vr[], size_t nvr,
                              const char *value[]) {
    if (!readable(inst, fn, vr, nvr, value)) return fmi2Error;
    for (size_t k = 0; k < nvr; k++) {
        const cw_var_info *v = typed_var(inst, fn, vr[k], CW_STRING);
        if (!v) return fmi2Error;
        value[k] = inst->str[vr[k]];
    }
    return fmi2OK;
}

fmi2Status cw_core_set_string(cw_instance *inst, const char *fn,
                              const unsigned vr[], size_t nvr,
                              const char *const value[]) {
    if (!writable(inst, fn, vr, nvr, value)) return fmi2Error;
    for (size_t k = 0; k < nvr; k++) {
        const cw_var_info *v = typed_var(inst, fn, vr[k], CW_STRING);
        if (!v) return fmi2Error;
        if (!settable(inst, v, fn)) return fmi2Error;
        if (!value[k]) {
            cw_log(inst, fmi2Error, "logStatusError",
                   "%s: the value of %s is NULL: expected a string.", fn,
                   v->name);
            inst->state = CW_ERROR;
            return fmi2Error;
        }
    }
    /* Copy every value first, so that running out of memory changes
     * nothing; then give up the old copies. */
    char **copies = alloc(inst, nvr, sizeof(char *));
    if (!copies) return fail(inst, "%s: out of memory.", fn);
    size_t made = 0;
    for (; made < nvr; made++)
        if (!(copies[made] = join(inst, value[made], NULL))) break;
    if (made < nvr) {
        for (size_t k = 0; k < made; k++) inst->free_mem(copies[k]);
        inst->free_mem(copies);
        return fail(inst, "%s: out of memory.", fn);
    }
    int tunable = 0;
    for (size_t k = 0; k < nvr; k++) {
        if (inst->str[vr[k]]) inst->free_mem(inst->str[vr[k]]);
        inst->str[vr[k]] = copies[k];
        if (inst->model->vars[vr[k]].causality != CW_INPUT) tunable = 1;
    }
    inst->free_mem(copies);
    return after_set(inst, tunable);
}

/* ------------------------------------------------------------------ */
/* FMU state: one flat, versioned byte layout for get/set and serialize */

typedef struct {
    size_t size;
    unsigned char bytes[];
} cw_state_blob;

static uint64_t fnv1a(const unsigned char *p, size_t n, uint64_t h) {
    for (size_t k = 0; k < n; k++) {
        h ^= p[k];
        h *= 1099511628211ULL;
    }
    return h;
}

/* The state's checksum: FNV-1a over little-endian 64-bit words, the tail
 * byte by byte. One multiplication per 8 bytes instead of per byte: a
 * rollback checks it on every fmi2SetFMUstate. Each step is a bijection of
 * the running hash, so any one changed word changes the result. */
static uint64_t get_u64(const unsigned char **p);

static uint64_t state_checksum(const unsigned char *p, size_t n) {
    uint64_t h = FNV_SEED;
    size_t k = 0;
    for (; k + 8 <= n; k += 8) {
        const unsigned char *q = p + k;
        const uint64_t w = get_u64(&q);
        h ^= w;
        h *= 1099511628211ULL;
    }
    return fnv1a(p + k, n - k, h);
}

static int has_strings(const cw_model *m) {
    for (int k = 0; k < m->nvars; k++)
        if (m->vars[k].name && m->vars[k].type == CW_STRING) return 1;
    return 0;
}

/* The size of a state without its String section: the whole state of a
 * model without String variables. */
static size_t fixed_state_size(const cw_model *m) {
    size_t n = 4 + 4 + 8 + 4 + 4 + 8;
    for (int k = 0; k < m->nvars; k++) {
        const cw_var_info *v = &m->vars[k];
        if (!v->name || v->type == CW_STRING) continue;
        n += v->type == CW_REAL ? 8 : 4;
        if (v->type == CW_REAL && v->causality == CW_INPUT) n += 24;
    }
    n += 4 + 8 * (size_t)m->n_real_state + 4 + 8 * (size_t)m->n_uint_state;
    return n + 8;
}

/* The instance's state size: the fixed part and, for each String
 * variable, u32 byte count and the bytes (no terminating NUL). */
static size_t state_size(const cw_instance *inst) {
    const cw_model *m = inst->model;
    size_t n = inst->state_fixed;
    if (inst->state_strings)
        for (int k = 0; k < m->nvars; k++)
            if (m->vars[k].name && m->vars[k].type == CW_STRING)
                n += 4 + strlen(inst->str[k]);
    return n;
}

/* Explicit little-endian encoding, independent of the host's layout (on a
 * little-endian host a plain copy, which every save and rollback does). */
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
#define CW_LITTLE_ENDIAN 1
#else
#define CW_LITTLE_ENDIAN 0
#endif
static void put_u32(unsigned char **p, uint32_t x) {
    if (CW_LITTLE_ENDIAN) {
        memcpy(*p, &x, 4);
        *p += 4;
        return;
    }
    for (int b = 0; b < 4; b++) *(*p)++ = (unsigned char)(x >> (8 * b));
}
static void put_u64(unsigned char **p, uint64_t x) {
    if (CW_LITTLE_ENDIAN) {
        memcpy(*p, &x, 8);
        *p += 8;
        return;
    }
    for (int b = 0; b < 8; b++) *(*p)++ = (unsigned char)(x >> (8 * b));
}
static void put_f64(unsigned char **p, double x) {
    uint64_t u;
    memcpy(&u, &x, 8);
    put_u64(p, u);
}
static uint32_t get_u32(const unsigned char **p) {
    uint32_t x = 0;
    if (CW_LITTLE_ENDIAN) {
        memcpy(&x, *p, 4);
        *p += 4;
        return x;
    }
    for (int b = 0; b < 4; b++) x |= (uint32_t)(*(*p)++) << (8 * b);
    return x;
}
static uint64_t get_u64(const unsigned char **p) {
    uint64_t x = 0;
    if (CW_LITTLE_ENDIAN) {
        memcpy(&x, *p, 8);
        *p += 8;
        return x;
    }
    for (int b = 0; b < 8; b++) x |= (uint64_t)(*(*p)++) << (8 * b);
    return x;
}
static double get_f64(const unsigned char **p) {
    uint64_t u = get_u64(p);
    double x;
    memcpy(&x, &u, 8);
    return x;
}

static void encode_state(const cw_instance *inst, unsigned char *buf,
                         size_t size) {
    const cw_model *m = inst->model;
    unsigned char *p = buf;
    put_u32(&p, STATE_MAGIC);
    put_u32(&p, STATE_LAYOUT_VERSION);
    put_u64(&p, inst->guid_hash);
    put_u32(&p, (uint32_t)size);
    put_u32(&p, (uint32_t)inst->state);
    put_f64(&p, inst->time);
    for (int k = 0; k < m->nvars; k++) {
        const cw_var_info *v = &m->vars[k];
        if (!v->name || v->type == CW_STRING) continue;
        if (v->type == CW_REAL) {
            put_f64(&p, inst->r[k]);
            if (v->causality == CW_INPUT) {
                put_f64(&p, inst->in_d1[k]);
                put_f64(&p, inst->in_d2[k]);
                put_f64(&p, inst->in_tref[k]);
            }
        } else {
            put_u32(&p, (uint32_t)inst->i[k]);
        }
    }
    put_u32(&p, (uint32_t)m->n_real_state);
    for (int k = 0; k < m->n_real_state; k++) put_f64(&p, inst->s[k]);
    put_u32(&p, (uint32_t)m->n_uint_state);
    for (int k = 0; k < m->n_uint_state; k++) put_u64(&p, inst->u[k]);
    for (int k = 0; k < m->nvars; k++) {
        if (!m->vars[k].name || m->vars[k].type != CW_STRING) continue;
        const size_t len = strlen(inst->str[k]);
        put_u32(&p, (uint32_t)len);
        memcpy(p, inst->str[k], len);
        p += len;
    }
    put_u64(&p, state_checksum(buf, (size_t)(p - buf)));
}

/* Check a state buffer and decode it into inst, which is a scratch copy
 * (see restore_state): the layout, the checksum and every value's range. */
static fmi2Status decode_state(cw_instance *inst, const unsigned char *buf,
                               size_t size, const char *fn) {
    const cw_model *m = inst->model;
    const size_t fixed = inst->state_fixed;
    const int strings = inst->state_strings;
    if (!buf) return fail(inst, "%s: the state is NULL.", fn);
    if (strings ? size < fixed : size != fixed)
        return fail(inst, "%s: the state has %zu bytes; %s expects %s%zu.", fn,
                    size, m->name, strings ? "at least " : "", fixed);
    const size_t expected = size;
    const unsigned char *p = buf;
    uint32_t magic = get_u32(&p), version = get_u32(&p);
    uint64_t guid_hash = get_u64(&p);
    uint32_t stored_size = get_u32(&p);
    if (magic != STATE_MAGIC)
        return fail(inst, "%s: not a clockwork FMU state (bad magic).", fn);
    if (version != STATE_LAYOUT_VERSION)
        return fail(inst, "%s: state layout version %u, expected %u.", fn,
                    version, STATE_LAYOUT_VERSION);
    if (guid_hash != inst->guid_hash)
        return fail(inst, "%s: the state belongs to another model, not %s.", fn,
                    m->name);
    if (stored_size != expected)
        return fail(inst, "%s: the state header says %u bytes, given %zu.",
                    fn, stored_size, expected);
    const unsigned char *end = buf + size - 8;
    const unsigned char *q = end;
    if (get_u64(&q) != state_checksum(buf, size - 8))
        return fail(inst, "%s: the state is corrupt (checksum mismatch).", fn);

    /* Decode into scratch space first: a refused state changes nothing. */
    uint32_t machine = get_u32(&p);
    /* Event Mode exists on FMI 3.0 only: the FMI 2.0 build refuses it. */
    const uint32_t machine_states =
        CW_INSTANTIATED | CW_INIT_MODE | CW_STEP_COMPLETE | CW_STEP_FAILED |
        CW_TERMINATED | (inst->api[3] == '3' ? CW_EVENT_MODE : 0);
    if (!(machine & machine_states) ||
        (machine & (machine - 1)))
        return fail(inst, "%s: the state holds an invalid machine state %u.", fn,
                    machine);
    double t = get_f64(&p);
    if (!isfinite(t)) return fail(inst, "%s: the state's time is not finite.", fn);
    const unsigned char *values = p;
    for (int k = 0; k < m->nvars; k++) {
        const cw_var_info *v = &m->vars[k];
        if (!v->name || v->type == CW_STRING) continue;
        if (v->type == CW_REAL) {
            double x = get_f64(&p);
            if (!isfinite(x))
                return fail(inst, "%s: the state's %s is not finite.", fn,
                            v->name);
            if ((v->causality == CW_PARAMETER || v->causality == CW_INPUT) &&
                (x < v->min || x > v->max))
                return fail(inst, "%s: the state's %s = %g is outside [%g, %g].",
                            fn, v->name, x, v->min, v->max);
            if (v->causality == CW_INPUT)
                for (int d = 0; d < 3; d++)
                    if (!isfinite(get_f64(&p)))
                        return fail(inst,
                                    "%s: the state's derivative of %s is not "
                                    "finite.",
                                    fn, v->name);
        } else {
            int32_t x = (int32_t)get_u32(&p);
            if (v->type == CW_BOOLEAN && x != 0 && x != 1)
                return fail(inst, "%s: the state's %s = %d is not a Boolean (0 or 1).",
                            fn, v->name, (int)x);
            if ((double)x < v->min || (double)x > v->max)
                return fail(inst, "%s: the state's %s = %d is outside [%g, %g].",
                            fn, v->name, (int)x, v->min, v->max);
        }
    }
    if (get_u32(&p) != (uint32_t)m->n_real_state)
        return fail(inst, "%s: the state has the wrong model state size.", fn);
    for (int k = 0; k < m->n_real_state; k++)
        if (!isfinite(get_f64(&p)))
            return fail(inst, "%s: the state's model state %d is not finite.",
                        fn, k);
    if (get_u32(&p) != (uint32_t)m->n_uint_state)
        return fail(inst, "%s: the state has the wrong counter count.", fn);
    /* The String section: each count within the buffer, no NUL inside, and
     * nothing after the last one. */
    const unsigned char *sp = buf + fixed - 8;
    for (int k = 0; k < m->nvars; k++) {
        if (!m->vars[k].name || m->vars[k].type != CW_STRING) continue;
        if ((size_t)(end - sp) < 4)
            return fail(inst, "%s: the state ends inside its Strings.", fn);
        const uint32_t len = get_u32(&sp);
        if ((size_t)(end - sp) < len || memchr(sp, 0, len))
            return fail(inst, "%s: the state's String %s is not %u bytes of "
                        "text.", fn, m->vars[k].name, (unsigned)len);
        sp += len;
    }
    if (sp != end)
        return fail(inst, "%s: the state has %zu bytes after its Strings.", fn,
                    (size_t)(end - sp));

    /* Everything checked: commit. */
    p = values;
    inst->state = (cw_machine_state)machine;
    inst->time = t;
    for (int k = 0; k < m->nvars; k++) {
        const cw_var_info *v = &m->vars[k];
        if (!v->name || v->type == CW_STRING) continue;
        if (v->type == CW_REAL) {
            inst->r[k] = get_f64(&p);
            if (v->causality == CW_INPUT) {
                inst->in_d1[k] = get_f64(&p);
                inst->in_d2[k] = get_f64(&p);
                inst->in_tref[k] = get_f64(&p);
            }
        } else {
            inst->i[k] = (int32_t)get_u32(&p);
        }
    }
    get_u32(&p);
    for (int k = 0; k < m->n_real_state; k++) inst->s[k] = get_f64(&p);
    get_u32(&p);
    for (int k = 0; k < m->n_uint_state; k++) inst->u[k] = get_u64(&p);
    inst->outputs_dirty = 1;
    return fmi2OK;
}

/* Scratch storage shaped like inst's, so that a state can be decoded and
 * checked whole before anything of inst changes. */
static int probe_open(cw_instance *inst, cw_instance *probe) {
    const cw_model *m = inst->model;
    const size_t nv = (size_t)m->nvars;
    /* One block: the doubles and words first, the 4-byte integers last. */
    const size_t words = 4 * nv + (size_t)m->n_real_state + (size_t)m->n_uint_state;
    if (!inst->scratch)
        inst->scratch = alloc(inst, 1, words * 8 + (nv ? nv : 1) * sizeof(int32_t));
    if (!inst->scratch) return 0;
    double *d = (double *)inst->scratch;
    *probe = *inst;
    probe->r = d;
    probe->in_d1 = d + nv;
    probe->in_d2 = d + 2 * nv;
    probe->in_tref = d + 3 * nv;
    probe->s = d + 4 * nv;
    probe->u = (uint64_t *)(d + 4 * nv + (size_t)m->n_real_state);
    probe->i = (int32_t *)(d + words);
    return 1;
}

/* Decode a state into scratch storage and check it: layout and values
 * (decode_state), and, for a state saved after initialization, the model's
 * cross-parameter rules, which fmi2ExitInitializationMode and every change
 * of a tunable parameter enforce too; a saved state must not smuggle in a
 * parameter combination that fmi2SetReal / fmi3SetFloat64 would refuse. With `commit`, an
 * accepted state is copied into inst. A refused state changes no value of
 * inst, which goes to Error like after any other refused state. */
static fmi2Status restore_state(cw_instance *inst, const unsigned char *buf,
                                size_t size, const char *fn, int commit) {
    const cw_model *m = inst->model;
    cw_instance probe;
    fmi2Status st = fmi2Error;
    if (!probe_open(inst, &probe)) {
        cw_log(inst, fmi2Error, "logStatusError", "%s: out of memory.", fn);
    } else {
        st = decode_state(&probe, buf, size, fn);
        if (st == fmi2OK && m->validate &&
            (probe.state & (CW_STEP_COMPLETE | CW_STEP_FAILED | CW_TERMINATED |
                         CW_EVENT_MODE)) &&
            m->validate(&probe) > fmi2Warning) {
            cw_log(inst, fmi2Error, "logStatusError",
                   "%s: the state's parameters break a rule of %s between "
                   "parameters (see above); the state is refused.",
                   fn, m->name);
            st = fmi2Error;
        }
    }
    /* The state's Strings, copied before anything changes (decode_state
     * checked the section). */
    char **strings = NULL;
    const int with_strings = inst->state_strings;
    if (st == fmi2OK && commit && with_strings &&
        (strings = alloc(inst, m->nvars, sizeof(char *)))) {
        const unsigned char *sp = buf + inst->state_fixed - 8;
        for (int k = 0; k < m->nvars; k++) {
            strings[k] = NULL;
            if (!m->vars[k].name || m->vars[k].type != CW_STRING) continue;
            const uint32_t len = get_u32(&sp);
            if (!(strings[k] = inst->alloc_mem((size_t)len + 1, 1))) {
                st = fmi2Error;
                break;
            }
            memcpy(strings[k], sp, len);
            strings[k][len] = '\0';
            sp += len;
        }
    } else if (st == fmi2OK && commit && with_strings) {
        cw_log(inst, fmi2Error, "logStatusError", "%s: out of memory.", fn);
        st = fmi2Error;
    }
    if (strings && st != fmi2OK) {
        cw_log(inst, fmi2Error, "logStatusError", "%s: out of memory.", fn);
        for (int k = 0; k < m->nvars; k++)
            if (strings[k]) inst->free_mem(strings[k]);
        inst->free_mem(strings);
        strings = NULL;
    }
    if (st == fmi2OK && commit) {
        const size_t nv = (size_t)m->nvars;
        for (int k = 0; strings && k < m->nvars; k++)
            if (strings[k]) {
                if (inst->str[k]) inst->free_mem(inst->str[k]);
                inst->str[k] = strings[k];
            }
        if (strings) inst->free_mem(strings);
        memcpy(inst->r, probe.r, nv * sizeof(double));
        memcpy(inst->i, probe.i, nv * sizeof(int32_t));
        memcpy(inst->in_d1, probe.in_d1, nv * sizeof(double));
        memcpy(inst->in_d2, probe.in_d2, nv * sizeof(double));
        memcpy(inst->in_tref, probe.in_tref, nv * sizeof(double));
        memcpy(inst->s, probe.s, (size_t)m->n_real_state * sizeof(double));
        memcpy(inst->u, probe.u, (size_t)m->n_uint_state * sizeof(uint64_t));
        inst->state = probe.state;
        inst->time = probe.time;
        inst->outputs_dirty = 1;
        inst->values_epoch += 1;
    }
    if (st != fmi2OK) {
        inst->state = CW_ERROR;
        return fmi2Error;
    }
    return fmi2OK;
}

#define STATE_STATES ANY_OPEN_STATE

#define STATE_STATES ANY_OPEN_STATE

fmi2Status cw_core_get_state(cw_instance *inst, const char *fn, void **state) {
    if (!allowed(inst, fn, STATE_STATES & ~CW_ERROR)) return fmi2Error;
    if (!state) return fail(inst, "%s: FMUstate is NULL.", fn);
    /* A state with non-finite outputs could never be restored. */
    if (!outputs_finite(inst, fn)) return fmi2Error;
    size_t size = state_size(inst);
    cw_state_blob *blob = (cw_state_blob *)*state;
    if (!blob || blob->size != size) {
        /* A state of another size (a String changed length): the new block
         * first, so that running out of memory leaves the old state whole. */
        cw_state_blob *fresh = inst->alloc_mem(1, sizeof(cw_state_blob) + size);
        if (!fresh) return fail(inst, "%s: out of memory.", fn);
        fresh->size = size;
        if (blob) inst->free_mem(blob);
        blob = fresh;
    }
    encode_state(inst, blob->bytes, size);
    *state = blob;
    return fmi2OK;
}

fmi2Status cw_core_set_state(cw_instance *inst, const char *fn, void *state) {
    if (!allowed(inst, fn, STATE_STATES)) return fmi2Error;
    cw_state_blob *blob = (cw_state_blob *)state;
    if (!blob) return fail(inst, "%s: FMUstate is NULL.", fn);
    cw_settle(inst); /* a refused state leaves this one whole */
    return restore_state(inst, blob->bytes, blob->size, fn, 1);
}

fmi2Status cw_core_free_state(cw_instance *inst, const char *fn, void **state) {
    if (!allowed(inst, fn, STATE_STATES)) return fmi2Error;
    if (!state) return fail(inst, "%s: FMUstate is NULL.", fn);
    if (*state) inst->free_mem(*state);
    *state = NULL;
    return fmi2OK;
}

fmi2Status cw_core_state_size(cw_instance *inst, const char *fn, void *state,
                              size_t *size) {
    if (!allowed(inst, fn, STATE_STATES)) return fmi2Error;
    if (!state || !size) return fail(inst, "%s: NULL argument.", fn);
    *size = ((cw_state_blob *)state)->size;
    return fmi2OK;
}

fmi2Status cw_core_serialize(cw_instance *inst, const char *fn, void *state,
                             unsigned char *buf, size_t size) {
    if (!allowed(inst, fn, STATE_STATES)) return fmi2Error;
    cw_state_blob *blob = (cw_state_blob *)state;
    if (!blob || !buf) return fail(inst, "%s: NULL argument.", fn);
    if (size < blob->size)
        return fail(inst, "%s: buffer of %zu bytes is too small for %zu.", fn,
                    size, blob->size);
    memcpy(buf, blob->bytes, blob->size);
    return fmi2OK;
}

fmi2Status cw_core_deserialize(cw_instance *inst, const char *fn,
                               const unsigned char *buf, size_t size,
                               void **state) {
    if (!allowed(inst, fn, STATE_STATES)) return fmi2Error;
    if (!buf || !state) return fail(inst, "%s: NULL argument.", fn);
    /* Check it whole now, so that a bad buffer is refused here rather than
     * when the state is set. */
    if (restore_state(inst, buf, size, fn, 0) != fmi2OK) return fmi2Error;
    cw_state_blob *blob = inst->alloc_mem(1, sizeof(cw_state_blob) + size);
    if (!blob) return fail(inst, "%s: out of memory.", fn);
    blob->size = size;
    memcpy(blob->bytes, buf, size);
    if (*state) inst->free_mem(*state);
    *state = blob;
    return fmi2OK;
}

fmi2Status cw_core_unsupported(cw_instance *inst, const char *fn,
                               const char *why) {
    if (!inst) return fmi2Error;
    cw_log(inst, fmi2Error, "logStatusError", "%s: %s %s.", fn,
           inst->model->name, why);
    return fmi2Error;
}

/* ------------------------------------------------------------------ */
/* Co-Simulation                                                      */

fmi2Status cw_core_set_input_derivatives(cw_instance *inst, const char *fn,
                                         const unsigned vr[], size_t nvr,
                                         const int32_t order[],
                                         const double value[]) {
    if (!allowed(inst, fn, CW_INSTANTIATED | CW_INIT_MODE | CW_STEP_COMPLETE))
        return fmi2Error;
    cw_settle(inst); /* with the input polynomials it was reached with */
    inst->values_epoch += 1;
    if (nvr > 0 && (!vr || !order || !value)) {
        cw_log(inst, fmi2Error, "logStatusError",
               "%s: NULL argument with nvr = %zu.", fn, nvr);
        return fmi2Error;
    }
    for (size_t k = 0; k < nvr; k++) {
        const cw_var_info *v = var(inst, vr[k]);
        if (!v || v->type != CW_REAL || v->causality != CW_INPUT) {
            cw_log(inst, fmi2Error, "logStatusError",
                   "%s: %u is not a Real input of %s.", fn,
                   (unsigned)vr[k], inst->model->name);
            return fmi2Error;
        }
        const int max_order = inst->model->max_input_order ? inst->model->max_input_order : 2;
        if (order[k] < 1 || order[k] > max_order) {
            cw_log(inst, fmi2Error, "logStatusError",
                   "%s: order %d for %s; expected 1 to %d.", fn,
                   (int)order[k], v->name, max_order);
            return fmi2Error;
        }
        if (!isfinite(value[k])) {
            cw_log(inst, fmi2Error, "logStatusError",
                   "%s: derivative of %s = %g; expected a finite number.",
                   fn, v->name, value[k]);
            inst->state = CW_ERROR;
            return fmi2Error;
        }
    }
    for (size_t k = 0; k < nvr; k++) {
        if (inst->in_tref[vr[k]] != inst->time) {
            /* Re-base the polynomial at the current point. */
            inst->r[vr[k]] = cw_input(inst, vr[k], inst->time);
            inst->in_d1[vr[k]] = inst->in_d2[vr[k]] = 0.0;
            inst->in_tref[vr[k]] = inst->time;
        }
        if (order[k] == 1)
            inst->in_d1[vr[k]] = value[k];
        else
            inst->in_d2[vr[k]] = value[k];
    }
    /* An output may show an input's slope (TestTypes' u_rate; found by
     * fuzz/fuzz_fmu.c: a restored state recomputed it, the live one not). */
    inst->outputs_dirty = 1;
    return fmi2OK;
}

fmi2Status cw_core_get_output_derivatives(cw_instance *inst, const char *fn,
                                          const unsigned vr[], size_t nvr,
                                          const int32_t order[],
                                          double value[]) {
    if (!allowed(inst, fn,
                 CW_STEP_COMPLETE | CW_STEP_FAILED | CW_TERMINATED | CW_ERROR |
                     CW_EVENT_MODE))
        return fmi2Error;
    if (nvr > 0 && (!vr || !order || !value)) {
        cw_log(inst, fmi2Error, "logStatusError",
               "%s: NULL argument with nvr = %zu.", fn, nvr);
        return fmi2Error;
    }
    if (!outputs_finite(inst, fn)) return fmi2Error;
    for (size_t k = 0; k < nvr; k++) {
        const cw_var_info *v = var(inst, vr[k]);
        if (!v || v->type != CW_REAL || v->causality != CW_OUTPUT) {
            cw_log(inst, fmi2Error, "logStatusError",
                   "%s: %u is not a %s output of %s.", fn, (unsigned)vr[k],
                   inst->api[3] == '3' ? "Float64" : "Real", inst->model->name);
            return fmi2Error;
        }
        if (order[k] < 1 || order[k] > v->max_derivative_order ||
            !inst->model->output_derivative ||
            !inst->model->output_derivative(inst, vr[k], order[k], &value[k])) {
            cw_log(inst, fmi2Error, "logStatusError",
                   "%s: %s offers derivatives up to order %d, not %d.", fn,
                   v->name, v->max_derivative_order, (int)order[k]);
            return fmi2Error;
        }
        if (!isfinite(value[k]))
            return fail(inst,
                        "%s: derivative of order %d of %s = %g at t = %.17g is "
                        "not finite.",
                        fn, (int)order[k], v->name, value[k], inst->time);
    }
    return fmi2OK;
}

fmi2Status cw_core_do_step(cw_instance *inst, const char *fn, double tc,
                           double h) {
    if (!allowed(inst, fn, CW_STEP_COMPLETE)) return fmi2Error;
    if (!isfinite(tc) || !isfinite(h) || !(h > 0)) {
        cw_log(inst, fmi2Error, "logStatusError",
               "%s: communication point %g and step size %g; expected finite "
               "values and a step size > 0.",
               fn, tc, h);
        return fmi2Error;
    }
    /* The master's time is authoritative, but it must be the point where
     * this FMU stands. */
    if (fabs(tc - inst->time) > 1e-9 * fmax(1.0, fabs(inst->time))) {
        cw_log(inst, fmi2Error, "logStatusError",
               "%s: communication point %.17g does not match the FMU's time "
               "%.17g.",
               fn, tc, inst->time);
        return fmi2Error;
    }
    const double t_end = tc + h;
    if (!isfinite(t_end)) { /* found by fuzzing: time became inf */
        cw_log(inst, fmi2Error, "logStatusError",
               "%s: the step from %.17g by %.17g ends beyond the largest "
               "representable time.",
               fn, tc, h);
        return fmi2Error;
    }
    if (inst->stop_time_defined &&
        t_end > inst->stop_time + 1e-9 * fmax(1.0, fabs(inst->stop_time))) {
        cw_log(inst, fmi2Error, "logStatusError",
               "%s: step to %.17g goes beyond stopTime %.17g.", fn, t_end,
               inst->stop_time);
        return fmi2Error;
    }
    /* Input polynomials are checked where the model will evaluate them:
     * huge derivatives can overflow them to inf over a step. A held value
     * (no derivatives, no intermediate update) is itself at both ends. */
    for (int a = 0; a < inst->n_real_in; a++) {
        const int k = inst->real_io[a];
        const cw_var_info *v = &inst->model->vars[k];
        if (!inst->intermediate_update && inst->in_d1[k] == 0.0 &&
            inst->in_d2[k] == 0.0) {
            if (isfinite(inst->r[k])) continue;
        }
        const double u0 = cw_input(inst, (unsigned)k, tc),
                     u1 = cw_input(inst, (unsigned)k, t_end);
        if (!isfinite(u0) || !isfinite(u1))
            return fail(inst,
                        "%s: input %s, following its derivatives, is %g at "
                        "t = %.17g and %g at t = %.17g; expected finite values.",
                        fn, v->name, u0, tc, u1, t_end);
    }
    inst->time = tc;
    if (inst->model->commit) {
        cw_settle(inst);
        inst->model->commit(inst);
    }
    fmi2Status st = fmi2OK;
    inst->returned_early = 0;
    if (inst->model->do_step) st = inst->model->do_step(inst, t_end);
    inst->outputs_dirty = 1;
    if (st == fmi2OK || st == fmi2Warning) {
        /* An early return must end inside the step (a model bug else). */
        if (inst->returned_early &&
            !(inst->early_time > tc && inst->early_time < t_end))
            return fail(inst,
                        "%s: %s returned early at t = %.17g, outside the step "
                        "from %.17g to %.17g.",
                        fn, inst->model->name, inst->early_time, tc, t_end);
        inst->time = inst->returned_early ? inst->early_time : t_end;
        /* A pending state is checked where it is computed (cw_settle). */
        if (!inst->state_pending && !outputs_finite(inst, fn)) return fmi2Error;
        return st;
    }
    inst->returned_early = 0;
    if (st == fmi2Discard) {
        inst->state = CW_STEP_FAILED;
        refresh_outputs(inst);
        return st;
    }
    inst->state = CW_ERROR;
    return fmi2Error;
}

/* What cw_integrate_to_event's observer watches for. */
typedef struct {
    struct cw_instance *inst;
    cw_rhs f;
    cw_event_fn g;
    cw_settle_fn settle;
    double t_start, t_end; /* the communication step */
    int stopped;
    double t_event, x_event[CW_RK_MAXN];
} event_watch;

/* The root of g on the dense output of the last accepted step (Illinois). */
static double event_root(const event_watch *w, const cw_rk *rk) {
    double a = rk->t0, b = rk->t0 + rk->h, x[CW_RK_MAXN];
    double fa = w->g(w->inst, rk->x0), fb = w->g(w->inst, rk->x1);
    int side = 0;
    for (int it = 0; it < 200; it++) {
        double t = (fa * b - fb * a) / (fa - fb);
        if (!(t > a && t < b)) t = 0.5 * (a + b);
        cw_rk_dense(rk, t, x);
        const double ft = w->g(w->inst, x);
        if (ft == 0.0 || b - a <= 4e-16 * fmax(1.0, fabs(t))) return t;
        if ((ft > 0) == (fa > 0)) {
            a = t, fa = ft;
            if (side == -1) fb *= 0.5;
            side = -1;
        } else {
            b = t, fb = ft;
            if (side == 1) fa *= 0.5;
            side = 1;
        }
    }
    return 0.5 * (a + b);
}

static int watch_events(void *ctx, const cw_rk *rk) {
    event_watch *w = ctx;
    if ((w->g(w->inst, rk->x0) > 0) == (w->g(w->inst, rk->x1) > 0)) return 0;
    const double t = event_root(w, rk);
    if (!(t > w->t_start && t < w->t_end)) return 0;
    cw_rk_single_step_with(rk->method, rk->n, w->f, w->inst, rk->t0, rk->x0,
                           t - rk->t0, w->x_event);
    w->settle(w->inst, w->x_event);
    w->stopped = 1;
    w->t_event = t;
    return 1;
}

static int integrate(struct cw_instance *inst, const char *model, cw_rhs f,
                     int n, int first, int h_slot, double t_end, double rtol,
                     double atol, double h_max, int integrator,
                     const char *const names[], cw_rk_observer observer,
                     event_watch *watch) {
    cw_rk rk;
    cw_rk_init(&rk, n, rtol, atol, h_max);
    cw_rk_set_method(&rk, integrator);
    double x[CW_RK_MAXN];
    for (int k = 0; k < n; k++) x[k] = inst->s[first + k];
    double t = inst->time, h_next = inst->s[h_slot];
    cw_rk_result res =
        watch ? cw_rk_advance(&rk, f, inst, &t, t_end, x, &h_next, watch_events, watch)
              : cw_rk_advance(&rk, f, inst, &t, t_end, x, &h_next, observer, inst);
    if (watch && res == CW_RK_STOPPED && watch->stopped) {
        t = watch->t_event;
        for (int k = 0; k < n; k++) x[k] = watch->x_event[k];
        res = CW_RK_OK;
    }
    int finite = 1;
    for (int k = 0; k < n; k++) finite = finite && isfinite(x[k]);
    if (res != CW_RK_OK || !finite) {
        char state[256];
        size_t used = 0;
        for (int k = 0; k < n && used < sizeof state; k++)
            used += (size_t)snprintf(state + used, sizeof state - used, "%s%s = %g",
                                     k ? ", " : "", names[k], x[k]);
        cw_log(inst, fmi2Discard, "logStatusDiscard",
               "%s: integration from t = %.17g to %.17g failed (%s) at t = "
               "%.17g with %s; the step is discarded and the state is "
               "unchanged.",
               model, inst->time, t_end,
               res == CW_RK_STEP_TOO_SMALL   ? "step size underflow"
               : res == CW_RK_TOO_MANY_STEPS ? "too many internal steps"
                                             : "non-finite state",
               t, state);
        return fmi2Discard;
    }
    for (int k = 0; k < n; k++) inst->s[first + k] = x[k];
    inst->s[h_slot] = h_next;
    if (watch && watch->stopped) cw_return_early(inst, t);
    return fmi2OK;
}

int cw_integrate(struct cw_instance *inst, const char *model, cw_rhs f, int n,
                 int first, int h_slot, double t_end, double rtol, double atol,
                 double h_max, int integrator, const char *const names[],
                 cw_rk_observer observer) {
    return integrate(inst, model, f, n, first, h_slot, t_end, rtol, atol, h_max,
                     integrator, names, observer, NULL);
}

int cw_integrate_to_event(struct cw_instance *inst, const char *model, cw_rhs f,
                          int n, int first, int h_slot, double t_end,
                          double rtol, double atol, double h_max,
                          int integrator, const char *const names[],
                          cw_event_fn g, cw_settle_fn settle) {
    event_watch watch = {inst, f, g, settle, inst->time, t_end, 0, 0.0, {0.0}};
    return integrate(inst, model, f, n, first, h_slot, t_end, rtol, atol, h_max,
                     integrator, names, NULL,
                     cw_may_return_early(inst) ? &watch : NULL);
}
