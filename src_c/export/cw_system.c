/* The exported system FMU's front (clockwork export-fmu): an FMI 2.0
 * Co-Simulation FMU whose fmi2DoStep runs clockwork's compiled master
 * (src_c/master) over the scene's own FMUs.
 *
 * The exporter (clockwork/run/export_fmu.py) unpacks the scene's FMUs into
 * this FMU's resources and writes resources/clockwork/system.txt: the FMUs,
 * the instances, the parameters, and the master's structs as the Python
 * side builds them for the scene (engine/compiled.py), field by field. This
 * file reads that description (no XML: whitespace-separated tokens), loads
 * the inner FMUs with the platform's loader, initializes them as
 * Master.initialize does (parameters, two sweeps of the evaluation order in
 * Initialization Mode, the outputs after it), and steps with cw_run_until on
 * the scene's grid. The structs are filled by name through cw_layout, the
 * core's own table of its fields, so that this file does not repeat their
 * definitions. Nothing here is global: every instance owns its state. */

#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>
#else
#include <dlfcn.h>
#endif

#include "fmi2Functions.h"
#include "fmi3Functions.h"
#include "cw_layout.h"

/* The compiled core's entry points (src_c/master). */
const cw_field *cw_layout(const char *name, size_t *n_fields, size_t *struct_size);
void cw_start(void *m);
void cw_discontinuity(void *m);
int cw_run_until(void *m, double t_stop, void *r, double slice_s);
int cw_step(void *m, double h, double *taken);

#ifdef _WIN32
/* The core's logger and crash guard (cw_log.c, cw_guard.c: POSIX) are not in
 * the Windows build; the logger's registry of environments serves FMI 3.0
 * inner FMUs, which an exported system does not have. */
int cw_env_known(const void *key) { return 0; }
#endif

#define CW_DESCRIPTION "clockwork/system.txt"
#define CW_FORMAT 1
enum { CW_DONE = 0, CW_CHECK_DIVERGENCE = 2, CW_ERR_FMI = -1, CW_ERR_NO_CHECKPOINT = -2, CW_ERR_REPLAY = -3,
       CW_ERR_LOCATE = -4, CW_ERR_CAPACITY = -5, CW_ERR_LOOP = -6 };

typedef struct {
    const cw_field *fields;
    size_t n, size;
} layout;

/* An array or a scalar of a struct field, as the description gives it. */
typedef struct {
    char name[48];
    char kind;          /* d: double, i: int, u: unsigned, l: long long, p: pointer (arrays only) */
    int port;           /* -1: the master's */
    int is_array;
    int n;              /* elements of an array */
    void *values;       /* the array's values (an array), or the scalar's bytes */
} cw_item;

typedef struct {
    char *dir;          /* under resources/ */
    char *identifier;
    char *guid;
#ifdef _WIN32
    HMODULE lib;
#else
    void *lib;
#endif
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *freeInstance;
    fmi2SetupExperimentTYPE *setupExperiment;
    fmi2EnterInitializationModeTYPE *enterInit;
    fmi2ExitInitializationModeTYPE *exitInit;
    fmi2TerminateTYPE *terminate;
    fmi2ResetTYPE *reset;
    fmi2SetRealTYPE *setReal;
    fmi2GetRealTYPE *getReal;
    fmi2SetIntegerTYPE *setInteger;
    fmi2SetBooleanTYPE *setBoolean;
    fmi2DoStepTYPE *doStep;
    fmi2SetRealInputDerivativesTYPE *setInputDerivatives;
    fmi2GetRealOutputDerivativesTYPE *getOutputDerivatives;
    fmi2GetFMUstateTYPE *getState;
    fmi2SetFMUstateTYPE *setState;
    fmi2FreeFMUstateTYPE *freeState;
} cw_inner_fmu;

typedef struct {
    char *name;
    int fmu;
    int tol_defined;
    double tol;
    int after_inputs;   /* outputs may be read after inputs are set without a step (FMI 2.0 4.2.4) */
    fmi2Component comp;
    void *state;        /* the one saved FMU state the master keeps (port.state) */
} cw_instance;

typedef struct {
    unsigned vr;
    char type;          /* R, I, B */
    char role;          /* p: parameter, o: output, i: input, t: time (FMI 3.0's independent variable) */
    int inst;
    unsigned inner_vr;
    int pos;            /* an output: its position in the port's outputs */
    double start;       /* R; I and B as whole numbers */
    double value;
    int set;            /* set by the importer (an input: since the last step) */
} cw_var;

enum { MODE_INSTANTIATED, MODE_INIT, MODE_STEP, MODE_TERMINATED, MODE_ERROR };

typedef struct {
    char *name;
    char *resources;    /* the path of this FMU's resources folder, with a trailing separator */
    fmi2CallbackFunctions cb;       /* FMI 2.0: the importer's callbacks */
    fmi3LogMessageCallback log3;    /* FMI 3.0: its logger and environment */
    fmi3InstanceEnvironment env3;
    int logging;
    int early_return;   /* FMI 3.0: the importer allows a return at the first located event */
    int mode;
    int inner_init;  /* the inner FMUs are in Initialization Mode (an output was read in it) */
    int pending;     /* a variable set since they entered it */
    char *guid;
    int n_fmus, n_inst, n_order, n_vars, n_items;
    cw_inner_fmu *fmus;
    cw_instance *inst;
    int *order;
    cw_var *vars;
    cw_item *items;
    double start_time, step;
    double divergence_limit;
    /* The master: its struct, the ports, the loops, the output buffer; the arrays of the items. */
    layout Lm, Lp, Ll;
    unsigned char *master;
    unsigned char *ports;
    unsigned char *loops;
    double *t;          /* the master's time, s (its field t) */
    double *buffer;
    int n_buffer;
    void **arrays;
    size_t *array_bytes;
    int n_arrays;
} cw_system;

/* -- messages ------------------------------------------------------------ */

static void say(cw_system *s, fmi2Status status, const char *fmt, ...)
{
    if (!s || (!s->cb.logger && !s->log3) || (status == fmi2OK && !s->logging))
        return;
    char text[1024], escaped[2100];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    const char *category = status == fmi2OK ? "logAll" : "logStatusError";
    if (s->log3) {  /* FMI 3.0: the text as it is */
        s->log3(s->env3, (fmi3Status)status, category, text);
        return;
    }
    size_t j = 0;
    for (size_t i = 0; text[i] && j + 2 < sizeof escaped; i++) {  /* the importer may format the text again */
        escaped[j++] = text[i];
        if (text[i] == '%')
            escaped[j++] = '%';
    }
    escaped[j] = 0;
    s->cb.logger(s->cb.componentEnvironment, s->name, status, category, escaped);
}

/* The inner FMUs' messages, passed on under the inner instance's name. */
static void inner_logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                         fmi2String category, fmi2String message, ...)
{
    cw_system *s = (cw_system *)env;
    if (!s || !message)
        return;
    char text[1024];
    va_list ap;
    va_start(ap, message);
    vsnprintf(text, sizeof text, message, ap);
    va_end(ap);
    say(s, status, "%s: %s", instance ? instance : "?", text);
}

/* -- the description ------------------------------------------------------ */

typedef struct {
    char *text, *at;
} reader;

static char *token(reader *r)
{
    char *p = r->at;
    while (*p == ' ' || *p == '\n' || *p == '\r' || *p == '\t')
        p++;
    if (!*p)
        return NULL;
    char *start = p;
    while (*p && *p != ' ' && *p != '\n' && *p != '\r' && *p != '\t')
        p++;
    if (*p)
        *p++ = 0;
    r->at = p;
    return start;
}

/* A token written percent-encoded (names, paths, GUIDs), decoded in place. */
static char *text_token(reader *r)
{
    char *t = token(r);
    if (!t)
        return NULL;
    char *w = t;
    for (char *p = t; *p; p++) {
        if (*p == '%' && p[1] && p[2]) {
            char hex[3] = {p[1], p[2], 0};
            *w++ = (char)strtol(hex, NULL, 16);
            p += 2;
        } else {
            *w++ = *p;
        }
    }
    *w = 0;
    char *copy = malloc(strlen(t) + 1);
    if (copy)
        strcpy(copy, t);
    return copy;
}

static int int_token(reader *r, int *out)
{
    char *t = token(r), *end;
    if (!t)
        return 0;
    long v = strtol(t, &end, 10);
    *out = (int)v;
    return *end == 0;
}

static int double_token(reader *r, double *out)
{
    char *t = token(r), *end;
    if (!t)
        return 0;
    *out = strtod(t, &end);  /* hexadecimal floats: the exporter's exact bits */
    return *end == 0;
}

static size_t kind_size(char kind)
{
    switch (kind) {
    case 'd': return sizeof(double);
    case 'i': return sizeof(int);
    case 'u': return sizeof(unsigned);
    case 'l': return sizeof(long long);
    case 'p': return sizeof(void *);
    default: return 0;
    }
}

