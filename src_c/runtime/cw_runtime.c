/* FMI 2.0 Co-Simulation functions shared by all clockwork models.
 *
 * Everything here is model independent: the state machine of the standard
 * (FMI 2.0.4, Sec. 4.2.4), argument and range checks driven by the generated
 * variable table, logging through the environment's callbacks, per-instance
 * storage, input polynomials, and the versioned FMU state layout described
 * in docs/design.md. */
#include "cw_runtime.h"
#include "cw_rk.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#define STATE_MAGIC 0x31535743u /* "CWS1" little endian */
#define STATE_LAYOUT_VERSION 2u  /* 2: the checksum runs over 64-bit words */

#define ANY_OPEN_STATE                                                      \
    (CW_INSTANTIATED | CW_INIT_MODE | CW_STEP_COMPLETE | CW_STEP_FAILED |   \
     CW_TERMINATED | CW_ERROR)
#define READABLE_STATES                                                     \
    (CW_INIT_MODE | CW_STEP_COMPLETE | CW_STEP_FAILED | CW_TERMINATED |     \
     CW_ERROR)

static const char *state_name(cw_machine_state s) {
    switch (s) {
    case CW_INSTANTIATED: return "Instantiated";
    case CW_INIT_MODE: return "InitializationMode";
    case CW_STEP_COMPLETE: return "StepComplete";
    case CW_STEP_FAILED: return "StepFailed";
    case CW_TERMINATED: return "Terminated";
    case CW_ERROR: return "Error";
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
    if (!inst || !inst->cb.logger) return;
    /* Problems are always reported; chatter only when asked for. */
    if (status == fmi2OK && !inst->logging_on) return;
    char buf[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    /* The message is passed as a printf format by some environments. */
    for (char *p = buf; *p; p++)
        if (*p == '%') *p = ' ';
    inst->cb.logger(inst->cb.componentEnvironment, inst->instance_name, status,
                    category ? category : status_category(status), buf);
}

fmi2Status cw_refuse(cw_instance *inst, const char *var, double value,
                     const char *expected) {
    cw_log(inst, fmi2Error, "logStatusError",
           "%s = %.17g is not allowed: expected %s.", var, value, expected);
    return fmi2Error;
}

static fmi2Status fail(cw_instance *inst, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

static fmi2Status fail(cw_instance *inst, const char *fmt, ...) {
    char buf[900];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    cw_log(inst, fmi2Error, "logStatusError", "%s", buf);
    inst->state = CW_ERROR;
    return fmi2Error;
}

/* Refuse a call made in the wrong state without changing the state: the
 * instance itself is still consistent, the caller is not. */
static int allowed(cw_instance *inst, const char *fn, int mask) {
    if (!inst) return 0;
    if (inst->state & mask) return 1;
    cw_log(inst, fmi2Error, "logStatusError",
           "%s may not be called in state %s.", fn, state_name(inst->state));
    return 0;
}

double cw_input(const cw_instance *inst, unsigned vr, double t) {
    double dt = t - inst->in_tref[vr];
    return inst->r[vr] + dt * (inst->in_d1[vr] + 0.5 * dt * inst->in_d2[vr]);
}

double cw_input_rate(const cw_instance *inst, unsigned vr, double t) {
    return inst->in_d1[vr] + (t - inst->in_tref[vr]) * inst->in_d2[vr];
}

static const cw_var_info *var(cw_instance *inst, fmi2ValueReference vr) {
    if (vr >= (fmi2ValueReference)inst->model->nvars) return NULL;
    const cw_var_info *v = &inst->model->vars[vr];
    return v->name ? v : NULL;
}

static void *alloc(cw_instance *inst, size_t n, size_t size) {
    if (n == 0) n = 1;
    return inst->cb.allocateMemory(n, size);
}

static void set_start_values(cw_instance *inst) {
    const cw_model *m = inst->model;
    for (int k = 0; k < m->nvars; k++) {
        const cw_var_info *v = &m->vars[k];
        if (!v->name) continue;
        if (v->type == CW_REAL)
            inst->r[k] = v->start;
        else
            inst->i[k] = (int32_t)v->start;
        inst->in_d1[k] = inst->in_d2[k] = 0.0;
        inst->in_tref[k] = 0.0;
    }
    memset(inst->s, 0, sizeof(double) * (m->n_real_state ? m->n_real_state : 1));
    memset(inst->u, 0, sizeof(uint64_t) * (m->n_uint_state ? m->n_uint_state : 1));
    inst->time = 0.0;
    inst->start_time = 0.0;
    inst->stop_time = 0.0;
    inst->stop_time_defined = 0;
    inst->outputs_dirty = 1;
    inst->terminate_requested = 0;
}

static void refresh_outputs(cw_instance *inst) {
    if (inst->outputs_dirty && inst->model->calc_outputs) {
        inst->model->calc_outputs(inst);
    }
    inst->outputs_dirty = 0;
}

/* Refresh the outputs and refuse to hand out a non-finite one: inputs and
 * parameters inside their ranges can still overflow a model's arithmetic
 * (found by fuzz/fuzz_fmu.c), and a NaN or inf must never reach the master
 * with fmi2OK. */
static int outputs_finite(cw_instance *inst, const char *fn) {
    refresh_outputs(inst);
    const cw_model *m = inst->model;
    for (int k = 0; k < m->nvars; k++) {
        const cw_var_info *v = &m->vars[k];
        if (v->name && v->type == CW_REAL && v->causality == CW_OUTPUT &&
            !isfinite(inst->r[k])) {
            fail(inst,
                 "%s: output %s = %g at t = %.17g is not finite: the inputs "
                 "or parameters are beyond what %s can represent.",
                 fn, v->name, inst->r[k], inst->time, m->name);
            return 0;
        }
    }
    return 1;
}

/* ------------------------------------------------------------------ */
/* Inquire version numbers and setting logging status                 */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn,
                               size_t nCategories,
                               const fmi2String categories[]) {
    cw_instance *inst = (cw_instance *)c;
    if (!allowed(inst, "fmi2SetDebugLogging", ANY_OPEN_STATE)) return fmi2Error;
    static const char *known[] = {"logEvents", "logStatusWarning",
                                  "logStatusDiscard", "logStatusError",
                                  "logStatusFatal", "logAll"};
    if (nCategories > 0 && !categories) {
        cw_log(inst, fmi2Error, "logStatusError",
               "fmi2SetDebugLogging: categories is NULL but nCategories = %zu.",
               nCategories);
        return fmi2Error;
    }
    for (size_t k = 0; k < nCategories; k++) {
        int found = 0;
        for (size_t j = 0; j < sizeof known / sizeof *known; j++)
            if (categories[k] && strcmp(categories[k], known[j]) == 0) found = 1;
        if (!found) {
            cw_log(inst, fmi2Error, "logStatusError",
                   "fmi2SetDebugLogging: unknown log category '%s'.",
                   categories[k] ? categories[k] : "(null)");
            return fmi2Error;
        }
    }
    inst->logging_on = loggingOn ? 1 : 0;
    return fmi2OK;
}

/* ------------------------------------------------------------------ */
/* Creation and destruction of instances                              */

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType,
                              fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)fmuResourceLocation;
    (void)visible;
    if (!functions || !functions->allocateMemory || !functions->freeMemory)
        return NULL; /* nobody to tell: the standard requires these */
    cw_instance tmp;
    memset(&tmp, 0, sizeof tmp);
    tmp.cb = *functions;
    tmp.instance_name = (char *)(instanceName ? instanceName : "?");
    tmp.model = &CW_MODEL;
    if (!instanceName || !*instanceName) {
        cw_log(&tmp, fmi2Error, "logStatusError",
               "fmi2Instantiate: instanceName must be a non-empty string.");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        cw_log(&tmp, fmi2Error, "logStatusError",
               "fmi2Instantiate: %s supports only fmi2CoSimulation.",
               CW_MODEL.name);
        return NULL;
    }
    if (!fmuGUID || strcmp(fmuGUID, CW_MODEL.guid) != 0) {
        cw_log(&tmp, fmi2Error, "logStatusError",
               "fmi2Instantiate: GUID '%s' does not match %s's '%s'.",
               fmuGUID ? fmuGUID : "(null)", CW_MODEL.name, CW_MODEL.guid);
        return NULL;
    }
    cw_instance *inst = functions->allocateMemory(1, sizeof(cw_instance));
    if (!inst) return NULL;
    *inst = tmp;
    size_t len = strlen(instanceName) + 1;
    inst->instance_name = functions->allocateMemory(len, 1);
    int nv = CW_MODEL.nvars;
    inst->r = alloc(inst, nv, sizeof(double));
    inst->i = alloc(inst, nv, sizeof(int32_t));
    inst->in_d1 = alloc(inst, nv, sizeof(double));
    inst->in_d2 = alloc(inst, nv, sizeof(double));
    inst->in_tref = alloc(inst, nv, sizeof(double));
    inst->s = alloc(inst, CW_MODEL.n_real_state, sizeof(double));
    inst->u = alloc(inst, CW_MODEL.n_uint_state, sizeof(uint64_t));
    if (!inst->instance_name || !inst->r || !inst->i || !inst->in_d1 ||
        !inst->in_d2 || !inst->in_tref || !inst->s || !inst->u) {
        cw_log(&tmp, fmi2Error, "logStatusError",
               "fmi2Instantiate: out of memory.");
        fmi2FreeInstance(inst);
        return NULL;
    }
    memcpy(inst->instance_name, instanceName, len);
    inst->logging_on = loggingOn ? 1 : 0;
    inst->state = CW_INSTANTIATED;
    set_start_values(inst);
    return inst;
}

