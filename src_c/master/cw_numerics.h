/* The numerics the master's event location (cw_events.c) and the Model
 * Exchange wrapper's (cw_me.c) share: what counts as a zero crossing, and
 * the root finder on a bracket.
 *
 * A crossing (clockwork/engine/events.py's crossed): from a non-zero value
 * to zero or the other sign. A value that starts at zero has not crossed.
 *
 * The Illinois variant of regula falsi on a bracket [lo, hi] whose ends'
 * values z_lo, z_hi have opposite signs (clockwork/engine/events.py's
 * Illinois, the same arithmetic): the trial is where the secant crosses
 * zero; an end kept twice in a row has its value halved. */
#ifndef CW_NUMERICS_H
#define CW_NUMERICS_H

static inline int crossed(double z0, double z1)
{
    return (z0 > 0.0 && z1 <= 0.0) || (z0 < 0.0 && z1 >= 0.0);
}

typedef struct {
    double lo, z_lo, hi, z_hi;
    int kept, iterations;
} illinois;

static inline double illinois_next(const illinois *s)
{
    double dz = s->z_lo - s->z_hi;
    if (dz == 0.0)
        return 0.5 * (s->lo + s->hi);
    return (s->z_lo * s->hi - s->z_hi * s->lo) / dz;
}

static inline void illinois_update(illinois *s, double x, double z, int was_crossed)
{
    s->iterations++;
    if (was_crossed) {
        s->hi = x;
        s->z_hi = z;
        if (s->kept == 1)
            s->z_lo *= 0.5;
        s->kept = 1;
    } else {
        s->lo = x;
        s->z_lo = z;
        if (s->kept == -1)
            s->z_hi *= 0.5;
        s->kept = -1;
    }
}

static inline illinois illinois_new(double lo, double z_lo, double hi, double z_hi)
{
    illinois s = {lo, z_lo, hi, z_hi, 0, 0};
    return s;
}

#endif
