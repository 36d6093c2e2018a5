/* Event location (clockwork/engine/events.py, location.py): the
 * indicators' Hermite polynomials and their roots, the prediction of a
 * crossing before the step (plan), and landing just past a crossing after
 * it (locate, land_on_events) by rollback and shorter steps.
 */

#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "cw_master.h"

/* -- event location: polynomials (events.py) ------------------------------------- */

static void hermite_coefficients(double h, double z0, double dz0, double z1, double dz1,
                                 double *a, double *b, double *c, double *d)
{
    *c = h * dz0;
    *d = z0;
    *a = 2 * z0 - 2 * z1 + h * dz0 + h * dz1;
    *b = -3 * z0 + 3 * z1 - 2 * h * dz0 - h * dz1;
}

static double horner(const double *coef, int n, double x)
{
    double value = 0.0;
    for (int k = n - 1; k >= 0; k--)
        value = value * x + coef[k];
    return value;
}

/* A root of the polynomial (n coefficients, n <= 6) in (lo, hi), where it
 * is `positive` at lo: Newton's method from x, kept inside the shrinking
 * bracket by bisection, until a step is below 1e-15 (relative: <= 1e-15
 * hi) (events._newton_in_bracket). */
static double newton_in_bracket(const double *coef, int n, double x, double lo, double hi, int positive,
                                int relative)
{
    double slope[5];
    for (int k = 1; k < n; k++)
        slope[k - 1] = (double)k * coef[k];
    for (int it = 0; it < 50; it++) {
        double f = horner(coef, n, x);
        if (f == 0.0)
            break;
        if ((f > 0.0) == positive)
            lo = x;
        else
            hi = x;
        double df = horner(slope, n - 1, x);
        double x_new = df != 0.0 ? x - f / df : 0.5 * (lo + hi);
        if (!(lo < x_new && x_new < hi))
            x_new = 0.5 * (lo + hi);
        if (relative ? fabs(x_new - x) <= 1e-15 * hi : fabs(x_new - x) < 1e-15)
            return x_new;
        x = x_new;
    }
    return x;
}

/* Root in (0, h) of the indicator's Hermite interpolant, or NAN. */
static double hermite_root(double h, double z0, double dz0, double z1, double dz1,
                           int curvature, double ddz0, double ddz1)
{
    if (!(z0 * z1 < 0.0 || z1 == 0.0))
        return NAN;
    double coef[6];
    int n;
    if (curvature) {
        double c0 = z0, c1 = h * dz0, c2 = 0.5 * h * h * ddz0;
        double a = z1 - (c0 + c1 + c2);
        double b = h * dz1 - (c1 + 2.0 * c2);
        double c = h * h * ddz1 - 2.0 * c2;
        coef[0] = c0;
        coef[1] = c1;
        coef[2] = c2;
        coef[3] = 10.0 * a - 4.0 * b + 0.5 * c;
        coef[4] = -15.0 * a + 7.0 * b - c;
        coef[5] = 6.0 * a - 3.0 * b + 0.5 * c;
        n = 6;
    } else {
        hermite_coefficients(h, z0, dz0, z1, dz1, &coef[3], &coef[2], &coef[1], &coef[0]);
        n = 4;
    }
    double x = newton_in_bracket(coef, n, z0 != z1 ? z0 / (z0 - z1) : 0.5, 0.0, 1.0, z0 > 0.0, 0);
    return (0.0 < x && x < 1.0) ? x * h : NAN;
}

/* Where in (0, h) the cubic interpolant reaches the other sign, or NAN. */
static double hermite_extremum(double h, double z0, double dz0, double z1, double dz1)
{
    double a, b, c, d;
    hermite_coefficients(h, z0, dz0, z1, dz1, &a, &b, &c, &d);
    double roots[2];
    int n = 0;
    if (fabs(a) < 1e-300) {
        if (b != 0) {
            roots[0] = -c / (2 * b);
            n = 1;
        }
    } else {
        double disc = b * b - 3 * a * c;
        if (disc >= 0) {
            double r = pow(disc, 0.5);  /* as Python's disc ** 0.5 */
            roots[0] = (-b - r) / (3 * a);
            roots[1] = (-b + r) / (3 * a);
            n = 2;
            if (roots[1] < roots[0]) {
                double s = roots[0];
                roots[0] = roots[1];
                roots[1] = s;
            }
        }
    }
    for (int k = 0; k < n; k++) {
        double sx = roots[k];
        if (0.0 < sx && sx < 1.0) {
            double val = ((a * sx + b) * sx + c) * sx + d;
            if ((val > 0) != (z0 > 0) || val == 0.0)
                return sx * h;
        }
    }
    return NAN;
}

