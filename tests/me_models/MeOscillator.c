/* A damped linear oscillator (see MeOscillator.toml). */
#include "me_model.h"

#define MODEL_GUID "{cw-me-oscillator-1}"
#define N_STATES 2
#define N_INDICATORS 0
#define N_INPUTS 0
#define N_TUNABLE 0
enum { VR_x = 1, VR_v, VR_a, VR_omega, VR_zeta, VR_x0, VR_v0 };
static const unsigned STATE_VR[N_STATES] = {VR_x, VR_v};
static const unsigned DER_VR[N_STATES] = {VR_v, VR_a};
static const unsigned INPUT_VR[1] = {0};
static const unsigned TUNABLE_VR[1] = {0};

static void model_start(me_instance *m) {
    m->r[VR_omega] = 6.283185307179586;
    m->r[VR_zeta] = 0.05;
    m->r[VR_x0] = 1.0;
    m->r[VR_v0] = 0.0;
}

static void model_init(me_instance *m) {
    m->r[VR_x] = m->r[VR_x0];
    m->r[VR_v] = m->r[VR_v0];
}

static void model_update(me_instance *m) {
    const double w = m->r[VR_omega];
    m->r[VR_a] = -w * w * m->r[VR_x] - 2.0 * m->r[VR_zeta] * w * m->r[VR_v];
}

static void model_indicators(const me_instance *m, double *z) { (void)m; (void)z; }
static int model_event(me_instance *m) { (void)m; return 0; }
static int model_step_event(me_instance *m) { (void)m; return 0; }
