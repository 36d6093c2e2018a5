/* The FMU log messages: what the master hands an FMU as its logger, made
 * safe against an FMU that breaks the rules.
 *
 * The FMI 2.0 logger (cw_logger). An FMU passes back whatever it likes as
 * componentEnvironment (an Overture FMU passes 1), an instance name, a
 * category and a printf format that may be NULL, point nowhere, or ask for
 * arguments it does not pass. Nothing the FMU passes is called or read
 * directly: the environment is looked up in a registry of the live sinks
 * (cw_env_register), strings are copied by the crash guard's safe read
 * (cw_guard.c: an unreadable address is an error, not a fault) and the
 * format is interpreted here, one conversion at a time, %s reading its
 * argument the same way and %n writing nothing. A message reaches the
 * instance its environment names, or the one its instance name names, else
 * the fallback sink: never a crash, never silently dropped.
 *
 * The registry is behind one recursive mutex of its own; the crash guard's
 * is taken under it (a safe read in a nested message), never the other way
 * round. The FMUs keep no global state.
 */

#define _GNU_SOURCE
#include <errno.h>
#include <pthread.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cw_guard.h"

#define CW_EXPORT __attribute__((visibility("default")))

/* What cw_logger hands the formatted message to: the instance name as the
 * FMU gave it (copied), the status, the category and the text. */
typedef void (*cw_log_sink_t)(const char *instance, int status, const char *category, const char *text);

enum { NAME_CAP = 256, TEXT_CAP = 65536, ARG_CAP = 8192 };

/* The registry's, recursive: a sink may lead to another message. */
static pthread_mutex_t lock = PTHREAD_RECURSIVE_MUTEX_INITIALIZER_NP;

/* ---- a printf that trusts neither the format nor the arguments ----------- */

typedef struct {
    char *buf;
    size_t cap, len;
} out_t;

static void put(out_t *o, const char *s, size_t n)
{
    if (o->len + 1 >= o->cap)
        return;
    size_t room = o->cap - 1 - o->len;
    if (n > room)
        n = room;
    memcpy(o->buf + o->len, s, n);
    o->len += n;
    o->buf[o->len] = '\0';
}

static void put_formatted(out_t *o, const char *spec, ...)
{
    if (o->len + 1 >= o->cap)
        return;
    va_list ap;
    va_start(ap, spec);
    int n = vsnprintf(o->buf + o->len, o->cap - o->len, spec, ap);
    va_end(ap);
    if (n > 0)
        o->len += (size_t)n < o->cap - o->len ? (size_t)n : o->cap - o->len - 1;
}

/* A width or precision read from the format or an argument, bounded. */
static int bounded(long v) { return v < 0 ? 0 : v > 4096 ? 4096 : (int)v; }

/* Format `fmt` (already copied out of the FMU) with `ap` into o. Each
 * conversion is rebuilt from its parsed parts and formatted alone; %s
 * reads its argument with safe_string, %n is skipped, and a conversion
 * this does not know (or positional arguments) ends the formatting: the
 * rest of the format is handed on as it is. */