static int value_token(reader *r, char kind, void *at)
{
    char *t = token(r), *end;
    if (!t)
        return 0;
    switch (kind) {
    case 'd': *(double *)at = strtod(t, &end); break;
    case 'i': *(int *)at = (int)strtol(t, &end, 10); break;
    case 'u': *(unsigned *)at = (unsigned)strtoul(t, &end, 10); break;
    case 'l': *(long long *)at = strtoll(t, &end, 10); break;
    default: return 0;
    }
    return *end == 0;
}

static char *read_file(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    size_t cap = 1 << 16, n = 0;
    char *buf = malloc(cap + 1);
    while (buf) {
        size_t got = fread(buf + n, 1, cap - n, f);
        n += got;
        if (n < cap)
            break;
        char *bigger = realloc(buf, 2 * cap + 1);
        if (!bigger) {
            free(buf);
            buf = NULL;
            break;
        }
        buf = bigger;
        cap *= 2;
    }
    fclose(f);
    if (buf)
        buf[n] = 0;
    return buf;
}

static int read_description(cw_system *s, char *text)
{
    reader r = {text, text};
    char *t = token(&r);
    int version = 0;
    if (!t || strcmp(t, "clockwork-system") || !int_token(&r, &version) || version != CW_FORMAT) {
        say(s, fmi2Error, "%s" CW_DESCRIPTION ": not a clockwork system description of format %d", s->resources,
            CW_FORMAT);
        return 0;
    }
    int fi = 0, ii = 0, vi = 0, ti = 0, port = -1;
    while ((t = token(&r)) != NULL) {
        int ok = 1;
        if (!strcmp(t, "guid")) {
            ok = (s->guid = text_token(&r)) != NULL;
        } else if (!strcmp(t, "counts")) {
            ok = int_token(&r, &s->n_fmus) && int_token(&r, &s->n_inst) && int_token(&r, &s->n_vars)
                 && int_token(&r, &s->n_items) && s->n_fmus >= 0 && s->n_inst > 0 && s->n_vars >= 0
                 && s->n_items >= 0;
            if (ok) {
                s->fmus = calloc((size_t)s->n_fmus + 1, sizeof *s->fmus);
                s->inst = calloc((size_t)s->n_inst, sizeof *s->inst);
                s->vars = calloc((size_t)s->n_vars + 1, sizeof *s->vars);
                s->items = calloc((size_t)s->n_items + 1, sizeof *s->items);
                ok = s->fmus && s->inst && s->vars && s->items;
            }
        } else if (!strcmp(t, "settings")) {
            ok = double_token(&r, &s->start_time) && double_token(&r, &s->step)
                 && double_token(&r, &s->divergence_limit);
        } else if (!strcmp(t, "fmu")) {
            ok = s->fmus && fi < s->n_fmus;
            if (ok) {
                cw_inner_fmu *f = &s->fmus[fi++];
                ok = (f->dir = text_token(&r)) && (f->identifier = text_token(&r)) && (f->guid = text_token(&r));
            }
        } else if (!strcmp(t, "instance")) {
            ok = s->inst && ii < s->n_inst;
            if (ok) {
                cw_instance *in = &s->inst[ii++];
                ok = (in->name = text_token(&r)) && int_token(&r, &in->fmu) && in->fmu >= 0 && in->fmu < s->n_fmus
                     && int_token(&r, &in->tol_defined) && double_token(&r, &in->tol)
                     && int_token(&r, &in->after_inputs);
            }
        } else if (!strcmp(t, "order")) {
            ok = int_token(&r, &s->n_order) && s->n_order >= 0 && s->n_order <= s->n_inst;
            if (ok) {
                s->order = calloc((size_t)s->n_order + 1, sizeof(int));
                for (int k = 0; ok && k < s->n_order; k++)
                    ok = s->order && int_token(&r, &s->order[k]) && s->order[k] >= 0 && s->order[k] < s->n_inst;
            }
        } else if (!strcmp(t, "var")) {
            ok = s->vars && vi < s->n_vars;
            if (ok) {
                cw_var *v = &s->vars[vi++];
                char *type = token(&r), *role = token(&r);
                int vr = 0, inner = 0;
                ok = type && role && int_token(&r, &vr) && int_token(&r, &v->inst) && int_token(&r, &inner)
                     && int_token(&r, &v->pos) && double_token(&r, &v->start) && v->inst >= 0
                     && v->inst < s->n_inst && strchr("RIB", type[0]) && strchr("poit", role[0]);
                if (ok) {
                    v->type = type[0];
                    v->role = role[0];
                    v->vr = (unsigned)vr;
                    v->inner_vr = (unsigned)inner;
                    v->value = v->start;
                }
            }
        } else if (!strcmp(t, "port")) {
            ok = int_token(&r, &port) && port >= 0 && port < s->n_inst;
        } else if (!strcmp(t, "master")) {
            port = -1;
        } else if (!strcmp(t, "a") || !strcmp(t, "s")) {
            ok = s->items && ti < s->n_items;
            if (ok) {
                cw_item *it = &s->items[ti++];
                char *name = token(&r), *kind = token(&r);
                ok = name && kind && strlen(name) < sizeof it->name && kind_size(kind[0]);
                if (ok) {
                    strcpy(it->name, name);
                    it->kind = kind[0];
                    it->port = port;
                    it->is_array = t[0] == 'a';
                    it->n = 1;
                    if (it->is_array)
                        ok = int_token(&r, &it->n) && it->n >= 0;
                }
                if (ok) {
                    size_t size = kind_size(it->kind);
                    it->values = calloc((size_t)(it->n > 0 ? it->n : 1), size);
                    ok = it->values != NULL;
                    char *peek = r.at;
                    while (*peek == ' ')
                        peek++;
                    if (ok && it->is_array && *peek == 'z') {  /* zeros: a work array */
                        token(&r);
                    } else {
                        for (int k = 0; ok && k < it->n; k++)
                            ok = value_token(&r, it->kind, (char *)it->values + (size_t)k * size);
                    }
                }
            }
        } else if (!strcmp(t, "end")) {
            break;
        } else {
            ok = 0;
        }
        if (!ok) {
            say(s, fmi2Error, "%s" CW_DESCRIPTION ": unreadable at '%s'", s->resources, t);
            return 0;
        }
    }
    if (!s->guid || fi != s->n_fmus || ii != s->n_inst || vi != s->n_vars || ti != s->n_items || !s->order) {
        say(s, fmi2Error, "%s" CW_DESCRIPTION ": incomplete", s->resources);
        return 0;
    }
    return 1;
}

/* -- loading the inner FMUs ----------------------------------------------- */

#ifdef _WIN32
#define CW_PLATFORM "win64"
#define CW_SUFFIX ".dll"
#define CW_SEP "\\"
#else
#define CW_PLATFORM "linux64"
#define CW_SUFFIX ".so"
#define CW_SEP "/"
#endif

static void *symbol(cw_inner_fmu *f, const char *name)
{
#ifdef _WIN32
    return (void *)GetProcAddress(f->lib, name);
#else
    return dlsym(f->lib, name);
#endif
}

static int load_fmu(cw_system *s, cw_inner_fmu *f)
{
    size_t n = strlen(s->resources) + strlen(f->dir) + strlen(f->identifier) + 64;
    char *path = malloc(n);
    if (!path)
        return 0;
    snprintf(path, n, "%s%s" CW_SEP "binaries" CW_SEP CW_PLATFORM CW_SEP "%s" CW_SUFFIX, s->resources, f->dir,
             f->identifier);
#ifdef _WIN32
    f->lib = LoadLibraryA(path);
#else
    int flags = RTLD_NOW | RTLD_LOCAL;
#ifdef RTLD_DEEPBIND
    flags |= RTLD_DEEPBIND;  /* the inner FMU's fmi2 symbols are its own, not this FMU's */
#endif
    f->lib = dlopen(path, flags);
#endif
    if (!f->lib) {
#ifdef _WIN32
        say(s, fmi2Error, "cannot load %s (error %lu)", path, (unsigned long)GetLastError());
#else
        say(s, fmi2Error, "cannot load %s (%s)", path, dlerror());
#endif
        free(path);
        return 0;
    }
    free(path);
#define CW_GET(field, name)                                                               \
    if (!(*(void **)&f->field = symbol(f, name))) {                                       \
        say(s, fmi2Error, "%s: the binary has no %s", f->identifier, name);               \
        return 0;                                                                         \
    }
    CW_GET(instantiate, "fmi2Instantiate")
    CW_GET(freeInstance, "fmi2FreeInstance")
    CW_GET(setupExperiment, "fmi2SetupExperiment")
    CW_GET(enterInit, "fmi2EnterInitializationMode")
    CW_GET(exitInit, "fmi2ExitInitializationMode")
    CW_GET(terminate, "fmi2Terminate")
    CW_GET(reset, "fmi2Reset")
    CW_GET(setReal, "fmi2SetReal")
    CW_GET(getReal, "fmi2GetReal")
    CW_GET(setInteger, "fmi2SetInteger")
    CW_GET(setBoolean, "fmi2SetBoolean")
    CW_GET(doStep, "fmi2DoStep")
    CW_GET(setInputDerivatives, "fmi2SetRealInputDerivatives")
    CW_GET(getOutputDerivatives, "fmi2GetRealOutputDerivatives")
    CW_GET(getState, "fmi2GetFMUstate")
    CW_GET(setState, "fmi2SetFMUstate")
    CW_GET(freeState, "fmi2FreeFMUstate")
#undef CW_GET
    return 1;
}

