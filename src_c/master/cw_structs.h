/* Every struct that Python mirrors with ctypes, in one place: the
 * master's (cw_port, cw_loop, cw_loops, cw_master, cw_inputs, cw_recorder,
 * cw_marks: clockwork/engine/compiled.py; cw_clocks: compiled_clocks.py), the adapters' (cw_fmi3:
 * clockwork/fmi/cs3.py's _Events; cw_fmi1: cs1.py's _Fmi1) and the Model
 * Exchange wrapper's (cw_sundials: engine/cvode.py's Table; cw_me:
 * engine/model_exchange.py's _ME).
 *
 * Each has its field table in cw_layout.c, which the Python side checks
 * field by field (clockwork/fmi/layout.py, tests/test_layout.py). A struct
 * Python mirrors goes here and nowhere else, with its table; a struct only
 * C uses does not (tests/test_layout.py holds this header's structs and
 * the package's ctypes mirrors to the same list). Mirrored structs pad
 * explicitly (pad_ fields): cw_layout.h.
 */
#ifndef CW_STRUCTS_H
#define CW_STRUCTS_H

#include <stdbool.h>
#include <stddef.h>

#include "cw_pool.h"
#include "cw_rk.h"

/* -- the master (cw_step.c and the files it calls) ----------------------- */

/* The fmi2-shaped calls the master makes on every instance: fmpy's fmi2
 * functions themselves, or an adapter's (cw_cs3.c, cw_cs1.c, cw_me.c). */
typedef int (*cw_doStep_t)(void *, double, double, int);
typedef int (*cw_getReal_t)(void *, const unsigned *, size_t, double *);
typedef int (*cw_setReal_t)(void *, const unsigned *, size_t, const double *);
typedef int (*cw_setDer_t)(void *, const unsigned *, size_t, const int *, const double *);
typedef int (*cw_getDer_t)(void *, const unsigned *, size_t, const int *, double *);
typedef int (*cw_getState_t)(void *, void **);
typedef int (*cw_setState_t)(void *, void *);

#define HISTORY 3  /* input history kept for divided differences */

typedef struct {
    void *comp;
    cw_doStep_t doStep;
    cw_getReal_t getReal;
    cw_setReal_t setReal;
    cw_setDer_t setInputDerivatives;
    cw_getDer_t getOutputDerivatives;
    cw_getState_t getState;
    cw_setState_t setState;
    void **state;             /* the instance's one saved FMU state (freed by Python) */
    const unsigned *out_vr;   /* connected and recorded outputs, then indicators */
    double *out;              /* a slice of the master's one output buffer */
    const unsigned *in_vr;
    double *inp;
    const unsigned *der_vr;   /* inputs twice: first and second derivatives */
    const int *der_order;
    double *der;
    const int *src_port;      /* per input: the port and output position it comes from */
    const int *src_pos;
    double *sent;             /* inputs last given to the FMU (zero-order hold) */
    const int *dsrc_port;     /* per input: the port offering output derivatives, or -1 */
    const unsigned *dsrc_vr;  /* per input: (vr, vr) of that output */
    const int *dsrc_m;        /* per input: highest derivative order offered (1 or 2) */
    double *hist_t;           /* HISTORY + 1 times of the input history, s */
    double *hist_v;           /* (HISTORY + 1) * n_in source values */
    double *snap_hist_t;      /* the history at the checkpoint */
    double *snap_hist_v;
    const int *scaled;        /* inputs whose link is not the identity: factor * output + offset */
    const double *in_factor;  /* per scaled input */
    const double *in_offset;
    double out_time;          /* when `out` was read, s */
    double lowered_at;        /* when ext_order was last lowered, s */
    int n_out, n_in, n_z;
    int max_output_derivative_order;
    int sent_valid;
    int hist_n, snap_hist_n;
    int n_scaled;
    int ext_order;            /* order of this FMU's input polynomials (lowered where refused) */
    int pad_;
    /* Strong coupling (coupling.iterate_step): the sources' values at the
     * step's start and at the last iterate's end, per input. */
    double *it_start, *it_end;
    int can_interpolate;      /* canInterpolateInputs: the iterate's line is handed over as a slope */
    int rate;                 /* where cw_master.rates is set: it steps every `rate` base steps (cw_rates.c) */
    /* Sums (Port.adds, an OSP Sum): per added term, in order, the input it
     * adds to and its source port and output position. */
    const int *add_at;
    const int *add_port;
    const int *add_pos;
    int n_adds;
    int pad3_;
} cw_port;

