/* Connected Model Exchange FMUs as one FMU of the Model Exchange wrapper
 * (cw_me.c): the twin of engine/me_group.py's MEGroup calls, operation for
 * operation, so that both engines give the same bits.
 *
 * cwmg_bind points a group's cw_me at its cw_me_group: the wrapper's one
 * integrator (the Runge-Kutta pairs or CVode), its event location and
 * event iteration, and the master's calls then run over the members'
 * concatenated states and indicators. Each call here goes to every member
 * through the member's own cw_me (its FMU's functions and its table of
 * calls whose shape differs); the connections between members are
 * evaluated, in dependency order, before any member is read after a time,
 * states or values were set (in continuous-time mode those into
 * continuous inputs only), and around every member's discrete update in an
 * event iteration, which goes on while a connected value changes. Real
 * connections go through the members' calls tables; Integer and Boolean
 * ones through the get and set of their type that Python hands over with
 * the shape of a value in them (CW_VALUE_*), never asking a version.
 *
 * Python owns every array and fills the struct (me_group._Group).
 */

#include <math.h>
#include <string.h>

#include "cw_me.h"

#define CW_EXPORT __attribute__((visibility("default")))

enum { FMI_OK = 0, FMI_WARNING = 1 };
enum { CONTINUOUS = 2 };

static int worse(int a, int b) { return b > a ? b : a; }

static cw_me *member(const cw_me_group *g, int i) { return ((cw_me *const *)g->members)[i]; }

static void **member_state(const cw_me_group *g, int i) { return ((void **const *)g->member_state)[i]; }

typedef int (*get_value_t)(void *, const unsigned *, size_t, void *);
typedef int (*get_values_t)(void *, const unsigned *, size_t, void *, size_t);
typedef int (*set_value_t)(void *, const unsigned *, size_t, const void *);
typedef int (*set_values_t)(void *, const unsigned *, size_t, const void *, size_t);

typedef union {
    unsigned char byte;
    int i32;
    long long i64;
} raw_value;

/* A discrete value through the FMU function `fn` of its shape (CW_VALUE_*). */
static int get_discrete(cw_me *m, void *fn, int shape, const unsigned *vr, long long *value)
{
    raw_value raw;
    memset(&raw, 0, sizeof raw);
    int st = shape & CW_VALUE_COUNTED ? ((get_values_t)fn)(m->instance, vr, 1, &raw, 1)
                                      : ((get_value_t)fn)(m->instance, vr, 1, &raw);
    int size = shape & CW_VALUE_SIZE;
    *value = size == 1 ? raw.byte : size == 4 ? raw.i32 : raw.i64;
    if (shape & CW_VALUE_BOOLEAN)
        *value = *value != 0;
    return st;
}

static int set_discrete(cw_me *m, void *fn, int shape, const unsigned *vr, long long value)
{
    raw_value raw;
    memset(&raw, 0, sizeof raw);
    if (shape & CW_VALUE_BOOLEAN)
        value = value != 0;
    int size = shape & CW_VALUE_SIZE;
    if (size == 1)
        raw.byte = (unsigned char)value;
    else if (size == 4)
        raw.i32 = (int)value;
    else
        raw.i64 = value;
    return shape & CW_VALUE_COUNTED ? ((set_values_t)fn)(m->instance, vr, 1, &raw, 1)
                                    : ((set_value_t)fn)(m->instance, vr, 1, &raw);
}

/* An Integer or Boolean connection (in event and initialization mode). */
static int propagate_discrete(cw_me_group *g, int k, int *changed)
{
    cw_me *src = member(g, g->c_src[k]), *dst = member(g, g->c_dst[k]);
    void *get = ((void *const *)g->c_get)[k], *set = ((void *const *)g->c_set)[k];
    long long value;
    int st = get_discrete(src, get, g->c_get_shape[k], &g->c_src_vr[k], &value);
    if (st > FMI_WARNING)
        return st;
    if (g->c_has_last[k] && value == g->c_last_int[k])
        return FMI_OK;
    st = set_discrete(dst, set, g->c_set_shape[k], &g->c_dst_vr[k], value);
    if (st > FMI_WARNING)
        return st;
    *changed = *changed || g->c_has_last[k];
    g->c_last_int[k] = value;
    g->c_has_last[k] = 1;
    return FMI_OK;
}

/* The connections in dependency order (_propagate): `every` in event and
 * initialization mode, else those into continuous inputs; *changed: a
 * value set before changed. */
