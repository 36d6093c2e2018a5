/* Pendulum: Ziemkiewicz Eq. (A2) with a sum of torque inputs, in air.
 *   phi' = w
 *   w'   = -(g g_factor / L_T) (m - m_b) / (m + m_a) sin(phi)
 *          - (omega0 / Q) w + tau / ((m + m_a) L_T^2)
 * with the buoyant mass m_b = rho V and the added mass of the entrained air
 * m_a = rho V k + V c_bl sqrt(2 mu rho / omega0) / R (Nelson and Olsson
 * 1986; Stokes 1851), V = m / rho_bob, and the length L_T = L (1 + alpha
 * (T - T_ref)). With rho_air = 0 and alpha = 0 (the defaults) every factor
 * is exactly 1 and the equation is Eq. (A2) bit for bit.
 * Ticks (upward zero crossings) and turning points are located on the
 * dense output of each accepted step, then the tick time is polished with
 * a full step of the same Runge-Kutta pair, so that period measurements do
 * not depend on the communication step. Both are the model's own events:
 * with early return (FMI 3.0) the step ends at the first of them. */
#include <math.h>

#include "cw_rk.h"
#include "cw_runtime.h"
#include "cw_vars.h"

static double damping_rate(const cw_instance *inst) {
    return R(Q) > 0 ? sqrt(R(g) / R(L)) / R(Q) : 0.0;
}

static double torque(const cw_instance *inst, double t) {
    return IN(tau_escapement, t) + IN(tau_drag, t) + IN(tau_coupling, t) +
           IN(tau_external, t);
}

/* The pendulum's factors at time t: the length at the rod's temperature,
 * the mass that gravity pulls (bob minus buoyancy) and the mass that moves
 * (bob plus entrained air). Inputs outside their ranges (an extrapolation
 * may leave them) are clamped to the physical ones. */
typedef struct {
    double length, inertial_mass;
    double weight_ratio; /* (m - m_b) / (m + m_a): gravity's share */
} air_factors;

static air_factors factors(const cw_instance *inst, double t) {
    const double rho = fmax(IN(rho_air, t), 0.0);
    const double mu = fmax(IN(mu_air, t), 0.0);
    const double volume = R(m) / R(bob_density);
    double added = rho * R(added_mass_coefficient);
    if (R(bob_radius) > 0) {
        /* rho delta with delta = sqrt(2 mu / (rho omega0)): finite at rho = 0. */
        const double omega0 = sqrt(R(g) / R(L));
        added += R(boundary_layer_coefficient) * sqrt(2.0 * mu * rho / omega0) /
                 R(bob_radius);
    }
    air_factors f;
    f.length = R(L) * (1.0 + R(alpha) * (IN(temperature, t) - R(T_ref)));
    f.inertial_mass = R(m) + added * volume;
    f.weight_ratio = (R(m) - rho * volume) / f.inertial_mass;
    return f;
}

/* The air and the temperature hold still over a step unless the master
 * gave their inputs derivatives: then the factors are computed once. */
static int air_is_steady(const cw_instance *inst) {
    /* FMI 3.0's intermediate update hands new input values inside the step. */
    if (inst->intermediate_update) return 0;
    static const unsigned vrs[] = {VR_rho_air, VR_mu_air, VR_temperature};
    for (int k = 0; k < 3; k++)
        if (inst->in_d1[vrs[k]] != 0.0 || inst->in_d2[vrs[k]] != 0.0) return 0;
    return 1;
}

/* factors(inst, t), kept while nothing is set when the air holds still
 * (then they do not depend on t): a doStep, the outputs and their
 * derivatives each need them, and they cost two square roots and three
 * divisions. */
static air_factors factors_now(cw_instance *inst, double t) {
    if (!air_is_steady(inst)) return factors(inst, t);
    double *kept = inst->model_cache;
    if (inst->model_cache_epoch != inst->values_epoch) {
        const air_factors f = factors(inst, t);
        kept[0] = f.length;
        kept[1] = f.inertial_mass;
        kept[2] = f.weight_ratio;
        inst->model_cache_epoch = inst->values_epoch;
    }
    air_factors f;
    f.length = kept[0];
    f.inertial_mass = kept[1];
    f.weight_ratio = kept[2];
    return f;
}

static double accelerate(const cw_instance *inst, const air_factors *f,
                         double t, double phi, double w) {
    const double inertia = f->inertial_mass * f->length * f->length;
    return -(R(g) * IN(g_factor, t) * f->weight_ratio / f->length) * sin(phi) -
           damping_rate(inst) * w + torque(inst, t) / inertia;
}

static double acceleration(cw_instance *inst, double t, double phi,
                           double w) {
    const air_factors f = factors_now(inst, t);
    return accelerate(inst, &f, t, phi, w);
}

