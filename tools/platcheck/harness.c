/* platcheck: load FMU binaries with the platform's own loader and run each
 * through its Co-Simulation API, printing every communication point's
 * outputs as the bits of the doubles. Built natively (against the .so) and
 * cross-compiled (the Windows DLLs, run under wine; the aarch64 .so, under
 * qemu), from the same source, so that tests/test_platforms.py can compare
 * the platforms' numbers bit for bit. It reads no XML: the test reads the
 * modelDescription.xml and writes the jobs.
 *
 *   platcheck [--x87-53] JOBS
 *   platcheck [--x87-53] --libm N
 *
 * JOBS has one line per run, tab-separated:
 *   fmiVersion(2|3)  library  instanceToken  resourceLocation(may be empty)
 *   start  stop  step  tolerance(0: none)  vr,vr,... (at most 256)
 * with the four times and the tolerance as the 16 hex digits of their IEEE
 * 754 bits (no decimal conversion by either platform's C library). For each
 * run it prints "run <n> <library>", one line "<t> <v...>" per communication
 * point (the start included) in the same hex form, and "end ok", or "end
 * <what failed>". Exit 0 when every run ended ok, 1 otherwise, 2 for bad
 * arguments.
 *
 * --libm N prints "<function> <x> <f(x)>" (hex bits) for N arguments of
 * each C library function the models and the runtime call (sin, cos, exp,
 * log, pow, j1), drawn by a fixed generator from the ranges they are
 * called on: where two platforms' FMUs differ, this shows whether their C
 * libraries do.
 *
 * On Windows, mingw-w64's sin, cos, exp, log and pow (linked into each
 * DLL) compute in the x87 unit, whose precision control a process sets:
 * 64 bits where mingw-w64's start-up code ran (this program), 53 bits in a
 * program built with MSVC (most FMI tools). --x87-53 sets 53 bits before
 * the runs, as such a host has it; the first line says which is in force. */

#define _DEFAULT_SOURCE /* j1() from <math.h>, as AveragedPendulum */
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2FunctionTypes.h"
#include "fmi3FunctionTypes.h"

#ifdef _WIN32
#include <windows.h>
typedef HMODULE lib_handle;
static lib_handle lib_open(char *path) {
    for (char *p = path; *p; p++) /* LoadLibrary wants backslashes */
        if (*p == '/')
            *p = '\\';
    return LoadLibraryA(path);
}
static void *lib_sym(lib_handle h, const char *name) {
    return (void *)(uintptr_t)GetProcAddress(h, name);
}
static void lib_close(lib_handle h) { FreeLibrary(h); }
/* The x87 control word's precision bits (8-9: 0 24 bits, 2 53, 3 64),
 * directly: msvcrt's _controlfp ignores _MCW_PC on x64. */
static unsigned short x87_cw(void) {
    unsigned short cw;
    __asm__ volatile("fnstcw %0" : "=m"(cw));
    return cw;
}
static void x87_53(void) {
    unsigned short cw = (unsigned short)((x87_cw() & ~0x300u) | 0x200u);
    __asm__ volatile("fldcw %0" : : "m"(cw));
}
static int x87_precision(void) {
    unsigned pc = (x87_cw() >> 8) & 3u;
    return pc == 3 ? 64 : pc == 2 ? 53 : 24;
}
#else
#include <dlfcn.h>
typedef void *lib_handle;
static lib_handle lib_open(char *path) { return dlopen(path, RTLD_NOW | RTLD_LOCAL); }
static void *lib_sym(lib_handle h, const char *name) { return dlsym(h, name); }
static void lib_close(lib_handle h) { dlclose(h); }
static void x87_53(void) {}  /* glibc's double functions use SSE2 only */
static int x87_precision(void) { return 0; }
#endif

#define MAX_VRS 256
#define MAX_LINE 8192

static double from_bits(const char *hex, int *ok) {
    char *end;
    uint64_t u = strtoull(hex, &end, 16);
    double x;
    if (end == hex || *end || strlen(hex) != 16)
        *ok = 0;
    memcpy(&x, &u, sizeof x);
    return x;
}