/* resources/<dir>/resources as a file URI. */
static char *resource_uri(cw_system *s, cw_inner_fmu *f)
{
    size_t n = 3 * (strlen(s->resources) + strlen(f->dir)) + 64;
    char *uri = malloc(n);
    if (!uri)
        return NULL;
    char path[4096];
    snprintf(path, sizeof path, "%s%s" CW_SEP "resources" CW_SEP, s->resources, f->dir);
    strcpy(uri, "file://");
    char *w = uri + strlen(uri);
#ifdef _WIN32
    *w++ = '/';
#endif
    for (const char *p = path; *p; p++) {
        unsigned char c = (unsigned char)*p;
        if (c == '\\')
            c = '/';
        if ((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || strchr("/-._~:", c)) {
            *w++ = (char)c;
        } else {
            sprintf(w, "%%%02X", c);
            w += 3;
        }
    }
    *w = 0;
    return uri;
}

/* The resources folder's path from fmuResourceLocation (a file URI). */
static char *resource_path(const char *uri)
{
    if (!uri)
        return NULL;
    const char *p = uri;
    if (!strncmp(p, "file://", 7)) {
        p += 7;
        if (!strncmp(p, "localhost/", 10))
            p += 9;
    } else if (!strncmp(p, "file:", 5)) {
        p += 5;
    }
#ifdef _WIN32
    if (p[0] == '/' && p[1] && p[2] == ':')
        p++;
#endif
    char *path = malloc(strlen(p) + 2);
    if (!path)
        return NULL;
    char *w = path;
    for (; *p; p++) {
        if (*p == '%' && p[1] && p[2]) {
            char hex[3] = {p[1], p[2], 0};
            *w++ = (char)strtol(hex, NULL, 16);
            p += 2;
        } else {
            *w++ = *p;
        }
    }
    if (w == path || (w[-1] != '/' && w[-1] != '\\'))
        *w++ = CW_SEP[0];
    *w = 0;
    return path;
}

/* -- the master's structs, by field name ----------------------------------- */

static const cw_field *find(const layout *L, const char *name)
{
    for (size_t k = 0; k < L->n; k++)
        if (!strcmp(L->fields[k].name, name))
            return &L->fields[k];
    return NULL;
}

static int put(cw_system *s, const layout *L, unsigned char *base, const char *name, const void *value, size_t size)
{
    const cw_field *f = find(L, name);
    if (!f || f->size != size) {
        say(s, fmi2Error, "the compiled master has no field %s of %u bytes: this FMU was exported by another "
            "version of clockwork", name, (unsigned)size);
        return 0;
    }
    memcpy(base + f->offset, value, size);
    return 1;
}

static void *get(const layout *L, unsigned char *base, const char *name)
{
    const cw_field *f = find(L, name);
    return f ? base + f->offset : NULL;
}

static int put_ptr(cw_system *s, const layout *L, unsigned char *base, const char *name, void *p)
{
    return put(s, L, base, name, &p, sizeof p);
}

static void free_master(cw_system *s)
{
    for (int k = 0; k < s->n_arrays; k++)
        free(s->arrays[k]);
    free(s->arrays);
    free(s->array_bytes);
    s->arrays = NULL;
    s->array_bytes = NULL;
    s->n_arrays = 0;
    free(s->master);
    free(s->ports);
    free(s->loops);
    free(s->buffer);
    s->master = s->ports = s->loops = NULL;
    s->t = NULL;
    s->buffer = NULL;
}

static unsigned char *port_at(cw_system *s, int i)
{
    return s->ports + (size_t)i * s->Lp.size;
}

static double *port_out(cw_system *s, int i)
{
    return *(double **)get(&s->Lp, port_at(s, i), "out");
}

static int port_int(cw_system *s, int i, const char *name)
{
    return *(int *)get(&s->Lp, port_at(s, i), name);
}

/* Every pointer of the master's structs: the item arrays, the instances'
 * functions and saved states, the output buffer, the ports and the loops.
 * Also after an FMU state is restored over the structs' bytes. */
static int wire(cw_system *s)
{
    for (int k = 0, a = 0; k < s->n_items; k++) {
        cw_item *it = &s->items[k];
        if (it->is_array && !put_ptr(s, it->port < 0 ? &s->Lm : &s->Lp,
                                     it->port < 0 ? s->master : port_at(s, it->port), it->name, s->arrays[a++]))
            return 0;
    }
    int offset = 0;
    for (int i = 0; i < s->n_inst; i++) {
        cw_instance *in = &s->inst[i];
        cw_inner_fmu *f = &s->fmus[in->fmu];
        unsigned char *p = port_at(s, i);
        int n = port_int(s, i, "n_out");
        if (!put_ptr(s, &s->Lp, p, "comp", in->comp) || !put_ptr(s, &s->Lp, p, "doStep", *(void **)&f->doStep)
            || !put_ptr(s, &s->Lp, p, "getReal", *(void **)&f->getReal)
            || !put_ptr(s, &s->Lp, p, "setReal", *(void **)&f->setReal)
            || !put_ptr(s, &s->Lp, p, "setInputDerivatives", *(void **)&f->setInputDerivatives)
            || !put_ptr(s, &s->Lp, p, "getOutputDerivatives", *(void **)&f->getOutputDerivatives)
            || !put_ptr(s, &s->Lp, p, "getState", *(void **)&f->getState)
            || !put_ptr(s, &s->Lp, p, "setState", *(void **)&f->setState)
            || !put_ptr(s, &s->Lp, p, "state", &in->state) || !put_ptr(s, &s->Lp, p, "out", s->buffer + offset))
            return 0;
        offset += n > 0 ? n : 1;
    }
    s->t = get(&s->Lm, s->master, "t");
    return put_ptr(s, &s->Ll, s->loops, "loop", s->arrays[s->n_arrays - 1])
           && put_ptr(s, &s->Lm, s->master, "ports", s->ports) && put_ptr(s, &s->Lm, s->master, "buffer", s->buffer)
           && put_ptr(s, &s->Lm, s->master, "loops", s->loops);
}

static int build_master(cw_system *s)
{
    s->Lm.fields = cw_layout("master", &s->Lm.n, &s->Lm.size);
    s->Lp.fields = cw_layout("port", &s->Lp.n, &s->Lp.size);
    s->Ll.fields = cw_layout("loops", &s->Ll.n, &s->Ll.size);
    if (!s->Lm.fields || !s->Lp.fields || !s->Ll.fields)
        return 0;
    s->master = calloc(1, s->Lm.size);
    s->ports = calloc((size_t)s->n_inst, s->Lp.size);
    s->loops = calloc(1, s->Ll.size);
    s->arrays = calloc((size_t)s->n_items + 2, sizeof(void *));
    s->array_bytes = calloc((size_t)s->n_items + 2, sizeof(size_t));
    if (!s->master || !s->ports || !s->loops || !s->arrays || !s->array_bytes)
        return 0;
    for (int k = 0; k < s->n_items; k++) {
        cw_item *it = &s->items[k];
        const layout *L = it->port < 0 ? &s->Lm : &s->Lp;
        unsigned char *base = it->port < 0 ? s->master : port_at(s, it->port);
        size_t size = kind_size(it->kind);
        if (it->is_array) {
            size_t bytes = (size_t)(it->n > 0 ? it->n : 1) * size;
            void *copy = calloc(1, bytes);
            if (!copy)
                return 0;
            s->array_bytes[s->n_arrays] = bytes;
            s->arrays[s->n_arrays++] = copy;
            memcpy(copy, it->values, (size_t)it->n * size);
        } else if (!put(s, L, base, it->name, it->values, size)) {
            return 0;
        }
    }
    /* The loops' array (no loops are exported, so never read), last. */
    if (!(s->arrays[s->n_arrays] = calloc(1, 64)))
        return 0;
    s->array_bytes[s->n_arrays++] = 64;
    /* The output buffer: each port's outputs (at least one slot) in turn. */
    s->n_buffer = 0;
    for (int i = 0; i < s->n_inst; i++) {
        int n = *(int *)get(&s->Lp, port_at(s, i), "n_out");
        s->n_buffer += n > 0 ? n : 1;
    }
    s->buffer = calloc((size_t)s->n_buffer, sizeof(double));
    if (!s->buffer)
        return 0;
    double tol = *(double *)get(&s->Lm, s->master, "iteration_tolerance");
    return put(s, &s->Ll, s->loops, "tolerance", &tol, sizeof tol)
           && put(s, &s->Lm, s->master, "n_buffer", &s->n_buffer, sizeof(int)) && wire(s);
}

/* -- initialization, as Master.initialize ---------------------------------- */

static int check(cw_system *s, int inst, fmi2Status st, const char *call)
{
    if (st > fmi2Warning) {
        say(s, fmi2Error, "%s: %s failed (status %d)", s->inst[inst].name, call, (int)st);
        return 0;
    }
    return 1;
}

static int port_read(cw_system *s, int i)
{
    unsigned char *p = port_at(s, i);
    int n = port_int(s, i, "n_out");
    if (n) {
        const unsigned *vr = *(const unsigned **)get(&s->Lp, p, "out_vr");
        if (!check(s, i, s->fmus[s->inst[i].fmu].getReal(s->inst[i].comp, vr, (size_t)n, port_out(s, i)),
                   "fmi2GetReal"))
            return 0;
    }
    return 1;
}

/* Port.pull: inputs from their sources (with the links' factor and offset), then the outputs. */
static int port_pull(cw_system *s, int i)
{
    unsigned char *p = port_at(s, i);
    int n_in = port_int(s, i, "n_in");
    if (n_in) {
        double *inp = *(double **)get(&s->Lp, p, "inp");
        const int *src_port = *(const int **)get(&s->Lp, p, "src_port");
        const int *src_pos = *(const int **)get(&s->Lp, p, "src_pos");
        const int *scaled = *(const int **)get(&s->Lp, p, "scaled");
        const double *factor = *(const double **)get(&s->Lp, p, "in_factor");
        const double *offset = *(const double **)get(&s->Lp, p, "in_offset");
        const unsigned *in_vr = *(const unsigned **)get(&s->Lp, p, "in_vr");
        for (int k = 0; k < n_in; k++)
            inp[k] = port_out(s, src_port[k])[src_pos[k]];
        for (int a = 0; a < port_int(s, i, "n_scaled"); a++)
            inp[scaled[a]] = factor[a] * inp[scaled[a]] + offset[a];
        if (!check(s, i, s->fmus[s->inst[i].fmu].setReal(s->inst[i].comp, in_vr, (size_t)n_in, inp),
                   "fmi2SetReal of inputs"))
            return 0;
        int zero = 0;
        put(s, &s->Lp, p, "sent_valid", &zero, sizeof zero);
    }
    return port_read(s, i);
}

static int set_var(cw_system *s, cw_var *v)
{
    cw_instance *in = &s->inst[v->inst];
    cw_inner_fmu *f = &s->fmus[in->fmu];
    fmi2Status st;
    if (v->type == 'R') {
        st = f->setReal(in->comp, &v->inner_vr, 1, &v->value);
    } else {
        fmi2Integer x = (fmi2Integer)v->value;
        st = v->type == 'I' ? f->setInteger(in->comp, &v->inner_vr, 1, &x) : f->setBoolean(in->comp, &v->inner_vr, 1, &x);
    }
    return check(s, v->inst, st, v->role == 'p' ? "setting parameters" : "fmi2Set* of inputs");
}

static int diverged(cw_system *s, double t)
{
    double sum = 0.0;
    for (int k = 0; k < s->n_buffer; k++)
        sum += fabs(s->buffer[k]);
    if (sum < s->divergence_limit)
        return 0;
    for (int k = 0; k < s->n_buffer; k++) {
        double x = s->buffer[k];
        if (!(-s->divergence_limit < x && x < s->divergence_limit)) {
            say(s, fmi2Error, "an output = %.17g is not finite or exceeds the divergence limit %g at t = %.17g s",
                x, s->divergence_limit, t);
            return 1;
        }
    }
    return 0;  /* a sum of large but legal outputs */
}

/* The inner FMUs into Initialization Mode as Master.initialize takes them
 * there: setup, the parameters in the scene's order, inputs set so far,
 * then two sweeps of the evaluation order settle feedthrough chains. Done
 * at the end of the front's Initialization Mode, or earlier when the
 * importer reads an output in it (FMI 2.0 allows that: the outputs'
 * initial values). */
static int enter_inner(cw_system *s)
{
    for (int i = 0; i < s->n_inst; i++) {
        cw_instance *in = &s->inst[i];
        cw_inner_fmu *f = &s->fmus[in->fmu];
        if (!check(s, i, f->setupExperiment(in->comp, in->tol_defined, in->tol, s->start_time, fmi2False, 0.0),
                   "fmi2SetupExperiment"))
            return 0;
        for (int k = 0; k < s->n_vars; k++) {
            cw_var *v = &s->vars[k];
            if (v->inst != i)
                continue;
            if ((v->role == 'p' || (v->role == 'i' && v->set)) && !set_var(s, v))
                return 0;
            v->set = 0;
        }
        if (!check(s, i, f->enterInit(in->comp), "fmi2EnterInitializationMode"))
            return 0;
    }
    for (int i = 0; i < s->n_inst; i++)
        s->inst[i].state = NULL;  /* freed by fmi2Reset */
    if (!build_master(s))
        return 0;
    for (int sweep = 0; sweep < 2; sweep++)
        for (int a = 0; a < s->n_order; a++)
            if (!port_pull(s, s->order[a]))
                return 0;
    s->inner_init = 1;
    s->pending = 0;
    return 1;
}

/* Variables the importer set after the inner FMUs entered Initialization
 * Mode: set on them, and the outputs settled again. */
static int apply_pending(cw_system *s)
{
    if (!s->pending)
        return 1;
    for (int k = 0; k < s->n_vars; k++) {
        cw_var *v = &s->vars[k];
        if ((v->role == 'p' || v->role == 'i') && v->set) {
            if (!set_var(s, v))
                return 0;
            v->set = 0;
        }
    }
    s->pending = 0;
    for (int sweep = 0; sweep < 2; sweep++)
        for (int a = 0; a < s->n_order; a++)
            if (!port_pull(s, s->order[a]))
                return 0;
    return 1;
}

static int initialize(cw_system *s)
{
    if (!s->inner_init && !enter_inner(s))
        return 0;
    if (!apply_pending(s))
        return 0;
    for (int i = 0; i < s->n_inst; i++)
        if (!check(s, i, s->fmus[s->inst[i].fmu].exitInit(s->inst[i].comp), "fmi2ExitInitializationMode"))
            return 0;
    for (int a = 0; a < s->n_order; a++) {  /* Ports.after_init */
        int i = s->order[a];
        if (!(s->inst[i].after_inputs ? port_pull(s, i) : port_read(s, i)))
            return 0;
    }
    if (diverged(s, s->start_time))
        return 0;
    for (int i = 0; i < s->n_inst; i++) {
        int zero = 0;
        if (!put(s, &s->Lp, port_at(s, i), "out_time", &s->start_time, sizeof(double))
            || !put(s, &s->Lp, port_at(s, i), "sent_valid", &zero, sizeof zero))
            return 0;
    }
    if (!put(s, &s->Lm, s->master, "t", &s->start_time, sizeof(double))
        || !put(s, &s->Lm, s->master, "start_time", &s->start_time, sizeof(double)))
        return 0;
    cw_start(s->master);
    return 1;
}

/* An input the importer changed between steps: set, the outputs again, and
 * a discontinuity for the master (Master.discontinuity). */
static int apply_inputs(cw_system *s)
{
    int changed = 0;
    for (int k = 0; k < s->n_vars; k++) {
        cw_var *v = &s->vars[k];
        if (v->role == 'i' && v->set) {
            if (!set_var(s, v))
                return 0;
            v->set = 0;
            changed = 1;
        }
    }
    if (!changed)
        return 1;
    for (int a = 0; a < s->n_order; a++) {  /* Ports.refresh */
        int i = s->order[a];
        if (s->inst[i].after_inputs && !port_pull(s, i))
            return 0;
    }
    cw_discontinuity(s->master);
    return 1;
}

static double master_t(cw_system *s)
{
    return *s->t;
}

static const char *why(int rc)
{
    switch (rc) {
    case CW_ERR_FMI: return "an inner FMU's call failed";
    case CW_ERR_NO_CHECKPOINT: return "an event indicator changed sign in a step without a checkpoint";
    case CW_ERR_REPLAY: return "a replay did not end where it should";
    case CW_ERR_LOCATE: return "event location did not converge";
    case CW_ERR_CAPACITY: return "the master ran out of room";
    case CW_ERR_LOOP: return "an algebraic loop did not converge";
    default: return "the compiled master stopped";
    }
}

/* -- the FMI 2.0 functions ------------------------------------------------- */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String categories[])
{
    if (!c)
        return fmi2Error;
    ((cw_system *)c)->logging = on != 0;
    return fmi2OK;
}