/* Every input holds still over the step (zero-order hold, the usual
 * case): then the whole right-hand side but sin(phi) and w is fixed. */
static int inputs_held(const cw_instance *inst) {
    if (inst->intermediate_update) return 0;
    for (int a = 0; a < inst->n_real_in; a++) {
        const int k = inst->real_io[a];
        if (inst->in_d1[k] != 0.0 || inst->in_d2[k] != 0.0) return 0;
    }
    return 1;
}

/* What the right-hand side needs over one fmi2DoStep: the factors, when
 * they hold still over the step (rhs_steady), the terms of accelerate()
 * when every input does (rhs_held; a held input has the same value at
 * every time of the step, so these are its very numbers), and the
 * right-hand side chosen for the step. */
typedef struct {
    cw_instance *inst;
    air_factors fixed;
    double gravity, damping, push; /* accelerate = -gravity sin(phi) - damping w + push */
    cw_rhs f;
} step_context;

static void rhs_held(void *ctx, double t, const double *x, double *dx) {
    const step_context *c = ctx;
    (void)t;
    dx[0] = x[1];
    dx[1] = -(c->gravity) * sin(x[0]) - c->damping * x[1] + c->push;
}

static void rhs_steady(void *ctx, double t, const double *x, double *dx) {
    const step_context *c = ctx;
    dx[0] = x[1];
    dx[1] = accelerate(c->inst, &c->fixed, t, x[0], x[1]);
}

static void rhs(void *ctx, double t, const double *x, double *dx) {
    const step_context *c = ctx;
    const air_factors f = factors(c->inst, t);
    dx[0] = x[1];
    dx[1] = accelerate(c->inst, &f, t, x[0], x[1]);
}

/* The right-hand side of a step that starts at t, with what it can compute
 * once for the step. */
static step_context step_context_at(cw_instance *inst, double t) {
    step_context ctx = {inst, factors_now(inst, t), 0.0, 0.0, 0.0,
                        air_is_steady(inst) ? rhs_steady : rhs};
    if (inputs_held(inst)) {
        const air_factors *f = &ctx.fixed;
        ctx.gravity = R(g) * IN(g_factor, t) * f->weight_ratio / f->length;
        ctx.damping = damping_rate(inst);
        ctx.push = torque(inst, t) / (f->inertial_mass * f->length * f->length);
        ctx.f = rhs_held;
    }
    return ctx;
}

static void initialize(cw_instance *inst) {
    inst->s[S_PHI] = R(phi_start);
    inst->s[S_W] = R(w_start);
    inst->s[S_H_NEXT] = 0.0;
    I(tick_count) = 0;
    R(tick_time) = 0.0;
    R(period) = 0.0;
    R(amplitude) = 0.0;
    R(tick_w) = 0.0;
    I(turn_count) = 0;
}

static void calc_outputs(cw_instance *inst) {
    const double phi = inst->s[S_PHI], w = inst->s[S_W];
    R(phi) = phi;
    R(w) = w;
    R(a) = acceleration(inst, inst->time, phi, w);
    R(energy) = 0.5 * R(m) * R(L) * R(L) * w * w +
                R(m) * R(g) * R(L) * (1.0 - cos(phi));
}

/* Root of component `c` of the dense output inside the last step, by the
 * Illinois variant of regula falsi. */
static double dense_root(const cw_rk *rk, int c) {
    double a = rk->t0, b = rk->t0 + rk->h;
    double fa = rk->x0[c], fb = rk->x1[c], x[CW_RK_MAXN];
    int side = 0;
    for (int it = 0; it < 200; it++) {
        double t = (fa * b - fb * a) / (fa - fb);
        if (!(t > a && t < b)) t = 0.5 * (a + b);
        cw_rk_dense(rk, t, x);
        double ft = x[c];
        if (ft == 0.0 || b - a <= 4e-16 * fmax(1.0, fabs(t))) return t;
        if ((ft < 0) == (fa < 0)) {
            a = t;
            fa = ft;
            if (side == -1) fb *= 0.5;
            side = -1;
        } else {
            b = t;
            fb = ft;
            if (side == 1) fa *= 0.5;
            side = 1;
        }
    }
    return 0.5 * (a + b);
}

/* What the step observer watches for. With early return (FMI 3.0's
 * earlyReturnAllowed), the first tick or turning point inside the
 * communication step ends it there, with the state at the event. */
typedef struct {
    cw_instance *inst;
    step_context *rhs_ctx; /* what the right-hand side needs */
    int stop_at_events;
    double t_start, t_end; /* the communication step */
    int stopped;
    double t_event;
    /* The accepted step that held the event: its pair, start and state,
     * and the component that crosses at the event. */
    int method, component;
    double t0, x0[2];
} step_watch;

