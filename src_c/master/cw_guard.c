/* What the master hands an FMU, made safe against an FMU that breaks the
 * rules, and what catches an FMU that crashes.
 *
 * 1. The FMI 2.0 logger (cw_logger). An FMU passes back whatever it likes as
 *    componentEnvironment (an Overture FMU passes 1), an instance name, a
 *    category and a printf format that may be NULL, point nowhere, or ask
 *    for arguments it does not pass. Nothing the FMU passes is called or
 *    read directly: the environment is looked up in a registry of the live
 *    sinks (cw_env_register), strings are copied through the kernel
 *    (process_vm_readv: an unreadable address is an error, not a fault) and
 *    the format is interpreted here, one conversion at a time, %s reading
 *    its argument the same way and %n writing nothing. A message reaches
 *    the instance its environment names, or the one its instance name
 *    names, else the fallback sink: never a crash, never silently dropped.
 *
 * 2. A fatal signal (SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT) inside an
 *    FMU's own code (cw_crash_install): the handler finds the FMU and the
 *    FMI call from the frames of the crashed thread with dladdr (Python
 *    registers each FMU binary) and returns into the master's or ctypes'
 *    frame as if the call had returned fmi2Fatal, so the run fails as for
 *    any error, its history kept; where it cannot (below) it parks the
 *    thread and the watchdog thread ends the run. A crash outside any FMU,
 *    or a second one, keeps the signal's earlier action (a core dump is the
 *    right report of a bug of clockwork's own). Nothing runs per FMI call:
 *    the cost is the handler's installation, once.
 *
 * The registry is the master library's only mutable global state, behind
 * one mutex; the FMUs keep none.
 */

#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <execinfo.h>
#include <fcntl.h>
#include <limits.h>
#include <pthread.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <sys/uio.h>
#include <time.h>
#include <ucontext.h>
#include <unistd.h>

#define CW_EXPORT __attribute__((visibility("default")))

/* What cw_logger hands the formatted message to: the instance name as the
 * FMU gave it (copied), the status, the category and the text. */
typedef void (*cw_log_sink_t)(const char *instance, int status, const char *category, const char *text);

enum { NAME_CAP = 256, TEXT_CAP = 65536, ARG_CAP = 8192 };

/* ---- reading what an FMU points at, without trusting it ------------------ */

static pthread_mutex_t lock = PTHREAD_RECURSIVE_MUTEX_INITIALIZER_NP;
static int probe[2] = {-1, -1};  /* a pipe, where process_vm_readv is refused */

/* Copy up to n bytes at src into dst through the kernel: the bytes copied
 * (fewer at the first unreadable page), -1 when none could be read. */
static long read_remote(char *dst, const char *src, size_t n)
{
    struct iovec local = {dst, n}, remote = {(void *)src, n};
    ssize_t got = process_vm_readv(getpid(), &local, 1, &remote, 1, 0);
    if (got >= 0 || (errno != ENOSYS && errno != EPERM))
        return got > 0 ? (long)got : -1;
    /* A sandbox that refuses the call: write() through a pipe reads the
     * memory in the kernel too (EFAULT), one page at most at a time. */
    pthread_mutex_lock(&lock);
    long done = -1;
    if (probe[0] >= 0 || pipe2(probe, O_CLOEXEC) == 0) {
        ssize_t w = write(probe[1], src, n);
        if (w > 0) {
            ssize_t r = read(probe[0], dst, (size_t)w);
            done = r > 0 ? (long)r : -1;
        }
    }
    pthread_mutex_unlock(&lock);
    return done;
}

/* Reading directly, under the crash handler (cw_crash_install): a fault
 * while `probing` jumps back to probe_env. A system call per string
 * (process_vm_readv, some microseconds) is kept for when the handler is not
 * installed, or is no longer the one in place (checked every 0.1 s at
 * most). All of it with `lock` held. */
static void on_fatal(int sig, siginfo_t *si, void *context);
static volatile sig_atomic_t probing;
static pthread_t probe_thread;
static sigjmp_buf probe_env;
static int handler_installed;
static struct timespec handler_checked;