static void free_system(cw_system *s)
{
    if (!s)
        return;
    free_master(s);
    for (int i = 0; s->inst && i < s->n_inst; i++) {
        cw_instance *in = &s->inst[i];
        if (in->comp) {
            cw_inner_fmu *f = &s->fmus[in->fmu];
            if (in->state)
                f->freeState(in->comp, &in->state);
            f->freeInstance(in->comp);
        }
        free(in->name);
    }
    for (int k = 0; s->fmus && k < s->n_fmus; k++) {
        cw_inner_fmu *f = &s->fmus[k];
        if (f->lib) {
#ifdef _WIN32
            FreeLibrary(f->lib);
#else
            dlclose(f->lib);
#endif
        }
        free(f->dir);
        free(f->identifier);
        free(f->guid);
    }
    for (int k = 0; s->items && k < s->n_items; k++)
        free(s->items[k].values);
    free(s->items);
    free(s->fmus);
    free(s->inst);
    free(s->vars);
    free(s->order);
    free(s->guid);
    free(s->resources);
    free(s->name);
    free(s);
}

/* The system, its description read from resources/ (a folder path ending in
 * a separator) and its FMUs loaded and instantiated; NULL after saying why. */
static cw_system *instantiate(cw_system *s, const char *name, const char *guid, int logging)
{
    s->logging = logging != 0;
    s->name = malloc(strlen(name ? name : "") + 1);
    if (s->name)
        strcpy(s->name, name ? name : "");
    char *text = NULL;
    if (s->resources) {
        size_t n = strlen(s->resources) + sizeof CW_DESCRIPTION;
        char *path = malloc(n);
        if (path) {
            snprintf(path, n, "%s%s", s->resources, CW_DESCRIPTION);
            text = read_file(path);
            if (!text)
                say(s, fmi2Error, "cannot read %s", path);
            free(path);
        }
    } else {
        say(s, fmi2Error, "no resource location");
    }
    int ok = text && read_description(s, text);
    free(text);
    if (ok && (!guid || strcmp(guid, s->guid))) {
        say(s, fmi2Error, "GUID %s does not match the description's %s", guid ? guid : "(none)", s->guid);
        ok = 0;
    }
    for (int k = 0; ok && k < s->n_fmus; k++)
        ok = load_fmu(s, &s->fmus[k]);
    /* The C library's calloc and free for the inner FMUs, as clockwork gives them: an importer's own
     * (fmpy's are Python callbacks) would be called at every FMU state the master saves. */
    fmi2CallbackFunctions inner = {inner_logger, calloc, free, NULL, s};
    for (int i = 0; ok && i < s->n_inst; i++) {
        cw_instance *in = &s->inst[i];
        cw_inner_fmu *f = &s->fmus[in->fmu];
        char *uri = resource_uri(s, f);
        in->comp = uri ? f->instantiate(in->name, fmi2CoSimulation, f->guid, uri, &inner, fmi2False,
                                        logging) : NULL;
        free(uri);
        if (!in->comp) {
            say(s, fmi2Error, "%s: fmi2Instantiate failed", in->name);
            ok = 0;
        }
    }
    if (!ok) {
        free_system(s);
        return NULL;
    }
    s->mode = MODE_INSTANTIATED;
    return s;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible, fmi2Boolean logging)
{
    if (!functions || !functions->logger)
        return NULL;
    cw_system *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    s->cb = *functions;
    if (type != fmi2CoSimulation) {
        say(s, fmi2Error, "this FMU has Co-Simulation only");
        free_system(s);
        return NULL;
    }
    s->resources = resource_path(resources);
    return instantiate(s, name, guid, logging);
}