/* -- prediction: where an indicator will cross, before the step (events.py) -------- */

#define PREDICTION_HORIZON 16.0 /* extrapolate at most this many times the last step */
#define PREDICTION_SCAN 8       /* points scanned for the extrapolant's first sign change */

/* The Hermite polynomials through the last step of h s (a: z0..., b: z1...)
 * continued past b, in y = (time since b) / h: the higher order into high
 * (n_high coefficients), the lower into low (events.extrapolants). */
static void extrapolants(double h, double z0, double dz0, double z1, double dz1, int second, double ddz0,
                         double ddz1, double *high, int *n_high, double *low, int *n_low)
{
    double c1 = h * dz1;
    if (second) {
        double hh = h * h;
        double c2 = 0.5 * hh * ddz1;
        double e0 = z0 - ((z1 - c1) + c2);
        double e1 = h * dz0 - (c1 - hh * ddz1);
        double e2 = hh * ddz0 - hh * ddz1;
        high[0] = z1;
        high[1] = c1;
        high[2] = c2;
        high[3] = -0.5 * (e2 + 8.0 * e1 + 20.0 * e0);
        high[4] = -(e2 + 7.0 * e1 + 15.0 * e0);
        high[5] = -0.5 * (e2 + 6.0 * e1 + 12.0 * e0);
        *n_high = 6;
        low[0] = z1;
        low[1] = c1;
        low[2] = c2;
        low[3] = -(4.0 * e0 + e1);
        low[4] = -(3.0 * e0 + e1);
        *n_low = 5;
    } else {
        double e0 = z0 - (z1 - c1);
        double e1 = h * dz0 - c1;
        high[0] = z1;
        high[1] = c1;
        high[2] = 3.0 * e0 + e1;
        high[3] = 2.0 * e0 + e1;
        *n_high = 4;
        low[0] = z1;
        low[1] = c1;
        low[2] = e0;
        *n_low = 3;
    }
}

static double slope_at(const double *coef, int n, double y)
{
    double slope[5];
    for (int k = 1; k < n; k++)
        slope[k - 1] = (double)k * coef[k];
    return horner(slope, n - 1, y);
}

/* The first y in (0, y_max] where the polynomial leaves its sign at 0, or
 * NAN (events.first_root). */
static double first_root(const double *coef, int n, double y_max)
{
    double z0 = coef[0];
    int positive = z0 > 0.0;
    double lo = 0.0, f_lo = z0, hi = 0.0, f_hi = 0.0;
    int found = 0;
    for (int i = 1; i <= PREDICTION_SCAN; i++) {
        double y = y_max * (double)i / (double)PREDICTION_SCAN;
        double f = horner(coef, n, y);
        if (f == 0.0 || (f > 0.0) != positive) {
            hi = y;
            f_hi = f;
            found = 1;
            break;
        }
        lo = y;
        f_lo = f;
    }
    if (!found)
        return NAN;
    if (f_hi == 0.0)
        return hi;
    return newton_in_bracket(coef, n, lo + (hi - lo) * (f_lo / (f_lo - f_hi)), lo, hi, positive, 1);
}

/* -- event location: the locator (location.py) ----------------------------------- */

/* -1 when an indicator changed sign over the step; else the time until the
 * nearest one would reach zero at its rate over the step, s. */
static double scan(const double *z0, const double *z1, int n, double h)
{
    double steps = INFINITY;
    for (int k = 0; k < n; k++) {
        double a = z0[k], b = z1[k];
        if ((a > 0.0 && b <= 0.0) || (a < 0.0 && b >= 0.0))
            return -1.0;
        double dist = fabs(b);
        if (dist <= 1e-15)
            return 0.0;
        double change = fabs(b - a);
        if (dist < steps * change)
            steps = dist / change;
    }
    return steps * h;
}

/* d^order u/dt^order of indicator k's source output; 0 when refused. */
static int output_rate(cw_master *m, int k, int order, double *rate)
{
    cw_port *src = &m->ports[m->zs_port[k]];
    int orders[1] = {order};
    return src->getOutputDerivatives(src->comp, &m->zs_vr[k], 1, orders, rate) <= FMI_WARNING;
}

/* du/dt and d2u/dt2 of indicator k's source in one call (EventLocator.
 * output_rates): 0 when du/dt is refused; *have_acc when d2u/dt2 came too. */