static void record_tick(cw_instance *inst, double t, double w) {
    R(tick_w) = w;
    int n = I(tick_count);
    if (n > 0) R(period) = t - R(tick_time);
    R(tick_time) = t;
    I(tick_count) = n + 1;
    cw_log(inst, fmi2OK, "logEvents", "tick %d at t = %.17g s", n + 1, t);
}

/* Where an early return at an event at time t reports the pendulum: a
 * full step of the pair from the start (t0, x0) of the accepted step that
 * held it, with the crossing component exactly 0 so that a step restarted
 * there does not find the same event again. */
static void state_at_event(step_context *ctx, int method, double t0,
                           const double x0[2], double t, int c, double x[2]) {
    cw_rk_single_step_with(method, 2, ctx->f, ctx, t0, x0, t - t0, x);
    x[c] = 0.0;
}

/* The state at the last early return's event, when first needed (the
 * importer usually steps on from the event without reading it): computed
 * with the inputs the step was taken with, which nothing has changed since
 * (cw_settle runs before any setter). */
static void settle(cw_instance *inst) {
    step_context ctx = step_context_at(inst, inst->event_inputs_t);
    double x[2];
    state_at_event(&ctx, inst->event_method, inst->event_step_t0,
                   inst->event_step_x0, inst->event_time,
                   inst->event_component, x);
    inst->s[S_PHI] = x[0];
    inst->s[S_W] = x[1];
}

/* Every accepted step: ticks and turning points are recorded the same way
 * with or without early return. With early return, a step that holds one
 * of them (not both) inside the communication step ends it there; the
 * integrator's own state (the end of this step) is kept to resume from. */
static int observe_step(void *ctx, const cw_rk *rk) {
    step_watch *watch = ctx;
    cw_instance *inst = watch->inst;
    const double phi0 = rk->x0[0], phi1 = rk->x1[0];
    const double w0 = rk->x0[1], w1 = rk->x1[1];
    const int tick = phi0 < 0.0 && phi1 >= 0.0;
    const int turn = (w0 > 0.0 && w1 <= 0.0) || (w0 < 0.0 && w1 >= 0.0);
    double t_event = 0.0;
    if (tick) {
        double t = dense_root(rk, 0);
        /* Polish: integrate exactly to t and take Newton steps on phi. */
        double x[2] = {0.0, rk->x1[1]};
        for (int it = 0; it < 2; it++) {
            cw_rk_single_step_with(rk->method, 2, watch->rhs_ctx->f, watch->rhs_ctx, rk->t0, rk->x0,
                                   t - rk->t0, x);
            if (x[1] == 0.0) break;
            double dt = -x[0] / x[1];
            if (!(fabs(dt) < rk->h)) break;
            t += dt;
        }
        record_tick(inst, t, x[1]);
        t_event = t;
    }
    if (turn) {
        double t = dense_root(rk, 1), x[CW_RK_MAXN];
        cw_rk_dense(rk, t, x);
        R(amplitude) = fabs(x[0]);
        I(turn_count) = I(turn_count) + 1;
        t_event = t;
    }
    if (watch->stop_at_events && tick != turn && t_event > watch->t_start &&
        t_event < watch->t_end) {
        watch->stopped = 1;
        watch->t_event = t_event;
        watch->method = rk->method;
        watch->component = tick ? 0 : 1;
        watch->t0 = rk->t0;
        watch->x0[0] = rk->x0[0];
        watch->x0[1] = rk->x0[1];
        return 1;
    }
    return 0;
}