void fmi2FreeInstance(fmi2Component c)
{
    free_system((cw_system *)c);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolerance_defined, fmi2Real tolerance,
                               fmi2Real start, fmi2Boolean stop_defined, fmi2Real stop)
{
    cw_system *s = c;
    if (!s || s->mode != MODE_INSTANTIATED)
        return fmi2Error;
    s->start_time = start;  /* the grid starts here; the scene's own tolerance and settings stay */
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    cw_system *s = c;
    if (!s || s->mode != MODE_INSTANTIATED)
        return fmi2Error;
    s->mode = MODE_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    cw_system *s = c;
    if (!s || s->mode != MODE_INIT)
        return fmi2Error;
    if (!initialize(s)) {
        s->mode = MODE_ERROR;
        return fmi2Error;
    }
    s->mode = MODE_STEP;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    cw_system *s = c;
    if (!s)
        return fmi2Error;
    fmi2Status worst = fmi2OK;
    for (int i = 0; i < s->n_inst; i++) {
        if (s->mode == MODE_STEP) {
            fmi2Status st = s->fmus[s->inst[i].fmu].terminate(s->inst[i].comp);
            if (st > worst)
                worst = st;
        }
    }
    s->mode = MODE_TERMINATED;
    return worst > fmi2Warning ? fmi2Error : worst;
}

fmi2Status fmi2Reset(fmi2Component c)
{
    cw_system *s = c;
    if (!s)
        return fmi2Error;
    for (int i = 0; i < s->n_inst; i++) {
        cw_instance *in = &s->inst[i];
        cw_inner_fmu *f = &s->fmus[in->fmu];
        if (in->state) {
            f->freeState(in->comp, &in->state);
            in->state = NULL;
        }
        if (!check(s, i, f->reset(in->comp), "fmi2Reset")) {
            s->mode = MODE_ERROR;
            return fmi2Error;
        }
    }
    free_master(s);
    for (int k = 0; k < s->n_vars; k++) {
        s->vars[k].value = s->vars[k].start;
        s->vars[k].set = 0;
    }
    s->inner_init = s->pending = 0;
    s->mode = MODE_INSTANTIATED;
    return fmi2OK;
}

static cw_var *var_of(cw_system *s, fmi2ValueReference vr, char type)
{
    if (vr < (unsigned)s->n_vars && s->vars[vr].vr == vr && s->vars[vr].type == type)
        return &s->vars[vr];  /* the exporter numbers the variables 0, 1, ... in order */
    return NULL;
}

/* In Initialization Mode an output's value is the inner FMUs' initial one:
 * they enter Initialization Mode on the first such read. 0: failed. */
static int ready_to_read(cw_system *s, cw_var *v)
{
    if (s->mode != MODE_INIT || v->role != 'o')
        return 1;
    if (!s->inner_init && !enter_inner(s))
        return 0;
    return apply_pending(s);
}

static double value_of(cw_system *s, cw_var *v)
{
    if (v->role == 'o')
        return s->master ? port_out(s, v->inst)[v->pos] : 0.0;
    if (v->role == 't')  /* FMI 3.0's independent variable */
        return s->t ? *s->t : s->start_time;
    return v->value;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[])
{
    cw_system *s = c;
    if (!s || (n && (!vr || !value)))
        return fmi2Error;
    for (size_t k = 0; k < n; k++) {
        cw_var *v = var_of(s, vr[k], 'R');
        if (!v) {
            say(s, fmi2Error, "fmi2GetReal: no Real variable with value reference %u", vr[k]);
            return fmi2Error;
        }
        if (!ready_to_read(s, v)) {
            s->mode = MODE_ERROR;
            return fmi2Error;
        }
        value[k] = value_of(s, v);
    }
    return fmi2OK;
}

