/* Components at their own steps: the twin of clockwork/engine/multirate.py's
 * MultiRate.step and .advance (libcosim's fixed-step rule), operation for
 * operation, so that both engines give the same bits.
 *
 * A port of factor k steps k * step every k base steps, from the point of
 * its own grid where that step started to the base step's end; a value
 * passes along a link across rates only where both ends share a point
 * (every lcm of their factors), through the link's held copy (cw_rates).
 * Only whole base steps are taken: an announced time event or an input
 * sample's event inside one is refused (CW_ERR_RATES), as Python refuses
 * it. What multirate.py refuses before the first step (event location,
 * strong coupling, extrapolation, loops with a slow member) never gets
 * here.
 */

#include <math.h>
#include <stddef.h>

#include "cw_master.h"

/* MultiRate._pass: the values along the links whose ends share base step n. */
static void pass(cw_master *m, long long n)
{
    const cw_rates *r = m->rates;
    for (int a = 0; a < r->n_links; a++)
        if (n % r->every[a] == 0)
            m->ports[r->held_port[a]].out[r->held_pos[a]] = m->ports[r->src_port[a]].out[r->src_pos[a]];
}

/* MultiRate.start: the count from 0, the held copies those of now. */
void rates_start(cw_master *m)
{
    m->rates->count = 0;
    pass(m, 0);
}

static int refuse(cw_master *m, int why, double t, double h)
{
    m->err_call = why;
    m->err_t = t;
    m->err_h = h;
    return CW_ERR_RATES;
}

/* The step of dynamic port i that ends at t + h: (start, own step), s. */
static void own_step(const cw_master *m, int i, double t, double h, double *start, double *own)
{
    if (m->ports[i].rate == 1) {
        *start = t;
        *own = h;
    } else {
        *start = m->rates->starts[i];
        *own = (t + h) - *start;
    }
}

/* MultiRate.advance */
static int advance_rates(cw_master *m, double t, double h)
{
    cw_rates *r = m->rates;
    const cw_inputs *in = m->inputs;
    long long n = r->count;
    double t_new = t + h;
    if (in) {  /* sampled inputs at t for what steps from t; a slow one's at its own step's start */
        for (int a = 0; a < m->n_first; a++)
            TRY(inputs_set(m, m->first[a], t, 1));
        for (int a = 0; a < m->n_dynamic; a++)
            if (m->ports[m->dynamic[a]].rate == 1)
                TRY(inputs_set(m, m->dynamic[a], t, 1));
    }
    /* 1. Feedthrough-only instances (all at the base rate) commit the mode decided at t. */
    for (int a = 0; a < m->n_first; a++) {
        cw_port *p = &m->ports[m->first[a]];
        int st = p->doStep(p->comp, t, h, 1);
        if (st > FMI_WARNING)
            return fail(m, m->first[a], CALL_DO_STEP, st, t, h);
    }
    if (in)
        for (int a = 0; a < m->n_first; a++)
            if (in->after_step[m->first[a]])
                TRY(inputs_set(m, m->first[a], t_new, 0));
    /* 2. The dynamic instances whose own step ends at t + h, each from its own start. */
    int last = -1;
    for (int a = 0; a < m->n_dynamic; a++) {
        int i = m->dynamic[a], k = m->ports[i].rate;
        if (k != 1 && n % k == 0)  /* a slow step starts here */
            r->starts[i] = t;
        if ((n + 1) % k == 0)
            last = a;
    }
    double start, own;
    if (m->jacobi)
        for (int a = 0; a <= last; a++) {
            int i = m->dynamic[a];
            if ((n + 1) % m->ports[i].rate == 0 && m->ports[i].n_in) {
                own_step(m, i, t, h, &start, &own);
                TRY(set_inputs(m, i, start, own, 0));
            }
        }
    for (int a = 0; a <= last; a++) {
        int i = m->dynamic[a];
        cw_port *p = &m->ports[i];
        if ((n + 1) % p->rate)
            continue;
        own_step(m, i, t, h, &start, &own);
        if (p->rate != 1 && in)
            TRY(inputs_set(m, i, start, 1));
        if (!m->jacobi && p->n_in)
            TRY(set_inputs(m, i, start, own, 0));
        int st = p->doStep(p->comp, start, own, 1);
        if (st > FMI_WARNING)
            return fail(m, i, CALL_DO_STEP, st, start, own);
        if (in && p->rate == 1 && in->after_step[i])
            TRY(inputs_set(m, i, t_new, 0));
        TRY(port_read(m, i, t_new));
        if (!m->jacobi && a != last)
            TRY(propagate(m, m->after_order + m->after_start[a], m->after_start[a + 1] - m->after_start[a],
                          t_new));
    }
    /* 3. What the slow ones gave passes on, then outputs at t + h in
     * dependency order, then what those gave passes on too. */
    r->count = n + 1;
    pass(m, n + 1);
    m->t = t_new;
    TRY(propagate(m, m->final_order, m->n_final, t_new));
    pass(m, n + 1);
    return 0;
}

/* MultiRate.step: one base step from m->t (h must be the base step). */
int rates_step(cw_master *m, double h, double *taken)
{
    double t = m->t, base = m->step;
    if (fabs(h - base) > 1e-9 * base)
        return refuse(m, RATES_OFF_BASE, t, h);
    for (int i = 0; i < m->n_announcers; i++) {
        if (cw_asked_to_end(m->announcers[i]))
            return CW_ENDED;
        double te = cw_announced_event_time(m->announcers[i]);
        if (t < te && te < t + h && !cw_isclose(te, t + h))
            return refuse(m, RATES_TIME_EVENT, t, te);
    }
    if (m->inputs) {
        double te = inputs_next_event(m->inputs, t);
        if (t < te && te < t + h && !cw_isclose(te, t + h))
            return refuse(m, RATES_SAMPLE_EVENT, t, te);
    }
    TRY(advance_rates(m, t, h));
    m->steps++;
    *taken = h;
    m->diverged = diverged(m);
    if (m->diverged) {
        m->err_t = t;
        return CW_CHECK_DIVERGENCE;
    }
    return CW_DONE;
}