static int output_rates(cw_master *m, int k, double *du, double *ddu, int *have_acc)
{
    cw_port *src = &m->ports[m->zs_port[k]];
    *have_acc = 0;
    if (src->max_output_derivative_order >= 2) {
        unsigned vr2[2] = {m->zs_vr[k], m->zs_vr[k]};
        static const int orders[2] = {1, 2};
        double got[2];
        if (src->getOutputDerivatives(src->comp, vr2, 2, orders, got) <= FMI_WARNING) {
            *du = got[0];
            *ddu = got[1];
            *have_acc = 1;
            return 1;
        }
    }
    return output_rate(m, k, 1, du);
}

void remember_sources(cw_master *m)
{
    double cap = INFINITY;
    for (int k = 0; k < m->n_z; k++) {
        if (m->zs_port[k] < 0) {
            m->prev_kind[k] = 0;
            continue;
        }
        cw_port *src = &m->ports[m->zs_port[k]];
        double u = src->out[m->zs_pos[k]];
        double z_now = m->z_end[k];
        int constant = z_now == m->z_seen[k];
        m->z_seen[k] = z_now;
        m->prev_u[k] = u;
        if (constant) {
            /* An indicator that did not move says nothing about its source's time scale. */
            m->prev_kind[k] = 1;
            continue;
        }
        double du, acc = 0.0;
        int have_du = 1, have_acc = 0;
        int second = src->max_output_derivative_order >= 2 && u != 0.0;
        if (m->end_rate_set[k])
            du = m->end_rate[k];
        else if (second)  /* both derivatives in one call where both are wanted */
            have_du = output_rates(m, k, &du, &acc, &have_acc);
        else
            have_du = output_rate(m, k, 1, &du);
        m->prev_kind[k] = have_du ? 2 : 1;
        m->prev_du[k] = du;
        if (have_du) {
            double amp_u = py_max(fabs(u), 0.999 * m->amp_u[k]);
            double amp_du = py_max(fabs(du), 0.999 * m->amp_du[k]);
            m->amp_u[k] = amp_u;
            m->amp_du[k] = amp_du;
            double omega = amp_u > 0.0 ? amp_du / amp_u : 0.0;
            if (second) {
                if (!have_acc)
                    have_acc = output_rate(m, k, 2, &acc);
                if (have_acc)
                    omega = py_max(omega, sqrt(fabs(acc / u)));
            }
            if (omega > 0.0)
                cap = py_min(cap, 0.2 * 2 * M_PI / omega);
        }
    }
    m->prev_valid = 1;
    m->step_cap = cap;
    for (int k = 0; k < m->n_z; k++)
        m->end_rate_set[k] = 0;
}

/* Offset of an indicator's extremum inside the step where its interpolant
 * changes sign although z has one sign at both ends, or NAN. */
static double hidden_crossing(cw_master *m, double h, const double *z0, const double *z1)
{
    if (!m->prev_valid)
        return NAN;
    double best = NAN;
    for (int k = 0; k < m->n_z; k++) {
        if (m->zs_port[k] < 0 || m->prev_kind[k] != 2)
            continue;
        double u0 = m->prev_u[k], du0 = m->prev_du[k];
        double u1 = m->ports[m->zs_port[k]].out[m->zs_pos[k]];
        if (u1 == u0 || z0[k] == 0.0)
            continue;
        double ratio = (z1[k] - z0[k]) / (u1 - u0);
        double dz0 = ratio * du0;
        if (z0[k] * dz0 >= 0.0)
            continue;  /* moving away from zero at the start */
        double du1;
        if (!output_rate(m, k, 1, &du1))
            continue;
        m->end_rate[k] = du1;
        m->end_rate_set[k] = 1;
        double dz1 = ratio * du1;
        if (z1[k] * dz1 <= 0.0)
            continue;  /* still approaching at the end */
        double x = hermite_extremum(h, z0[k], dz0, z1[k], dz1);
        if (!isnan(x) && (isnan(best) || x < best))
            best = x;
    }
    return best;
}