static fmi2Status get_whole(cw_system *s, const fmi2ValueReference vr[], size_t n, fmi2Integer value[], char type)
{
    if (!s || (n && (!vr || !value)))
        return fmi2Error;
    for (size_t k = 0; k < n; k++) {
        cw_var *v = var_of(s, vr[k], type);
        if (!v) {
            say(s, fmi2Error, "no %s variable with value reference %u", type == 'I' ? "Integer" : "Boolean", vr[k]);
            return fmi2Error;
        }
        value[k] = (fmi2Integer)v->value;
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer value[])
{
    return get_whole(c, vr, n, value, 'I');
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean value[])
{
    return get_whole(c, vr, n, value, 'B');
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String value[])
{
    cw_system *s = c;
    if (n)
        say(s, fmi2Error, "fmi2GetString: this FMU has no String variables");
    return n ? fmi2Error : fmi2OK;
}

/* A parameter before initialization, an input any time before a step. */
static fmi2Status set_value(cw_system *s, fmi2ValueReference vr, char type, double x)
{
    cw_var *v = var_of(s, vr, type);
    if (!v || v->role == 'o' || v->role == 't') {
        say(s, fmi2Error, "no settable variable of this type with value reference %u", vr);
        return fmi2Error;
    }
    if (v->role == 'p' && s->mode != MODE_INSTANTIATED && s->mode != MODE_INIT) {
        say(s, fmi2Error, "parameter with value reference %u: fixed after initialization", vr);
        return fmi2Error;
    }
    if (s->mode == MODE_TERMINATED || s->mode == MODE_ERROR)
        return fmi2Error;
    if (v->role == 'i' && s->mode == MODE_STEP && x == v->value)
        return fmi2OK;  /* the same value again: nothing changed */
    v->value = x;
    v->set = 1;
    if (s->mode == MODE_INIT && s->inner_init)
        s->pending = 1;
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[])
{
    cw_system *s = c;
    if (!s || (n && (!vr || !value)))
        return fmi2Error;
    for (size_t k = 0; k < n; k++)
        if (set_value(s, vr[k], 'R', value[k]) != fmi2OK)
            return fmi2Error;
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer value[])
{
    cw_system *s = c;
    if (!s || (n && (!vr || !value)))
        return fmi2Error;
    for (size_t k = 0; k < n; k++)
        if (set_value(s, vr[k], 'I', (double)value[k]) != fmi2OK)
            return fmi2Error;
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean value[])
{
    cw_system *s = c;
    if (!s || (n && (!vr || !value)))
        return fmi2Error;
    for (size_t k = 0; k < n; k++)
        if (set_value(s, vr[k], 'B', value[k] ? 1.0 : 0.0) != fmi2OK)
            return fmi2Error;
    return fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String value[])
{
    return n ? fmi2Error : fmi2OK;
}

/* -- the FMU state: the master's structs and arrays, the importer's values,
 * and every inner FMU's state and the master's saved one, serialized ------- */

typedef struct {
    size_t size;
    unsigned char bytes[];
} cw_state;

typedef struct {
    unsigned char *data;
    size_t n, cap;
    int failed;
} writer;

static void put_bytes(writer *w, const void *p, size_t n)
{
    if (w->failed)
        return;
    if (w->n + n > w->cap) {
        size_t cap = w->cap ? w->cap : 4096;
        while (cap < w->n + n)
            cap *= 2;
        unsigned char *bigger = realloc(w->data, cap);
        if (!bigger) {
            w->failed = 1;
            return;
        }
        w->data = bigger;
        w->cap = cap;
    }
    memcpy(w->data + w->n, p, n);
    w->n += n;
}

static void put_size(writer *w, size_t n)
{
    unsigned long long x = n;
    put_bytes(w, &x, sizeof x);
}

static const char CW_STATE_MAGIC[8] = "cwsys01";

/* An inner FMU state, serialized (size, then bytes). */
static int put_inner(cw_system *s, writer *w, int i, fmi2FMUstate st)
{
    cw_inner_fmu *f = &s->fmus[s->inst[i].fmu];
    fmi2SerializedFMUstateSizeTYPE *size_of = (fmi2SerializedFMUstateSizeTYPE *)symbol(f, "fmi2SerializedFMUstateSize");
    fmi2SerializeFMUstateTYPE *serialize = (fmi2SerializeFMUstateTYPE *)symbol(f, "fmi2SerializeFMUstate");
    size_t n = 0;
    if (!size_of || !serialize || !check(s, i, size_of(s->inst[i].comp, st, &n), "fmi2SerializedFMUstateSize"))
        return 0;
    unsigned char *bytes = malloc(n ? n : 1);
    if (!bytes || !check(s, i, serialize(s->inst[i].comp, st, (fmi2Byte *)bytes, n), "fmi2SerializeFMUstate")) {
        free(bytes);
        return 0;
    }
    put_size(w, n);
    put_bytes(w, bytes, n);
    free(bytes);
    return 1;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    cw_system *s = c;
    if (!s || !state)
        return fmi2Error;
    if (s->mode != MODE_STEP || !s->master) {
        say(s, fmi2Error, "fmi2GetFMUstate: the state is kept from the end of initialization on");
        return fmi2Error;
    }
    writer w = {0};
    put_bytes(&w, CW_STATE_MAGIC, sizeof CW_STATE_MAGIC);
    size_t counts[] = {(size_t)s->n_inst, s->Lm.size, s->Lp.size, s->Ll.size, (size_t)s->n_arrays,
                       (size_t)s->n_buffer, (size_t)s->n_vars};
    for (size_t k = 0; k < sizeof counts / sizeof counts[0]; k++)
        put_size(&w, counts[k]);
    put_bytes(&w, s->master, s->Lm.size);
    put_bytes(&w, s->ports, (size_t)s->n_inst * s->Lp.size);
    put_bytes(&w, s->loops, s->Ll.size);
    for (int k = 0; k < s->n_arrays; k++) {
        put_size(&w, s->array_bytes[k]);
        put_bytes(&w, s->arrays[k], s->array_bytes[k]);
    }
    put_bytes(&w, s->buffer, (size_t)s->n_buffer * sizeof(double));
    for (int k = 0; k < s->n_vars; k++) {
        put_bytes(&w, &s->vars[k].value, sizeof(double));
        put_bytes(&w, &s->vars[k].set, sizeof(int));
    }
    int ok = 1;
    for (int i = 0; ok && i < s->n_inst; i++) {
        cw_instance *in = &s->inst[i];
        cw_inner_fmu *f = &s->fmus[in->fmu];
        fmi2FMUstate now = NULL;
        ok = check(s, i, f->getState(in->comp, &now), "fmi2GetFMUstate") && put_inner(s, &w, i, now);
        if (now)
            f->freeState(in->comp, &now);
        if (ok) {
            put_size(&w, in->state != NULL);  /* the master's checkpoint of this FMU, where it holds one */
            if (in->state)
                ok = put_inner(s, &w, i, in->state);
        }
    }
    if (!ok || w.failed) {
        free(w.data);
        if (w.failed)
            say(s, fmi2Error, "fmi2GetFMUstate: out of memory");
        return fmi2Error;
    }
    cw_state *st = malloc(sizeof(cw_state) + w.n);
    if (!st) {
        free(w.data);
        return fmi2Error;
    }
    st->size = w.n;
    memcpy(st->bytes, w.data, w.n);
    free(w.data);
    if (*state)
        free(*state);  /* a state given back to be overwritten (FMI 2.0 2.1.8) */
    *state = st;
    return fmi2OK;
}

typedef struct {
    const unsigned char *at, *end;
} bytes_reader;

static int take(bytes_reader *r, void *out, size_t n)
{
    if ((size_t)(r->end - r->at) < n)
        return 0;
    if (out)
        memcpy(out, r->at, n);
    r->at += n;
    return 1;
}

static int take_size(bytes_reader *r, size_t *n)
{
    unsigned long long x;
    if (!take(r, &x, sizeof x))
        return 0;
    *n = (size_t)x;
    return 1;
}

static int inner_from(cw_system *s, bytes_reader *r, int i, fmi2FMUstate *out)
{
    cw_inner_fmu *f = &s->fmus[s->inst[i].fmu];
    fmi2DeSerializeFMUstateTYPE *deserialize = (fmi2DeSerializeFMUstateTYPE *)symbol(f, "fmi2DeSerializeFMUstate");
    size_t n;
    if (!deserialize || !take_size(r, &n) || (size_t)(r->end - r->at) < n)
        return 0;
    *out = NULL;
    int ok = check(s, i, deserialize(s->inst[i].comp, (const fmi2Byte *)r->at, n, out), "fmi2DeSerializeFMUstate");
    r->at += n;
    return ok;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state)
{
    cw_system *s = c;
    cw_state *st = state;
    if (!s || !st)
        return fmi2Error;
    if (s->mode != MODE_STEP || !s->master) {
        say(s, fmi2Error, "fmi2SetFMUstate: the state is set from the end of initialization on");
        return fmi2Error;
    }
    bytes_reader r = {st->bytes, st->bytes + st->size};
    char magic[sizeof CW_STATE_MAGIC];
    size_t counts[7];
    size_t expect[] = {(size_t)s->n_inst, s->Lm.size, s->Lp.size, s->Ll.size, (size_t)s->n_arrays,
                       (size_t)s->n_buffer, (size_t)s->n_vars};
    int ok = take(&r, magic, sizeof magic) && !memcmp(magic, CW_STATE_MAGIC, sizeof magic);
    for (int k = 0; ok && k < 7; k++)
        ok = take_size(&r, &counts[k]) && counts[k] == expect[k];
    ok = ok && take(&r, s->master, s->Lm.size) && take(&r, s->ports, (size_t)s->n_inst * s->Lp.size)
         && take(&r, s->loops, s->Ll.size);
    for (int k = 0; ok && k < s->n_arrays; k++) {
        size_t n;
        ok = take_size(&r, &n) && n == s->array_bytes[k] && take(&r, s->arrays[k], n);
    }
    ok = ok && take(&r, s->buffer, (size_t)s->n_buffer * sizeof(double));
    for (int k = 0; ok && k < s->n_vars; k++)
        ok = take(&r, &s->vars[k].value, sizeof(double)) && take(&r, &s->vars[k].set, sizeof(int));
    if (!ok || !wire(s)) {
        say(s, fmi2Error, "fmi2SetFMUstate: not a state of this FMU");
        s->mode = MODE_ERROR;
        return fmi2Error;
    }
    for (int i = 0; ok && i < s->n_inst; i++) {
        cw_instance *in = &s->inst[i];
        cw_inner_fmu *f = &s->fmus[in->fmu];
        fmi2FMUstate now = NULL;
        ok = inner_from(s, &r, i, &now) && check(s, i, f->setState(in->comp, now), "fmi2SetFMUstate");
        if (now)
            f->freeState(in->comp, &now);
        size_t held = 0;
        ok = ok && take_size(&r, &held);
        if (ok && in->state) {
            f->freeState(in->comp, &in->state);
            in->state = NULL;
        }
        if (ok && held)
            ok = inner_from(s, &r, i, &in->state);
    }
    if (!ok) {
        s->mode = MODE_ERROR;
        return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    if (state) {
        free(*state);
        *state = NULL;
    }
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size)
{
    if (!state || !size)
        return fmi2Error;
    *size = sizeof(unsigned long long) + ((cw_state *)state)->size;
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[], size_t size)
{
    cw_state *st = state;
    unsigned long long n = st ? st->size : 0;
    if (!st || !bytes || size < sizeof n + st->size)
        return fmi2Error;
    memcpy(bytes, &n, sizeof n);
    memcpy(bytes + sizeof n, st->bytes, st->size);
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size, fmi2FMUstate *state)
{
    unsigned long long n;
    if (!bytes || !state || size < sizeof n)
        return fmi2Error;
    memcpy(&n, bytes, sizeof n);
    if (n != size - sizeof n || n < sizeof CW_STATE_MAGIC || memcmp(bytes + sizeof n, CW_STATE_MAGIC, sizeof CW_STATE_MAGIC)) {
        say((cw_system *)c, fmi2Error, "fmi2DeSerializeFMUstate: not a state of this FMU");
        return fmi2Error;
    }
    cw_state *st = malloc(sizeof(cw_state) + n);
    if (!st)
        return fmi2Error;
    st->size = (size_t)n;
    memcpy(st->bytes, bytes + sizeof n, (size_t)n);
    *state = st;
    return fmi2OK;
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real du[], fmi2Real dz[])
{
    return fmi2Error;
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    return fmi2Error;  /* canInterpolateInputs is false */
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real value[])
{
    return fmi2Error;  /* maxOutputDerivativeOrder is 0 */
}

/* One communication step: the master from t to t + H on the scene's grid
 * start + k * step (an end within 1e-9 steps of a grid point is that point,
 * so that the importer's t + H lands where clockwork run's steps land). */
/* The master from its time to stop as cw_run_until steps it (the same grid,
 * the same steps), but returning after the first step that ended at a
 * located event (FMI 3.0 early return): *early is then set. */
static int run_to_event(cw_system *s, double stop, int *early)
{
    double h_nom = s->step, t0 = s->start_time;
    double eps = 1e-12 * (fabs(stop) > 1.0 ? fabs(stop) : 1.0);
    long long k = (long long)floor((*s->t - t0) / h_nom + 1e-9) + 1;
    long long *events = get(&s->Lm, s->master, "events");
    while (*s->t < stop - eps) {
        double grid = t0 + (double)k * h_nom;
        if (grid > stop)
            grid = stop;
        double h = grid - *s->t;
        if (h <= eps) {
            k++;
            continue;
        }
        long long before = *events;
        double taken;
        int rc = cw_step(s->master, h, &taken);
        if (rc < 0 || (rc != CW_DONE && rc != CW_CHECK_DIVERGENCE))
            return rc;
        if (*s->t >= grid - eps)
            k++;
        if (rc == CW_CHECK_DIVERGENCE && diverged(s, *s->t))
            return rc;
        if (*events != before && *s->t < stop - eps) {
            *early = 1;
            return CW_DONE;
        }
    }
    return CW_DONE;
}

/* One communication step: the master from t to t + H on the scene's grid
 * start + k * step (an end within 1e-9 steps of a grid point is that point,
 * so that the importer's t + H lands where clockwork run's steps land).
 * `early`: FMI 3.0's early return allowed; *returned_early says it was taken. */
static fmi2Status do_step(cw_system *s, double t, double h, int early, int *returned_early)
{
    if (!s || s->mode != MODE_STEP)
        return fmi2Error;
    double now = master_t(s);
    double slack = 1e-9 * s->step;
    if (!(h >= 0.0) || fabs(t - now) > slack + 1e-12 * fabs(now)) {
        say(s, fmi2Error, "DoStep(%.17g, %.17g): the system is at t = %.17g s", t, h, now);
        return fmi2Error;
    }
    if (!apply_inputs(s)) {
        s->mode = MODE_ERROR;
        return fmi2Error;
    }
    double stop = t + h;
    double k = nearbyint((stop - s->start_time) / s->step);
    double grid = s->start_time + k * s->step;
    if (fabs(grid - stop) <= slack)
        stop = grid;
    for (;;) {
        int rc = early ? run_to_event(s, stop, returned_early) : cw_run_until(s->master, stop, NULL, 0.0);
        if (rc == CW_DONE)
            return fmi2OK;
        if (rc == CW_CHECK_DIVERGENCE && !diverged(s, master_t(s)))
            continue;  /* large but legal outputs: on */
        if (rc != CW_CHECK_DIVERGENCE)
            say(s, fmi2Error, "at t = %.17g s: %s (code %d)", master_t(s), why(rc), rc);
        s->mode = MODE_ERROR;
        return fmi2Error;
    }
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_set_prior)
{
    return do_step(c, t, h, 0, NULL);
}

fmi2Status fmi2CancelStep(fmi2Component c) { return fmi2Error; }

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind kind, fmi2Status *value) { return fmi2Discard; }

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind kind, fmi2Real *value)
{
    cw_system *s = c;
    if (s && s->master && s->t && kind == fmi2LastSuccessfulTime) {
        *value = master_t(s);
        return fmi2OK;
    }
    return fmi2Discard;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind kind, fmi2Integer *value) { return fmi2Discard; }

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind kind, fmi2Boolean *value)
{
    if (kind == fmi2Terminated && value) {
        *value = fmi2False;
        return fmi2OK;
    }
    return fmi2Discard;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind kind, fmi2String *value) { return fmi2Discard; }