/* One algebraic loop solved at communication points (clockwork/engine/loops.py). */
typedef struct {
    const int *members;       /* its ports, in instance order */
    const int *u_port;        /* per unknown (a Real input fed from inside the loop): port and input position */
    const int *u_pos;
    const int *u_src;         /* ... its source port and output position */
    const int *u_src_pos;
    const double *u_factor;   /* ... and its link's transformation, where u_scaled */
    const double *u_offset;
    const int *u_scaled;
    double *r;                /* n: the residual of the sweeps */
    double fail_worst;        /* a failure: the largest residual, where, after what */
    int n_members, n;
    int fail_why, fail_at, fail_sweeps, fail_newton;
} cw_loop;

typedef struct {
    cw_loop *loop;
    double tolerance;         /* master.iteration_tolerance */
    long long iterations, fallbacks;
    int n_loops, pad_;
} cw_loops;

typedef struct {
    cw_port *ports;
    const int *first;          /* feedthrough-only ports, stepped first */
    const int *dynamic;        /* dynamic ports, in step order */
    const int *first_in_order; /* feedthrough-only ports in dependency order */
    const int *final_order;    /* ports updated at t + h, in dependency order */
    double *buffer;            /* every output of every port */
    const int *z_port;         /* per indicator: its port and output position */
    const int *z_pos;
    double *z_start, *z_end;   /* indicators at t+ of the step and at its end */
    const int *zs_port;        /* per indicator: the source port of its single input, or -1 */
    const int *zs_pos;
    const unsigned *zs_vr;
    int *prev_kind;            /* sources at the last sample: 0 none, 1 (u, None), 2 (u, du) */
    double *prev_u, *prev_du;
    double *amp_u, *amp_du;    /* slowly forgotten max |u|, max |du/dt| */
    double *z_seen;            /* NaN = not seen */
    int *end_rate_set;
    double *end_rate;          /* d(source)/dt at the step's end */
    double *snap_z_end;
    double *since;             /* steps taken since the checkpoint, s */
    double t, start_time, step;
    double event_time_tolerance, event_indicator_tolerance, divergence_limit;
    double time_to_zero, step_cap, located_from;
    double snap_t, snap_time_to_zero;
    double err_t, err_h;
    long long steps, events, event_iterations, rollbacks, replays, states_saved;
    int n_ports, n_first, n_dynamic, n_first_in_order, n_final, n_buffer, n_z, cap_since;
    int jacobi, extrapolation, locating, has_sources;
    int after_event, after_event_step, sample_countdown, prev_valid, stale_sources;
    int snap_valid, snap_after_event, n_since;
    int max_replay_steps;      /* a checkpoint after this many steps bounds replay work */
    int diverged;
    int err_port, err_call, err_status;
    int orders_lowered;        /* a port's ext_order was lowered: Python says so */
    /* Instances whose adapter announces time events (they cap the step)
     * and may ask to end the run: Python's n_fmi3 and fmi3, the FMI 3.0
     * adapter's cw_fmi3s. The loop reads them as announcers, through
     * cw_announced_event_time and cw_asked_to_end, never asking a version. */
    union { int n_fmi3; int n_announcers; };
    int pad4_;
    union { struct cw_fmi3 **fmi3; void **announcers; };
    /* Prediction (EventLocator.sample and .plan): per indicator, the
     * sources at the last two sampled step starts, [0, n_z) the newer and
     * [n_z, 2 n_z) the older: kind 0 none, 1 (u, du/dt), 2 (u, du/dt, d2u/dt2). */
    int *pred_kind;
    double *pred_u, *pred_du, *pred_ddu;
    double *last_z;            /* the indicators at the last step's start (t+) */
    double sampled_t, sampled_before_t, last_t;
    long long predicted_landings, mispredicted;
    int predicting, last_valid;
    /* Strong coupling: fixed-point iterations per step (0: off). */
    double iteration_tolerance;
    long long coupling_iterations;
    int iterations, pad3_;
    cw_loops *loops;           /* algebraic loops: an order's entry -(i + 1) is loop i */
    cw_pool *pool;             /* master.threads > 1: instances step at once (cw_pool.c); else NULL */
    const int *par_end;        /* per dynamic position a: the end of the run of instances from a that
                                  depend on none of each other within a step (engine/parallel.py) */
    int *par_status;           /* 2 per port: fmi2DoStep's and fmi2GetReal's status, stepped at once */
    const int *after_start;    /* per dynamic position a: after_order[after_start[a] .. after_start[a + 1]) */
    const int *after_order;    /* ... is the part of first_in_order updated after it steps (parallel.py) */
    struct cw_inputs *inputs;  /* inputs driven from samples, or NULL */
    struct cw_clocks *clocks;  /* FMI 3.0 clocks (cw_clocks.c), or NULL */
    struct cw_rates *rates;    /* components at their own steps (cw_rates.c), or NULL: all at `step` */
} cw_master;

