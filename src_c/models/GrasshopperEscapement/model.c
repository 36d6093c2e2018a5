/* GrasshopperEscapement: Ziemkiewicz Eq. (6) written as Hoyng's model
 * escapement, a relay with hysteresis.
 *
 *   tau = d torque f_profile(phi, d, w) (1 + g_v |v_vib|) (1 + delta)
 *
 * d = +1 pushes towards +phi. It flips to -1 when phi rises to +phi_r and
 * back to +1 when phi falls to -phi_r, so the torque drives with the motion
 * from the far turning point to the threshold and recoils (opposes the
 * motion) from the threshold to the turning point: 4 torque phi_r of work
 * per period (Ziemkiewicz Eq. B3). The mode is state: a swing with
 * amplitude below phi_r never flips it and the pendulum stalls.
 *
 * Discrete state follows docs/design.md: calc_outputs derives the pending
 * (right-limit) mode and noise deviation from the committed state and the
 * current inputs without changing anything; commit(), run by the runtime at
 * the start of every fmi2DoStep, makes them the committed state. The event
 * indicator uses the committed mode (left limit).
 *
 * Noise (Hoyng Eq. 23): delta ~ N(0, noise_rms^2) is renewed at each upward
 * zero crossing of phi. The FMU sees inputs only at communication points, so
 * the renewal happens at the first communication point with phi >= 0 after
 * one with phi < 0, provided its time is >= noise_start. */
#include <math.h>

#include "cw_runtime.h"
#include "cw_vars.h"

static const double TWO_PI = 6.283185307179586;

/* splitmix64: one 64-bit word of state, every seed is a good seed. */
static uint64_t splitmix64(uint64_t *x) {
    uint64_t z = (*x += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

/* Standard normal deviate by Box-Muller (cosine branch only, so that one
 * deviate is a fixed number of draws and the state stays a single word). */
static double normal_deviate(uint64_t *x) {
    const double u1 = (double)((splitmix64(x) >> 11) + 1) * 0x1p-53; /* (0,1] */
    const double u2 = (double)(splitmix64(x) >> 11) * 0x1p-53;       /* [0,1) */
    return sqrt(-2.0 * log(u1)) * cos(TWO_PI * u2);
}

typedef struct {
    double phi, w, v; /* inputs at inst->time */
    int d;            /* pending mode */
    int switched;
    double delta; /* pending noise deviation */
    int renewed;
    uint64_t rng; /* generator state after the pending renewal */
} pending;

/* Right-limit values from the committed state and the current inputs. */
static pending pending_state(const cw_instance *inst) {
    pending p;
    const double t = inst->time;
    p.phi = IN(phi, t);
    p.w = IN(w, t);
    p.v = IN(vibration_velocity, t);
    const int d_c = inst->s[S_MODE] < 0 ? -1 : 1;
    const double ind = R(phi_r) - d_c * p.phi;
    /* With phi_r = 0 the indicator is 0 at phi = 0 for either mode; demand
     * that phi has left 0, or the relay would flip at every step there. */
    p.switched = ind <= 0.0 && !(ind == 0.0 && R(phi_r) == 0.0);
    p.d = p.switched ? -d_c : d_c;
    p.delta = inst->s[S_DELTA];
    p.rng = inst->u[U_RNG];
    p.renewed = inst->s[S_PHI] < 0.0 && p.phi >= 0.0 &&
                t >= R(noise_start) && R(noise_rms) > 0.0;
    if (p.renewed) p.delta = R(noise_rms) * normal_deviate(&p.rng);
    return p;
}

static double profile_factor(const cw_instance *inst, const pending *p) {
    const double x = fabs(p->phi) / R(profile_angle);
    switch (I(profile)) {
    case 1: return 0.5 + x;
    case 2: return fmax(0.0, 1.5 - x);
    case 3:
        /* Recoil: the torque opposes the motion. At the turning point
         * (w = 0) the drive value is used. */
        return p->d * p->w < 0.0 ? R(harrison_ratio) : 1.0;
    default: return 1.0;
    }
}

static void initialize(cw_instance *inst) {
    const double t = inst->time;
    const double phi = IN(phi, t), w = IN(w, t), phi_r = R(phi_r);
    int d = I(mode_start);
    if (d == 0) {
        if (w >= 0.0)
            d = phi < phi_r ? 1 : -1;
        else
            d = phi > -phi_r ? -1 : 1;
    }
    inst->s[S_MODE] = d;
    inst->s[S_PHI] = phi;
    inst->s[S_DELTA] = 0.0;
    inst->u[U_RNG] = (uint64_t)(uint32_t)I(noise_seed);
    inst->u[U_RENEWALS] = 0;
}

static void calc_outputs(cw_instance *inst) {
    const pending p = pending_state(inst);
    const double velocity_factor = 1.0 + R(velocity_gain) * fabs(p.v);
    R(tau) = p.d * R(torque) * profile_factor(inst, &p) * velocity_factor *
             (1.0 + p.delta);
    R(event_indicator) = R(phi_r) - inst->s[S_MODE] * p.phi;
    /* Only Harrison's profile changes the torque where the swing reverses. */
    R(event_indicator_turn) = I(profile) == 3 ? IN(w, inst->time) : 1.0;
    I(mode) = p.d;
    R(torque_amplitude) = R(torque) * (1.0 + p.delta);
}

static void commit(cw_instance *inst) {
    const pending p = pending_state(inst);
    if (p.switched)
        cw_log(inst, fmi2OK, "logEvents",
               "t = %.17g s: mode %+d -> %+d at phi = %.17g rad", inst->time,
               -p.d, p.d, p.phi);
    if (p.renewed) {
        inst->u[U_RENEWALS]++;
        cw_log(inst, fmi2OK, "logEvents",
               "t = %.17g s: torque noise renewal %llu, delta = %.17g",
               inst->time, (unsigned long long)inst->u[U_RENEWALS], p.delta);
    }
    inst->s[S_MODE] = p.d;
    inst->s[S_PHI] = p.phi;
    inst->s[S_DELTA] = p.delta;
    inst->u[U_RNG] = p.rng;
}