static int propagate(cw_me_group *g, int every, int *changed)
{
    *changed = 0;
    for (int k = 0; k < g->n_conns; k++) {
        if (!(every || g->c_continuous[k]))
            continue;
        if (((void *const *)g->c_get)[k]) {
            int st = propagate_discrete(g, k, changed);
            if (st > FMI_WARNING)
                return st;
            continue;
        }
        cw_me *src = member(g, g->c_src[k]), *dst = member(g, g->c_dst[k]);
        double value;
        int st = CWME_CALLS(src)->get_real(src, &g->c_src_vr[k], 1, &value);
        if (st > FMI_WARNING)
            return st;
        if (!g->c_identity[k])
            value = g->c_factor[k] * value + g->c_offset[k];
        if (!g->c_has_last[k] || value != g->c_last[k]) {
            st = CWME_CALLS(dst)->set_real(dst, &g->c_dst_vr[k], 1, &value);
            if (st > FMI_WARNING)
                return st;
            *changed = *changed || g->c_has_last[k];
            g->c_last[k] = value;
            g->c_has_last[k] = 1;
        }
    }
    g->dirty = 0;
    return FMI_OK;
}

/* The connections up to date before a member is read (_fresh). */
static int fresh(cw_me_group *g)
{
    int changed;
    return g->dirty ? propagate(g, g->me->mode != CONTINUOUS, &changed) : FMI_OK;
}

/* ---- the FMU functions the wrapper calls on its instance: the group ---- */

static int group_set_time(void *group, double t)
{
    cw_me_group *g = group;
    g->dirty = 1;
    int st = FMI_OK;
    for (int i = 0; i < g->n_members; i++) {
        cw_me *m = member(g, i);
        st = worse(st, ((set_time_t)m->setTime)(m->instance, t));
        if (st > FMI_WARNING)
            return st;
    }
    return st;
}

static int group_set_states(void *group, const double *x, size_t n)
{
    cw_me_group *g = group;
    (void)n;
    g->dirty = 1;
    int st = FMI_OK;
    for (int i = 0; i < g->n_members; i++) {
        cw_me *m = member(g, i);
        int off = g->offsets[4 * i], mn = g->offsets[4 * i + 1];
        if (!mn)
            continue;
        memcpy(m->xbuf, x + off, (size_t)mn * sizeof(double));
        st = worse(st, ((set_vector_t)m->setStates)(m->instance, m->xbuf, (size_t)mn));
        if (st > FMI_WARNING)
            return st;
    }
    return st;
}

/* Each member's vector (derivatives, states, nominals: `which` its cw_me's
 * function, `scratch` its buffer) into the group's at the member's offset;
 * `part` 0 for states, 2 for indicators. */
static int gather(cw_me_group *g, double *out, size_t which, size_t scratch, int part)
{
    int st = FMI_OK;
    for (int i = 0; i < g->n_members; i++) {
        cw_me *m = member(g, i);
        int off = g->offsets[4 * i + part], mn = g->offsets[4 * i + part + 1];
        if (!mn)
            continue;
        vector_t fn = (vector_t)*(void **)((char *)m + which);
        double *buf = *(double **)((char *)m + scratch);
        st = worse(st, fn(m->instance, buf, (size_t)mn));
        if (st > FMI_WARNING)
            return st;
        memcpy(out + off, buf, (size_t)mn * sizeof(double));
    }
    return st;
}

/* gather, after the connections are brought up to date: what follows the inputs. */
static int gather_fresh(cw_me_group *g, double *out, size_t which, size_t scratch, int part)
{
    int st = fresh(g);
    return st > FMI_WARNING ? st : gather(g, out, which, scratch, part);
}

static int group_get_derivatives(void *group, double *dx, size_t n)
{
    (void)n;
    return gather_fresh(group, dx, offsetof(cw_me, getDerivatives), offsetof(cw_me, dx), 0);
}

static int group_get_indicators(void *group, double *z, size_t nz)
{
    (void)nz;
    return gather_fresh(group, z, offsetof(cw_me, getIndicators), offsetof(cw_me, z), 2);
}

static int group_get_states(void *group, double *x, size_t n)
{
    (void)n;
    return gather(group, x, offsetof(cw_me, getStates), offsetof(cw_me, xw), 0);
}

static int group_get_nominals(void *group, double *x, size_t n)
{
    (void)n;
    return gather(group, x, offsetof(cw_me, getNominals), offsetof(cw_me, nominal), 0);
}

/* Every member's mode call (`which` its cw_me's function). */
static int each_mode(cw_me_group *g, size_t which)
{
    g->dirty = 1;
    int st = FMI_OK;
    for (int i = 0; i < g->n_members; i++) {
        cw_me *m = member(g, i);
        st = worse(st, ((mode_t_)*(void **)((char *)m + which))(m->instance));
        if (st > FMI_WARNING)
            return st;
    }
    return st;
}

static int group_enter_event(void *group) { return each_mode(group, offsetof(cw_me, enterEventMode)); }

static int group_enter_continuous(void *group) { return each_mode(group, offsetof(cw_me, enterContinuousMode)); }

