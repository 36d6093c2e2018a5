/* The Model Exchange test FMUs: an instance and its modes. A model's file
 * (ME_MODEL) includes this header; each face (me_fmi2.c, me_fmi3.c)
 * includes the model's file, then me_core.h, the checks both faces share.
 *
 * Variables live in r[] (Real / Float64) and i[] (Integer / Int32 and
 * Boolean), both indexed by value reference (0 is FMI 3.0's time). A model
 * file defines:
 *   MODEL_GUID, N_STATES, N_INDICATORS, STATE_VR[], DER_VR[] (states and
 *   their derivatives, in ModelStructure order), N_INPUTS and INPUT_VR[]
 *   (continuous Real inputs, settable in any mode), N_TUNABLE and
 *   TUNABLE_VR[] (values that may be set in event mode), and
 *   model_start(m)      start values, at instantiation and reset;
 *   model_init(m)       the states from the parameters, when initialization ends;
 *   model_update(m)     derivatives and outputs from time, states and inputs;
 *   model_indicators(m, z) the event indicators (after model_update);
 *   model_event(m)      one event-mode update: the discrete states, with
 *                       m->values_changed when a state jumps; may set
 *                       m->terminate and m->next_event_*; returns nonzero
 *                       when another update is needed;
 *   model_step_event(m) after an integrator step: nonzero asks for event mode.
 * The faces check the calling sequence strictly (a call in the wrong mode
 * returns Error and logs why): these FMUs test an importer.
 */
#ifndef ME_MODEL_H
#define ME_MODEL_H

#include <math.h>
#include <stddef.h>

#define ME_MAX_VR 32

typedef enum { M_INSTANTIATED, M_INIT, M_EVENT, M_CONTINUOUS, M_TERMINATED } me_mode;

typedef struct {
    double time;
    double r[ME_MAX_VR];
    int i[ME_MAX_VR];
    me_mode mode;
    int terminate;         /* terminateSimulation, asked by the model */
    int next_event_defined;
    double next_event_time;
    int values_changed;    /* in event mode: a continuous state jumped */
    int updates;           /* update calls in this event */
} me_instance;

#endif
