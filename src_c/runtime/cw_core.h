/* The runtime's core as its two faces see it (cw_fmi2.c, cw_fmi3.c): one
 * implementation of every check, state transition, value access and FMU
 * state operation, named by the calling face's function in its messages
 * (`fn`). Not for models: they see cw_runtime.h. */
#ifndef CW_CORE_H
#define CW_CORE_H

#include <stdbool.h>

#include "cw_runtime.h"

#define CW_ANY_OPEN_STATE                                                   \
    (CW_INSTANTIATED | CW_INIT_MODE | CW_STEP_COMPLETE | CW_STEP_FAILED |   \
     CW_TERMINATED | CW_ERROR | CW_EVENT_MODE)

/* The message as text an FMI 1.0/2.0 logger can take as its printf format:
 * copied into buf (truncated to size - 1 bytes) with every '%' a blank. */
void cw_core_plain_text(char *buf, size_t size, const char *message);

/* Log through the face and put the instance into Error. */
fmi2Status cw_core_fail(cw_instance *inst, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(CW_PRINTF_FORMAT, 2, 3)))
#endif
    ;

/* Whether `fn` may be called in the instance's state (one of `mask`); if
 * not, say so and leave the state alone. */
int cw_core_allowed(cw_instance *inst, const char *fn, int mask);

/* A new instance in state Instantiated with the start values, or NULL after
 * logging why through `proto` (whose emit, env and memory functions are
 * used for the new instance). */
cw_instance *cw_core_instantiate(const cw_instance *proto, const char *fn,
                                 const char *instance_name, const char *token,
                                 const char *token_name);
void cw_core_free_instance(cw_instance *inst);

fmi2Status cw_core_set_debug_logging(cw_instance *inst, const char *fn,
                                     int logging_on, size_t n,
                                     const char *const categories[]);
fmi2Status cw_core_setup(cw_instance *inst, const char *fn, double start_time,
                         int stop_time_defined, double stop_time);
fmi2Status cw_core_enter_initialization(cw_instance *inst, const char *fn);
/* Validate, initialize and go to `next` (Step Mode or Event Mode). */
fmi2Status cw_core_exit_initialization(cw_instance *inst, const char *fn,
                                       cw_machine_state next);
fmi2Status cw_core_terminate(cw_instance *inst, const char *fn);
fmi2Status cw_core_reset(cw_instance *inst, const char *fn);
/* Commit the discrete modes decided from the current inputs (Event Mode). */
void cw_core_commit(cw_instance *inst);

/* Values. Integer and Boolean values are int32_t, or bool with as_bool. */
fmi2Status cw_core_get_real(cw_instance *inst, const char *fn,
                            const unsigned vr[], size_t nvr, double value[]);
fmi2Status cw_core_get_int(cw_instance *inst, const char *fn, cw_type type,
                           const unsigned vr[], size_t nvr, void *value,
                           int as_bool);
fmi2Status cw_core_set_real(cw_instance *inst, const char *fn,
                            const unsigned vr[], size_t nvr,
                            const double value[]);
fmi2Status cw_core_set_int(cw_instance *inst, const char *fn, cw_type type,
                           const unsigned vr[], size_t nvr, const void *value,
                           int as_bool);
/* String values (FMI 2.0): the instance's own copies are handed out, valid
 * until the variable next changes; a set copies every value. */
fmi2Status cw_core_get_string(cw_instance *inst, const char *fn,
                              const unsigned vr[], size_t nvr,
                              const char *value[]);
fmi2Status cw_core_set_string(cw_instance *inst, const char *fn,
                              const unsigned vr[], size_t nvr,
                              const char *const value[]);
/* A type the models have no variables of: refused unless nvr == 0. */
fmi2Status cw_core_no_such_type(cw_instance *inst, const char *fn,
                                const char *type, const unsigned vr[],
                                size_t nvr, int setter);

/* FMU states (opaque blobs of the serialized layout). */
fmi2Status cw_core_get_state(cw_instance *inst, const char *fn, void **state);
fmi2Status cw_core_set_state(cw_instance *inst, const char *fn, void *state);
fmi2Status cw_core_free_state(cw_instance *inst, const char *fn, void **state);
fmi2Status cw_core_state_size(cw_instance *inst, const char *fn, void *state,
                              size_t *size);
fmi2Status cw_core_serialize(cw_instance *inst, const char *fn, void *state,
                             unsigned char *buf, size_t size);
fmi2Status cw_core_deserialize(cw_instance *inst, const char *fn,
                               const unsigned char *buf, size_t size,
                               void **state);

fmi2Status cw_core_set_input_derivatives(cw_instance *inst, const char *fn,
                                         const unsigned vr[], size_t nvr,
                                         const int32_t order[],
                                         const double value[]);
fmi2Status cw_core_get_output_derivatives(cw_instance *inst, const char *fn,
                                          const unsigned vr[], size_t nvr,
                                          const int32_t order[],
                                          double value[]);

/* One communication step from tc by h. Ends at inst->time: tc + h, or the
 * time of the model's own event when the model returned early
 * (inst->returned_early). */
fmi2Status cw_core_do_step(cw_instance *inst, const char *fn, double tc,
                           double h);

/* A function the FMU does not provide: fmi2Error with a message. */
fmi2Status cw_core_unsupported(cw_instance *inst, const char *fn,
                               const char *why);

#endif