/* Every member's FMU state, each in its own place (the group's `state` is not used). */
static int group_get_state(void *group, void **state)
{
    cw_me_group *g = group;
    (void)state;
    int st = FMI_OK;
    for (int i = 0; i < g->n_members; i++) {
        cw_me *m = member(g, i);
        st = worse(st, ((get_state_t)m->getState)(m->instance, member_state(g, i)));
        if (st > FMI_WARNING)
            return st;
    }
    return st;
}

static int group_set_state(void *group, void *state)
{
    cw_me_group *g = group;
    (void)state;
    g->dirty = 1;
    for (int k = 0; k < g->n_conns; k++)
        g->c_has_last[k] = 0; /* the members' inputs come back with them: set again */
    int st = FMI_OK;
    for (int i = 0; i < g->n_members; i++) {
        cw_me *m = member(g, i);
        st = worse(st, ((set_state_t)m->setState)(m->instance, *member_state(g, i)));
        if (st > FMI_WARNING)
            return st;
    }
    return st;
}

/* ---- the group's table of calls (cw_me.h) ---- */

static int group_get_real(cw_me *me, const unsigned *vr, size_t n, double *out)
{
    cw_me_group *g = me->instance;
    int st = fresh(g);
    if (st > FMI_WARNING)
        return st;
    for (size_t j = 0; j < n; j++) {
        cw_me *m = member(g, g->vr_member[vr[j]]);
        double one;
        st = worse(st, CWME_CALLS(m)->get_real(m, &g->vr_own[vr[j]], 1, &one));
        if (st > FMI_WARNING)
            return st;
        out[j] = one;
    }
    return st;
}

static int group_set_real(cw_me *me, const unsigned *vr, size_t n, const double *values)
{
    cw_me_group *g = me->instance;
    g->dirty = 1;
    int st = FMI_OK;
    for (size_t j = 0; j < n; j++) {
        cw_me *m = member(g, g->vr_member[vr[j]]);
        st = worse(st, CWME_CALLS(m)->set_real(m, &g->vr_own[vr[j]], 1, &values[j]));
        if (st > FMI_WARNING)
            return st;
    }
    return st;
}

static int group_completed(cw_me *me, int *enter, int *terminate)
{
    cw_me_group *g = me->instance;
    int st = FMI_OK;
    *enter = *terminate = 0;
    for (int i = 0; i < g->n_members; i++) {
        cw_me *m = member(g, i);
        if (!m->needs_completed)
            continue;
        int e = 0, t = 0;
        int s = CWME_CALLS(m)->completed(m, &e, &t);
        st = worse(st, s);
        if (s > FMI_WARNING) {
            *enter = *terminate = 0;
            return st;
        }
        *enter = *enter || e;
        *terminate = *terminate || t;
    }
    return st;
}

/* One event iteration across the members (_g_update): the connections,
 * every member's update, the connections again; another iteration where
 * a member asks for one or a connected value changed. */
static int group_update(cw_me *me, event_info2 *info)
{
    cw_me_group *g = me->instance;
    int changed;
    int st = propagate(g, 1, &changed);
    if (st > FMI_WARNING)
        return st;
    event_info2 all = {0, 0, 0, 0, 0, INFINITY};
    for (int i = 0; i < g->n_members; i++) {
        cw_me *m = member(g, i);
        event_info2 e = {0, 0, 0, 0, 0, 0.0};
        int s = CWME_CALLS(m)->update(m, &e);
        st = worse(st, s);
        if (s > FMI_WARNING)
            return st;
        all.need = all.need || e.need;
        all.terminate = all.terminate || e.terminate;
        all.nominals = all.nominals || e.nominals;
        all.values = all.values || e.values;
        if (e.defined) {
            all.defined = 1;
            if (e.next_time < all.next_time)
                all.next_time = e.next_time;
        }
    }
    int s = propagate(g, 1, &changed);
    st = worse(st, s);
    all.need = all.need || changed;
    *info = all;
    return st;
}

CW_EXPORT const cw_me_calls cwmg_calls = {group_get_real, group_set_real, group_completed, group_update};

/* The group's wrapper calls the group: its instance and functions. */
CW_EXPORT void cwmg_bind(cw_me *me, cw_me_group *g)
{
    g->me = me;
    me->instance = g;
    me->setTime = (void *)group_set_time;
    me->setStates = (void *)group_set_states;
    me->getDerivatives = (void *)group_get_derivatives;
    me->getIndicators = (void *)group_get_indicators;
    me->getStates = (void *)group_get_states;
    me->getNominals = (void *)group_get_nominals;
    me->enterEventMode = (void *)group_enter_event;
    me->enterContinuousMode = (void *)group_enter_continuous;
    me->getState = (void *)group_get_state;
    me->setState = (void *)group_set_state;
    me->completedStep = me->update = me->getReal = me->setReal = NULL; /* through cwmg_calls */
}