void fmi2FreeInstance(fmi2Component c) {
    cw_instance *inst = (cw_instance *)c;
    if (!inst) return;
    fmi2CallbackFreeMemory freeMemory = inst->cb.freeMemory;
    void *blocks[] = {inst->r,     inst->i,       inst->in_d1, inst->in_d2,
                      inst->in_tref, inst->s,     inst->u,
                      inst->instance_name, inst->scratch};
    for (size_t k = 0; k < sizeof blocks / sizeof *blocks; k++)
        if (blocks[k]) freeMemory(blocks[k]);
    freeMemory(inst);
}

/* ------------------------------------------------------------------ */
/* Initialization                                                     */

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined,
                               fmi2Real stopTime) {
    cw_instance *inst = (cw_instance *)c;
    if (!allowed(inst, "fmi2SetupExperiment", CW_INSTANTIATED)) return fmi2Error;
    /* Kept for models that integrate to it; the clock's models take their
     * tolerances as parameters. */
    inst->tolerance_defined = toleranceDefined ? 1 : 0;
    inst->tolerance = toleranceDefined ? tolerance : 0.0;
    if (!isfinite(startTime))
        return fail(inst, "fmi2SetupExperiment: startTime = %g must be finite.",
                    startTime);
    if (stopTimeDefined && !(isfinite(stopTime) && stopTime >= startTime))
        return fail(inst,
                    "fmi2SetupExperiment: stopTime = %g must be finite and >= "
                    "startTime = %g.",
                    stopTime, startTime);
    inst->start_time = startTime;
    inst->time = startTime;
    inst->stop_time = stopTime;
    inst->stop_time_defined = stopTimeDefined ? 1 : 0;
    for (int k = 0; k < inst->model->nvars; k++) inst->in_tref[k] = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    cw_instance *inst = (cw_instance *)c;
    if (!allowed(inst, "fmi2EnterInitializationMode", CW_INSTANTIATED))
        return fmi2Error;
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

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    cw_instance *inst = (cw_instance *)c;
    if (!allowed(inst, "fmi2ExitInitializationMode", CW_INIT_MODE))
        return fmi2Error;
    fmi2Status st = validate_and_initialize(inst);
    if (st > fmi2Warning) return st;
    if (!outputs_finite(inst, "fmi2ExitInitializationMode")) return fmi2Error;
    inst->state = CW_STEP_COMPLETE;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    cw_instance *inst = (cw_instance *)c;
    if (!allowed(inst, "fmi2Terminate", CW_STEP_COMPLETE | CW_STEP_FAILED))
        return fmi2Error;
    inst->state = CW_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    cw_instance *inst = (cw_instance *)c;
    if (!allowed(inst, "fmi2Reset", ANY_OPEN_STATE)) return fmi2Error;
    set_start_values(inst);
    inst->state = CW_INSTANTIATED;
    return fmi2OK;
}

