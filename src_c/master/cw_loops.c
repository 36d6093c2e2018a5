/* Algebraic loops solved at communication points, as
 * clockwork/engine/loops.py solves them: Gauss-Seidel sweeps, then Newton
 * with a finite-difference Jacobian and halvings (loop_solve); and the
 * outputs handed on in dependency order, a loop where the order names one
 * (propagate, ports.py).
 */

#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "cw_master.h"

/* -- algebraic loops (loops.py) ------------------------------------------------------ */

enum { LOOP_PLAIN_SWEEPS = 50, LOOP_NEWTON_ITERATIONS = 20, LOOP_HALVINGS = 10 };
#define LOOP_FD_STEP 1.4901161193847656e-08  /* 2 ** -26 */
enum { LOOP_NOT_CONVERGED = 0, LOOP_SINGULAR = 1, LOOP_NO_DECREASE = 2, LOOP_NO_MEMORY = 4 };

/* r = what the sources give minus the inputs (x, else those set); the
 * largest |r| into *worst and where into *at (-1: none larger than zero). */
static void loop_residual(cw_master *m, const cw_loop *L, const double *x, double *r, double *worst, int *at)
{
    double w = 0.0;
    int where = -1;
    for (int i = 0; i < L->n; i++) {
        double g = m->ports[L->u_src[i]].out[L->u_src_pos[i]];
        const cw_port *p = &m->ports[L->u_port[i]];
        for (int a = 0; a < p->n_adds; a++)  /* a sum's further terms, in order (sum_and_scale) */
            if (p->add_at[a] == L->u_pos[i])
                g += m->ports[p->add_port[a]].out[p->add_pos[a]];
        if (L->u_scaled[i])
            g = L->u_factor[i] * g + L->u_offset[i];
        r[i] = g - (x ? x[i] : m->ports[L->u_port[i]].inp[L->u_pos[i]]);
        double a = fabs(r[i]);
        if (a > w || a != a) {
            w = a;
            where = i;
        }
    }
    *worst = w;
    *at = where;
}

static int loop_small(cw_master *m, const cw_loop *L, const double *r)
{
    double tol = m->loops->tolerance;
    for (int i = 0; i < L->n; i++)
        if (!(fabs(r[i]) <= tol * py_max(1.0, fabs(m->ports[L->u_port[i]].inp[L->u_pos[i]]))))
            return 0;
    return 1;
}

/* Set the loop's inputs to x, read the members' outputs; r = g(x) - x. */
static int loop_evaluate(cw_master *m, const cw_loop *L, const double *x, double *r, double t,
                         double *worst, int *at)
{
    for (int i = 0; i < L->n; i++)
        m->ports[L->u_port[i]].inp[L->u_pos[i]] = x[i];
    for (int a = 0; a < L->n_members; a++) {
        int i = L->members[a];
        cw_port *p = &m->ports[i];
        if (p->n_in) {
            int st = p->setReal(p->comp, p->in_vr, (size_t)p->n_in, p->inp);
            if (st > FMI_WARNING)
                return fail(m, i, CALL_SET_INPUTS, st, t, 0.0);
            p->sent_valid = 0;
        }
        TRY(port_read(m, i, t));
    }
    loop_residual(m, L, x, r, worst, at);
    return 0;
}

/* Gaussian elimination with partial pivoting (loops.solve_linear). */
static int solve_linear(double *a, double *b, int n)
{
    for (int c = 0; c < n; c++) {
        int piv = c;
        double best = fabs(a[c * n + c]);
        for (int row = c + 1; row < n; row++) {
            double v = fabs(a[row * n + c]);
            if (v > best) {
                piv = row;
                best = v;
            }
        }
        if (!(best > 0.0 && best < INFINITY))
            return 0;
        if (piv != c) {
            for (int k = 0; k < n; k++) {
                double tmp = a[c * n + k];
                a[c * n + k] = a[piv * n + k];
                a[piv * n + k] = tmp;
            }
            double tmp = b[c];
            b[c] = b[piv];
            b[piv] = tmp;
        }
        for (int row = c + 1; row < n; row++) {
            double f = a[row * n + c] / a[c * n + c];
            for (int k = c; k < n; k++)
                a[row * n + k] = a[row * n + k] - f * a[c * n + k];
            b[row] = b[row] - f * b[c];
        }
    }
    for (int row = n - 1; row >= 0; row--) {
        double s = b[row];
        for (int k = row + 1; k < n; k++)
            s = s - a[row * n + k] * b[k];
        b[row] = s / a[row * n + row];
    }
    return 1;
}