static int direct_reads(void)
{
    if (!handler_installed)
        return 0;
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    double age = (double)(now.tv_sec - handler_checked.tv_sec) + 1e-9 * (double)(now.tv_nsec - handler_checked.tv_nsec);
    if (handler_checked.tv_sec && age >= 0 && age < 0.1)
        return 1;
    const int faults[] = {SIGSEGV, SIGBUS};
    for (int k = 0; k < 2; k++) {
        struct sigaction cur;
        if (sigaction(faults[k], NULL, &cur) != 0 || !(cur.sa_flags & SA_SIGINFO) || cur.sa_sigaction != on_fatal) {
            handler_checked.tv_sec = 0;
            return 0;
        }
    }
    handler_checked = now;
    return 1;
}

/* Copy the string at src directly (at most cap - 1 bytes): its length, -1
 * when reading it faulted. */
static long direct_string(char *dst, size_t cap, const char *src)
{
    volatile size_t len = 0;
    probe_thread = pthread_self();
    probing = 1;
    if (sigsetjmp(probe_env, 0)) {
        probing = 0;
        sigset_t faults;
        sigemptyset(&faults);
        sigaddset(&faults, SIGSEGV);
        sigaddset(&faults, SIGBUS);
        pthread_sigmask(SIG_UNBLOCK, &faults, NULL);  /* left blocked by the jump out of the handler */
        dst[len] = '\0';
        return len ? (long)len : -1;
    }
    while (len < cap - 1 && src[len]) {
        dst[len] = src[len];
        len++;
    }
    probing = 0;
    dst[len] = '\0';
    return (long)len;
}

/* The NUL-terminated string at src, at most cap - 1 bytes of it, into dst
 * (always terminated): its length, or -1 when src cannot be read at all. */
static long safe_string(char *dst, size_t cap, const char *src)
{
    dst[0] = '\0';
    if (!src || cap < 2)
        return -1;
    pthread_mutex_lock(&lock);
    int direct = direct_reads();
    long copied = direct ? direct_string(dst, cap, src) : 0;
    pthread_mutex_unlock(&lock);
    if (direct)
        return copied;
    size_t len = 0;
    const size_t page = 4096;
    while (len < cap - 1) {
        uintptr_t at = (uintptr_t)(src + len);
        size_t chunk = page - (at % page);
        if (chunk > cap - 1 - len)
            chunk = cap - 1 - len;
        long got = read_remote(dst + len, src + len, chunk);
        if (got <= 0)
            break;
        char *nul = memchr(dst + len, '\0', (size_t)got);
        if (nul)
            return (long)(nul - dst);
        len += (size_t)got;
        if ((size_t)got < chunk)
            break;  /* the next byte is unreadable */
    }
    dst[len] = '\0';
    return len == 0 ? -1 : (long)len;  /* nothing read: unreadable */
}

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
                text = safe_string(copy, cap, arg) < 0 ? "(unreadable string)" : copy;
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
    int name_known = safe_string(name, sizeof name, instance) >= 0;
    if (safe_string(cat, sizeof cat, category) < 0)
        cat[0] = '\0';
    const char *shown;
    if (!message)
        shown = "";
    else if (!text)
        shown = "(out of memory for the FMU's message)";
    else if (safe_string(format, TEXT_CAP, message) < 0)
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
    return safe_string(dst, cap, src);
}

/* ---- a crash inside an FMU ------------------------------------------------- *
 *
 * The handler walks the crashed thread's frames (libgcc's unwinder, which
 * reads through the signal frame) and finds the outermost frame inside a
 * registered FMU binary. When the frame that called it is the master's
 * (this library) or ctypes' (libffi), and the FMU's frame is an FMI
 * function, the call is abandoned: the handler returns into the caller as
 * if the FMI function had returned fmi2Fatal (NULL for an instantiate),
 * with the caller's callee-saved registers as the unwinder restores them.
 * The master then fails the run as for any fmi2Fatal, history kept, and
 * Python reads what happened with cw_crash_info. The FMU's frames are left
 * behind, its instance is never called again (not even freed).
 *
 * Otherwise (no unwind tables, a thread of the FMU's own) the thread is
 * parked, one byte goes to the watchdog's pipe (cw_crash_install), and the
 * watchdog ends the process as a failed run; without a watchdog, or when
 * it has not done so within 10 s, the handler writes the line itself and
 * calls _exit(1). A crash outside every FMU keeps the earlier action
 * (Python's faulthandler, or the default: a core dump). */

