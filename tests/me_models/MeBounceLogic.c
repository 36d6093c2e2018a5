/* The bounce logic of MeLogicBall (see MeBounceLogic.toml). */
#include "me_model.h"

#define MODEL_GUID "{cw-me-bouncelogic-1}"
#define N_STATES 0
#define N_INDICATORS 2
#define N_INPUTS 2
#define N_TUNABLE 0
enum { VR_h = 1, VR_v, VR_hit };
static const unsigned STATE_VR[1] = {0};
static const unsigned DER_VR[1] = {0};
static const unsigned INPUT_VR[N_INPUTS] = {VR_h, VR_v};
static const unsigned TUNABLE_VR[1] = {0};

static void model_start(me_instance *m) {
    m->r[VR_h] = 1.0;
    m->r[VR_v] = 0.0;
}

static void model_init(me_instance *m) { m->i[VR_hit] = 0; }

static void model_update(me_instance *m) { (void)m; }

static void model_indicators(const me_instance *m, double *z) {
    z[0] = m->r[VR_h];
    z[1] = m->r[VR_v];
}

static int model_event(me_instance *m) {
    m->i[VR_hit] = m->r[VR_h] <= 0.0 && m->r[VR_v] < 0.0;
    return 0;
}

static int model_step_event(me_instance *m) { (void)m; return 0; }