/* The sources' values and derivatives at t (EventLocator.sample). */
void sample_sources(cw_master *m, double t)
{
    int nz = m->n_z;
    memcpy(m->pred_kind + nz, m->pred_kind, (size_t)nz * sizeof(int));
    memcpy(m->pred_u + nz, m->pred_u, (size_t)nz * sizeof(double));
    memcpy(m->pred_du + nz, m->pred_du, (size_t)nz * sizeof(double));
    memcpy(m->pred_ddu + nz, m->pred_ddu, (size_t)nz * sizeof(double));
    m->sampled_before_t = m->sampled_t;
    for (int k = 0; k < nz; k++) {
        m->pred_kind[k] = 0;
        if (m->zs_port[k] < 0)
            continue;
        int same = -1;  /* an earlier indicator with the same source output: asked once */
        for (int j = 0; j < k && same < 0; j++)
            if (m->zs_port[j] == m->zs_port[k] && m->zs_vr[j] == m->zs_vr[k])
                same = j;
        if (same >= 0) {
            m->pred_kind[k] = m->pred_kind[same];
            m->pred_u[k] = m->pred_u[same];
            m->pred_du[k] = m->pred_du[same];
            m->pred_ddu[k] = m->pred_ddu[same];
            continue;
        }
        cw_port *src = &m->ports[m->zs_port[k]];
        int have_acc;
        if (output_rates(m, k, &m->pred_du[k], &m->pred_ddu[k], &have_acc)) {
            m->pred_u[k] = src->out[m->zs_pos[k]];
            m->pred_kind[k] = have_acc ? 2 : 1;
        }
    }
    m->sampled_t = t;
}

/* Before the step from t of h s: PLAN_CLEAR, PLAN_APPROACH or PLAN_LAND
 * with *step, when every indicator's next crossing can be predicted from
 * the Hermite polynomial through the last step; else PLAN_NONE
 * (EventLocator.plan). */
int plan(cw_master *m, double t, double h, double *step_out)
{
    if (!m->last_valid || m->sampled_t != t || m->sampled_before_t != m->last_t)
        return PLAN_NONE;
    double span = t - m->last_t;
    if (!(span > 0.0))
        return PLAN_NONE;
    int nz = m->n_z, kind = PLAN_CLEAR;
    double step = h;
    for (int k = 0; k < nz; k++) {
        double za = m->last_z[k], zb = m->z_end[k];
        if (za == zb)
            continue;  /* did not move: does not cross by moving */
        int now = m->pred_kind[k], before = m->pred_kind[nz + k];
        if (!now || !before || zb == 0.0)
            return PLAN_NONE;
        double u1 = m->pred_u[k], u0 = m->pred_u[nz + k];
        if (u1 == u0)
            return PLAN_NONE;
        double ratio = (zb - za) / (u1 - u0);
        int second = before == 2 && now == 2;
        double high[6], low[5];
        int n_high, n_low;
        extrapolants(span, za, ratio * m->pred_du[nz + k], zb, ratio * m->pred_du[k], second,
                     second ? ratio * m->pred_ddu[nz + k] : 0.0, second ? ratio * m->pred_ddu[k] : 0.0,
                     high, &n_high, low, &n_low);
        double y_max = py_min(h / span, PREDICTION_HORIZON);
        double y_high = first_root(high, n_high, y_max), y_low = first_root(low, n_low, y_max);
        if (isnan(y_high)) {
            if (!isnan(y_low) || h / span > PREDICTION_HORIZON)
                return PLAN_NONE;
            continue;  /* clear of this indicator */
        }
        if (isnan(y_low))
            return PLAN_NONE;
        double at = y_high * span;
        double err = fabs(at - y_low * span);
        double rate = slope_at(high, n_high, y_high) / span;
        double past = 0.25 * m->event_time_tolerance;
        if (rate != 0.0)
            past = py_min(past, 0.25 * m->event_indicator_tolerance / fabs(rate));
        int this;
        double mine;
        if (2.0 * err <= past && at + past <= h) {
            this = PLAN_LAND;
            mine = at + past;
        } else if (2.0 * err < 0.95 * at) {
            this = PLAN_APPROACH;
            mine = at - 2.0 * err;
        } else {
            return PLAN_NONE;
        }
        if (mine < step) {
            kind = this;
            step = mine;
        }
    }
    if ((t + step) - t < 8 * ulp(fabs(t) + step + 1.0))
        return PLAN_NONE;
    *step_out = step;
    return kind;
}

/* The indicator among the crossing ones whose linear interpolant crosses first. */
static int earliest(const int *crossing, const double *z0, const double *z1, int n)
{
    int lead = -1;
    double best = 0.0;
    for (int k = 0; k < n; k++) {
        if (!crossing[k])
            continue;
        double x = z0[k] / (z0[k] - z1[k]);
        if (lead < 0 || x < best) {
            lead = k;
            best = x;
        }
    }
    return lead;
}

