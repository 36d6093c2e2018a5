/* clockwork Co-Simulation runtime: the part shared by every model.
 *
 * The runtime owns the state machine, argument checks, logging,
 * per-instance storage of variable values and the FMU state serialization
 * (cw_runtime.c), and two thin faces over it: the fmi2 functions
 * (cw_fmi2.c) and the fmi3 functions (cw_fmi3.c). A model is built once
 * with each face. It supplies its equations as the static callbacks of
 * cw_model in model.c; its variable table and its cw_model are generated
 * into cw_vars.h from model.toml. Statuses are fmi2Status for both faces:
 * fmi3Status has the same values for OK, Warning, Discard, Error, Fatal
 * (cw_fmi3.c checks it when compiled). */
#ifndef CW_RUNTIME_H
#define CW_RUNTIME_H

#include <stddef.h>
#include <stdint.h>

/* The printf dialect the messages are checked against: mingw-w64's own C99
 * printf in the Windows build (__USE_MINGW_ANSI_STDIO, cmake/cross.cmake),
 * where plain `printf` would mean msvcrt's, which lacks %zu. */
#if defined(__MINGW32__) && defined(__USE_MINGW_ANSI_STDIO) && __USE_MINGW_ANSI_STDIO
#define CW_PRINTF_FORMAT gnu_printf
#else
#define CW_PRINTF_FORMAT printf
#endif

/* The statuses, by FMI 2.0's names: from its header where the fmi2 face
 * includes it first, else declared here with the same values, so that the
 * FMI 3.0 build (its sources too) needs FMI 3.0's headers only. */
#ifndef fmi2FunctionTypes_h
typedef enum {
    fmi2OK,
    fmi2Warning,
    fmi2Discard,
    fmi2Error,
    fmi2Fatal,
    fmi2Pending
} fmi2Status;
#endif

typedef enum {
    CW_REAL = 0,
    CW_INTEGER = 1,
    CW_BOOLEAN = 2,
    CW_STRING = 3 /* FMI 2.0 only: the FMI 3.0 build takes none */
} cw_type;

typedef enum {
    CW_PARAMETER = 0,
    CW_INPUT = 1,
    CW_OUTPUT = 2,
    CW_LOCAL = 3
} cw_causality;

typedef enum {
    CW_FIXED = 0,
    CW_TUNABLE = 1,
    CW_DISCRETE = 2,
    CW_CONTINUOUS = 3
} cw_variability;

typedef struct {
    const char *name;
    unsigned vr;
    cw_type type;
    cw_causality causality;
    cw_variability variability;
    double start;
    double min; /* -HUGE_VAL when unbounded */
    double max; /* +HUGE_VAL when unbounded */
    int max_derivative_order;
    int event_indicator;
    const char *start_string; /* a String's start value (NULL: "") */
} cw_var_info;

/* States of the Co-Simulation state machine. FMI 2.0's StepComplete is
 * FMI 3.0's Step Mode; Event Mode is FMI 3.0's alone. */
typedef enum {
    CW_INSTANTIATED = 1 << 0,
    CW_INIT_MODE = 1 << 1,
    CW_STEP_COMPLETE = 1 << 2,
    CW_STEP_FAILED = 1 << 3,
    CW_TERMINATED = 1 << 4,
    CW_ERROR = 1 << 5,
    CW_EVENT_MODE = 1 << 6,
    CW_INTERMEDIATE_UPDATE = 1 << 7 /* FMI 3.0: inside the importer's callback */
} cw_machine_state;

struct cw_instance;