static void print_bits(double x) {
    uint64_t u;
    memcpy(&u, &x, sizeof u);
    printf(" %08lx%08lx", (unsigned long)(u >> 32), (unsigned long)(u & 0xffffffffu));
}

static void print_point(double t, const double *v, size_t n) {
    uint64_t u;
    memcpy(&u, &t, sizeof u);
    printf("%08lx%08lx", (unsigned long)(u >> 32), (unsigned long)(u & 0xffffffffu));
    for (size_t i = 0; i < n; i++)
        print_bits(v[i]);
    printf("\n");
}

/* The FMUs' own messages go to stderr, so that stdout is the numbers only. */
static void logger2(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                 fmi2String message, ...) {
    va_list ap;
    (void)env;
    fprintf(stderr, "[%s %d %s] ", name ? name : "", (int)status, category ? category : "");
    va_start(ap, message);
    vfprintf(stderr, message ? message : "", ap);
    va_end(ap);
    fprintf(stderr, "\n");
}

static void logger3(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
    (void)env;
    fprintf(stderr, "[%d %s] %s\n", (int)status, category ? category : "", message ? message : "");
}

typedef struct {
    int version;
    char *library, *token, *resources;
    double start, stop, step, tolerance;
    fmi2ValueReference vr2[MAX_VRS];
    fmi3ValueReference vr3[MAX_VRS];
    size_t nvr;
} job;

/* The number of communication steps from start to stop, the last one
 * landing on stop within a millionth of a step (as fmpy counts them). */
static long n_steps(const job *j) {
    double n = (j->stop - j->start) / j->step;
    long k = (long)n;
    if (n - (double)k > 1e-6)
        k++;
    return k;
}