/* How close locate brackets a crossing in the step from t of h s: far from
 * t = 0 a double cannot resolve the tolerance, so a few ulps. */
static double time_tolerance(const cw_master *m, double t, double h)
{
    return py_max(m->event_time_tolerance, 4 * ulp(fabs(t) + h));
}

/* Shorten the step from t (a checkpoint) to land just past the earliest
 * crossing (EventLocator.locate); *taken gets the step, s. */
static int locate(cw_master *m, double t, double h, const int *crossings, const double *z0,
                  const double *z1, double *taken)
{
    int nz = m->n_z;
    int lead = earliest(crossings, z0, z1, nz);
    /* The source's slope at the step's end, before the rollback. */
    int have_slope = 0, have_dd1 = 0;
    double u1 = 0.0, du1 = 0.0, ddu1 = 0.0;
    if (m->zs_port[lead] >= 0 && output_rate(m, lead, 1, &du1)) {
        have_slope = 1;
        u1 = m->ports[m->zs_port[lead]].out[m->zs_pos[lead]];
        if (m->ports[m->zs_port[lead]].max_output_derivative_order >= 2)
            have_dd1 = output_rate(m, lead, 2, &ddu1);
    }
    TRY(rollback(m));
    double first = 0.0;
    int have_first = 0;  /* a trial proposed by the interpolant or by Newton (may be NaN) */
    int newton = 0, newton_lead = -1, curvature = 0;
    double ratio = 0.0;
    if (have_slope) {
        double u0 = m->ports[m->zs_port[lead]].out[m->zs_pos[lead]];
        double du0, ddu0 = 0.0;
        int have_du0 = output_rate(m, lead, 1, &du0);
        int have_dd0 = have_dd1 ? output_rate(m, lead, 2, &ddu0) : 0;
        if (have_du0 && u1 != u0) {
            /* The indicator is affine in its source near the crossing: z' = ratio u'. */
            ratio = (z1[lead] - z0[lead]) / (u1 - u0);
            curvature = have_dd0 && have_dd1;
            first = hermite_root(h, z0[lead], ratio * du0, z1[lead], ratio * du1, curvature,
                                 curvature ? ratio * ddu0 : 0.0, curvature ? ratio * ddu1 : 0.0);
            have_first = !isnan(first);  /* NaN: no root in the step */
            newton = 1;
            newton_lead = lead;
        }
    }
    illinois search = illinois_new(0.0, z0[lead], h, z1[lead]);
    double hi = h;
    double z_hi[nz > 0 ? nz : 1], z_lo[nz > 0 ? nz : 1];
    int now[nz > 0 ? nz : 1];
    memcpy(z_hi, z1, (size_t)nz * sizeof(double));
    memcpy(z_lo, z0, (size_t)nz * sizeof(double));
    double base = 0.0;
    int have_last = 0;  /* the FMUs stand at the checkpoint after the rollback */
    double last = 0.0;
    double time_tol = time_tolerance(m, t, h);
    for (;;) {
        if (hi - search.lo <= time_tol || fabs(z_hi[lead]) <= m->event_indicator_tolerance)
            break;
        double trial;
        if (have_first) {
            trial = first;
            have_first = 0;
        } else {
            trial = illinois_next(&search);
        }
        if (!(search.lo < trial && trial < hi))
            trial = 0.5 * (search.lo + hi);
        /* A trial must move the FMUs' clock: at least a few ulps past lo. */
        double min_move = 8 * ulp(fabs(t) + fabs(hi) + 1.0);
        if ((t + trial) - (t + search.lo) < min_move)
            trial = search.lo + py_min(0.5 * (hi - search.lo),
                                       py_max(min_move, 0.25 * m->event_time_tolerance));
        if (have_last)
            TRY(rollback(m));
        TRY(advance(m, m->t, (t + trial) - m->t));
        m->event_iterations++;
        have_last = 1;
        last = trial;
        const double *z = m->z_end;
        if (newton && newton_lead == lead) {
            /* Newton from this trial, aimed a hair past the root in time. */
            double rate;
            if (output_rate(m, lead, 1, &rate) && rate != 0.0) {
                double slope = ratio * rate;
                double delta = -z[lead] / slope;
                double acc;
                if (curvature && output_rate(m, lead, 2, &acc)) {
                    double bend = ratio * acc;
                    double disc = slope * slope - 2.0 * z[lead] * bend;
                    if (disc >= 0.0)
                        delta = -2.0 * z[lead] / (slope + copysign(sqrt(disc), slope));
                }
                double past = py_min(0.25 * m->event_time_tolerance,
                                     0.25 * m->event_indicator_tolerance / fabs(slope));
                first = trial + delta + past;
                have_first = 1;
            }
        }
        int any = 0;
        for (int k = 0; k < nz; k++) {
            now[k] = crossed(m->z_start[k], z[k]);
            any |= now[k];
        }
        if (any) {
            if (!now[lead]) {
                /* Another indicator crosses first: restart on it. */
                lead = earliest(now, z_lo, z, nz);
                search = illinois_new(search.lo, z_lo[lead], trial, z[lead]);
                have_first = 0;
            } else {
                illinois_update(&search, trial, z[lead], 1);
            }
            hi = trial;
            memcpy(z_hi, z, (size_t)nz * sizeof(double));
        } else {
            illinois_update(&search, trial, z[lead], 0);
            /* Later trials start here: no need to integrate [t, t + trial] again. */
            memcpy(z_lo, z, (size_t)nz * sizeof(double));
            TRY(checkpoint_mark(m));
            base = trial;
            have_last = 0;
        }
        if (search.iterations > 200) {
            m->err_t = t;
            m->err_h = h;
            return CW_ERR_LOCATE;
        }
    }
    if (!have_last || last != hi) {
        if (have_last)
            TRY(rollback(m));
        TRY(advance(m, m->t, (t + hi) - m->t));
    }
    if (base > 0.0)
        m->n_since = 0;
    m->located_from = t + base;
    m->events++;
    *taken = hi;
    return 0;
}