static void safe_format(out_t *o, const char *fmt, va_list ap)
{
    const char *p = fmt, *rest = NULL;
    while (*p && !rest) {
        const char *pct = strchr(p, '%');
        if (!pct) {
            put(o, p, strlen(p));
            return;
        }
        put(o, p, (size_t)(pct - p));
        const char *q = pct + 1;
        if (*q == '%') {
            put(o, "%", 1);
            p = q + 1;
            continue;
        }
        char flags[8];
        int nf = 0;
        while (*q && strchr("-+ #0", *q) && nf < 7)
            flags[nf++] = *q++;
        flags[nf] = '\0';
        int width = -1, prec = -1;
        if (*q == '*') {
            width = va_arg(ap, int);
            if (width < 0) {  /* a negative width is a '-' flag */
                width = -width;
                if (nf < 7) {
                    flags[nf++] = '-';
                    flags[nf] = '\0';
                }
            }
            width = bounded(width);
            q++;
        } else if (*q >= '0' && *q <= '9') {
            long w = 0;
            while (*q >= '0' && *q <= '9')
                w = w > 100000 ? w : w * 10 + (*q++ - '0');
            if (*q == '$') {
                rest = pct;  /* positional arguments: not interpreted */
                break;
            }
            width = bounded(w);
        }
        if (*q == '.') {
            q++;
            if (*q == '*') {
                int pr = va_arg(ap, int);
                prec = pr < 0 ? -1 : bounded(pr);
                q++;
            } else {
                long pr = 0;
                while (*q >= '0' && *q <= '9')
                    pr = pr > 100000 ? pr : pr * 10 + (*q++ - '0');
                prec = bounded(pr);
            }
        }
        char len[3] = {0};
        if ((q[0] == 'h' && q[1] == 'h') || (q[0] == 'l' && q[1] == 'l')) {
            len[0] = q[0];
            len[1] = q[1];
            q += 2;
        } else if (*q == 'q') {  /* BSD's ll */
            len[0] = len[1] = 'l';
            q++;
        } else if (*q && strchr("hlLjzt", *q)) {
            len[0] = *q++;
        }
        char conv = *q;
        if (!conv || !strchr("diouxXcspneEfFgGaAm", conv)) {
            rest = pct;
            break;
        }
        q++;
        /* The spec rebuilt: flags, width and precision as numbers. */
        char spec[48], wp[32] = "";
        if (width >= 0 && prec >= 0)
            snprintf(wp, sizeof wp, "%d.%d", width, prec);
        else if (width >= 0)
            snprintf(wp, sizeof wp, "%d", width);
        else if (prec >= 0)
            snprintf(wp, sizeof wp, ".%d", prec);
        switch (conv) {
        case 'd': case 'i': case 'o': case 'u': case 'x': case 'X': {
            int is_signed = conv == 'd' || conv == 'i';
            if (len[0] == 'l' && len[1] == 'l') {
                snprintf(spec, sizeof spec, "%%%s%sll%c", flags, wp, conv);
                if (is_signed) put_formatted(o, spec, va_arg(ap, long long));
                else put_formatted(o, spec, va_arg(ap, unsigned long long));
            } else if (len[0] == 'l' || len[0] == 'j' || len[0] == 'z' || len[0] == 't') {
                snprintf(spec, sizeof spec, "%%%s%sl%c", flags, wp, conv);
                if (is_signed) put_formatted(o, spec, va_arg(ap, long));
                else put_formatted(o, spec, va_arg(ap, unsigned long));
            } else {
                snprintf(spec, sizeof spec, "%%%s%s%s%c", flags, wp, len[0] == 'h' ? len : "", conv);
                if (is_signed) put_formatted(o, spec, va_arg(ap, int));
                else put_formatted(o, spec, va_arg(ap, unsigned));
            }
            break;
        }
        case 'c':
            snprintf(spec, sizeof spec, "%%%s%sc", flags, width >= 0 ? wp : "");
            put_formatted(o, spec, (int)(unsigned char)va_arg(ap, int));
            break;
        case 'p':
            snprintf(spec, sizeof spec, "%%%s%sp", flags, width >= 0 ? wp : "");
            put_formatted(o, spec, va_arg(ap, void *));
            break;
        case 'n':
            (void)va_arg(ap, void *);  /* never written through */
            break;
        case 'm':
            put_formatted(o, "%s", strerror(errno));
            break;
        case 's': {
            const char *arg = va_arg(ap, const char *);
            char copy[ARG_CAP];
            const char *text;
            if (len[0] == 'l')
                text = "(wide string)";
            else if (!arg)
                text = "(null)";
            else if (prec == 0)
                text = "";
            else {
                size_t cap = prec >= 0 && (size_t)prec + 1 < sizeof copy ? (size_t)prec + 1 : sizeof copy;
                text = cw_safe_string(copy, cap, arg) < 0 ? "(unreadable string)" : copy;
            }
            char w[16] = "";
            if (width >= 0)
                snprintf(w, sizeof w, "%d", width);
            snprintf(spec, sizeof spec, "%%%s%ss", flags, w);
            put_formatted(o, spec, text);
            break;
        }
        default:  /* the floating-point conversions */
            if (len[0] == 'L') {
                snprintf(spec, sizeof spec, "%%%s%sL%c", flags, wp, conv);
                put_formatted(o, spec, va_arg(ap, long double));
            } else {
                snprintf(spec, sizeof spec, "%%%s%s%c", flags, wp, conv);
                put_formatted(o, spec, va_arg(ap, double));
            }
        }
        p = q;
    }
    if (rest)  /* from a conversion this does not interpret on, as it is */
        put(o, rest, strlen(rest));
}

/* ---- the registry of live environments ------------------------------------ */

typedef struct {
    const void *key;     /* what the FMU was given as its environment */
    cw_log_sink_t sink;  /* NULL: an environment without a logger sink */
    char *name;          /* the instance name it was given */
} cw_env;

static cw_env *envs;
static size_t n_envs, cap_envs;
static cw_log_sink_t fallback;

/* Register `key` as a live environment of instance `name`, with `sink` for
 * its log messages: 0, or -1 when out of memory. */