/* FMI 3.0 clocks (cw_clocks.c; engine/clocks.py says what they are):
 * the next tick of each input clock the master ticks, which cuts the step,
 * and what tells the core that a step ended at an event of the clocks,
 * which Python's ClockedMaster then runs (its FMI calls, its records). */
typedef struct cw_clocks {
    double *next;    /* per scheduled input clock, its next tick, s; inf: none */
    int n_next;
    int asked;       /* some Co-Simulation FMU has output clocks: every located state event is one */
    int pending;     /* an FMU signalled an event (an output clock) in the step now taken */
    int due;         /* the step just taken ended at an event of the clocks (set by the core) */
} cw_clocks;

/* Components at their own steps (engine/multirate.py, cw_rates.c): port i
 * takes a step of rate * step every `rate` base steps, from its own grid.
 * An input whose source steps at another rate reads a held copy of the
 * source's outputs: a port past n_ports that never steps (only its `out`
 * is used), filled at the points both ends share. */
typedef struct cw_rates {
    const int *held_port, *held_pos;  /* per link across rates: the held copy's port and output position */
    const int *src_port, *src_pos;    /* ... the source it copies */
    const long long *every;           /* ... which passes every lcm(k_source, k_target) base steps */
    double *starts;                   /* per port: where its own step under way started, s */
    long long count;                  /* base steps taken since the start */
    int n_links, pad_;
} cw_rates;

/* Inputs driven from samples (engine/samples.py): the sample table, its
 * input events, and per port the Real inputs it drives. */
typedef struct cw_inputs {
    const double *times;      /* n_times sample times, s, non-decreasing */
    const double *values;     /* n_signals * n_times values, signal after signal */
    const int *continuous;    /* per signal: interpolated (1) or held (0) */
    const double *events;     /* n_events input events, s, sorted */
    const int *port_start;    /* per port, its first target; n_ports + 1 entries */
    const unsigned *vr;       /* per target: the input's value reference */
    const int *signal;        /* per target: its signal */
    double *value;            /* per target: the value set */
    const int *after_step;    /* per port: 1 where its inputs are set again after its step (at t + h,
                                 before its outputs are read): only where outputs may follow inputs */
    int n_times, n_signals, n_events, pad_;
} cw_inputs;

typedef struct {
    const int *col_port;  /* per recorded column: port and output position */
    const int *col_pos;
    double *rows;         /* capacity rows of (time, columns...) */
    double *ticks;
    double last_tick;
    long long grid_seen;  /* grid points seen (the stride counts them) */
    long long grid_k;     /* run_until's next grid index; -1: compute it */
    int n_cols, capacity, n_rows, tick_capacity, n_ticks, stride, tick_port, tick_pos;
    int has_interval, pad_;
} cw_recorder;