/* -- the FMI 3.0 face (export-fmu --fmi 3): the same system behind fmi3
 * calls; the inner FMUs stay FMI 2.0. Statuses have the same numbers. ---- */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean on, size_t n, const fmi3String categories[])
{
    if (!c)
        return fmi3Error;
    ((cw_system *)c)->logging = on;
    return fmi3OK;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String resources, fmi3Boolean visible,
                                         fmi3Boolean logging, fmi3Boolean event_mode, fmi3Boolean early_return,
                                         const fmi3ValueReference required[], size_t n_required,
                                         fmi3InstanceEnvironment env, fmi3LogMessageCallback log,
                                         fmi3IntermediateUpdateCallback update)
{
    cw_system *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    s->log3 = log;
    s->env3 = env;
    s->early_return = early_return;  /* at the inner events located inside a step */
    if (resources) {  /* a folder path (FMI 3.0 2.4.7), its separator at the end */
        size_t n = strlen(resources);
        s->resources = malloc(n + 2);
        if (s->resources) {
            strcpy(s->resources, resources);
            if (n == 0 || (resources[n - 1] != '/' && resources[n - 1] != '\\'))
                strcat(s->resources, CW_SEP);
        }
    }
    return instantiate(s, name, token, logging);
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token, fmi3String resources, fmi3Boolean visible,
                                          fmi3Boolean logging, fmi3InstanceEnvironment env, fmi3LogMessageCallback log)
{
    if (log)
        log(env, fmi3Error, "logStatusError", "this FMU has Co-Simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String name, fmi3String token, fmi3String resources,
                                               fmi3Boolean visible, fmi3Boolean logging, fmi3InstanceEnvironment env,
                                               fmi3LogMessageCallback log, fmi3ClockUpdateCallback clock_update,
                                               fmi3LockPreemptionCallback lock, fmi3UnlockPreemptionCallback unlock)
{
    if (log)
        log(env, fmi3Error, "logStatusError", "this FMU has Co-Simulation only");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance c) { free_system((cw_system *)c); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean tolerance_defined, fmi3Float64 tolerance,
                                       fmi3Float64 start, fmi3Boolean stop_defined, fmi3Float64 stop)
{
    fmi2Status st = fmi2SetupExperiment(c, tolerance_defined, tolerance, start, stop_defined, stop);
    return st != fmi2OK ? (fmi3Status)st : (fmi3Status)fmi2EnterInitializationMode(c);
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance c)
{
    cw_system *s = c;
    fmi2Status st = fmi2ExitInitializationMode(c);
    if (st == fmi2OK && s)
        s->mode = MODE_STEP;  /* FMI 3.0 Co-Simulation without event mode: Step Mode */
    return (fmi3Status)st;
}

fmi3Status fmi3EnterEventMode(fmi3Instance c) { return fmi3Error; }
fmi3Status fmi3Terminate(fmi3Instance c) { return (fmi3Status)fmi2Terminate(c); }
fmi3Status fmi3Reset(fmi3Instance c) { return (fmi3Status)fmi2Reset(c); }

fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Float64 v[], size_t nv)
{
    return nv != n ? fmi3Error : (fmi3Status)fmi2GetReal(c, vr, n, v);
}

fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Float64 v[], size_t nv)
{
    return nv != n ? fmi3Error : (fmi3Status)fmi2SetReal(c, vr, n, v);
}

fmi3Status fmi3GetInt32(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Int32 v[], size_t nv)
{
    return nv != n ? fmi3Error : (fmi3Status)fmi2GetInteger(c, vr, n, v);
}

fmi3Status fmi3SetInt32(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Int32 v[], size_t nv)
{
    return nv != n ? fmi3Error : (fmi3Status)fmi2SetInteger(c, vr, n, v);
}

fmi3Status fmi3GetBoolean(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Boolean v[], size_t nv)
{
    if (nv != n)
        return fmi3Error;
    for (size_t k = 0; k < n; k++) {
        fmi2Boolean x = 0;
        fmi2Status st = fmi2GetBoolean(c, &vr[k], 1, &x);
        if (st != fmi2OK)
            return (fmi3Status)st;
        v[k] = x != 0;
    }
    return fmi3OK;
}

fmi3Status fmi3SetBoolean(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Boolean v[], size_t nv)
{
    if (nv != n)
        return fmi3Error;
    for (size_t k = 0; k < n; k++) {
        fmi2Boolean x = v[k] ? fmi2True : fmi2False;
        fmi2Status st = fmi2SetBoolean(c, &vr[k], 1, &x);
        if (st != fmi2OK)
            return (fmi3Status)st;
    }
    return fmi3OK;
}

/* The types this FMU has no variables of. */
#define CW_NONE_GET(Name, Type)                                                                        \
    fmi3Status fmi3Get##Name(fmi3Instance c, const fmi3ValueReference vr[], size_t n, Type v[], size_t nv) \
    {                                                                                                  \
        return n ? fmi3Error : fmi3OK;                                                                 \
    }
#define CW_NONE_SET(Name, Type)                                                                              \
    fmi3Status fmi3Set##Name(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const Type v[], size_t nv) \
    {                                                                                                        \
        return n ? fmi3Error : fmi3OK;                                                                       \
    }
#define CW_NONE(Name, Type) CW_NONE_GET(Name, Type) CW_NONE_SET(Name, Type)
CW_NONE(Float32, fmi3Float32)
CW_NONE(Int8, fmi3Int8)
CW_NONE(UInt8, fmi3UInt8)
CW_NONE(Int16, fmi3Int16)
CW_NONE(UInt16, fmi3UInt16)
CW_NONE(UInt32, fmi3UInt32)
CW_NONE(Int64, fmi3Int64)
CW_NONE(UInt64, fmi3UInt64)
CW_NONE(String, fmi3String)

fmi3Status fmi3GetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t n, size_t sizes[], fmi3Binary v[],
                         size_t nv)
{
    return n ? fmi3Error : fmi3OK;
}

fmi3Status fmi3SetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const size_t sizes[],
                         const fmi3Binary v[], size_t nv)
{
    return n ? fmi3Error : fmi3OK;
}

fmi3Status fmi3GetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Clock v[])
{
    return n ? fmi3Error : fmi3OK;
}

fmi3Status fmi3SetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Clock v[])
{
    return n ? fmi3Error : fmi3OK;
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance c, fmi3ValueReference vr, size_t *n) { return fmi3Error; }

fmi3Status fmi3GetVariableDependencies(fmi3Instance c, fmi3ValueReference dependent, size_t element[],
                                       fmi3ValueReference independents[], size_t independent_element[],
                                       fmi3DependencyKind kinds[], size_t n)
{
    return fmi3Error;
}

fmi3Status fmi3GetFMUState(fmi3Instance c, fmi3FMUState *state) { return (fmi3Status)fmi2GetFMUstate(c, state); }
fmi3Status fmi3SetFMUState(fmi3Instance c, fmi3FMUState state) { return (fmi3Status)fmi2SetFMUstate(c, state); }
fmi3Status fmi3FreeFMUState(fmi3Instance c, fmi3FMUState *state) { return (fmi3Status)fmi2FreeFMUstate(c, state); }

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance c, fmi3FMUState state, size_t *size)
{
    return (fmi3Status)fmi2SerializedFMUstateSize(c, state, size);
}

fmi3Status fmi3SerializeFMUState(fmi3Instance c, fmi3FMUState state, fmi3Byte bytes[], size_t size)
{
    return (fmi3Status)fmi2SerializeFMUstate(c, state, (fmi2Byte *)bytes, size);
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance c, const fmi3Byte bytes[], size_t size, fmi3FMUState *state)
{
    return (fmi3Status)fmi2DeSerializeFMUstate(c, (const fmi2Byte *)bytes, size, state);
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance c, const fmi3ValueReference unknowns[], size_t n_unknowns,
                                        const fmi3ValueReference knowns[], size_t n_knowns, const fmi3Float64 seed[],
                                        size_t n_seed, fmi3Float64 sensitivity[], size_t n_sensitivity)
{
    return fmi3Error;
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance c, const fmi3ValueReference unknowns[], size_t n_unknowns,
                                    const fmi3ValueReference knowns[], size_t n_knowns, const fmi3Float64 seed[],
                                    size_t n_seed, fmi3Float64 sensitivity[], size_t n_sensitivity)
{
    return fmi3Error;
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance c) { return fmi3Error; }
fmi3Status fmi3ExitConfigurationMode(fmi3Instance c) { return fmi3Error; }

fmi3Status fmi3GetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Float64 intervals[],
                                  fmi3IntervalQualifier qualifiers[])
{
    return fmi3Error;
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3UInt64 counters[],
                                   fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[])
{
    return fmi3Error;
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Float64 shifts[])
{
    return fmi3Error;
}

fmi3Status fmi3GetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3UInt64 counters[],
                                fmi3UInt64 resolutions[])
{
    return fmi3Error;
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Float64 intervals[])
{
    return fmi3Error;
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3UInt64 counters[],
                                   const fmi3UInt64 resolutions[])
{
    return fmi3Error;
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Float64 shifts[])
{
    return fmi3Error;
}

fmi3Status fmi3SetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3UInt64 counters[],
                                const fmi3UInt64 resolutions[])
{
    return fmi3Error;
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance c) { return fmi3Error; }

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance c, fmi3Boolean *needed, fmi3Boolean *terminate,
                                    fmi3Boolean *nominals_changed, fmi3Boolean *values_changed,
                                    fmi3Boolean *next_defined, fmi3Float64 *next)
{
    return fmi3Error;
}

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance c) { return fmi3Error; }

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance c, fmi3Boolean no_set_prior, fmi3Boolean *enter_event_mode,
                                       fmi3Boolean *terminate)
{
    return fmi3Error;
}

fmi3Status fmi3SetTime(fmi3Instance c, fmi3Float64 t) { return fmi3Error; }
fmi3Status fmi3SetContinuousStates(fmi3Instance c, const fmi3Float64 x[], size_t n) { return fmi3Error; }
fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance c, fmi3Float64 dx[], size_t n) { return fmi3Error; }
fmi3Status fmi3GetEventIndicators(fmi3Instance c, fmi3Float64 z[], size_t n) { return fmi3Error; }
fmi3Status fmi3GetContinuousStates(fmi3Instance c, fmi3Float64 x[], size_t n) { return fmi3Error; }
fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance c, fmi3Float64 x[], size_t n) { return fmi3Error; }
fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance c, size_t *n) { return fmi3Error; }
fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance c, size_t *n) { return fmi3Error; }
fmi3Status fmi3EnterStepMode(fmi3Instance c) { return fmi3Error; }

fmi3Status fmi3GetOutputDerivatives(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Int32 order[],
                                    fmi3Float64 v[], size_t nv)
{
    return fmi3Error;  /* maxOutputDerivativeOrder is 0 */
}

fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 t, fmi3Float64 h, fmi3Boolean no_set_prior,
                      fmi3Boolean *event_handling_needed, fmi3Boolean *terminate, fmi3Boolean *early_return,
                      fmi3Float64 *last_successful_time)
{
    cw_system *s = c;
    int returned_early = 0;
    fmi2Status st = do_step(s, t, h, s && s->early_return, &returned_early);
    if (event_handling_needed)
        *event_handling_needed = false;
    if (terminate)
        *terminate = false;
    if (early_return)
        *early_return = returned_early != 0;
    if (last_successful_time && s && s->t)
        *last_successful_time = *s->t;
    return (fmi3Status)st;
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance c, fmi3ValueReference clock, fmi3Float64 t) { return fmi3Error; }
