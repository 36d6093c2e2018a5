/* What catches an FMU that crashes, and the reads of what an FMU points
 * at that cannot crash.
 *
 * 1. A string an FMU passed (cw_safe_string, for the logger in cw_log.c):
 *    copied through the kernel (process_vm_readv: an unreadable address is
 *    an error, not a fault), or directly under the crash handler, whose
 *    fault jumps back.
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
 * Its tables are behind one mutex; the FMUs keep no global state.
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

#include "cw_guard.h"

#define CW_EXPORT __attribute__((visibility("default")))

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

/* Declared in cw_guard.h: the string at src into dst, or -1. */
long cw_safe_string(char *dst, size_t cap, const char *src)
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