/* A run to marks (Master.run_marks, clockwork/engine/marks.py): the plan
 * and its place, kept across calls. A row is (t, the n_out outputs, the
 * n_prev outputs before the last step). */
typedef struct {
    double *times;                   /* n_times marks, s (follow rewrites times[0]) */
    const int *sets;                 /* per mark: give the inputs values[k] */
    const double *values;
    const int *in_port;              /* n_in unconnected inputs: port, value reference */
    const unsigned *in_vr;
    const int *out_port, *out_pos;   /* n_out: a row's values at its point */
    const int *prev_port, *prev_pos; /* n_prev: a row's values before the last step */
    double *previous;                /* their values before the last step */
    const int *watch_port, *watch_pos;
    double *seen;                    /* the n_watch watched values at the last row */
    double *rows;                    /* capacity rows */
    double margin;                   /* the step once no mark lies ahead, s; <= 0: none */
    double max_step, tolerance;      /* s; tolerance < 0: 1e-12 max(1, |t_stop|) */
    double period, last_event, prev_event;  /* follow: the event times */
    int n_times, next, n_in, n_out, n_prev, n_watch, capacity, n_rows;
    int follow;                      /* the watched output whose events move the mark, or -1 */
    int has_prev, record, stop_at_change;
    int stopped;                     /* set where the run stopped at a change */
    int pad_;
} cw_marks;

/* -- the FMI 3.0 adapter (cw_cs3.c) -------------------------------------- */

typedef int (*fmi3DoStep_t)(void *, double, double, bool, bool *, bool *, bool *, double *);
typedef int (*fmi3GetFloat64_t)(void *, const unsigned *, size_t, double *, size_t);
typedef int (*fmi3SetFloat64_t)(void *, const unsigned *, size_t, const double *, size_t);
typedef int (*fmi3GetOutputDerivatives_t)(void *, const unsigned *, size_t, const int *, double *, size_t);
typedef int (*fmi3GetFMUState_t)(void *, void **);
typedef int (*fmi3SetFMUState_t)(void *, void *);
typedef int (*fmi3ModeChange_t)(void *);
typedef int (*fmi3UpdateDiscreteStates_t)(void *, bool *, bool *, bool *, bool *, bool *, double *);

typedef struct cw_fmi3 {
    void *instance;
    fmi3DoStep_t doStep;
    fmi3GetFloat64_t getFloat64;
    fmi3SetFloat64_t setFloat64;
    fmi3GetOutputDerivatives_t getOutputDerivatives;
    fmi3GetFMUState_t getState;
    fmi3SetFMUState_t setState;
    fmi3ModeChange_t enterEventMode;
    fmi3UpdateDiscreteStates_t updateDiscreteStates;
    fmi3ModeChange_t enterStepMode;
    double next_event_time;       /* s; INFINITY when none is announced */
    double saved_next_event_time; /* with the saved FMU state */
    double end_time;              /* where terminateSimulation stopped the FMU, s */
    long long early_returns, events;
    int event_mode_used, terminated;
    int failed_call;              /* 0, or which call failed (fmu3.FAILED_CALLS) */
    int pad_;
    /* Intermediate update: the input polynomials FMI 2.0 would hand over
     * with fmi2SetRealInputDerivatives, kept here as an FMI 2.0 FMU keeps
     * them (u0 + d1 dt + d2 dt^2/2, dt from iu_tref: the FMU's time when
     * the value was set) and set by cw3_intermediateUpdate at the times
     * the FMU asks for. */
    int n_iu;                     /* inputs with intermediateUpdate = true */
    int iu_poly;                  /* some derivative is not 0 */
    const unsigned *iu_vr;
    double *iu_u0, *iu_d1, *iu_d2, *iu_tref;
    int *iu_fed;                  /* set by the master at least once */
    unsigned *iu_set_vr;          /* scratch for the callback's fmi3SetFloat64 */
    double *iu_val;
    double iu_time;               /* the FMU's time: start, then the end of each step, s */
    double iu_saved_time;
    long long iu_calls;           /* callbacks that set inputs */
    double *iu_saved;             /* u0, d1, d2, tref (4 n_iu) with the saved FMU state, */
    int *iu_saved_fed;            /* as FMI 2.0 saves its polynomials in its state */
    /* Array elements (fmu3.Instance3._number_elements): the code
     * code_base + k names value code_off[k] of the code_size[k] values of
     * the array variable code_vr[k]. A request whose codes cover whole
     * arrays in order is one fmi3 call with nValues > nValueReferences;
     * any other is served element by element. */
    unsigned code_base;
    int n_codes;
    const unsigned *code_vr;
    const int *code_off, *code_size;
    unsigned *scratch_vr;         /* the value references of one call, translated */
    int *scratch_order;           /* and their derivative orders */
    double *scratch_val;          /* one array's values */
    int scratch_cap, scratch_val_cap;
    /* With clocks: the master's handler of an event the FMU signals in its
     * step (engine/clocks.py), called with the time reached instead of
     * settling here; NULL without clocks. */
    int (*clock_event)(double);
} cw_fmi3;