/* ------------------------------------------------------------------ */
/* Getting and setting variable values                                */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[],
                       size_t nvr, fmi2Real value[]) {
    cw_instance *inst = (cw_instance *)c;
    if (!allowed(inst, "fmi2GetReal", READABLE_STATES)) return fmi2Error;
    if (nvr > 0 && (!vr || !value)) {
        cw_log(inst, fmi2Error, "logStatusError",
               "fmi2GetReal: vr or value is NULL with nvr = %zu.", nvr);
        return fmi2Error;
    }
    if (inst->state == CW_INIT_MODE && inst->outputs_dirty &&
        inst->model->initialize)
        inst->model->initialize(inst); /* outputs from the current parameters */
    if (!outputs_finite(inst, "fmi2GetReal")) return fmi2Error;
    for (size_t k = 0; k < nvr; k++) {
        const cw_var_info *v = var(inst, vr[k]);
        if (!v || v->type != CW_REAL) {
            cw_log(inst, fmi2Error, "logStatusError",
                   "fmi2GetReal: %u is not the value reference of a Real "
                   "variable of %s.",
                   (unsigned)vr[k], inst->model->name);
            return fmi2Error;
        }
        value[k] = inst->r[vr[k]];
    }
    return fmi2OK;
}

static fmi2Status get_int_like(cw_instance *inst, const char *fn, cw_type type,
                               const fmi2ValueReference vr[], size_t nvr,
                               int32_t value[]) {
    if (!allowed(inst, fn, READABLE_STATES)) return fmi2Error;
    if (nvr > 0 && (!vr || !value)) {
        cw_log(inst, fmi2Error, "logStatusError",
               "%s: vr or value is NULL with nvr = %zu.", fn, nvr);
        return fmi2Error;
    }
    if (inst->state == CW_INIT_MODE && inst->outputs_dirty &&
        inst->model->initialize)
        inst->model->initialize(inst);
    if (!outputs_finite(inst, fn)) return fmi2Error;
    for (size_t k = 0; k < nvr; k++) {
        const cw_var_info *v = var(inst, vr[k]);
        if (!v || v->type != type) {
            cw_log(inst, fmi2Error, "logStatusError",
                   "%s: %u is not the value reference of a%s variable of %s.",
                   fn, (unsigned)vr[k],
                   type == CW_INTEGER ? "n Integer" : " Boolean",
                   inst->model->name);
            return fmi2Error;
        }
        value[k] = inst->i[vr[k]];
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[],
                          size_t nvr, fmi2Integer value[]) {
    return get_int_like((cw_instance *)c, "fmi2GetInteger", CW_INTEGER, vr, nvr,
                        value);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[],
                          size_t nvr, fmi2Boolean value[]) {
    return get_int_like((cw_instance *)c, "fmi2GetBoolean", CW_BOOLEAN, vr, nvr,
                        value);
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[],
                         size_t nvr, fmi2String value[]) {
    cw_instance *inst = (cw_instance *)c;
    (void)value;
    if (!allowed(inst, "fmi2GetString", READABLE_STATES)) return fmi2Error;
    if (nvr == 0) return fmi2OK;
    cw_log(inst, fmi2Error, "logStatusError",
           "fmi2GetString: %s has no String variables (vr %u).",
           inst->model->name, vr ? (unsigned)vr[0] : 0u);
    return fmi2Error;
}

/* May variable v be set in the instance's current state? */
static int settable(cw_instance *inst, const cw_var_info *v, const char *fn) {
    int ok;
    switch (v->causality) {
    case CW_INPUT:
        ok = inst->state & (CW_INSTANTIATED | CW_INIT_MODE | CW_STEP_COMPLETE);
        break;
    case CW_PARAMETER:
        ok = v->variability == CW_TUNABLE
                 ? inst->state &
                       (CW_INSTANTIATED | CW_INIT_MODE | CW_STEP_COMPLETE)
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
                        "fmi2ExitInitializationMode"
                      : "not in this state";
        cw_log(inst, fmi2Error, "logStatusError",
               "%s: cannot set '%s' in state %s: %s.", fn, v->name,
               state_name(inst->state), why);
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
    if (tunable_changed && inst->state == CW_STEP_COMPLETE &&
        inst->model->validate) {
        fmi2Status st = inst->model->validate(inst);
        if (st > fmi2Warning) {
            inst->state = CW_ERROR;
            return st;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[],
                       size_t nvr, const fmi2Real value[]) {
    cw_instance *inst = (cw_instance *)c;
    if (!allowed(inst, "fmi2SetReal",
                 CW_INSTANTIATED | CW_INIT_MODE | CW_STEP_COMPLETE))
        return fmi2Error;
    if (nvr > 0 && (!vr || !value)) {
        cw_log(inst, fmi2Error, "logStatusError",
               "fmi2SetReal: vr or value is NULL with nvr = %zu.", nvr);
        return fmi2Error;
    }
    /* Check everything first so that a refused call changes nothing. */
    for (size_t k = 0; k < nvr; k++) {
        const cw_var_info *v = var(inst, vr[k]);
        if (!v || v->type != CW_REAL) {
            cw_log(inst, fmi2Error, "logStatusError",
                   "fmi2SetReal: %u is not the value reference of a Real "
                   "variable of %s.",
                   (unsigned)vr[k], inst->model->name);
            return fmi2Error;
        }
        if (!settable(inst, v, "fmi2SetReal")) return fmi2Error;
        if (!acceptable(inst, v, value[k], "fmi2SetReal")) {
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

static fmi2Status set_int_like(cw_instance *inst, const char *fn, cw_type type,
                               const fmi2ValueReference vr[], size_t nvr,
                               const int32_t value[]) {
    if (!allowed(inst, fn, CW_INSTANTIATED | CW_INIT_MODE | CW_STEP_COMPLETE))
        return fmi2Error;
    if (nvr > 0 && (!vr || !value)) {
        cw_log(inst, fmi2Error, "logStatusError",
               "%s: vr or value is NULL with nvr = %zu.", fn, nvr);
        return fmi2Error;
    }
    for (size_t k = 0; k < nvr; k++) {
        const cw_var_info *v = var(inst, vr[k]);
        if (!v || v->type != type) {
            cw_log(inst, fmi2Error, "logStatusError",
                   "%s: %u is not the value reference of a%s variable of %s.",
                   fn, (unsigned)vr[k],
                   type == CW_INTEGER ? "n Integer" : " Boolean",
                   inst->model->name);
            return fmi2Error;
        }
        if (!settable(inst, v, fn)) return fmi2Error;
        double x = type == CW_BOOLEAN ? (value[k] != 0) : (double)value[k];
        if (!acceptable(inst, v, x, fn)) {
            inst->state = CW_ERROR;
            return fmi2Error;
        }
    }
    int tunable = 0;
    for (size_t k = 0; k < nvr; k++) {
        const cw_var_info *v = &inst->model->vars[vr[k]];
        inst->i[vr[k]] = type == CW_BOOLEAN ? (value[k] != 0) : value[k];
        if (v->causality != CW_INPUT) tunable = 1;
    }
    return after_set(inst, tunable);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[],
                          size_t nvr, const fmi2Integer value[]) {
    return set_int_like((cw_instance *)c, "fmi2SetInteger", CW_INTEGER, vr, nvr,
                        value);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[],
                          size_t nvr, const fmi2Boolean value[]) {
    return set_int_like((cw_instance *)c, "fmi2SetBoolean", CW_BOOLEAN, vr, nvr,
                        value);
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[],
                         size_t nvr, const fmi2String value[]) {
    cw_instance *inst = (cw_instance *)c;
    (void)value;
    if (!allowed(inst, "fmi2SetString",
                 CW_INSTANTIATED | CW_INIT_MODE | CW_STEP_COMPLETE))
        return fmi2Error;
    if (nvr == 0) return fmi2OK;
    cw_log(inst, fmi2Error, "logStatusError",
           "fmi2SetString: %s has no String variables (vr %u).",
           inst->model->name, vr ? (unsigned)vr[0] : 0u);
    return fmi2Error;
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
#define FNV_SEED 14695981039346656037ULL

/* The state's checksum: FNV-1a over little-endian 64-bit words, the tail
 * byte by byte. One multiplication per 8 bytes instead of per byte: a
 * rollback checks it on every fmi2SetFMUstate. Each step is a bijection of
 * the running hash, so any one changed word changes the result. */
static uint64_t state_checksum(const unsigned char *p, size_t n) {
    uint64_t h = FNV_SEED;
    size_t k = 0;
    for (; k + 8 <= n; k += 8) {
        uint64_t w = 0;
        for (int b = 0; b < 8; b++) w |= (uint64_t)p[k + b] << (8 * b);
        h ^= w;
        h *= 1099511628211ULL;
    }
    return fnv1a(p + k, n - k, h);
}

static size_t state_size(const cw_model *m) {
    size_t n = 4 + 4 + 8 + 4 + 4 + 8;
    for (int k = 0; k < m->nvars; k++) {
        const cw_var_info *v = &m->vars[k];
        if (!v->name) continue;
        n += v->type == CW_REAL ? 8 : 4;
        if (v->type == CW_REAL && v->causality == CW_INPUT) n += 24;
    }
    n += 4 + 8 * (size_t)m->n_real_state + 4 + 8 * (size_t)m->n_uint_state;
    return n + 8;
}

/* Explicit little-endian encoding, independent of the host's layout. */
static void put_u32(unsigned char **p, uint32_t x) {
    for (int b = 0; b < 4; b++) *(*p)++ = (unsigned char)(x >> (8 * b));
}
static void put_u64(unsigned char **p, uint64_t x) {
    for (int b = 0; b < 8; b++) *(*p)++ = (unsigned char)(x >> (8 * b));
}
static void put_f64(unsigned char **p, double x) {
    uint64_t u;
    memcpy(&u, &x, 8);
    put_u64(p, u);
}
static uint32_t get_u32(const unsigned char **p) {
    uint32_t x = 0;
    for (int b = 0; b < 4; b++) x |= (uint32_t)(*(*p)++) << (8 * b);
    return x;
}
static uint64_t get_u64(const unsigned char **p) {
    uint64_t x = 0;
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
    put_u64(&p, fnv1a((const unsigned char *)m->guid, strlen(m->guid), FNV_SEED));
    put_u32(&p, (uint32_t)size);
    put_u32(&p, (uint32_t)inst->state);
    put_f64(&p, inst->time);
    for (int k = 0; k < m->nvars; k++) {
        const cw_var_info *v = &m->vars[k];
        if (!v->name) continue;
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
    put_u64(&p, state_checksum(buf, (size_t)(p - buf)));
}

/* Check a state buffer and decode it into inst, which is a scratch copy
 * (see restore_state): the layout, the checksum and every value's range. */
static fmi2Status decode_state(cw_instance *inst, const unsigned char *buf,
                               size_t size, const char *fn) {
    const cw_model *m = inst->model;
    size_t expected = state_size(m);
    if (!buf) return fail(inst, "%s: the state is NULL.", fn);
    if (size != expected)
        return fail(inst, "%s: the state has %zu bytes; %s expects %zu.", fn,
                    size, m->name, expected);
    const unsigned char *p = buf;
    uint32_t magic = get_u32(&p), version = get_u32(&p);
    uint64_t guid_hash = get_u64(&p);
    uint32_t stored_size = get_u32(&p);
    if (magic != STATE_MAGIC)
        return fail(inst, "%s: not a clockwork FMU state (bad magic).", fn);
    if (version != STATE_LAYOUT_VERSION)
        return fail(inst, "%s: state layout version %u, expected %u.", fn,
                    version, STATE_LAYOUT_VERSION);
    if (guid_hash !=
        fnv1a((const unsigned char *)m->guid, strlen(m->guid), FNV_SEED))
        return fail(inst, "%s: the state belongs to another model, not %s.", fn,
                    m->name);
    if (stored_size != expected)
        return fail(inst, "%s: the state header says %u bytes, expected %zu.",
                    fn, stored_size, expected);
    const unsigned char *end = buf + size - 8;
    const unsigned char *q = end;
    if (get_u64(&q) != state_checksum(buf, size - 8))
        return fail(inst, "%s: the state is corrupt (checksum mismatch).", fn);

    /* Decode into scratch space first: a refused state changes nothing. */
    uint32_t machine = get_u32(&p);
    if (!(machine & (CW_INSTANTIATED | CW_INIT_MODE | CW_STEP_COMPLETE |
                     CW_STEP_FAILED | CW_TERMINATED)) ||
        (machine & (machine - 1)))
        return fail(inst, "%s: the state holds an invalid machine state %u.", fn,
                    machine);
    double t = get_f64(&p);
    if (!isfinite(t)) return fail(inst, "%s: the state's time is not finite.", fn);
    const unsigned char *values = p;
    for (int k = 0; k < m->nvars; k++) {
        const cw_var_info *v = &m->vars[k];
        if (!v->name) continue;
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

    /* Everything checked: commit. */
    p = values;
    inst->state = (cw_machine_state)machine;
    inst->time = t;
    for (int k = 0; k < m->nvars; k++) {
        const cw_var_info *v = &m->vars[k];
        if (!v->name) continue;
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
 * parameter combination that fmi2SetReal would refuse. With `commit`, an
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
            (probe.state & (CW_STEP_COMPLETE | CW_STEP_FAILED | CW_TERMINATED)) &&
            m->validate(&probe) > fmi2Warning) {
            cw_log(inst, fmi2Error, "logStatusError",
                   "%s: the state's parameters break a rule of %s between "
                   "parameters (see above); the state is refused.",
                   fn, m->name);
            st = fmi2Error;
        }
    }
    if (st == fmi2OK && commit) {
        const size_t nv = (size_t)m->nvars;
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
    }
    if (st != fmi2OK) {
        inst->state = CW_ERROR;
        return fmi2Error;
    }
    return fmi2OK;
}

#define STATE_STATES ANY_OPEN_STATE

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    cw_instance *inst = (cw_instance *)c;
    if (!allowed(inst, "fmi2GetFMUstate", STATE_STATES & ~CW_ERROR))
        return fmi2Error;
    if (!FMUstate) return fail(inst, "fmi2GetFMUstate: FMUstate is NULL.");
    /* A state with non-finite outputs could never be restored. */
    if (!outputs_finite(inst, "fmi2GetFMUstate")) return fmi2Error;
    size_t size = state_size(inst->model);
    cw_state_blob *blob = (cw_state_blob *)*FMUstate;
    if (blob && blob->size != size) {
        inst->cb.freeMemory(blob);
        blob = NULL;
    }
    if (!blob) {
        blob = inst->cb.allocateMemory(1, sizeof(cw_state_blob) + size);
        if (!blob) return fail(inst, "fmi2GetFMUstate: out of memory.");
        blob->size = size;
    }
    encode_state(inst, blob->bytes, size);
    *FMUstate = blob;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    cw_instance *inst = (cw_instance *)c;
    if (!allowed(inst, "fmi2SetFMUstate", STATE_STATES)) return fmi2Error;
    cw_state_blob *blob = (cw_state_blob *)FMUstate;
    if (!blob) return fail(inst, "fmi2SetFMUstate: FMUstate is NULL.");
    return restore_state(inst, blob->bytes, blob->size, "fmi2SetFMUstate", 1);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    cw_instance *inst = (cw_instance *)c;
    if (!allowed(inst, "fmi2FreeFMUstate", STATE_STATES)) return fmi2Error;
    if (!FMUstate) return fail(inst, "fmi2FreeFMUstate: FMUstate is NULL.");
    if (*FMUstate) inst->cb.freeMemory(*FMUstate);
    *FMUstate = NULL;
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate,
                                      size_t *size) {
    cw_instance *inst = (cw_instance *)c;
    if (!allowed(inst, "fmi2SerializedFMUstateSize", STATE_STATES))
        return fmi2Error;
    if (!FMUstate || !size)
        return fail(inst, "fmi2SerializedFMUstateSize: NULL argument.");
    *size = ((cw_state_blob *)FMUstate)->size;
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate,
                                 fmi2Byte serializedState[], size_t size) {
    cw_instance *inst = (cw_instance *)c;
    if (!allowed(inst, "fmi2SerializeFMUstate", STATE_STATES)) return fmi2Error;
    cw_state_blob *blob = (cw_state_blob *)FMUstate;
    if (!blob || !serializedState)
        return fail(inst, "fmi2SerializeFMUstate: NULL argument.");
    if (size < blob->size)
        return fail(inst,
                    "fmi2SerializeFMUstate: buffer of %zu bytes is too small "
                    "for %zu.",
                    size, blob->size);
    memcpy(serializedState, blob->bytes, blob->size);
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c,
                                   const fmi2Byte serializedState[],
                                   size_t size, fmi2FMUstate *FMUstate) {
    cw_instance *inst = (cw_instance *)c;
    if (!allowed(inst, "fmi2DeSerializeFMUstate", STATE_STATES))
        return fmi2Error;
    if (!serializedState || !FMUstate)
        return fail(inst, "fmi2DeSerializeFMUstate: NULL argument.");
    /* Check it whole now, so that a bad buffer is refused here rather than
     * at fmi2SetFMUstate. */
    size_t expected = state_size(inst->model);
    if (size != expected)
        return fail(inst,
                    "fmi2DeSerializeFMUstate: %zu bytes given; %s expects %zu.",
                    size, inst->model->name, expected);
    if (restore_state(inst, (const unsigned char *)serializedState, size,
                      "fmi2DeSerializeFMUstate", 0) != fmi2OK)
        return fmi2Error;
    cw_state_blob *blob = inst->cb.allocateMemory(1, sizeof(cw_state_blob) + size);
    if (!blob) return fail(inst, "fmi2DeSerializeFMUstate: out of memory.");
    blob->size = size;
    memcpy(blob->bytes, serializedState, size);
    if (*FMUstate) inst->cb.freeMemory(*FMUstate);
    *FMUstate = blob;
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c,
                                        const fmi2ValueReference vUnknown[],
                                        size_t nUnknown,
                                        const fmi2ValueReference vKnown[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[]) {
    cw_instance *inst = (cw_instance *)c;
    (void)vUnknown;
    (void)nUnknown;
    (void)vKnown;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    if (!inst) return fmi2Error;
    cw_log(inst, fmi2Error, "logStatusError",
           "fmi2GetDirectionalDerivative: %s does not provide directional "
           "derivatives (providesDirectionalDerivative=false).",
           inst->model->name);
    return fmi2Error;
}

/* ------------------------------------------------------------------ */
/* Co-Simulation                                                      */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c,
                                       const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[]) {
    cw_instance *inst = (cw_instance *)c;
    if (!allowed(inst, "fmi2SetRealInputDerivatives",
                 CW_INSTANTIATED | CW_INIT_MODE | CW_STEP_COMPLETE))
        return fmi2Error;
    if (nvr > 0 && (!vr || !order || !value)) {
        cw_log(inst, fmi2Error, "logStatusError",
               "fmi2SetRealInputDerivatives: NULL argument with nvr = %zu.",
               nvr);
        return fmi2Error;
    }
    for (size_t k = 0; k < nvr; k++) {
        const cw_var_info *v = var(inst, vr[k]);
        if (!v || v->type != CW_REAL || v->causality != CW_INPUT) {
            cw_log(inst, fmi2Error, "logStatusError",
                   "fmi2SetRealInputDerivatives: %u is not a Real input of %s.",
                   (unsigned)vr[k], inst->model->name);
            return fmi2Error;
        }
        const int max_order = inst->model->max_input_order ? inst->model->max_input_order : 2;
        if (order[k] < 1 || order[k] > max_order) {
            cw_log(inst, fmi2Error, "logStatusError",
                   "fmi2SetRealInputDerivatives: order %d for %s; expected 1 "
                   "to %d.",
                   (int)order[k], v->name, max_order);
            return fmi2Error;
        }
        if (!isfinite(value[k])) {
            cw_log(inst, fmi2Error, "logStatusError",
                   "fmi2SetRealInputDerivatives: derivative of %s = %g; "
                   "expected a finite number.",
                   v->name, value[k]);
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
    return fmi2OK;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c,
                                        const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    cw_instance *inst = (cw_instance *)c;
    if (!allowed(inst, "fmi2GetRealOutputDerivatives",
                 CW_STEP_COMPLETE | CW_STEP_FAILED | CW_TERMINATED | CW_ERROR))
        return fmi2Error;
    if (nvr > 0 && (!vr || !order || !value)) {
        cw_log(inst, fmi2Error, "logStatusError",
               "fmi2GetRealOutputDerivatives: NULL argument with nvr = %zu.",
               nvr);
        return fmi2Error;
    }
    if (!outputs_finite(inst, "fmi2GetRealOutputDerivatives")) return fmi2Error;
    for (size_t k = 0; k < nvr; k++) {
        const cw_var_info *v = var(inst, vr[k]);
        if (!v || v->type != CW_REAL || v->causality != CW_OUTPUT) {
            cw_log(inst, fmi2Error, "logStatusError",
                   "fmi2GetRealOutputDerivatives: %u is not a Real output of "
                   "%s.",
                   (unsigned)vr[k], inst->model->name);
            return fmi2Error;
        }
        if (order[k] < 1 || order[k] > v->max_derivative_order ||
            !inst->model->output_derivative ||
            !inst->model->output_derivative(inst, vr[k], order[k], &value[k])) {
            cw_log(inst, fmi2Error, "logStatusError",
                   "fmi2GetRealOutputDerivatives: %s offers derivatives up to "
                   "order %d, not %d.",
                   v->name, v->max_derivative_order, (int)order[k]);
            return fmi2Error;
        }
        if (!isfinite(value[k]))
            return fail(inst,
                        "fmi2GetRealOutputDerivatives: derivative of order %d "
                        "of %s = %g at t = %.17g is not finite.",
                        (int)order[k], v->name, value[k], inst->time);
    }
    return fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    cw_instance *inst = (cw_instance *)c;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!allowed(inst, "fmi2DoStep", CW_STEP_COMPLETE)) return fmi2Error;
    const double tc = currentCommunicationPoint, h = communicationStepSize;
    if (!isfinite(tc) || !isfinite(h) || !(h > 0)) {
        cw_log(inst, fmi2Error, "logStatusError",
               "fmi2DoStep: communication point %g and step size %g; expected "
               "finite values and a step size > 0.",
               tc, h);
        return fmi2Error;
    }
    /* The master's time is authoritative, but it must be the point where
     * this FMU stands. */
    if (fabs(tc - inst->time) > 1e-9 * fmax(1.0, fabs(inst->time))) {
        cw_log(inst, fmi2Error, "logStatusError",
               "fmi2DoStep: communication point %.17g does not match the "
               "FMU's time %.17g.",
               tc, inst->time);
        return fmi2Error;
    }
    const double t_end = tc + h;
    if (!isfinite(t_end)) { /* found by fuzzing: time became inf */
        cw_log(inst, fmi2Error, "logStatusError",
               "fmi2DoStep: the step from %.17g by %.17g ends beyond the "
               "largest representable time.",
               tc, h);
        return fmi2Error;
    }
    if (inst->stop_time_defined &&
        t_end > inst->stop_time + 1e-9 * fmax(1.0, fabs(inst->stop_time))) {
        cw_log(inst, fmi2Error, "logStatusError",
               "fmi2DoStep: step to %.17g goes beyond stopTime %.17g.", t_end,
               inst->stop_time);
        return fmi2Error;
    }
    /* Input polynomials are checked where the model will evaluate them:
     * huge derivatives can overflow them to inf over a step. */
    for (int k = 0; k < inst->model->nvars; k++) {
        const cw_var_info *v = &inst->model->vars[k];
        if (!v->name || v->type != CW_REAL || v->causality != CW_INPUT) continue;
        const double u0 = cw_input(inst, (unsigned)k, tc),
                     u1 = cw_input(inst, (unsigned)k, t_end);
        if (!isfinite(u0) || !isfinite(u1))
            return fail(inst,
                        "fmi2DoStep: input %s, following its derivatives, is "
                        "%g at t = %.17g and %g at t = %.17g; expected finite "
                        "values.",
                        v->name, u0, tc, u1, t_end);
    }
    inst->time = tc;
    if (inst->model->commit) inst->model->commit(inst);
    fmi2Status st = fmi2OK;
    if (inst->model->do_step) st = inst->model->do_step(inst, t_end);
    inst->outputs_dirty = 1;
    if (st == fmi2OK || st == fmi2Warning) {
        inst->time = t_end;
        if (!outputs_finite(inst, "fmi2DoStep")) return fmi2Error;
        return st;
    }
    if (st == fmi2Discard) {
        inst->state = CW_STEP_FAILED;
        refresh_outputs(inst);
        return st;
    }
    inst->state = CW_ERROR;
    return fmi2Error;
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    cw_instance *inst = (cw_instance *)c;
    if (!inst) return fmi2Error;
    cw_log(inst, fmi2Error, "logStatusError",
           "fmi2CancelStep: steps are synchronous; there is nothing to cancel.");
    return fmi2Error;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s,
                         fmi2Status *value) {
    cw_instance *inst = (cw_instance *)c;
    if (!allowed(inst, "fmi2GetStatus",
                 CW_STEP_COMPLETE | CW_STEP_FAILED | CW_TERMINATED))
        return fmi2Error;
    if (!value) {
        cw_log(inst, fmi2Error, "logStatusError", "fmi2GetStatus: value is NULL.");
        return fmi2Error;
    }
    if (s == fmi2DoStepStatus) {
        *value = inst->state == CW_STEP_FAILED ? fmi2Discard : fmi2OK;
        return fmi2OK;
    }
    cw_log(inst, fmi2Error, "logStatusError",
           "fmi2GetStatus: status kind %d is not provided.", (int)s);
    return fmi2Error;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s,
                             fmi2Real *value) {
    cw_instance *inst = (cw_instance *)c;
    if (!allowed(inst, "fmi2GetRealStatus",
                 CW_STEP_COMPLETE | CW_STEP_FAILED | CW_TERMINATED))
        return fmi2Error;
    if (!value) {
        cw_log(inst, fmi2Error, "logStatusError",
               "fmi2GetRealStatus: value is NULL.");
        return fmi2Error;
    }
    if (s == fmi2LastSuccessfulTime) {
        *value = inst->time;
        return fmi2OK;
    }
    cw_log(inst, fmi2Error, "logStatusError",
           "fmi2GetRealStatus: status kind %d is not provided.", (int)s);
    return fmi2Error;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s,
                                fmi2Integer *value) {
    cw_instance *inst = (cw_instance *)c;
    (void)s;
    (void)value;
    if (!inst) return fmi2Error;
    cw_log(inst, fmi2Error, "logStatusError",
           "fmi2GetIntegerStatus: no Integer status is provided.");
    return fmi2Error;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s,
                                fmi2Boolean *value) {
    cw_instance *inst = (cw_instance *)c;
    if (!allowed(inst, "fmi2GetBooleanStatus",
                 CW_STEP_COMPLETE | CW_STEP_FAILED | CW_TERMINATED))
        return fmi2Error;
    if (!value) {
        cw_log(inst, fmi2Error, "logStatusError",
               "fmi2GetBooleanStatus: value is NULL.");
        return fmi2Error;
    }
    if (s == fmi2Terminated) {
        *value = inst->terminate_requested ? fmi2True : fmi2False;
        return fmi2OK;
    }
    cw_log(inst, fmi2Error, "logStatusError",
           "fmi2GetBooleanStatus: status kind %d is not provided.", (int)s);
    return fmi2Error;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s,
                               fmi2String *value) {
    cw_instance *inst = (cw_instance *)c;
    (void)s;
    (void)value;
    if (!inst) return fmi2Error;
    cw_log(inst, fmi2Error, "logStatusError",
           "fmi2GetStringStatus: no String status is provided.");
    return fmi2Error;
}

int cw_integrate(struct cw_instance *inst, const char *model, cw_rhs f, int n,
                 int first, int h_slot, double t_end, double rtol, double atol,
                 double h_max, int integrator, const char *const names[],
                 cw_rk_observer observer) {
    cw_rk rk;
    cw_rk_init(&rk, n, rtol, atol, h_max);
    cw_rk_set_method(&rk, integrator);
    double x[CW_RK_MAXN];
    for (int k = 0; k < n; k++) x[k] = inst->s[first + k];
    double t = inst->time, h_next = inst->s[h_slot];
    cw_rk_result res =
        cw_rk_advance(&rk, f, inst, &t, t_end, x, &h_next, observer, inst);
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
    return fmi2OK;
}