typedef struct {
    const char *name;
    const char *guid;
    int nvars;               /* table size; value references are < nvars */
    const cw_var_info *vars; /* indexed by value reference */
    int n_real_state;        /* model doubles kept in inst->s and serialized */
    int n_uint_state;        /* model counters / RNG words in inst->u */

    /* Cross-parameter checks at fmi2ExitInitializationMode and whenever a
     * tunable parameter changes. Log the offending variable and value and
     * return fmi2Error to refuse. Single-variable ranges are checked by the
     * runtime from the table already. */
    fmi2Status (*validate)(struct cw_instance *inst);

    /* Set the model state from parameters; called once when leaving
     * initialization mode (after validate) and after fmi2Reset. */
    void (*initialize)(struct cw_instance *inst);

    /* Compute outputs from state and current inputs (at inst->time). Called
     * lazily by the runtime before outputs are read after inputs changed. */
    void (*calc_outputs)(struct cw_instance *inst);

    /* Advance the model from inst->time to t_end exactly. Inputs are read
     * through cw_input(). Return fmi2OK, or fmi2Discard/fmi2Error after
     * logging why. NULL for models without dynamics. */
    fmi2Status (*do_step)(struct cw_instance *inst, double t_end);

    /* Called at the start of fmi2DoStep / fmi3DoStep before do_step, and by
     * fmi3UpdateDiscreteStates: commit discrete modes decided from inputs
     * at the communication point (may be NULL). Calling it twice at the
     * same point with the same inputs must change nothing more. */
    void (*commit)(struct cw_instance *inst);

    /* Time derivative of given order of an output at inst->time; returns
     * 0 when unavailable (may be NULL). */
    int (*output_derivative)(struct cw_instance *inst, unsigned vr, int order,
                             double *value);

    /* Compute the state a do_step left pending (inst->state_pending, set by
     * the model after an early return); called through cw_settle before
     * anything reads or changes the state or the inputs. A do_step either
     * calls cw_settle first or overwrites the whole pending state (may be
     * NULL for models that never leave one pending). */
    void (*settle)(struct cw_instance *inst);

    /* FMI 3.0 builds with an output clock ([model] output_clock): whether
     * the clock ticks now, in Event Mode, from the committed state and the
     * current inputs (before fmi3UpdateDiscreteStates commits them); NULL
     * for models without one. Its value reference is output_clock_vr. */
    int (*clock_ticks)(struct cw_instance *inst);
    unsigned output_clock_vr;

    /* Highest order of input derivatives fmi2SetRealInputDerivatives takes;
     * 0 (the default) means 2. */
    int max_input_order;
} cw_model;

/* How a face hands a message to its environment's logger. */
typedef void (*cw_emit)(const struct cw_instance *inst, fmi2Status status,
                        const char *category, const char *message);

typedef struct cw_instance {
    const cw_model *model;
    /* The environment: memory (FMI 2.0's callbacks, calloc/free on FMI
     * 3.0), the face's logger and what it needs to call the environment's. */
    void *(*alloc_mem)(size_t n, size_t size);
    void (*free_mem)(void *p);
    cw_emit emit;
    void *env;                   /* componentEnvironment / instanceEnvironment */
    void (*env_logger)(void);    /* the environment's logger, cast by the face */
    const char *api;             /* "fmi2" or "fmi3": prefix of function names in messages */
    char *instance_name;
    int logging_on;
    cw_machine_state state;

    /* FMI 3.0 instantiation arguments (0 on FMI 2.0). */
    int event_mode_used;
    int early_return_allowed;
    /* Set by a model's do_step through cw_return_early: the time of the
     * model's own event where the step ended early (-1 flag: none). */
    int returned_early;
    double early_time;
    /* FMI 3.0 intermediate update: while fmi3DoStep runs with the
     * importer's callback, cw_input asks the importer for the inputs at a
     * new time through this hook (NULL otherwise: inputs are as set). */
    void (*intermediate_update)(struct cw_instance *inst, double t);
    void (*env_intermediate_update)(void); /* the importer's callback, cast by the face */
    double intermediate_time;              /* when the inputs were last asked for */
    /* After an early return, where the model's integrator stood (the end
     * of the accepted internal step that held the event), so that the next
     * fmi3DoStep from the event goes on with the same steps as a run
     * without early return. Valid until the importer sets a value, a state
     * or resets (the FMI 3.0 face clears it); never set on FMI 2.0. */
    int resume_valid;
    double resume_from;  /* the early return's time, s */
    double resume_t;     /* the internal step's end, s */
    double resume_h;     /* the integrator's next step size there, s */
    double resume_x[4];  /* the state there */
    /* After an early return, the state at the event is computed only when
     * something needs it (cw_settle): the importer usually handles the event
     * and steps on from it, and the next fmi3DoStep resumes from resume_x
     * without ever reading it. While pending, inst->s holds NaN where the
     * model's settle callback will write. The single step that gives it: */
    /* Bumped whenever a value, an input derivative or the whole state may
     * have changed (every setter, an FMU state restored, a reset): a model
     * may keep numbers derived from its parameters and held inputs in
     * model_cache while model_cache_epoch equals it (0: nothing kept). */
    uint64_t values_epoch;
    uint64_t model_cache_epoch;
    double model_cache[4];
    int state_pending;
    int event_method;       /* the Runge-Kutta pair (cw_rk method) */
    int event_component;    /* the crossing component, exactly 0 at the event */
    double event_step_t0;   /* the accepted step that held the event: start, s */
    double event_step_x0[4];
    double event_time;      /* s */
    double event_inputs_t;  /* where the right-hand side's held inputs were read, s */

    double time;       /* current communication point, s */
    double start_time; /* from fmi2SetupExperiment */
    double stop_time;
    int stop_time_defined;

    double *r;  /* Real values by value reference */
    int32_t *i; /* Integer and Boolean values by value reference */

    /* Input polynomials: u(t) = r[vr] + d1 (t - t_ref) + d2 (t - t_ref)^2/2 */
    double *in_d1, *in_d2, *in_tref;

    double *s;   /* model state doubles, n_real_state */
    uint64_t *u; /* model state words, n_uint_state */

    int outputs_dirty;
    /* The outputs were found finite since they last changed (outputs_finite
     * checks them once, not on every get and step). */
    int outputs_checked;
    int in_callback_error; /* set by cw_fail from model code */

    /* Where fmi2SetFMUstate decodes a state before accepting it: made on
     * the first restore and kept, so that a rollback allocates nothing. */
    void *scratch;

    /* From fmi2SetupExperiment: the environment's relative tolerance. */
    double tolerance;
    int tolerance_defined;
    /* Set by a model whose do_step returns fmi2Discard to end the
     * simulation: fmi2GetBooleanStatus(fmi2Terminated) says so. */
    int terminate_requested;
    /* The running step's noSetFMUStatePriorToCurrentPoint (fmi2DoStep,
     * fmi3DoStep): 1 when the importer will set no state from before the
     * step's start, so the model may drop its history. Always 1 on FMI 1.0,
     * which has no FMU state. */
    int no_set_prior;

    /* String values by value reference (NULL for other types): owned by
     * the instance, copied on every set, freed on reset and free. */
    char **str;

    /* The value references of the Real inputs (real_io[0 .. n_real_in)) and
     * outputs (the next n_real_out), found once at instantiation: the
     * checks at every step and every get visit these, not the whole table. */
    int *real_io;
    int n_real_in, n_real_out;

    /* The FMU state's layout constants, found once at instantiation: the
     * size without Strings, whether the model has Strings, the GUID's hash. */
    size_t state_fixed;
    int state_strings;
    uint64_t guid_hash;
} cw_instance;