/* The loop's questions to an announcer (cw_master.announcers): the FMI
 * 3.0 adapter answers them from its struct. */
static inline double cw_announced_event_time(const void *a) { return ((const cw_fmi3 *)a)->next_event_time; }
static inline int cw_asked_to_end(const void *a) { return ((const cw_fmi3 *)a)->terminated; }

/* -- the FMI 1.0 adapter (cw_cs1.c) -------------------------------------- */

typedef char fmi1_boolean;
typedef int (*fmi1DoStep_t)(void *, double, double, fmi1_boolean);

typedef struct cw_fmi1 {
    void *instance;
    fmi1DoStep_t doStep;
    cw_getReal_t getReal;
    cw_setReal_t setReal;
    cw_setDer_t setInputDerivatives;
    cw_getDer_t getOutputDerivatives;
    const unsigned *negated_vr; /* the master's value references of negated aliases */
    const unsigned *base_vr;    /* the FMU's, whose value they negate */
    double time;                /* the FMU's communication point, s */
    long long zero_steps;       /* steps of size 0 taken to compute outputs */
    int n_negated;
    int stale;                  /* inputs set since fmiDoStep last computed the outputs */
    int failed_zero;            /* the last zero step failed (fmu1.Instance1.fail says so) */
    int pad_;
} cw_fmi1;

/* -- the Model Exchange wrapper (cw_me.c) -------------------------------- */

typedef int (*cv_rhs_t)(double, void *, void *, void *);

/* fmpy's SUNDIALS functions (cvode.py's _SIGNATURES, in that order). */
typedef struct {
    int (*SUNContext_Create)(int, void **);
    int (*SUNContext_Free)(void **);
    int (*SUNContext_ClearErrHandlers)(void *);
    double *(*N_VGetArrayPointer)(void *);
    void (*N_VDestroy)(void *);
    void (*SUNMatDestroy)(void *);
    int (*SUNLinSolFree)(void *);
    void *(*N_VNew_Serial)(long long, void *);
    void *(*SUNDenseMatrix)(long long, long long, void *);
    void *(*SUNLinSol_Dense)(void *, void *, void *);
    void *(*CVodeCreate)(int, void *);
    int (*CVodeInit)(void *, cv_rhs_t, double, void *);
    int (*CVodeReInit)(void *, double, void *);
    int (*CVodeSVtolerances)(void *, double, void *);
    int (*CVodeSetLinearSolver)(void *, void *, void *);
    int (*CVodeSetUserData)(void *, void *);
    int (*CVodeSetStopTime)(void *, double);
    int (*CVode)(void *, double, void *, double *, int);
    int (*CVodeGetDky)(void *, double, int, void *);
    int (*CVodeGetNumRhsEvals)(void *, long *);
    int (*CVodeGetNumLinRhsEvals)(void *, long *);
    int (*CVodeGetNumErrTestFails)(void *, long *);
    int (*CVodeGetNumNonlinSolvConvFails)(void *, long *);
    void (*CVodeFree)(void **);
} cw_sundials;

