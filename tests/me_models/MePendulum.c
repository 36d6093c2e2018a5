/* The clock's pendulum in vacuum (see MePendulum.toml). */
#include "me_model.h"

#define MODEL_GUID "{cw-me-pendulum-1}"
#define N_STATES 2
#define N_INDICATORS 2
#define N_INPUTS 1
#define N_TUNABLE 0
enum { VR_phi = 1, VR_w, VR_a, VR_tau, VR_L, VR_m, VR_g, VR_Q, VR_phi_start, VR_w_start, VR_tick_time,
       VR_tick_count, VR_tick_w, VR_amplitude,
       I_SIDE = 20, I_WSIDE /* internal: the signs of phi and w at the last event */ };
static const unsigned STATE_VR[N_STATES] = {VR_phi, VR_w};
static const unsigned DER_VR[N_STATES] = {VR_w, VR_a};
static const unsigned INPUT_VR[N_INPUTS] = {VR_tau};
static const unsigned TUNABLE_VR[1] = {0};

static void model_start(me_instance *m) {
    m->r[VR_L] = 1.0;
    m->r[VR_m] = 1.0;
    m->r[VR_g] = 9.81;
    m->r[VR_Q] = 1000.0;
    m->r[VR_phi_start] = 0.17453292519943295;
    m->r[VR_w_start] = 0.0;
}

static void model_init(me_instance *m) {
    m->r[VR_phi] = m->r[VR_phi_start];
    m->r[VR_w] = m->r[VR_w_start];
    m->r[VR_tick_time] = 0.0;
    m->i[VR_tick_count] = 0;
    m->r[VR_tick_w] = 0.0;
    m->r[VR_amplitude] = 0.0;
    m->i[I_SIDE] = m->r[VR_phi] < 0.0 ? -1 : 1;
    m->i[I_WSIDE] = m->r[VR_w] < 0.0 ? -1 : 1;
}

static void model_update(me_instance *m) {
    const double L = m->r[VR_L], g = m->r[VR_g], Q = m->r[VR_Q];
    const double damping = Q > 0 ? sqrt(g / L) / Q : 0.0;
    m->r[VR_a] = -(g / L) * sin(m->r[VR_phi]) - damping * m->r[VR_w] + m->r[VR_tau] / (m->r[VR_m] * L * L);
}

static void model_indicators(const me_instance *m, double *z) {
    z[0] = m->r[VR_phi];
    z[1] = m->r[VR_w];
}

/* A tick: phi crossed zero upwards since the last event; a turning point:
 * w changed sign (the importer stops just past the crossing). */
static int model_event(me_instance *m) {
    const double phi = m->r[VR_phi], w = m->r[VR_w];
    const int side = (phi < 0.0 || (phi == 0.0 && w < 0.0)) ? -1 : 1;
    const int wside = (w < 0.0 || (w == 0.0 && phi > 0.0)) ? -1 : 1;
    if (side > 0 && m->i[I_SIDE] < 0) {
        m->i[VR_tick_count] += 1;
        m->r[VR_tick_time] = m->time;
        m->r[VR_tick_w] = w;
    }
    if (wside != m->i[I_WSIDE]) m->r[VR_amplitude] = fabs(phi);
    m->i[I_SIDE] = side;
    m->i[I_WSIDE] = wside;
    return 0;
}

static int model_step_event(me_instance *m) { (void)m; return 0; }