/* Value of input `vr` at time t, following the input derivatives. Inline:
 * a right-hand side reads every input at every stage. */
static inline double cw_input(const cw_instance *inst, unsigned vr, double t) {
    if (inst->intermediate_update && t != inst->intermediate_time)
        inst->intermediate_update((cw_instance *)inst, t);
    const double dt = t - inst->in_tref[vr];
    return inst->r[vr] + dt * (inst->in_d1[vr] + 0.5 * dt * inst->in_d2[vr]);
}

/* Time derivative of input `vr` at time t. */
double cw_input_rate(const cw_instance *inst, unsigned vr, double t);

/* Set String variable `vr` to head followed by tail (tail may be NULL):
 * a copy the instance owns. Returns 0 after logging when out of memory,
 * leaving the old value. */
int cw_set_string(cw_instance *inst, unsigned vr, const char *head,
                  const char *tail);

/* Log through the environment's logger; category "logStatusError" etc. */
void cw_log(cw_instance *inst, fmi2Status status, const char *category,
            const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(CW_PRINTF_FORMAT, 4, 5)))
#endif
    ;

/* For do_step: may the step end early at an event the model owns (FMI 3.0
 * with earlyReturnAllowed)? Always 0 on FMI 2.0. */
int cw_may_return_early(const cw_instance *inst);

/* Called by do_step that stops at its own event at time t before t_end,
 * with the model state already at t: the step then ends at t, and fmi3DoStep
 * reports earlyReturn, eventHandlingNeeded (with Event Mode) and
 * lastSuccessfulTime = t. */
void cw_return_early(cw_instance *inst, double t);

/* The state a do_step left pending after an early return, computed now
 * (the model's settle callback); the outputs follow it. A no-op otherwise. */
static inline void cw_settle(cw_instance *inst) {
    if (!inst->state_pending) return;
    inst->state_pending = 0;
    inst->model->settle(inst);
    inst->outputs_dirty = 1;
}

/* Shorthand used by models to refuse a parameter with a named message. */
fmi2Status cw_refuse(cw_instance *inst, const char *var, double value,
                     const char *expected);

/* The model's definition: generated into cw_vars.h from model.toml and
 * compiled with model.c, which defines the callbacks it names. */
extern const cw_model CW_MODEL;

#endif
