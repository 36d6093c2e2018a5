/* The Prothero-Robinson stiff problem (see MeStiff.toml). */
#include "me_model.h"

#define MODEL_GUID "{cw-me-stiff-1}"
#define N_STATES 1
#define N_INDICATORS 0
#define N_INPUTS 0
#define N_TUNABLE 0
enum { VR_y = 1, VR_der_y, VR_lambda, VR_y0 };
static const unsigned STATE_VR[N_STATES] = {VR_y};
static const unsigned DER_VR[N_STATES] = {VR_der_y};
static const unsigned INPUT_VR[1] = {0};
static const unsigned TUNABLE_VR[1] = {0};

static void model_start(me_instance *m) {
    m->r[VR_lambda] = 1e5;
    m->r[VR_y0] = 2.0;
}

static void model_init(me_instance *m) { m->r[VR_y] = m->r[VR_y0]; }

static void model_update(me_instance *m) {
    const double t = m->time;
    m->r[VR_der_y] = -m->r[VR_lambda] * (m->r[VR_y] - cos(t)) - sin(t);
}

static void model_indicators(const me_instance *m, double *z) { (void)m; (void)z; }
static int model_event(me_instance *m) { (void)m; return 0; }
static int model_step_event(me_instance *m) { (void)m; return 0; }
