/* The instances' inputs (clockwork/engine/coupling.py, samples.py): the
 * outputs read and handed on along the links (port_read, port_pull; in
 * dependency order with the loops, cw_loops.c's propagate), inputs driven
 * from samples (an input file), and the input history with its
 * polynomials for a step (extrapolate, set_inputs).
 */

#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "cw_master.h"

/* -- ports ------------------------------------------------------------- */

int port_read(cw_master *m, int i, double t)
{
    cw_port *p = &m->ports[i];
    if (p->n_out) {
        int st = p->getReal(p->comp, p->out_vr, (size_t)p->n_out, p->out);
        if (st > FMI_WARNING)
            return fail(m, i, CALL_GET_REAL, st, t, 0.0);
    }
    p->out_time = t;
    return 0;
}

/* The sums' further terms (Port.adds), in order, then the links' linear
 * transformations (Port.scale); the identity is skipped. */
static void sum_and_scale(const cw_master *m, cw_port *p)
{
    for (int a = 0; a < p->n_adds; a++)
        p->inp[p->add_at[a]] += m->ports[p->add_port[a]].out[p->add_pos[a]];
    for (int a = 0; a < p->n_scaled; a++) {
        int k = p->scaled[a];
        p->inp[k] = p->in_factor[a] * p->inp[k] + p->in_offset[a];
    }
}

int port_pull(cw_master *m, int i, double t)
{
    cw_port *p = &m->ports[i];
    if (p->n_in) {
        for (int k = 0; k < p->n_in; k++)
            p->inp[k] = m->ports[p->src_port[k]].out[p->src_pos[k]];
        sum_and_scale(m, p);
        int st = p->setReal(p->comp, p->in_vr, (size_t)p->n_in, p->inp);
        if (st > FMI_WARNING)
            return fail(m, i, CALL_SET_INPUTS, st, t, 0.0);
        p->sent_valid = 0;
    }
    return port_read(m, i, t);
}

/* -- inputs from samples (engine/samples.py) --------------------------- */

static int bisect_left(const double *a, int n, double x)
{
    int lo = 0, hi = n;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (a[mid] < x)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

static int bisect_right(const double *a, int n, double x)
{
    int lo = 0, hi = n;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (x < a[mid])
            hi = mid;
        else
            lo = mid + 1;
    }
    return lo;
}

/* Samples.next_event */
double inputs_next_event(const cw_inputs *in, double t)
{
    for (int i = bisect_right(in->events, in->n_events, t); i < in->n_events; i++)
        if (!cw_isclose(in->events[i], t))
            return in->events[i];
    return INFINITY;
}

/* Samples.event_at */
int inputs_event_at(const cw_inputs *in, double t)
{
    int i = bisect_left(in->events, in->n_events, t);
    for (int j = i - 1; j <= i; j++)
        if (j >= 0 && j < in->n_events && cw_isclose(in->events[j], t))
            return 1;
    return 0;
}

/* Samples.at for the targets [from, to): their values at `time`, after an
 * event there when after_event, else before it. */
static void inputs_at(const cw_inputs *in, int from, int to, double time, int after_event, double *out)
{
    const double *t = in->times;
    int n = in->n_times;
    int first = n < 2, i0 = 0;
    if (!first) {
        i0 = bisect_left(t, n, time);
        first = i0 == 0;
    }
    if (first || i0 == n) {
        for (int k = from; k < to; k++)
            out[k] = in->values[(size_t)in->signal[k] * (size_t)n + (size_t)(first ? 0 : n - 1)];
        return;
    }
    int held = i0 - 1;
    if (after_event)
        while (held + 1 < n && (t[held + 1] < time || cw_isclose(time, t[held + 1])))
            held++;
    int row = -1;
    double w0 = 0.0, w1 = 0.0;
    if (cw_isclose(time, t[i0]) && i0 < n - 1 && cw_isclose(t[i0], t[i0 + 1])) {
        row = i0;
        if (after_event)
            while (row < n - 1 && cw_isclose(t[row], t[row + 1]))
                row++;
    } else {
        double t0 = t[i0 - 1], t1 = t[i0];
        w0 = (t1 - time) / (t1 - t0);
        w1 = 1 - w0;
    }
    for (int k = from; k < to; k++) {
        const double *v = &in->values[(size_t)in->signal[k] * (size_t)n];
        if (!in->continuous[in->signal[k]])
            out[k] = v[held];
        else if (row >= 0)
            out[k] = v[row];
        else
            out[k] = w0 * v[i0 - 1] + w1 * v[i0];
    }
}