static fmi2Status do_step(cw_instance *inst, double t_end) {
    cw_rk rk;
    cw_rk_init(&rk, 2, R(rtol), R(atol), R(h_max));
    cw_rk_set_method(&rk, I(integrator));
    /* Right after an early return, untouched since: go on from the end of
     * the internal step that held the event, as without early return, and
     * the state at the event (if still pending) is never needed. */
    const int resuming = inst->resume_valid && inst->resume_from == inst->time &&
                         inst->resume_t <= t_end;
    if (!resuming) cw_settle(inst);
    double x[2] = {inst->s[S_PHI], inst->s[S_W]};
    double t = inst->time, h_next = inst->s[S_H_NEXT];
    if (resuming) {
        t = inst->resume_t;
        x[0] = inst->resume_x[0];
        x[1] = inst->resume_x[1];
        h_next = inst->resume_h;
    }
    inst->resume_valid = 0;
    const double t_inputs = t;
    step_context ctx = step_context_at(inst, t_inputs);
    /* Tick outputs are updated by the observer; keep them for a retry. */
    const int ticks = I(tick_count), turns = I(turn_count);
    const double tick_w = R(tick_w);
    const double tick_time = R(tick_time), period = R(period),
                 amplitude = R(amplitude);
    step_watch watch = {inst, &ctx, cw_may_return_early(inst), inst->time,
                        t_end, 0, 0.0, 0, 0, 0.0, {0.0, 0.0}};
    cw_rk_result res =
        cw_rk_advance(&rk, ctx.f, &ctx, &t, t_end, x, &h_next, observe_step, &watch);
    const int stopped = res == CW_RK_STOPPED && watch.stopped;
    /* The state at the event is left pending, unless the importer answers
     * input requests (intermediate update): it does so only inside
     * fmi3DoStep, so the state is computed now. */
    const int pend = stopped && !inst->intermediate_update;
    double x_event[2] = {x[0], x[1]};
    if (stopped) {
        res = CW_RK_OK;
        if (!pend)
            state_at_event(&ctx, watch.method, watch.t0, watch.x0, watch.t_event,
                           watch.component, x_event);
    }
    if (res != CW_RK_OK || !isfinite(x[0]) || !isfinite(x[1]) ||
        !isfinite(x_event[0]) || !isfinite(x_event[1])) {
        I(tick_count) = ticks;
        I(turn_count) = turns;
        R(tick_w) = tick_w;
        R(tick_time) = tick_time;
        R(period) = period;
        R(amplitude) = amplitude;
        cw_log(inst, fmi2Discard, "logStatusDiscard",
               "Pendulum: integration from t = %.17g to %.17g failed (%s) at "
               "t = %.17g with phi = %g rad, w = %g rad/s; the step is "
               "discarded.",
               inst->time, t_end,
               res == CW_RK_STEP_TOO_SMALL   ? "step size underflow"
               : res == CW_RK_TOO_MANY_STEPS ? "too many internal steps"
                                             : "non-finite state",
               stopped ? watch.t_event : t, x_event[0], x_event[1]);
        return fmi2Discard;
    }
    inst->s[S_H_NEXT] = h_next;
    inst->state_pending = pend;
    if (!stopped) {
        inst->s[S_PHI] = x[0];
        inst->s[S_W] = x[1];
        return fmi2OK;
    }
    inst->resume_valid = 1;
    inst->resume_from = watch.t_event;
    inst->resume_t = t;
    inst->resume_x[0] = x[0];
    inst->resume_x[1] = x[1];
    inst->resume_h = h_next;
    if (pend) {
        inst->event_method = watch.method;
        inst->event_component = watch.component;
        inst->event_step_t0 = watch.t0;
        inst->event_step_x0[0] = watch.x0[0];
        inst->event_step_x0[1] = watch.x0[1];
        inst->event_time = watch.t_event;
        inst->event_inputs_t = t_inputs;
        /* Read before cw_settle, it would show; nothing may. */
        x_event[0] = x_event[1] = NAN;
    }
    inst->s[S_PHI] = x_event[0];
    inst->s[S_W] = x_event[1];
    cw_return_early(inst, watch.t_event);
    return fmi2OK;
}

/* The acceleration at the FMU's time and state: the output a, which
 * calc_outputs computed with these very arguments, unless it is stale. */
static double current_acceleration(cw_instance *inst) {
    return inst->outputs_dirty
               ? acceleration(inst, inst->time, inst->s[S_PHI], inst->s[S_W])
               : R(a);
}

static int output_derivative(cw_instance *inst, unsigned vr, int order,
                             double *value) {
    const double phi = inst->s[S_PHI], w = inst->s[S_W], t = inst->time;
    if (vr == VR_phi) {
        /* dphi/dt = w needs no acceleration (the master asks for it at every sample). */
        *value = order == 1 ? w : current_acceleration(inst);
        return order <= 2;
    }
    if (vr == VR_w) {
        const double a = current_acceleration(inst);
        if (order == 1) {
            *value = a;
            return 1;
        }
        if (order == 2) {
            /* da/dt, including the torques' and g_factor's own first
             * derivatives; the air and the temperature change so slowly
             * (weather: hours) that their rates are left out. */
            const air_factors f = factors_now(inst, t);
            const double inertia = f.inertial_mass * f.length * f.length;
            double dtau = cw_input_rate(inst, VR_tau_escapement, t) +
                          cw_input_rate(inst, VR_tau_drag, t) +
                          cw_input_rate(inst, VR_tau_coupling, t) +
                          cw_input_rate(inst, VR_tau_external, t);
            double gf = IN(g_factor, t), dgf = cw_input_rate(inst, VR_g_factor, t);
            *value = -(R(g) * f.weight_ratio / f.length) *
                         (gf * cos(phi) * w + dgf * sin(phi)) -
                     damping_rate(inst) * a + dtau / inertia;
            return 1;
        }
    }
    return 0;
}