#include <unwind.h>

enum { MAX_BINARIES = 4096, CALL_CAP = 96 };

typedef struct {
    const void *base;     /* where the library is loaded (dli_fbase) */
    int crashed;          /* the signal number of its last crash */
    int crashes;          /* how many times it crashed */
    char call[CALL_CAP];  /* the FMI call it crashed in */
} cw_binary;

static cw_binary binaries[MAX_BINARIES];
static volatile int n_binaries;
static volatile int crash_fd = -1;
static volatile sig_atomic_t in_handler;
static struct sigaction previous[65];
static const int fatal_signals[] = {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT};
static char crash_line[512];  /* what the watchdog prints, or the handler when there is none */
static const void *own_base;

static const void *base_of(const void *address)
{
    Dl_info info;
    if (!address || !dladdr(address, &info))
        return NULL;
    return info.dli_fbase;
}

static cw_binary *binary_at(const void *base)
{
    if (!base)
        return NULL;
    for (int k = 0; k < n_binaries; k++)
        if (binaries[k].base == base)
            return &binaries[k];
    return NULL;
}

/* Register the FMU binary that holds `symbol` (any of its functions):
 * crashes inside it are caught. 0, or -1 when it is no loaded library or
 * the table is full. */
CW_EXPORT int cw_crash_binary(const void *symbol)
{
    const void *base = base_of(symbol);
    if (!base)
        return -1;
    pthread_mutex_lock(&lock);
    int rc = 0;
    if (!binary_at(base)) {
        if (n_binaries < MAX_BINARIES) {
            binaries[n_binaries].base = base;
            n_binaries++;
        } else
            rc = -1;
    }
    pthread_mutex_unlock(&lock);
    return rc;
}

/* How many times the binary that holds `symbol` crashed; with *signo the
 * signal number of its last crash and call (cap bytes) the FMI call it
 * was in. */
CW_EXPORT int cw_crash_info(const void *symbol, int *signo, char *call, size_t cap)
{
    cw_binary *b = binary_at(base_of(symbol));
    if (!b || !b->crashes)
        return 0;
    if (signo)
        *signo = b->crashed;
    if (call && cap) {
        strncpy(call, b->call, cap - 1);
        call[cap - 1] = '\0';
    }
    return b->crashes;
}

/* The line the handler left for the watchdog (a crash it could not return from). */
CW_EXPORT const char *cw_crash_line(void) { return crash_line; }


static const char *signal_name(int sig)
{
    switch (sig) {
    case SIGSEGV: return "SIGSEGV";
    case SIGBUS: return "SIGBUS";
    case SIGFPE: return "SIGFPE";
    case SIGILL: return "SIGILL";
    case SIGABRT: return "SIGABRT";
    default: return "a fatal signal";
    }
}

static void say(const char *text) { (void)!write(2, text, strlen(text)); }

typedef struct {
    int depth;
    int found;                /* frames seen inside an FMU */
    cw_binary *fmu;           /* the FMU of the outermost such frame */
    char call[CALL_CAP];      /* its FMI function */
    int call_ok;              /* that frame is an exported FMI function */
    uintptr_t resume_ip, resume_sp, regs[6]; /* the caller's: rbx rbp r12 r13 r14 r15 */
    int caller_ok;            /* the caller is the master or ctypes */
    int pending;              /* the previous frame was the outermost FMU frame so far */
} walk_t;

static const int callee_saved[6] = {3, 6, 12, 13, 14, 15};  /* DWARF numbers on x86-64 */

