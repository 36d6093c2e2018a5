/* A ball that bounces when its Boolean input says so (see MeLogicBall.toml). */
#include "me_model.h"

#define MODEL_GUID "{cw-me-logicball-1}"
#define N_STATES 2
#define N_INDICATORS 0
#define N_INPUTS 0
#define N_TUNABLE 1
enum { VR_h = 1, VR_v, VR_der_h, VR_der_v, VR_g, VR_e, VR_h0, VR_bounces, VR_t_bounce, VR_hit };
static const unsigned STATE_VR[N_STATES] = {VR_h, VR_v};
static const unsigned DER_VR[N_STATES] = {VR_der_h, VR_der_v};
static const unsigned INPUT_VR[1] = {0};
static const unsigned TUNABLE_VR[N_TUNABLE] = {VR_hit};

static void model_start(me_instance *m) {
    m->r[VR_g] = 9.81;
    m->r[VR_e] = 0.8;
    m->r[VR_h0] = 1.0;
    m->i[VR_hit] = 0;
}

static void model_init(me_instance *m) {
    m->r[VR_h] = m->r[VR_h0];
    m->r[VR_v] = 0.0;
    m->i[VR_bounces] = 0;
    m->r[VR_t_bounce] = 0.0;
}

static void model_update(me_instance *m) {
    m->r[VR_der_h] = m->r[VR_v];
    m->r[VR_der_v] = -m->r[VR_g];
}

static void model_indicators(const me_instance *m, double *z) { (void)m; (void)z; }

static int model_event(me_instance *m) {
    if (m->i[VR_hit] && m->r[VR_v] < 0.0) {
        m->r[VR_v] = -m->r[VR_e] * m->r[VR_v];
        m->i[VR_bounces] += 1;
        m->r[VR_t_bounce] = m->time;
        m->values_changed = 1;
    }
    return 0;
}

static int model_step_event(me_instance *m) { (void)m; return 0; }