/* The wrapper's state (model_exchange._ME, same layout). */
typedef struct {
    void *instance;
    /* the FMU's functions, and how to call those whose shape differs by
     * version (cw_me.c's cw_me_calls: the table its face names) */
    void *setTime, *setStates, *getDerivatives, *getIndicators, *getStates, *getNominals, *completedStep,
        *enterEventMode, *update, *enterContinuousMode, *getReal, *setReal, *getState, *setState;
    const void *calls;
    const cw_sundials *sundials;
    cw_rk *rk;
    double *x, *xbuf, *xw, *xd, *dx, *nominal, *atolv;  /* states, scratch, nominals, tolerances */
    double *z_prev, *z, *z_end, *z_lo, *z0;            /* indicators: last accepted, scratch */
    const unsigned *in_vr;
    double *u0, *d1, *d2, *tref, *in_val;              /* continuous inputs' polynomials */
    const unsigned *state_vr;
    const int *der_state;
    double *saved;                                     /* x, z_prev, (u0, d1, d2, tref) per input */
    void *cv_mem, *cv_ctx, *cv_y, *cv_abstol, *cv_dky, *cv_A, *cv_LS;
    double time, next_event_time, end_time, rtol, event_time_tolerance, h_next, err_t;
    double saved_time, saved_next_event_time, saved_end_time, saved_h_next;
    long long steps, rejected, rhs, state_events, time_events, step_events, input_events, event_iterations,
        switches;
    int n, nz, n_in, solver, method, stiff_count, nonstiff_count, terminated, mode, poly,
        inputs_dirty, restart, cv_owner, failed_call, failed_status, failed_detail, needs_completed,
        saved_method, saved_stiff_count, saved_nonstiff_count, saved_terminated, saved_poly, saved_mode,
        pad4_;  /* explicit: every byte is a field */
} cw_me;

/* -- the Model Exchange group (cw_me_group.c) ---------------------------- */

/* Connected Model Exchange FMUs as one (engine/me_group.py's _Group, same
 * layout): the group's own cw_me integrates the members' concatenated
 * states through the group's calls (cwmg_bind), which call each member
 * through its cw_me (its FMU's functions, calls table and scratch). */
typedef struct {
    cw_me *me;                  /* the group's wrapper (set by cwmg_bind) */
    void *members;              /* cw_me *[n_members], in member order */
    void *member_state;         /* void **[n_members]: where each member's FMU state is saved */
    const int *offsets;         /* per member: state offset, states, indicator offset, indicators */
    const int *vr_member;       /* per group value reference: its member */
    const unsigned *vr_own;     /* ... and the member's value reference */
    const int *c_src, *c_dst;   /* per connection, in dependency order: source and target member */
    const unsigned *c_src_vr, *c_dst_vr;
    const int *c_continuous;    /* into a continuous input: evaluated in continuous-time mode too */
    const int *c_identity;      /* else factor * value + offset */
    const double *c_factor, *c_offset;
    double *c_last;             /* the value last set */
    int *c_has_last;            /* 0: none since setup or a restored state */
    /* Integer and Boolean connections: the source's get and the target's
     * set of the value's type (void *[n_conns], NULL for Real) and the
     * shape of each call's value (CW_VALUE_* below). */
    void *c_get, *c_set;
    const int *c_get_shape, *c_set_shape;
    long long *c_last_int;      /* the discrete value last set (the source's) */
    int n_members, n_conns;
    int dirty;                  /* time, states or values set since the connections were evaluated */
    int pad_;
} cw_me_group;

/* A discrete value's shape in its FMU's get or set: its size in bytes
 * (1, 4 or 8), plus CW_VALUE_COUNTED where the call takes the number of
 * values after them, plus CW_VALUE_BOOLEAN for a Boolean (non-zero: true). */
enum { CW_VALUE_SIZE = 15, CW_VALUE_COUNTED = 16, CW_VALUE_BOOLEAN = 32 };

#endif
