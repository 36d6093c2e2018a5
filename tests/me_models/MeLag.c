/* A first-order lag with an input (see MeLag.toml). */
#include "me_model.h"

#define MODEL_GUID "{cw-me-lag-1}"
#define N_STATES 1
#define N_INDICATORS 0
#define N_INPUTS 1
#define N_TUNABLE 1
enum { VR_u = 1, VR_y, VR_e, VR_der_y, VR_k, VR_T, VR_y0 };
static const unsigned STATE_VR[N_STATES] = {VR_y};
static const unsigned DER_VR[N_STATES] = {VR_der_y};
static const unsigned INPUT_VR[N_INPUTS] = {VR_u};
static const unsigned TUNABLE_VR[N_TUNABLE] = {VR_k};

static void model_start(me_instance *m) {
    m->r[VR_k] = 1.0;
    m->r[VR_T] = 0.5;
    m->r[VR_y0] = 0.0;
}

static void model_init(me_instance *m) { m->r[VR_y] = m->r[VR_y0]; }

static void model_update(me_instance *m) {
    m->r[VR_e] = m->r[VR_k] * m->r[VR_u] - m->r[VR_y];
    m->r[VR_der_y] = m->r[VR_e] / m->r[VR_T];
}

static void model_indicators(const me_instance *m, double *z) { (void)m; (void)z; }
static int model_event(me_instance *m) { (void)m; return 0; }
static int model_step_event(me_instance *m) { (void)m; return 0; }
