/* What both faces share (included after the model's file). */
#ifndef ME_CORE_H
#define ME_CORE_H

#define B(x) (1u << (x))
#define ANY_RUNNING (B(M_INIT) | B(M_EVENT) | B(M_CONTINUOUS) | B(M_TERMINATED))

/* Whether a call is allowed in the instance's mode (mask: bits of me_mode). */
static int me_allowed(const me_instance *m, unsigned mask) { return (B(m->mode) & mask) != 0; }

/* At instantiation and reset. */
static void me_start(me_instance *m) {
    for (int k = 0; k < ME_MAX_VR; k++) {
        m->r[k] = 0.0;
        m->i[k] = 0;
    }
    m->time = 0.0;
    m->mode = M_INSTANTIATED;
    m->terminate = m->next_event_defined = m->values_changed = m->updates = 0;
    m->next_event_time = 0.0;
    model_start(m);
}

/* Whether value reference vr may be set now. */
static int me_settable(const me_instance *m, unsigned vr) {
    if (vr >= ME_MAX_VR) return 0;
    if (m->mode == M_INSTANTIATED || m->mode == M_INIT) return 1;
    for (int k = 0; k < N_INPUTS; k++)
        if (INPUT_VR[k] == vr) return m->mode != M_TERMINATED;
    if (m->mode != M_EVENT) return 0;
    for (int k = 0; k < N_TUNABLE; k++)
        if (TUNABLE_VR[k] == vr) return 1;
    return 0;
}

static void me_exit_init(me_instance *m) {
    model_init(m);
    m->mode = M_EVENT;
    m->updates = 0;
}

/* One event-mode update; returns whether another is needed. */
static int me_update(me_instance *m) {
    m->values_changed = 0;
    m->next_event_defined = 0;
    int again = model_event(m);
    m->updates++;
    return again;
}

static void me_set_states(me_instance *m, const double *x) {
    for (int k = 0; k < N_STATES; k++) m->r[STATE_VR[k]] = x[k];
}

static void me_get_states(const me_instance *m, double *x) {
    for (int k = 0; k < N_STATES; k++) x[k] = m->r[STATE_VR[k]];
}

/* What the getters see: in initialization mode the states follow the
 * parameters as they stand (the initial unknowns). */
static void me_refresh(me_instance *m) {
    if (m->mode == M_INIT) model_init(m);
    model_update(m);
}

static void me_derivatives(me_instance *m, double *dx) {
    me_refresh(m);
    for (int k = 0; k < N_STATES; k++) dx[k] = m->r[DER_VR[k]];
}

#endif