static int loop_fail(cw_master *m, int i, cw_loop *L, int why, double worst, int at, int sweeps, int newton,
                     double t)
{
    L->fail_why = why;
    L->fail_worst = worst;
    L->fail_at = at;
    L->fail_sweeps = sweeps;
    L->fail_newton = newton;
    m->err_port = i;
    m->err_t = t;
    return CW_ERR_LOOP;
}

static int newton_iterate(cw_master *m, int li, cw_loop *L, double t, int sweeps, double *work);

/* Newton's work arrays (5 n + n * n doubles) are taken only when a loop
 * needs the fallback, and given back after it: a large formal loop never
 * pays for an n x n Jacobian. */
static int loop_newton(cw_master *m, int li, cw_loop *L, double t, int sweeps, double worst)
{
    size_t n = (size_t)L->n;
    double *work = malloc((5 * n + n * n) * sizeof(double) + 1);
    if (!work)
        return loop_fail(m, li, L, LOOP_NO_MEMORY, worst, -1, sweeps, 0, t);
    int rc = newton_iterate(m, li, L, t, sweeps, work);
    free(work);
    return rc;
}

static int newton_iterate(cw_master *m, int li, cw_loop *L, double t, int sweeps, double *work)
{
    int n = L->n;
    double *x = work, *xn = work + n, *r = work + 2 * n, *rj = work + 3 * n, *dx = work + 4 * n;
    double *jac = work + 5 * n;
    double worst, worst_n = 0.0;
    int at, at_n = -1;
    for (int i = 0; i < n; i++)
        x[i] = m->ports[L->u_port[i]].inp[L->u_pos[i]];
    TRY(loop_evaluate(m, L, x, r, t, &worst, &at));
    int iterations = 0;
    while (!loop_small(m, L, r)) {
        if (iterations == LOOP_NEWTON_ITERATIONS)
            return loop_fail(m, li, L, LOOP_NOT_CONVERGED, worst, at, sweeps, iterations, t);
        iterations++;
        m->loops->iterations++;
        for (int j = 0; j < n; j++) {
            double xj = x[j];
            x[j] = xj + LOOP_FD_STEP * py_max(1.0, fabs(xj));
            double d = x[j] - xj;
            double w;
            int a;
            TRY(loop_evaluate(m, L, x, rj, t, &w, &a));
            x[j] = xj;
            for (int i = 0; i < n; i++)
                jac[i * n + j] = (rj[i] - r[i]) / d;
        }
        for (int i = 0; i < n; i++)
            dx[i] = -r[i];
        if (!solve_linear(jac, dx, n))
            return loop_fail(m, li, L, LOOP_SINGULAR, worst, at, sweeps, iterations, t);
        double lam = 1.0;
        int accepted = 0;
        for (int h = 0; h < LOOP_HALVINGS; h++) {
            for (int i = 0; i < n; i++)
                xn[i] = x[i] + lam * dx[i];
            TRY(loop_evaluate(m, L, xn, rj, t, &worst_n, &at_n));
            if (worst_n < worst) {
                accepted = 1;
                break;
            }
            lam *= 0.5;
        }
        if (!accepted)
            return loop_fail(m, li, L, LOOP_NO_DECREASE, worst, at, sweeps, iterations, t);
        double *swap = x;
        x = xn;
        xn = swap;
        swap = r;
        r = rj;
        rj = swap;
        worst = worst_n;
        at = at_n;
    }
    return 0;
}

/* Loop i's inputs to a fixed point at t: Gauss-Seidel sweeps over its
 * members, then Newton's method where they do not contract (Loop.solve). */
int loop_solve(cw_master *m, int i, double t)
{
    cw_loop *L = &m->loops->loop[i];
    double prev = INFINITY, worst = 0.0;
    int at = -1, sweeps = 0;
    while (sweeps < LOOP_PLAIN_SWEEPS) {
        for (int a = 0; a < L->n_members; a++)
            TRY(port_pull(m, L->members[a], t));
        sweeps++;
        m->loops->iterations++;
        loop_residual(m, L, NULL, L->r, &worst, &at);
        if (loop_small(m, L, L->r))
            return 0;
        if (!(worst < prev))
            break;  /* not contracting: growing, stalled or NaN */
        prev = worst;
    }
    m->loops->fallbacks++;
    return loop_newton(m, i, L, t, sweeps, worst);
}

/* The order's entries in turn: an instance's inputs pulled from its
 * sources and its outputs read, or (an entry -k - 1) loop k solved. */
int propagate(cw_master *m, const int *order, int n, double t)
{
    for (int a = 0; a < n; a++) {
        if (order[a] < 0)
            TRY(loop_solve(m, -order[a] - 1, t));
        else
            TRY(port_pull(m, order[a], t));
    }
    return 0;
}
