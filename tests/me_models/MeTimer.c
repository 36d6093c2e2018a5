/* Time events and step events (see MeTimer.toml). */
#include "me_model.h"

#define MODEL_GUID "{cw-me-timer-1}"
#define N_STATES 2
#define N_INDICATORS 0
#define N_INPUTS 0
#define N_TUNABLE 0
enum { VR_x = 1, VR_phase, VR_der_x, VR_der_phase, VR_tau, VR_A, VR_period, VR_omega, VR_level, VR_switches,
       VR_turns };
static const unsigned STATE_VR[N_STATES] = {VR_x, VR_phase};
static const unsigned DER_VR[N_STATES] = {VR_der_x, VR_der_phase};
static const unsigned INPUT_VR[1] = {0};
static const unsigned TUNABLE_VR[1] = {0};
static const double PI = 3.14159265358979323846;

static void model_start(me_instance *m) {
    m->r[VR_tau] = 0.3;
    m->r[VR_A] = 1.0;
    m->r[VR_period] = 0.7;
    m->r[VR_omega] = 5.0;
}

static void model_init(me_instance *m) {
    m->r[VR_x] = 0.0;
    m->r[VR_phase] = 0.0;
    m->r[VR_level] = 0.0;
    m->i[VR_switches] = 0;
    m->i[VR_turns] = 0;
}

static void model_update(me_instance *m) {
    m->r[VR_der_x] = (m->r[VR_level] - m->r[VR_x]) / m->r[VR_tau];
    m->r[VR_der_phase] = m->r[VR_omega];
}

static void model_indicators(const me_instance *m, double *z) { (void)m; (void)z; }

/* The level switches at k * period (k >= 1); the angle wraps after a step
 * that left it above pi. */
static int model_event(me_instance *m) {
    const double period = m->r[VR_period];
    const double next = (m->i[VR_switches] + 1) * period;
    if (m->time >= next) {
        m->i[VR_switches] += 1;
        m->r[VR_level] = (m->i[VR_switches] % 2) ? m->r[VR_A] : 0.0;
    }
    if (m->r[VR_phase] > PI) {
        m->r[VR_phase] -= 2.0 * PI;
        m->i[VR_turns] += 1;
        m->values_changed = 1;
    }
    m->next_event_defined = 1;
    m->next_event_time = (m->i[VR_switches] + 1) * period;
    return 0;
}

static int model_step_event(me_instance *m) { return m->r[VR_phase] > PI; }