static _Unwind_Reason_Code each_frame(struct _Unwind_Context *ctx, void *arg)
{
    walk_t *w = arg;
    if (++w->depth > 100000)  /* deep recursion inside the FMU is walked through */
        return _URC_END_OF_STACK;
    uintptr_t ip = _Unwind_GetIP(ctx);
    if (!ip)
        return _URC_END_OF_STACK;
    Dl_info info;
    int known = dladdr((void *)(ip - 1), &info);
    cw_binary *b = known ? binary_at(info.dli_fbase) : NULL;
    if (b) {
        w->found++;
        w->fmu = b;
        w->pending = 1;
        const char *name = info.dli_sname ? info.dli_sname : "";
        w->call_ok = strncmp(name, "fmi", 3) == 0 || strstr(name, "_fmi") != NULL;
        strncpy(w->call, name[0] ? name : "an FMI call", sizeof w->call - 1);
        w->call[sizeof w->call - 1] = '\0';
        w->caller_ok = 0;
        return _URC_NO_REASON;
    }
    if (w->pending) {  /* the caller of the outermost FMU frame so far */
        w->pending = 0;
        const char *file = known && info.dli_fname ? info.dli_fname : "";
        const char *base = strrchr(file, '/') ? strrchr(file, '/') + 1 : file;
        w->caller_ok = known && (info.dli_fbase == own_base || strncmp(base, "libffi", 6) == 0 ||
                                 strncmp(base, "_ctypes", 7) == 0);
        w->resume_ip = ip;
        /* libgcc's CFA of a frame's context is the stack pointer of that
         * frame at the call: where the FMU's `ret` would have left it. */
        w->resume_sp = _Unwind_GetCFA(ctx);
        for (int k = 0; k < 6; k++)
            w->regs[k] = _Unwind_GetGR(ctx, callee_saved[k]);
    }
    return _URC_NO_REASON;
}

static void append(char *dst, size_t cap, const char *s)
{
    size_t n = strlen(dst);
    while (*s && n + 1 < cap)
        dst[n++] = *s++;
    dst[n] = '\0';
}

#if defined(__x86_64__)
/* Where a call through a bad pointer from inside an FMU (a NULL
 * stepFinished) is resumed: as if the FMU had called this, whose ud2 then
 * gives the handler frames it can walk (at its first instruction the CFA
 * is rsp + 8, the return address into the FMU at rsp). */
void cw_trap(void);
__asm__(".text\n.globl cw_trap\n.hidden cw_trap\n.type cw_trap, @function\ncw_trap:\n"
        ".cfi_startproc\nud2\n.cfi_endproc\n.size cw_trap, .-cw_trap\n");
#endif
static volatile int trap_sig;  /* the signal of such a call, while cw_trap re-raises it */

