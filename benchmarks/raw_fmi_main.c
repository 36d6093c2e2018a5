/* bench_master's C floor as a program of its own, for a profiler: loads two
 * FMI 2.0 binaries with dlopen, instantiates and initializes them, and runs
 * raw_fmi_loop (the same calls as one Gauss-Seidel communication step, no
 * master logic). Under `valgrind --tool=callgrind` every instruction counted
 * is the FMUs' own work plus this loop's few, and nothing of Python's
 * start-up. benchmarks/profile_fmus.py builds it, finds the value
 * references and runs it:
 *
 *   raw_fmi_main STEPS H  PEND_SO PEND_GUID PEND_RES PEND_PARAMS
 *                         ESC_SO ESC_GUID ESC_RES ESC_PARAMS
 *                         PEND_OUT PEND_IN ESC_IN ESC_OUT
 *
 * PARAMS are "vr=value,vr=value" (set before initialization), the others
 * comma-separated value references: the pendulum's (phi, w), its
 * escapement torque input, the escapement's (phi, w) inputs and its torque
 * output. */
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#include "raw_fmi_loop.h"

typedef struct {
    void *lib;
    fmi2Component c;
    fmi2DoStepTYPE *doStep;
    fmi2GetRealTYPE *getReal;
    fmi2SetRealTYPE *setReal;
    fmi2ExitInitializationModeTYPE *exitInit;
} fmu;

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...)
{
    (void)env;
    if (status > fmi2Warning)
        fprintf(stderr, "%s [%s]: %s\n", name, category, message);
}

static void *sym(void *lib, const char *name)
{
    void *f = dlsym(lib, name);
    if (!f) {
        fprintf(stderr, "raw_fmi_main: %s not found\n", name);
        exit(2);
    }
    return f;
}

static int parse_vrs(const char *text, unsigned *vr, int cap)
{
    int n = 0;
    for (const char *s = text; *s && n < cap; n++) {
        char *end;
        vr[n] = (unsigned)strtoul(s, &end, 10);
        s = *end == ',' ? end + 1 : end;
    }
    return n;
}

static fmu load(const char *so, const char *name, const char *guid, const char *resources, const char *params)
{
    static const fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    fmu f;
    f.lib = dlopen(so, RTLD_NOW | RTLD_LOCAL);
    if (!f.lib) {
        fprintf(stderr, "raw_fmi_main: %s\n", dlerror());
        exit(2);
    }
    fmi2InstantiateTYPE *instantiate = sym(f.lib, "fmi2Instantiate");
    fmi2SetupExperimentTYPE *setup = sym(f.lib, "fmi2SetupExperiment");
    fmi2EnterInitializationModeTYPE *enter = sym(f.lib, "fmi2EnterInitializationMode");
    f.exitInit = sym(f.lib, "fmi2ExitInitializationMode");
    f.doStep = sym(f.lib, "fmi2DoStep");
    f.getReal = sym(f.lib, "fmi2GetReal");
    f.setReal = sym(f.lib, "fmi2SetReal");
    f.c = instantiate(name, fmi2CoSimulation, guid, resources, &callbacks, fmi2False, fmi2False);
    if (!f.c || setup(f.c, fmi2False, 0.0, 0.0, fmi2False, 0.0) > fmi2Warning) {
        fprintf(stderr, "raw_fmi_main: %s refused to start\n", name);
        exit(1);
    }
    for (const char *s = params; *s;) {
        char *end;
        unsigned vr = (unsigned)strtoul(s, &end, 10);
        double value = strtod(end + 1, &end);
        if (f.setReal(f.c, &vr, 1, &value) > fmi2Warning) {
            fprintf(stderr, "raw_fmi_main: %s refused parameter %u\n", name, vr);
            exit(1);
        }
        s = *end == ',' ? end + 1 : end;
    }
    if (enter(f.c) > fmi2Warning)
        exit(1);
    return f;
}

int main(int argc, char **argv)
{
    if (argc != 15) {
        fprintf(stderr, "usage: see the head of raw_fmi_main.c\n");
        return 2;
    }
    long steps = atol(argv[1]);
    double h = atof(argv[2]);
    fmu p = load(argv[3], "pendulum", argv[4], argv[5], argv[6]);
    fmu e = load(argv[7], "escapement", argv[8], argv[9], argv[10]);
    unsigned pend_out[2], pend_in[1], esc_in[2], esc_out[1];
    if (parse_vrs(argv[11], pend_out, 2) != 2 || parse_vrs(argv[12], pend_in, 1) != 1 ||
        parse_vrs(argv[13], esc_in, 2) != 2 || parse_vrs(argv[14], esc_out, 1) != 1) {
        fprintf(stderr, "raw_fmi_main: bad value references\n");
        return 2;
    }
    double phi_w[2];
    if (p.getReal(p.c, pend_out, 2, phi_w) > fmi2Warning || e.setReal(e.c, esc_in, 2, phi_w) > fmi2Warning ||
        p.exitInit(p.c) > fmi2Warning || e.exitInit(e.c) > fmi2Warning)
        return 1;
    int rc = raw_fmi_loop(p.c, e.c, (do_step_t)p.doStep, (do_step_t)e.doStep, (get_real_t)p.getReal,
                          (set_real_t)p.setReal, (get_real_t)e.getReal, (set_real_t)e.setReal, pend_out, pend_in,
                          esc_in, esc_out, steps, h);
    if (rc)
        fprintf(stderr, "raw_fmi_main: an FMU refused a call in the loop\n");
    return rc ? 1 : 0;
}
