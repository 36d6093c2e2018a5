/* The cost of one FMU log message in the core's cw_logger (a benchmark, not
 * a test): 200,000 messages "step %d at t = %g: %s" to a registered sink,
 * with the crash handler installed (direct reads, as in a run) or not
 * (each string through process_vm_readv).
 *
 *   cc -O2 benchmarks/bench_logger.c -o /tmp/bench_logger -ldl
 *   /tmp/bench_logger lib/libcw_master.so            # without the handler
 *   /tmp/bench_logger lib/libcw_master.so handler    # with it
 */
#include <dlfcn.h>
#include <stdio.h>
#include <time.h>

typedef void (*sink_t)(const char *, int, const char *, const char *);
typedef void (*logger_t)(void *, const char *, int, const char *, const char *, ...);

static long seen;
static void sink(const char *instance, int status, const char *category, const char *text)
{
    (void)instance; (void)status; (void)category;
    seen += text[0];
}

int main(int argc, char **argv)
{
    void *lib = argc > 1 ? dlopen(argv[1], RTLD_NOW) : NULL;
    if (!lib) {
        fprintf(stderr, "usage: bench_logger path/to/libcw_master.so [handler]\n");
        return 2;
    }
    logger_t logger = (logger_t)dlsym(lib, "cw_logger");
    int (*reg)(const void *, const char *, sink_t) = (int (*)(const void *, const char *, sink_t))dlsym(lib, "cw_env_register");
    int (*install)(int) = (int (*)(int))dlsym(lib, "cw_crash_install");
    if (reg)
        reg((void *)sink, "inst", sink);  /* an earlier core calls the environment as the sink */
    if (install && argc > 2)
        install(-1);
    enum { N = 200000 };
    struct timespec a, b;
    clock_gettime(CLOCK_MONOTONIC, &a);
    for (int k = 0; k < N; k++)
        logger((void *)sink, "inst", 0, "logAll", "step %d at t = %g: %s", k, k * 0.001, "fine");
    clock_gettime(CLOCK_MONOTONIC, &b);
    printf("%.3f us per message\n", ((double)(b.tv_sec - a.tv_sec) * 1e9 + (double)(b.tv_nsec - a.tv_nsec)) / N / 1e3);
    return seen == 0;
}