static void on_fatal(int sig, siginfo_t *si, void *context)
{
    if (probing && pthread_equal(pthread_self(), probe_thread) && (sig == SIGSEGV || sig == SIGBUS))
        siglongjmp(probe_env, 1);  /* a string an FMU passed is unreadable: direct_string says so */
    if (in_handler) {  /* a crash while handling one */
        say("clockwork: error: an FMU crashed, and again while that was handled\n");
        _exit(1);
    }
    in_handler = 1;
#if defined(__x86_64__)
    greg_t *r = ((ucontext_t *)context)->uc_mcontext.gregs;
    if (trap_sig && sig == SIGILL && r[REG_RIP] == (greg_t)cw_trap)
        sig = trap_sig;
    trap_sig = 0;
#endif
    walk_t w;
    memset(&w, 0, sizeof w);
    _Unwind_Backtrace(each_frame, &w);
#if defined(__x86_64__)
    Dl_info info;
    uintptr_t ret = 0;
    if (!w.found && !dladdr((void *)r[REG_RIP], &info) &&
        read_remote((char *)&ret, (const char *)r[REG_RSP], sizeof ret) == (long)sizeof ret &&
        dladdr((void *)(ret - 1), &info) && binary_at(info.dli_fbase)) {
        /* The program counter is in no library and the stack's top is a
         * return address into an FMU: a call through a bad pointer. */
        trap_sig = sig;
        r[REG_RIP] = (greg_t)cw_trap;
        in_handler = 0;
        return;
    }
#endif
    if (!w.found) {  /* not an FMU's: the earlier action, as if this handler were not there */
        in_handler = 0;
        struct sigaction *was = &previous[sig];
        if (was->sa_flags & SA_SIGINFO) {
            if (was->sa_sigaction) {
                was->sa_sigaction(sig, si, context);
                return;
            }
        } else if (was->sa_handler != SIG_DFL && was->sa_handler != SIG_IGN) {
            was->sa_handler(sig);
            return;
        }
        signal(sig, SIG_DFL);  /* the default action: for a fault the instruction faults again */
        if (si->si_code <= 0 || sig == SIGABRT)
            raise(sig);  /* sent, not a fault: delivered once this handler returns */
        return;
    }
    w.fmu->crashed = sig;
    w.fmu->crashes++;
    memcpy(w.fmu->call, w.call, sizeof w.call);
#if defined(__x86_64__)
    if (w.call_ok && w.caller_ok && !w.pending) {
        /* Return from the FMI call into its caller: rax is what it returns. */
        r[REG_RIP] = (greg_t)w.resume_ip;
        r[REG_RSP] = (greg_t)w.resume_sp;
        r[REG_RBX] = (greg_t)w.regs[0];
        r[REG_RBP] = (greg_t)w.regs[1];
        r[REG_R12] = (greg_t)w.regs[2];
        r[REG_R13] = (greg_t)w.regs[3];
        r[REG_R14] = (greg_t)w.regs[4];
        r[REG_R15] = (greg_t)w.regs[5];
        r[REG_RAX] = strstr(w.call, "Instantiate") || strstr(w.call, "GetTypesPlatform") ||
                     strstr(w.call, "GetVersion") ? 0 : 4;  /* NULL, or fmi2Fatal (fmi3Fatal, fmiFatal) */
        in_handler = 0;
        return;
    }
#endif
    /* Cannot return: park this thread and let the watchdog end the run. */
    crash_line[0] = '\0';
    append(crash_line, sizeof crash_line, "an FMU crashed in ");
    append(crash_line, sizeof crash_line, w.call);
    append(crash_line, sizeof crash_line, " (");
    append(crash_line, sizeof crash_line, signal_name(sig));
    append(crash_line, sizeof crash_line, ")");
    if (crash_fd >= 0) {
        unsigned char byte = (unsigned char)sig;
        (void)!write(crash_fd, &byte, 1);
        for (int k = 0; k < 100; k++) {
            struct timespec nap = {0, 100000000};
            nanosleep(&nap, NULL);
        }
    }
    if (crash_fd != -2) {  /* -2: a sweep worker, whose end its parent reports */
        say("clockwork: error: ");
        say(crash_line);
        say("\n");
    }
    _exit(1);
}

/* Install the handler (once; later calls only set the watchdog's pipe,
 * fd, or -1 for none, -2 for none and no line): 0, or -1 when sigaction
 * refused. */
CW_EXPORT int cw_crash_install(int fd)
{
    static int installed;
    crash_fd = fd;
    pthread_mutex_lock(&lock);
    int rc = 0;
    if (!installed) {
        own_base = base_of((const void *)cw_crash_install);
        /* The unwinder loads itself at its first use: not inside a handler. */
        void *frames[4];
        backtrace(frames, 4);
        static char alt[1 << 16];
        stack_t ss = {.ss_sp = alt, .ss_size = sizeof alt, .ss_flags = 0};
        sigaltstack(&ss, NULL);  /* this thread's: a stack overflow can be reported too */
        struct sigaction sa;
        memset(&sa, 0, sizeof sa);
        sa.sa_sigaction = on_fatal;
        sa.sa_flags = SA_SIGINFO | SA_ONSTACK;
        sigemptyset(&sa.sa_mask);
        for (size_t k = 0; k < sizeof fatal_signals / sizeof *fatal_signals; k++)
            if (sigaction(fatal_signals[k], &sa, &previous[fatal_signals[k]]) != 0)
                rc = -1;
        installed = 1;
        handler_installed = rc == 0;
    }
    pthread_mutex_unlock(&lock);
    return rc;
}