CW_EXPORT int cw_env_register(const void *key, const char *name, cw_log_sink_t sink)
{
    int rc = -1;
    pthread_mutex_lock(&lock);
    if (n_envs == cap_envs) {
        size_t cap = cap_envs ? 2 * cap_envs : 16;
        cw_env *grown = realloc(envs, cap * sizeof *grown);
        if (!grown)
            goto out;
        envs = grown;
        cap_envs = cap;
    }
    char *copy = strdup(name ? name : "");
    if (!copy)
        goto out;
    envs[n_envs++] = (cw_env){key, sink, copy};
    rc = 0;
out:
    pthread_mutex_unlock(&lock);
    return rc;
}

/* Forget `key` (an instance freed): later messages through it go to the fallback. */
CW_EXPORT void cw_env_unregister(const void *key)
{
    pthread_mutex_lock(&lock);
    for (size_t k = 0; k < n_envs; k++)
        if (envs[k].key == key) {
            free(envs[k].name);
            envs[k] = envs[--n_envs];
            break;
        }
    pthread_mutex_unlock(&lock);
}

/* Where messages go whose environment and instance name are no live instance's. */
CW_EXPORT void cw_env_fallback(cw_log_sink_t sink)
{
    pthread_mutex_lock(&lock);
    fallback = sink;
    pthread_mutex_unlock(&lock);
}

/* Whether `key` is a live environment (call with the lock held). */
static const cw_env *find_env(const void *key)
{
    if (!key)
        return NULL;
    for (size_t k = 0; k < n_envs; k++)
        if (envs[k].key == key)
            return &envs[k];
    return NULL;
}

CW_EXPORT int cw_env_known(const void *key)
{
    pthread_mutex_lock(&lock);
    int known = find_env(key) != NULL;
    pthread_mutex_unlock(&lock);
    return known;
}

/* The sink for a message (call with the lock held): the environment's
 * when it is live and its name agrees; else the one live instance of that
 * name (an FMU that passed another instance's environment, or none); else
 * the live environment's; else the fallback. */
static cw_log_sink_t route(const void *env, const char *name, int name_known)
{
    const cw_env *e = find_env(env);
    if (e && e->sink && (!name_known || strcmp(e->name, name) == 0))
        return e->sink;
    if (name_known) {
        const cw_env *only = NULL;
        int count = 0;
        for (size_t k = 0; k < n_envs; k++)
            if (envs[k].sink && strcmp(envs[k].name, name) == 0) {
                only = &envs[k];
                count++;
            }
        if (count == 1)
            return only->sink;
    }
    if (e && e->sink)
        return e->sink;
    return fallback;
}

/* The fmi2CallbackLogger of every FMI 2.0 instance: an FMU's message is a
 * printf format with arguments (FMI 2.0, 2.1.5), which ctypes cannot reach.
 * The lock is held while the sink runs, so that no instance is forgotten
 * (and its sink freed) under a message; it is recursive, for a sink that
 * leads to another message. */
CW_EXPORT void cw_logger(void *env, const char *instance, int status, const char *category,
                         const char *message, ...)
{
    char name[NAME_CAP], cat[NAME_CAP];
    char *text = malloc(2 * TEXT_CAP), *format = text ? text + TEXT_CAP : NULL;
    int name_known = cw_safe_string(name, sizeof name, instance) >= 0;
    if (cw_safe_string(cat, sizeof cat, category) < 0)
        cat[0] = '\0';
    const char *shown;
    if (!message)
        shown = "";
    else if (!text)
        shown = "(out of memory for the FMU's message)";
    else if (cw_safe_string(format, TEXT_CAP, message) < 0)
        shown = "(the FMU logged an unreadable message)";
    else {
        out_t o = {text, TEXT_CAP, 0};
        text[0] = '\0';
        va_list ap;
        va_start(ap, message);
        safe_format(&o, format, ap);
        va_end(ap);
        shown = text;
    }
    pthread_mutex_lock(&lock);
    cw_log_sink_t sink = route(env, name, name_known);
    if (sink)
        sink(name_known ? name : NULL, status, cat, shown);
    pthread_mutex_unlock(&lock);
    free(text);
}

/* A string an FMU passed (an FMI 3.0 or 1.0 message, whose callbacks
 * Python serves): copied into dst (cap bytes) without trusting it; its
 * length, or -1 when NULL or unreadable. */
CW_EXPORT long cw_read_string(const char *src, char *dst, size_t cap)
{
    if (!dst || cap == 0)
        return -1;
    return cw_safe_string(dst, cap, src);
}