/* After the step from t of h s: when an indicator crossed zero, land just
 * past the earliest crossing instead (Master._land_on_events). */
int land_on_events(cw_master *m, double t, double h, int near, int checkpointed, int predicted,
                          double *taken)
{
    int nz = m->n_z;
    double z0[nz > 0 ? nz : 1], z1[nz > 0 ? nz : 1];
    int crossings[nz > 0 ? nz : 1];
    memcpy(z0, m->z_start, (size_t)nz * sizeof(double));
    memcpy(z1, m->z_end, (size_t)nz * sizeof(double));
    double time_to_zero = scan(z0, z1, nz, h);
    int hit = time_to_zero < 0.0;
    if (!hit && near && m->has_sources) {
        double hidden = hidden_crossing(m, h, z0, z1);
        if (!isnan(hidden)) {
            /* Two crossings inside one step cancel at its ends: try the
             * step up to the interpolant's extremum. */
            TRY(rollback(m));
            TRY(advance(m, t, hidden));
            m->event_iterations++;
            memcpy(z0, m->z_start, (size_t)nz * sizeof(double));
            memcpy(z1, m->z_end, (size_t)nz * sizeof(double));
            time_to_zero = scan(z0, z1, nz, hidden);
            hit = time_to_zero < 0.0;
            if (hit) {
                h = hidden;
            } else {  /* the interpolant was wrong: redo the whole step */
                TRY(rollback(m));
                TRY(advance(m, t, h));
                memcpy(z0, m->z_start, (size_t)nz * sizeof(double));
                memcpy(z1, m->z_end, (size_t)nz * sizeof(double));
                time_to_zero = scan(z0, z1, nz, h);
            }
        }
    }
    if (!hit) {
        m->time_to_zero = time_to_zero;
        TRY(since_append(m, h));
        *taken = h;
        return 0;
    }
    for (int k = 0; k < nz; k++)
        crossings[k] = crossed(z0[k], z1[k]);
    int lead = earliest(crossings, z0, z1, nz);
    if (fabs(z1[lead]) <= m->event_indicator_tolerance || h <= time_tolerance(m, t, h)) {
        /* Already just past the crossing, where locate would stop at once. */
        if (predicted == PLAN_LAND)
            m->predicted_landings++;
        m->events++;
        m->located_from = t;
        m->after_event_step = 1;
        m->time_to_zero = 0.0;
        *taken = h;
        return since_append(m, h);
    }
    if (predicted)
        m->mispredicted++;
    if (!checkpointed) {
        /* An event in a step predicted free of them: replay from the checkpoint. */
        TRY(replay_to(m, t));
        TRY(advance(m, t, h));
    }
    TRY(locate(m, t, h, crossings, z0, z1, taken));
    m->after_event_step = 1;
    m->time_to_zero = 0.0;
    return since_append(m, m->t - m->located_from);
}