#define SYM(type, name)                                                                                \
    type name = (type)(uintptr_t)lib_sym(h, #name);                                                    \
    if (!name) {                                                                                       \
        printf("end %s is not exported\n", #name);                                                     \
        return 1;                                                                                      \
    }

static int run2(lib_handle h, const job *j) {
    SYM(fmi2InstantiateTYPE *, fmi2Instantiate)
    SYM(fmi2SetupExperimentTYPE *, fmi2SetupExperiment)
    SYM(fmi2EnterInitializationModeTYPE *, fmi2EnterInitializationMode)
    SYM(fmi2ExitInitializationModeTYPE *, fmi2ExitInitializationMode)
    SYM(fmi2DoStepTYPE *, fmi2DoStep)
    SYM(fmi2GetRealTYPE *, fmi2GetReal)
    SYM(fmi2TerminateTYPE *, fmi2Terminate)
    SYM(fmi2FreeInstanceTYPE *, fmi2FreeInstance)
    fmi2CallbackFunctions cb = {logger2, calloc, free, NULL, NULL};
    double v[MAX_VRS];
    fmi2Component c = fmi2Instantiate("platcheck", fmi2CoSimulation, j->token, j->resources, &cb, fmi2False,
                                      fmi2False);
    if (!c) {
        printf("end fmi2Instantiate returned NULL\n");
        return 1;
    }
    int failed = 1;
    if (fmi2SetupExperiment(c, j->tolerance > 0, j->tolerance, j->start, fmi2True, j->stop) > fmi2Warning)
        printf("end fmi2SetupExperiment failed\n");
    else if (fmi2EnterInitializationMode(c) > fmi2Warning || fmi2ExitInitializationMode(c) > fmi2Warning)
        printf("end initialization failed\n");
    else if (fmi2GetReal(c, j->vr2, j->nvr, v) > fmi2Warning)
        printf("end fmi2GetReal failed at the start\n");
    else {
        long n = n_steps(j), i;
        double t = j->start;
        print_point(t, v, j->nvr);
        for (i = 1; i <= n; i++) {
            double next = i == n ? j->stop : j->start + (double)i * j->step;
            fmi2Status s = fmi2DoStep(c, t, next - t, fmi2True);
            if (s > fmi2Warning) {
                printf("end fmi2DoStep returned %d at t = %.17g\n", (int)s, t);
                break;
            }
            t = next;
            if (fmi2GetReal(c, j->vr2, j->nvr, v) > fmi2Warning) {
                printf("end fmi2GetReal failed at t = %.17g\n", t);
                break;
            }
            print_point(t, v, j->nvr);
        }
        if (i > n) {
            failed = fmi2Terminate(c) > fmi2Warning;
            printf(failed ? "end fmi2Terminate failed\n" : "end ok\n");
        }
    }
    fmi2FreeInstance(c);
    return failed;
}

static int run3(lib_handle h, const job *j) {
    SYM(fmi3InstantiateCoSimulationTYPE *, fmi3InstantiateCoSimulation)
    SYM(fmi3EnterInitializationModeTYPE *, fmi3EnterInitializationMode)
    SYM(fmi3ExitInitializationModeTYPE *, fmi3ExitInitializationMode)
    SYM(fmi3DoStepTYPE *, fmi3DoStep)
    SYM(fmi3GetFloat64TYPE *, fmi3GetFloat64)
    SYM(fmi3TerminateTYPE *, fmi3Terminate)
    SYM(fmi3FreeInstanceTYPE *, fmi3FreeInstance)
    double v[MAX_VRS];
    fmi3Instance c = fmi3InstantiateCoSimulation("platcheck", j->token, j->resources, fmi3False, fmi3False,
                                                 fmi3False, fmi3False, NULL, 0, NULL, logger3, NULL);
    if (!c) {
        printf("end fmi3InstantiateCoSimulation returned NULL\n");
        return 1;
    }
    int failed = 1;
    if (fmi3EnterInitializationMode(c, j->tolerance > 0, j->tolerance, j->start, fmi3True, j->stop) > fmi3Warning ||
        fmi3ExitInitializationMode(c) > fmi3Warning)
        printf("end initialization failed\n");
    else if (fmi3GetFloat64(c, j->vr3, j->nvr, v, j->nvr) > fmi3Warning)
        printf("end fmi3GetFloat64 failed at the start\n");
    else {
        long n = n_steps(j), i;
        double t = j->start;
        print_point(t, v, j->nvr);
        for (i = 1; i <= n; i++) {
            double next = i == n ? j->stop : j->start + (double)i * j->step;
            fmi3Boolean event = fmi3False, terminate = fmi3False, early = fmi3False;
            double last = t;
            fmi3Status s = fmi3DoStep(c, t, next - t, fmi3True, &event, &terminate, &early, &last);
            if (s > fmi3Warning || terminate || early) {
                printf("end fmi3DoStep returned %d (terminate %d, early return %d) at t = %.17g\n", (int)s,
                       (int)terminate, (int)early, t);
                break;
            }
            t = next;
            if (fmi3GetFloat64(c, j->vr3, j->nvr, v, j->nvr) > fmi3Warning) {
                printf("end fmi3GetFloat64 failed at t = %.17g\n", t);
                break;
            }
            print_point(t, v, j->nvr);
        }
        if (i > n) {
            failed = fmi3Terminate(c) > fmi3Warning;
            printf(failed ? "end fmi3Terminate failed\n" : "end ok\n");
        }
    }
    fmi3FreeInstance(c);
    return failed;
}

/* xorshift64: the same sequence on every platform. */
static uint64_t next_u64(uint64_t *s) {
    *s ^= *s << 13;
    *s ^= *s >> 7;
    *s ^= *s << 17;
    return *s;
}

/* Uniform in [a, b], by exact IEEE arithmetic only. */
static double uniform(uint64_t *s, double a, double b) {
    return a + (b - a) * ((double)(next_u64(s) >> 11) * 0x1p-53);
}

static void probe(const char *fn, double x, double y) {
    printf("%s", fn);
    print_bits(x);
    print_bits(y);
    printf("\n");
}

static int libm_probe(long n) {
    uint64_t s = 0x9e3779b97f4a7c15u;
    for (long i = 0; i < n; i++) {
        double x = uniform(&s, -4.0, 4.0); /* angles */
        probe("sin", x, sin(x));
        probe("cos", x, cos(x));
        x = uniform(&s, -40.0, 40.0);
        probe("exp", x, exp(x));
        x = uniform(&s, 0.0, 1.0); /* Box-Muller's uniform */
        probe("log", x, log(x));
        x = uniform(&s, 0.0, 2.0); /* step-size control: error ratios */
        probe("pow0.2", x, pow(x, 0.2));
        probe("pow0.125", x, pow(x, 0.125));
        x = uniform(&s, 0.5, 2.0); /* temperature ratios */
        probe("pow1.5", x, pow(x, 1.5));
        x = uniform(&s, 2.0, 40.0); /* the averaged pendulum's Bessel form */
        probe("j1", x, j1(x));
    }
    return 0;
}

/* Splits line at tabs into at most max fields; returns their number. */
static int split(char *line, char **field, int max) {
    int n = 0;
    char *p = line;
    while (n < max) {
        field[n++] = p;
        p = strchr(p, '\t');
        if (!p)
            break;
        *p++ = '\0';
    }
    return n;
}

static int parse(char *line, job *j) {
    char *f[9];
    int ok = 1;
    line[strcspn(line, "\r\n")] = '\0';
    if (split(line, f, 9) != 9)
        return 0;
    j->version = atoi(f[0]);
    j->library = f[1];
    j->token = f[2];
    j->resources = *f[3] ? f[3] : NULL; /* empty: no resources */
    j->start = from_bits(f[4], &ok);
    j->stop = from_bits(f[5], &ok);
    j->step = from_bits(f[6], &ok);
    j->tolerance = from_bits(f[7], &ok);
    j->nvr = 0;
    for (char *p = f[8]; *p;) {
        char *end;
        if (j->nvr == MAX_VRS)
            return 0;
        unsigned long vr = strtoul(p, &end, 10);
        if (end == p)
            return 0;
        j->vr2[j->nvr] = (fmi2ValueReference)vr;
        j->vr3[j->nvr++] = (fmi3ValueReference)vr;
        p = *end == ',' ? end + 1 : end;
        if (*end && *end != ',')
            return 0;
    }
    return ok && (j->version == 2 || j->version == 3) && j->step > 0 && j->stop >= j->start;
}

int main(int argc, char **argv) {
    static char line[MAX_LINE];
    int failures = 0, n = 0, lineno = 0;
    if (argc > 1 && strcmp(argv[1], "--x87-53") == 0) {
        x87_53();
        argc--;
        argv++;
    }
    printf("x87 precision %d\n", x87_precision());
    if (argc == 3 && strcmp(argv[1], "--libm") == 0)
        return libm_probe(atol(argv[2]));
    if (argc != 2) {
        fprintf(stderr, "usage: platcheck [--x87-53] JOBS | platcheck [--x87-53] --libm N\n");
        return 2;
    }
    FILE *jobs = fopen(argv[1], "r");
    if (!jobs) {
        fprintf(stderr, "platcheck: cannot open %s\n", argv[1]);
        return 2;
    }
    while (fgets(line, sizeof line, jobs)) {
        job j;
        lineno++;
        if (line[0] == '\n' || line[0] == '#')
            continue;
        if (!parse(line, &j)) {
            fprintf(stderr, "platcheck: %s: line %d is not a job\n", argv[1], lineno);
            fclose(jobs);
            return 2;
        }
        printf("run %d %s\n", ++n, j.library);
        lib_handle h = lib_open(j.library);
        if (!h) {
            printf("end cannot load the library\n");
            failures++;
            continue;
        }
        failures += j.version == 2 ? run2(h, &j) : run3(h, &j);
        lib_close(h);
        fflush(stdout);
    }
    fclose(jobs);
    return failures ? 1 : 0;
}