/* FileInputs.set for port i */
int inputs_set(cw_master *m, int i, double t, int after_event)
{
    const cw_inputs *in = m->inputs;
    int from = in->port_start[i], to = in->port_start[i + 1];
    if (from == to)
        return 0;
    inputs_at(in, from, to, t, after_event, in->value);
    cw_port *p = &m->ports[i];
    int st = p->setReal(p->comp, &in->vr[from], (size_t)(to - from), &in->value[from]);
    if (st > FMI_WARNING)
        return fail(m, i, CALL_SET_INPUTS, st, t, 0.0);
    return 0;
}

/* -- coupling ------------------------------------------------------------- */

void history_forget(cw_master *m)
{
    for (int a = 0; a < m->n_dynamic; a++)
        m->ports[m->dynamic[a]].hist_n = 0;
}

void record_history(cw_master *m)
{
    if (!m->extrapolation)
        return;
    if (m->after_event_step || m->after_event)
        history_forget(m);
    for (int a = 0; a < m->n_dynamic; a++) {
        cw_port *p = &m->ports[m->dynamic[a]];
        if (!p->n_in)
            continue;
        int n = p->hist_n;
        p->hist_t[n] = m->t;
        for (int k = 0; k < p->n_in; k++)
            p->hist_v[n * p->n_in + k] = m->ports[p->src_port[k]].out[p->src_pos[k]];
        n++;
        if (n > HISTORY) {
            memmove(p->hist_t, p->hist_t + 1, (size_t)(n - 1) * sizeof(double));
            memmove(p->hist_v, p->hist_v + p->n_in, (size_t)((n - 1) * p->n_in) * sizeof(double));
            n--;
        }
        p->hist_n = n;
    }
}

/* Fill p->inp (values at t) and p->der (derivatives at t) from the sources. */
static void extrapolate(cw_master *m, cw_port *p, double t)
{
    int order = p->ext_order;
    int n = p->n_in;
    for (int k = 0; k < n; k++) {
        cw_port *src = &m->ports[p->src_port[k]];
        double ta = src->out_time, ua = src->out[p->src_pos[k]];
        double d1 = 0.0, d2 = 0.0;
        if (p->dsrc_port[k] >= 0) {
            cw_port *ds = &m->ports[p->dsrc_port[k]];
            static const int orders[2] = {1, 2};
            double got[2];
            int mm = p->dsrc_m[k] < order ? p->dsrc_m[k] : order;
            if (ds->getOutputDerivatives(ds->comp, &p->dsrc_vr[2 * k], (size_t)mm, orders, got) <= FMI_WARNING) {
                d1 = got[0];
                d2 = mm == 2 ? got[1] : 0.0;
            }
        } else {
            /* Divided differences through the history and the current value. */
            double pt[HISTORY + 1], pu[HISTORY + 1];
            int np = 0;
            for (int a = 0; a < p->hist_n; a++)
                if (p->hist_t[a] < ta - 1e-15) {
                    pt[np] = p->hist_t[a];
                    pu[np] = p->hist_v[a * n + k];
                    np++;
                }
            int keep = np < order ? np : order;
            int from = np - keep;
            for (int a = 0; a < keep; a++) {
                pt[a] = pt[from + a];
                pu[a] = pu[from + a];
            }
            np = keep;
            pt[np] = ta;
            pu[np] = ua;
            np++;
            if (np >= 2) {
                double t1 = pt[np - 2], u1 = pu[np - 2], t2 = pt[np - 1], u2 = pu[np - 1];
                d1 = (u2 - u1) / (t2 - t1);
                if (order >= 2 && np >= 3) {
                    double t0 = pt[np - 3], u0 = pu[np - 3];
                    double d0 = (u1 - u0) / (t1 - t0);
                    d2 = 2.0 * (d1 - d0) / (t2 - t0);
                    d1 += 0.5 * d2 * (t2 - t1);
                }
            }
        }
        double dt = t - ta;
        p->inp[k] = input_polynomial(ua, d1, d2, dt);
        p->der[k] = d1 + d2 * dt;
        p->der[n + k] = d2;
    }
    for (int a = 0; a < p->n_scaled; a++) {
        int k = p->scaled[a];
        double f = p->in_factor[a];
        p->inp[k] = f * p->inp[k] + p->in_offset[a];
        p->der[k] = f * p->der[k];
        p->der[n + k] = f * p->der[n + k];
    }
}

/* Strong coupling: inputs from the step's start, as a line towards the last
 * iterate's end where the FMU can interpolate them (coupling.set_inputs
 * with coupling_end). */
int set_coupled_inputs(cw_master *m, int i, double t, double h)
{
    cw_port *p = &m->ports[i];
    int n = p->n_in;
    memcpy(p->inp, p->it_start, (size_t)n * sizeof(double));
    double end[n > 0 ? n : 1];
    memcpy(end, p->it_end, (size_t)n * sizeof(double));
    for (int a = 0; a < p->n_scaled; a++) {
        int k = p->scaled[a];
        p->inp[k] = p->in_factor[a] * p->inp[k] + p->in_offset[a];
        end[k] = p->in_factor[a] * end[k] + p->in_offset[a];
    }
    int st = p->setReal(p->comp, p->in_vr, (size_t)n, p->inp);
    if (st > FMI_WARNING)
        return fail(m, i, CALL_SET_INPUTS, st, t, h);
    memcpy(p->sent, p->inp, (size_t)n * sizeof(double));
    p->sent_valid = 0;
    if (p->can_interpolate) {
        for (int k = 0; k < n; k++) {
            p->der[k] = (end[k] - p->inp[k]) / h;
            p->der[n + k] = 0.0;
        }
        st = p->setInputDerivatives(p->comp, p->der_vr, (size_t)n, p->der_order, p->der);
        if (st > FMI_WARNING)
            return fail(m, i, CALL_SET_INPUT_DERIVATIVES, st, t, h);
    }
    return 0;
}

/* Inputs of a dynamic instance for the step from t (coupling.set_inputs). */
int set_inputs(cw_master *m, int i, double t, double h, int smooth)
{
    cw_port *p = &m->ports[i];
    int n = p->n_in;
again:
    for (int k = 0; k < n; k++)
        p->inp[k] = m->ports[p->src_port[k]].out[p->src_pos[k]];
    sum_and_scale(m, p);
    int polynomial = p->ext_order && smooth;
    if (polynomial) {
        extrapolate(m, p, t);
    } else if (p->sent_valid) {
        int same = 1;
        for (int k = 0; k < n; k++)
            if (!(p->sent[k] == p->inp[k])) {
                same = 0;
                break;
            }
        if (same)
            return 0;  /* held value unchanged: the FMU already has it */
    }
    int st = p->setReal(p->comp, p->in_vr, (size_t)n, p->inp);
    if (st > FMI_WARNING)
        return fail(m, i, CALL_SET_INPUTS, st, t, h);
    memcpy(p->sent, p->inp, (size_t)n * sizeof(double));
    p->sent_valid = !polynomial;
    if (polynomial) {
        size_t nd = (size_t)n * (p->ext_order >= 2 ? 2 : 1);
        st = p->setInputDerivatives(p->comp, p->der_vr, nd, p->der_order, p->der);
        if (st > FMI_WARNING) {
            if (st >= FMI_FATAL)
                return fail(m, i, CALL_SET_INPUT_DERIVATIVES, st, t, h);
            /* Refused: one order lower, from the same sources, and never again this order. */
            p->ext_order--;
            p->lowered_at = t;
            m->orders_lowered = 1;
            goto again;
        }
    }
    return 0;
}
