/* SPDX-License-Identifier: MIT */
/*
 * mcf.c - the `mcf` command-line tool: smooth, inspect and convert meshes.
 *
 *   mcf smooth IN OUT [flags]   mean curvature flow, optional metrics file
 *   mcf info IN                 JSON: counts, topology, curvature summary
 *   mcf schemes                 JSON: every scheme and what it costs
 *   mcf params                  JSON: every job parameter (api_params_describe)
 *   mcf convert IN OUT          any input format to OUT's (or --format)
 *
 * Like curl's tool, this is only a client of the libraries: every job
 * parameter of the api table (api_params_describe) is an option, its name
 * with dashes for underscores, set through api_params_set, so the CLI and
 * the daemon accept and refuse exactly the same values with the same
 * messages, and `mcf smooth --help` lists them from the same table. The
 * input format is detected from the bytes, the output format comes from
 * OUT's extension unless --format says otherwise. "-" reads stdin / writes
 * stdout.
 *
 * Errors: exactly one line "mcf: <message>" on stderr; exit status 2 for
 * usage errors (unknown flag, missing argument, invalid parameter value),
 * 1 for everything else, 3 for `smooth --strict` with warnings. Output
 * files are written to a temporary name and renamed, so a failed run never
 * leaves a half-written OUT behind. `mcf smooth` also says what happened
 * on stderr: the core's warnings about the result (always), a summary line
 * (unless --quiet), and progress (a bar on a terminal; with --progress,
 * one plain line per 10% elsewhere).
 */
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include "api.h"
#include "prog.h"

#define EXIT_USAGE 2
#define EXIT_STRICT 3 /* --strict and the result has warnings */

/* `mcf --help`: the commands; each command's own --help has its options. */
static const char usage_text[] =
    "usage: mcf COMMAND [ARGS] [OPTIONS]\n"
    "\n"
    "  mcf smooth IN OUT [options]   smooth a mesh (mean curvature flow or a filter)\n"
    "  mcf info IN                   JSON on stdout: counts, topology, curvature summary\n"
    "  mcf schemes                   JSON on stdout: every scheme with order, stability, cost\n"
    "  mcf params                    JSON on stdout: every job parameter with its type,\n"
    "                                range, default and unit (the daemon's too)\n"
    "  mcf convert IN OUT [options]  any mesh format to OUT's (texture coordinates, colours\n"
    "                                pass through; normals recomputed)\n"
    "  mcf --version                 the version\n"
    "\n"
    "`mcf COMMAND --help` lists that command's options with their defaults and units.\n"
    "Formats: obj, draco (.drc), ply, stl, off, glb and gltf (glTF 2.0), detected from\n"
    "the bytes on input and taken from OUT's extension (or --format) on output; IN or\n"
    "OUT may be '-' (stdin/stdout; OUT '-' needs --format).\n"
    "Exit status: 0 done; 1 failed (one line 'mcf: ...' on stderr); 2 usage error;\n"
    "3 `mcf smooth --strict` and the result has warnings.\n";

/* The limits on the input (api_limits), options of smooth and convert:
 * none below memory by default (a 10M-vertex scan needs no option). */
#define LIMITS_HELP \
    "  --max-input-bytes N   refuse an input file larger than N bytes (default: no\n" \
    "                        limit; the daemon's --max-upload is 256 MiB)\n" \
    "  --max-vertices N      refuse a mesh of more than N vertices (default 100000000)\n" \
    "  --max-faces N         refuse a mesh of more than N triangles (default 200000000)\n" \
    "  --max-work N          refuse a job of more than N steps x vertices (default 2e10)\n"

static const char smooth_head[] =
    "usage: mcf smooth IN OUT [options]\n"
    "\n"
    "Smooths the mesh IN into OUT. Without --scheme: the fairing denoiser (fairing;\n"
    "fairing_explicit above 150,000 vertices): as many steps as Stein's unbiased risk\n"
    "estimate says for the noise it reads off the mesh, along the normals only;\n"
    "--iterations sets its steps, --strength the noise level (mean edges). With\n"
    "--time, --dt, --adaptive, --laplacian, --mass or --rescale and no --scheme:\n"
    "desbrun2, as before. An MCF scheme's (and taubin's) amount is automatic too, by\n"
    "the same risk estimate, unless --strength, --time, or --iterations with --dt set\n"
    "it (--iterations or --dt alone: strength 0.33). The job parameters are the\n"
    "daemon's (dashes here, underscores there); a boolean is --NAME or --no-NAME.\n"
    "\n"
    "Job parameters:\n";

static const char smooth_tail[] =
    "\n"
    "Options of the tool:\n"
    "  --fix-vertices FILE   vertices held in place: 0-based indices in FILE, separated\n"
    "                        by white space or commas\n"
    "  --target FILE         a clean mesh with the same connectivity: the metrics compare\n"
    "                        the result (and the input) with it\n"
    "  --metrics FILE.json   write the metrics document (the daemon's /v1/jobs/ID/metrics)\n"
    "  --progress            progress on stderr when it is not a terminal: one line per\n"
    "                        10% of the time (on a terminal the bar is always shown)\n"
    "  --quiet               no progress bar and no summary line (warnings still print)\n"
    "  --threads N           threads of the fairing filters' passes (default: the\n"
    "                        online cores); the result is one thread's bit for bit\n"
    "  --strict              a warning (folds, edge_collapse, area_loss,\n"
    "                        little_smoothing) fails the run: exit status 3, OUT not\n"
    "                        written (the metrics file is, when asked for)\n"
    LIMITS_HELP
    "\n"
    "On stderr, unless --quiet: a summary line (vertices, steps, time, strength, seconds).\n"
    "Always: one line per warning about the result, 'mcf: warning: NAME: ...'.\n";

static const char convert_head[] =
    "usage: mcf convert IN OUT [options]\n"
    "\n"
    "Reads any mesh format (detected from the bytes) and writes OUT's (its extension or\n"
    "--format). Texture coordinates and colours pass through, normals are recomputed;\n"
    "Draco keeps a Draco input's quantization.\n"
    "\n"
    "Options of the tool:\n"
    LIMITS_HELP
    "\n"
    "Options (the daemon's output parameters):\n";

static const char info_usage[] =
    "usage: mcf info IN\n"
    "\n"
    "Prints JSON on stdout: vertex and face counts, topology (boundary, components,\n"
    "genus, manifoldness, degenerate and duplicate faces), area, volume, edge lengths,\n"
    "bounding box, the curvature summary, the format and the size in bytes.\n";

static const char schemes_usage[] =
    "usage: mcf schemes\n"
    "\n"
    "Prints JSON on stdout: every scheme with its order, stability, cost per step and\n"
    "best use (the daemon's GET /v1/schemes).\n";

static const char params_usage[] =
    "usage: mcf params\n"
    "\n"
    "Prints JSON on stdout: every job parameter (mcf smooth's options, the daemon's query\n"
    "parameters, JSON keys and gRPC Params fields) with its type, range, default, unit\n"
    "and meaning, from the one table that validates them.\n";

/* Set by SIGINT/SIGTERM; the flow loads it before every step. A lock-free
 * C11 atomic (mcf_cancel_flag), which a signal handler may store to. */
static mcf_cancel_flag cancel_flag;

static void on_signal(int sig)
{
    (void)sig;
    cancel_flag = 1;
}

/* The one error line, then the exit status. */
static int fail(int code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

static int fail(int code, const char *fmt, ...)
{
    char msg[1024];
    va_list ap;
    size_t i;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    for (i = 0; msg[i]; i++) /* one line, whatever a message holds */
        if (msg[i] == '\n' || msg[i] == '\r')
            msg[i] = ' ';
    fprintf(stderr, "mcf: %s\n", msg);
    return code;
}

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* ------------------------------------------------------------------ files */

/* Reads path ("-": stdin) into a malloc'ed buffer of at most max bytes.
 * Returns 0, or an exit status after printing the error line. */
static int read_all(const char *path, size_t max, char **buf, size_t *len)
{
    FILE *f = strcmp(path, "-") == 0 ? stdin : fopen(path, "rb");
    char *data = NULL;
    size_t n = 0, cap = 0;
    int rc = 1;

    if (!f)
        return fail(1, "cannot read '%s': %s", path, strerror(errno));
    for (;;) {
        size_t got;
        if (cap - n < 65536) {
            size_t ncap = cap ? cap * 2 : 1 << 20;
            char *p = realloc(data, ncap + 1);
            if (!p) {
                fail(1, "'%s': out of memory", path);
                goto done;
            }
            data = p;
            cap = ncap;
        }
        got = fread(data + n, 1, cap - n, f);
        n += got;
        if (n > max) {
            fail(1, "'%s': larger than max_input_bytes (%zu)", path, max);
            goto done;
        }
        if (got == 0) {
            if (ferror(f)) {
                fail(1, "cannot read '%s': %s", path, strerror(errno));
                goto done;
            }
            break;
        }
    }
    data[n] = '\0';
    *buf = data;
    *len = n;
    data = NULL;
    rc = 0;
done:
    free(data);
    if (f != stdin)
        fclose(f);
    return rc;
}

/* Writes len bytes to path ("-": stdout) through a temporary file renamed
 * over path, so readers never see a partial file. 0, or -1 with the
 * error line's text in err. */
static int write_file(const char *path, const void *buf, size_t len,
                      mcf_error *err)
{
    char *tmp;
    FILE *f;
    int ok;

    if (strcmp(path, "-") == 0) {
        if (fwrite(buf, 1, len, stdout) != len || fflush(stdout) != 0) {
            mcf_error_set(err, MCF_EIO, "cannot write to stdout: %s", strerror(errno));
            return -1;
        }
        return 0;
    }
    tmp = malloc(strlen(path) + 32);
    if (!tmp) {
        mcf_error_set(err, MCF_ENOMEM, "out of memory");
        return -1;
    }
    sprintf(tmp, "%s.tmp%ld", path, (long)getpid());
    f = fopen(tmp, "wb");
    ok = f != NULL;
    if (f) {
        ok = fwrite(buf, 1, len, f) == len;
        ok = (fclose(f) == 0) && ok;
        ok = ok && rename(tmp, path) == 0;
    }
    if (!ok) {
        int e = errno;
        if (f)
            remove(tmp);
        mcf_error_set(err, MCF_EIO, "cannot write '%s': %s", path, strerror(e));
    }
    free(tmp);
    return ok ? 0 : -1;
}

/* write_file, or the error line and exit status 1. */
static int write_all(const char *path, const void *buf, size_t len)
{
    mcf_error err;
    return write_file(path, buf, len, &err) == 0 ? 0 : fail(1, "%s", err.msg);
}

/* Draco decodes under the daemon's bound (api_decode_bounds with the
 * daemon's default floors; the daemon's is a child process, here it is
 * this one: the CLI's files are its user's): libdraco 1.5.5 trusts counts
 * inside a stream that no header check sees (210 bytes cost 256 MiB and
 * 8.8 s of CPU). While it decodes, the soft RLIMIT_AS is the process's
 * size plus the memory bound (a failed allocation is an ENOMEM), and the
 * soft RLIMIT_CPU the CPU bound beyond what it used (SIGXCPU: the message
 * below, exit 1); both are put back after. No RLIMIT_AS under ASan/TSan
 * (API_SANITIZED). */

static void on_decode_cpu(int sig)
{
    static const char msg[] = "mcf: the Draco stream needs more than its "
                              "decode CPU limit (2 s + 1 us per declared face): refused\n";
    (void)sig;
    if (write(2, msg, sizeof msg - 1) < 0) {
        /* nothing more to say */
    }
    _exit(1);
}

static mcf_status decode_bounded(const char *buf, size_t len,
                                 const api_limits *lim, mcf_mesh **m,
                                 api_attrs **attrs, api_format *fmt,
                                 mcf_error *err)
{
    struct rlimit as0, cpu0, rl;
    struct rusage ru;
    api_mem_estimate est;
    double cpu;
    size_t mem;
    int bound_as = 0, bound_cpu = 0;
    mcf_status st;
    void (*old)(int);

    api_estimate_memory(buf, len, NULL, &est);
    if (!est.draco) /* libdraco is not reached (the daemon's rule too) */
        return api_mesh_decode_attrs(buf, len, lim, m, attrs, fmt, err);
    api_decode_bounds(&est, API_DECODE_CPU_S, API_DECODE_MEMORY, &cpu, &mem);
    if (!API_SANITIZED && getrlimit(RLIMIT_AS, &as0) == 0) {
        rl = as0;
        rl.rlim_cur = (rlim_t)(api_vm_size() + mem);
        bound_as = (as0.rlim_max == RLIM_INFINITY || rl.rlim_cur < as0.rlim_max) &&
                   setrlimit(RLIMIT_AS, &rl) == 0;
    }
    old = signal(SIGXCPU, on_decode_cpu);
    if (getrlimit(RLIMIT_CPU, &cpu0) == 0 && getrusage(RUSAGE_SELF, &ru) == 0) {
        rl = cpu0;
        rl.rlim_cur = (rlim_t)(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec + cpu + 1);
        bound_cpu = (cpu0.rlim_max == RLIM_INFINITY || rl.rlim_cur < cpu0.rlim_max) &&
                    setrlimit(RLIMIT_CPU, &rl) == 0;
    }
    st = api_mesh_decode_attrs(buf, len, lim, m, attrs, fmt, err);
    if (bound_cpu)
        setrlimit(RLIMIT_CPU, &cpu0);
    signal(SIGXCPU, old);
    if (bound_as)
        setrlimit(RLIMIT_AS, &as0);
    if (st == MCF_ENOMEM && bound_as)
        mcf_error_set(err, MCF_ELIMIT, "the Draco stream needs more than %.0f "
                      "MiB to decode: refused", (double)mem / 1048576.0);
    return st;
}

/* Reads and decodes a mesh file; *attrs (the input's texture coordinates,
 * colours, normals and precision, for the output), *fmt and the timings
 * are optional. */
static int load_mesh_attrs(const char *path, const api_limits *lim,
                           mcf_mesh **m, api_attrs **attrs, api_format *fmt,
                           size_t *bytes, double *read_s, double *decode_s)
{
    char *buf = NULL;
    size_t len = 0;
    mcf_error err = {MCF_OK, ""};
    mcf_status st;
    double t0 = now(), t1;
    int rc;

    if ((rc = read_all(path, lim->max_input_bytes, &buf, &len)) != 0)
        return rc;
    t1 = now();
    st = decode_bounded(buf, len, lim, m, attrs, fmt, &err);
    free(buf);
    if (st != MCF_OK)
        return fail(1, "%s: %s", path, err.msg);
    if (bytes)
        *bytes = len;
    if (read_s)
        *read_s = t1 - t0;
    if (decode_s)
        *decode_s = now() - t1;
    return 0;
}

static int load_mesh(const char *path, const api_limits *lim, mcf_mesh **m,
                     api_format *fmt, size_t *bytes, double *read_s,
                     double *decode_s)
{
    return load_mesh_attrs(path, lim, m, NULL, fmt, bytes, read_s, decode_s);
}

/* -------------------------------------------------------------- arguments */

typedef struct {
    const char *pos[3];
    int npos;
    const char *target, *metrics, *fix_file;
    int quiet, progress, strict;
    int threads;            /* --threads, default the online cores */
} cli_opts;

/* The parameter table (api_params_describe): every job parameter is an
 * option of `mcf smooth`, the output ones of `mcf convert` too, so the
 * tool, the daemon and the help cannot disagree on names or ranges. */
static cJSON *param_table(void)
{
    cJSON *t = api_params_describe(NULL);
    if (!t)
        fail(1, "out of memory");
    return t;
}

static const cJSON *find_param(const cJSON *table, const char *key, int smooth)
{
    const cJSON *e;
    cJSON_ArrayForEach(e, table) {
        if (strcmp(cJSON_GetStringValue(cJSON_GetObjectItem(e, "name")), key) == 0)
            return (smooth || cJSON_IsTrue(cJSON_GetObjectItem(e, "output"))) ? e : NULL;
    }
    return NULL;
}

static int is_type(const cJSON *e, const char *type)
{
    return strcmp(cJSON_GetStringValue(cJSON_GetObjectItem(e, "type")), type) == 0;
}

/* Applies one parameter; a refusal is a usage error (exit 2), a limit 1. */
static int set_param(api_params *p, const char *key, const char *value,
                     const api_limits *lim)
{
    mcf_error err = {MCF_OK, ""};
    mcf_status st = api_params_set(p, key, value, lim, &err);
    if (st != MCF_OK)
        return fail(st == MCF_EINVAL ? EXIT_USAGE : 1, "%s", err.msg);
    return 0;
}

/* Parses argv[first..] of command cmd ("smooth" or "convert"). */
/* The tool's limit options (LIMITS_HELP), in limit_option's order. */
static const char *const limit_names[] = {"max_input_bytes", "max_vertices", "max_faces",
                                          "max_work", NULL};

static int limit_index(const char *key)
{
    int k;
    for (k = 0; limit_names[k]; k++)
        if (!strcmp(key, limit_names[k]))
            return k;
    return -1;
}

/* Sets limit k (limit_index) of lim from the value val of option opt; a
 * value that is not a whole number in range is a usage error. */
static int limit_option(int k, const char *opt, const char *val, api_limits *lim)
{
    int count = k == 1 || k == 2; /* core's int counts (api_limits.c) */
    char *end;
    double v;

    errno = 0;
    v = strtod(val, &end);
    if (end == val || *end || errno || !(v >= 1) || v != floor(v) ||
        v > (count ? 2147483647.0 : 9e18))
        return fail(EXIT_USAGE, "option '--%s' needs a whole number from 1%s, got '%s'", opt,
                    count ? " to 2147483647" : "", val);
    if (k == 0)
        lim->max_input_bytes = (size_t)v;
    else if (k == 1)
        lim->max_vertices = lim->max_fixed = (int)v;
    else if (k == 2)
        lim->max_faces = (int)v;
    else
        lim->max_work = v;
    return 0;
}

/* The tool's limits before its options: api_limits_default's, without a
 * bound on the input's bytes (a local file; the mesh's counts and memory
 * are what bound a job). */
static void cli_limits(api_limits *lim)
{
    api_limits_default(lim);
    lim->max_input_bytes = SIZE_MAX;
}

static int parse_args(const char *cmd, int argc, char **argv, int first,
                      api_params *p, api_limits *lim, cli_opts *o,
                      const cJSON *table)
{
    int smooth = strcmp(cmd, "smooth") == 0, i, rc;

    for (i = first; i < argc; i++) {
        const char *a = argv[i], *val = NULL, *eq;
        const cJSON *e;
        char key[64];
        size_t nl, k;
        int off = 0;

        if (a[0] != '-' || strcmp(a, "-") == 0) {
            if (o->npos >= 2)
                return fail(EXIT_USAGE, "%s: unexpected argument '%s' (try mcf %s --help)",
                            cmd, a, cmd);
            o->pos[o->npos++] = a;
            continue;
        }
        if (a[1] != '-')
            return fail(EXIT_USAGE, "%s: unknown option '%s' (try mcf %s --help)", cmd, a, cmd);
        a += 2;
        eq = strchr(a, '=');
        nl = eq ? (size_t)(eq - a) : strlen(a);
        if (nl >= sizeof key)
            return fail(EXIT_USAGE, "%s: unknown option '--%.40s' (try mcf %s --help)",
                        cmd, a, cmd);
        for (k = 0; k < nl; k++)   /* the daemon's name: dashes become underscores */
            key[k] = a[k] == '-' ? '_' : a[k];
        key[nl] = '\0';

        /* The tool's own switches and files. */
        if (smooth && (!strcmp(key, "quiet") || !strcmp(key, "progress")
                       || !strcmp(key, "strict"))) {
            if (eq)
                return fail(EXIT_USAGE, "option '--%s' takes no value", key);
            *(key[0] == 'q' ? &o->quiet : key[0] == 'p' ? &o->progress : &o->strict) = 1;
            continue;
        }
        if (smooth && (!strcmp(key, "fix_vertices") || !strcmp(key, "target")
                       || !strcmp(key, "metrics"))) {
            if (eq)
                val = eq + 1;
            else if (i + 1 < argc)
                val = argv[++i];
            else
                return fail(EXIT_USAGE, "option '--%.*s' needs a value", (int)nl, a);
            *(key[0] == 'f' ? &o->fix_file : key[0] == 't' ? &o->target : &o->metrics) = val;
            continue;
        }
        if (smooth && !strcmp(key, "threads")) {
            char *end;
            long n;
            if (eq)
                val = eq + 1;
            else if (i + 1 < argc)
                val = argv[++i];
            else
                return fail(EXIT_USAGE, "option '--threads' needs a value");
            errno = 0;
            n = strtol(val, &end, 10);
            if (end == val || *end || errno || n < 1 || n > 64)
                return fail(EXIT_USAGE, "option '--threads' needs a whole number from 1 to 64, "
                            "got '%s'", val);
            o->threads = (int)n;
            continue;
        }
        if (limit_index(key) >= 0) {
            if (eq)
                val = eq + 1;
            else if (i + 1 < argc)
                val = argv[++i];
            else
                return fail(EXIT_USAGE, "option '--%.*s' needs a value", (int)nl, a);
            char opt[64];
            snprintf(opt, sizeof opt, "%.*s", (int)nl, a);
            if ((rc = limit_option(limit_index(key), opt, val, lim)) != 0)
                return rc;
            continue;
        }
        /* A job parameter: --NAME VALUE, --NAME=VALUE; a boolean --NAME or --no-NAME. */
        e = find_param(table, key, smooth);
        if (!e && strncmp(key, "no_", 3) == 0) {
            e = find_param(table, key + 3, smooth);
            off = 1;
            if (e && !is_type(e, "boolean"))
                e = NULL;
        }
        if (!e)
            return fail(EXIT_USAGE, "%s: unknown option '--%.*s' (try mcf %s --help)",
                        cmd, (int)nl, a, cmd);
        if (is_type(e, "boolean")) {
            if (eq)
                return fail(EXIT_USAGE, "option '--%.*s' takes no value", (int)nl, a);
            val = off ? "false" : "true";
        } else if (eq) {
            val = eq + 1;
        } else if (i + 1 < argc) {
            val = argv[++i];
        } else {
            return fail(EXIT_USAGE, "option '--%.*s' needs a value", (int)nl, a);
        }
        if ((rc = set_param(p, cJSON_GetStringValue(cJSON_GetObjectItem(e, "name")), val,
                            lim)) != 0)
            return rc;
    }
    if (o->npos < 2)
        return fail(EXIT_USAGE, "%s: needs IN and OUT (try mcf %s --help)", cmd, cmd);
    return 0;
}

/* One command's help: head, then every parameter of the table it takes
 * (with its placeholder, meaning, unit, range and default), then tail. */
static int print_help(const char *head, int smooth, const char *tail)
{
    cJSON *table = param_table();
    const cJSON *e;
    int pass;

    if (!table)
        return 1;
    fputs(head, stdout);
    /* smooth: the flow's parameters first, then the output ones */
    for (pass = smooth ? 0 : 1; pass < 2; pass++) {
        if (smooth && pass == 1)
            fputs("\nOutput (also `mcf convert`'s):\n", stdout);
        cJSON_ArrayForEach(e, table) {
            const char *name = cJSON_GetStringValue(cJSON_GetObjectItem(e, "name"));
            const char *unit = cJSON_GetStringValue(cJSON_GetObjectItem(e, "unit"));
            const cJSON *dv = cJSON_GetObjectItem(e, "default");
            char flag[64], meta[24], *dtext = NULL;
            size_t k;

            if (cJSON_IsTrue(cJSON_GetObjectItem(e, "output")) != (pass == 1))
                continue;
            for (k = 0; name[k] && k + 1 < sizeof flag; k++)
                flag[k] = name[k] == '_' ? '-' : name[k];
            flag[k] = '\0';
            if (is_type(e, "boolean"))
                snprintf(meta, sizeof meta, "%s", "");
            else
                snprintf(meta, sizeof meta, " %s%s",
                         is_type(e, "number") ? "X" : is_type(e, "integer") ? "N"
                         : is_type(e, "array") ? "I,J,..." : "NAME",
                         cJSON_IsTrue(cJSON_GetObjectItem(e, "auto")) ? "|auto" : "");
            if (is_type(e, "boolean"))
                printf("  --%s, --no-%s\n", flag, flag);
            else
                printf("  --%s%s\n", flag, meta);
            printf("      %s%s%s\n", cJSON_GetStringValue(cJSON_GetObjectItem(e, "help")),
                   unit ? "; unit: " : "", unit ? unit : "");
            if (dv && !cJSON_IsString(dv))
                dtext = cJSON_PrintUnformatted(dv);
            printf("      %s; default %s\n",
                   cJSON_GetStringValue(cJSON_GetObjectItem(e, "accepts")),
                   dtext ? dtext : dv ? cJSON_GetStringValue(dv)
                   : cJSON_GetStringValue(cJSON_GetObjectItem(e, "default_text")));
            cJSON_free(dtext);
        }
    }
    fputs(tail, stdout);
    cJSON_Delete(table);
    return fflush(stdout) == 0 ? 0 : 1;
}

/* The output format: --format, else OUT's extension. */
static int output_format(api_params *p, const char *out)
{
    if (p->encode.format != API_FMT_UNKNOWN)
        return 0;
    p->encode.format = api_format_from_name(out);
    if (p->encode.format == API_FMT_UNKNOWN)
        return fail(EXIT_USAGE,
                    "cannot tell the output format from '%s' (use --format obj|draco|ply|stl|off)",
                    out);
    return 0;
}

/* Encodes (measuring Draco's quantization error) and writes OUT, with the
 * input's attributes when opts->attrs has them. PLY curvature properties
 * are opt-in (--ply-curvature), as in the daemon (ply_curvature). */
static int save_mesh(const mcf_mesh *m, const api_encode_opts *opts,
                     const char *path, size_t *bytes, double *encode_s,
                     double *write_s, double *qerr)
{
    api_buf b;
    api_encode_opts o = *opts;
    mcf_error err = {MCF_OK, ""};
    mcf_status st;
    double t0 = now(), t1;
    int rc;

    api_buf_init(&b, 0);
    if (o.format == API_FMT_DRACO)
        st = api_draco_encode(m, &o, &b, qerr, &err);
    else
        st = api_mesh_encode(m, &o, &b, &err);
    if (st != MCF_OK) {
        api_buf_free(&b);
        return fail(1, "%s: %s", path, err.msg);
    }
    t1 = now();
    rc = write_all(path, b.data ? b.data : "", b.len);
    if (bytes)
        *bytes = b.len;
    if (encode_s)
        *encode_s = t1 - t0;
    if (write_s)
        *write_s = now() - t1;
    api_buf_free(&b);
    return rc;
}

/* --------------------------------------------------------------- progress */

typedef struct {
    double total_time;    /* > 0: progress by t, else by steps */
    int total_steps;
    int bar;              /* 1: a bar redrawn in place (a terminal) */
    double last;          /* when the bar was last drawn */
    int drawn;
    int next_tenth;       /* plain lines: the next 10% to report */
} progress_state;

static void on_progress(progress_state *ps, const api_job_step *s)
{
    double frac, tn = now();
    int i, fill;
    char bar[41];

    if (ps->total_time <= 0 && s->t_target > 0)
        ps->total_time = s->t_target; /* the amount came from strength */
    frac = ps->total_time > 0 ? s->t / ps->total_time
                              : (double)s->step / (ps->total_steps > 0 ? ps->total_steps : 1);
    if (!(frac >= 0))
        frac = 0;
    if (frac > 1)
        frac = 1;
    if (!ps->bar) {
        /* One plain line per 10% reached (a log or a pipe, not a terminal). */
        if (frac * 10 + 1e-9 >= ps->next_tenth && ps->next_tenth <= 10) {
            int tenth = (int)(frac * 10 + 1e-9);
            fprintf(stderr, "mcf: %3d%%  step %d  t %.4g  energy %.6g\n", tenth * 10,
                    s->step, s->t, s->energy);
            fflush(stderr);
            ps->next_tenth = tenth + 1;
        }
        return;
    }
    if (tn - ps->last < 0.1)
        return;
    ps->last = tn;
    fill = (int)(frac * 40 + 0.5);
    for (i = 0; i < 40; i++)
        bar[i] = i < fill ? '#' : '.';
    bar[40] = '\0';
    fprintf(stderr, "\r[%s] %3d%%  step %d  t %.4g  energy %.6g ", bar,
            (int)(frac * 100 + 0.5), s->step, s->t, s->energy);
    fflush(stderr);
    ps->drawn = 1;
}

static void progress_clear(progress_state *ps)
{
    if (ps->drawn)
        fprintf(stderr, "\r\033[K");
    ps->drawn = 0;
}

/* One line per warning of the core about the result, with the figure
 * behind it (mcf_flow_stats); returns how many. */
static int print_warnings(const mcf_flow_stats *st)
{
    unsigned bit;
    int n = 0;

    for (bit = 1; bit; bit <<= 1) {
        char why[96];
        if (!(st->warnings & bit) || !mcf_warning_name(bit))
            continue;
        if (bit == MCF_WARN_FOLDS)
            snprintf(why, sizeof why, "%d faces folded", st->folded_faces);
        else if (bit == MCF_WARN_EDGE_COLLAPSE)
            snprintf(why, sizeof why, "shortest edge x %.3g", st->min_edge_ratio);
        else if (bit == MCF_WARN_AREA_LOSS)
            snprintf(why, sizeof why, "area x %.3g", st->area_ratio);
        else if (bit == MCF_WARN_LITTLE_SMOOTHING)
            snprintf(why, sizeof why, "strength %.3g mean edges", st->strength);
        else
            why[0] = '\0';
        fprintf(stderr, "mcf: warning: %s: %s%s%s%s\n", mcf_warning_name(bit),
                mcf_warning_text(bit), why[0] ? " (" : "", why, why[0] ? ")" : "");
        n++;
    }
    return n;
}

/* ---------------------------------------------------------------- helpers */

/* Adds item to o under key; on allocation failure the document is simply
 * missing that member (the metrics file is best-effort detail). */
static void add(cJSON *o, const char *key, cJSON *item)
{
    if (item && !cJSON_AddItemToObject(o, key, item))
        cJSON_Delete(item);
}

static cJSON *info_json(const mcf_mesh *m, const mcf_curvature_summary *cs,
                        mcf_error *err)
{
    mcf_mesh_info info;
    if (mcf_mesh_inspect(m, &info, err) != MCF_OK)
        return NULL;
    return api_json_mesh_info(&info, cs);
}

/* ----------------------------------------------------------------- smooth */

/* The tool's side of the job (api_job_run's hooks): the bounded decode,
 * the progress bar, the warnings and --strict, and OUT's file. */
typedef struct {
    const cli_opts *o;
    progress_state ps;
    int show;             /* progress shown */
    int nwarn;            /* warnings printed */
} smooth_ctx;

static mcf_status hook_decode(void *ctx, const char *part, const void *buf, size_t len,
                              const api_limits *lim, mcf_mesh **out, api_attrs **attrs,
                              api_format *fmt, api_job_stage *stage, mcf_error *err)
{
    (void)ctx;
    (void)part;
    (void)stage;
    return decode_bounded(buf, len, lim, out, attrs, fmt, err);
}

static int hook_progress(void *ctx, const api_job_step *s)
{
    smooth_ctx *sc = ctx;
    if (sc->show)
        on_progress(&sc->ps, s);
    return 0;
}

/* What the core says about the result, whatever --quiet says; under
 * --strict a warning withholds OUT (a pipeline must not take it). */
static int hook_flowed(void *ctx, const mcf_flow_stats *st)
{
    smooth_ctx *sc = ctx;
    if (sc->show)
        progress_clear(&sc->ps);
    sc->nwarn = print_warnings(st);
    return sc->o->strict && sc->nwarn > 0;
}

static mcf_status hook_store(void *ctx, const api_buf *out, const char *name,
                             mcf_error *err)
{
    (void)ctx;
    return write_file(name, out->data ? out->data : "", out->len, err) == 0
               ? MCF_OK : err->status;
}

/* The job's failure as the tool's one error line and exit status: a
 * parameter the mesh refuses is a usage error (2), anything else 1. */
static int job_failed(const api_job_result *res, const cli_opts *o)
{
    const char *part = res->part ? res->part : "";
    const char *msg = res->err.msg;

    if (!strcmp(part, "mesh"))
        return fail(1, "%s: %s", o->pos[0], msg);
    if (!strcmp(part, "target"))
        return res->stage == API_JOB_DECODE ? fail(1, "%s: %s", o->target, msg)
                                            : fail(1, "--target '%s': %s", o->target, msg);
    if (!strcmp(part, "params"))
        return fail(res->err.status == MCF_EINVAL ? EXIT_USAGE : 1, "%s", msg);
    if (!strcmp(part, "flow"))
        return fail(1, "smooth: %s", msg);
    if (!strcmp(part, "encode"))
        return fail(1, "%s: %s", o->pos[1], msg);
    if (!strcmp(part, "output"))
        return fail(1, "%s", msg);
    return fail(1, "%s: %s", part, msg);
}

/* --fix-vertices FILE: its indices as the fixed_vertices parameter. */
static int fix_vertices(api_params *p, const char *path, const api_limits *lim)
{
    mcf_error err = {MCF_OK, ""};
    char *txt = NULL;
    size_t n = 0, k;
    int rc;

    if ((rc = read_all(path, lim->max_input_bytes, &txt, &n)) != 0)
        return rc;
    for (k = 0; k < n && strchr(" \t\r\n,", txt[k]); k++)
        ;
    if (k == n || memchr(txt, '\0', n)) {
        free(txt);
        return fail(EXIT_USAGE, "--fix-vertices '%s': %s", path,
                    k == n ? "the file holds no vertex index" : "binary data");
    }
    rc = api_params_set(p, "fixed_vertices", txt, lim, &err);
    free(txt);
    if (rc != MCF_OK)
        return fail(rc == MCF_EINVAL ? EXIT_USAGE : 1, "--fix-vertices '%s': %s", path,
                    err.msg);
    return 0;
}

/* The summary line: what ran, on how many vertices, how far, how long. */
static void print_summary(const cli_opts *o, const api_params *p, const api_job_result *res,
                          int nwarn)
{
    const mcf_flow_stats *st = &res->stats;

    if (p->flow.scheme == MCF_FAIRING || p->flow.scheme == MCF_FAIRING_EXPLICIT) {
        /* a filter: its steps and the noise they were chosen for */
        fprintf(stderr, "mcf: %s -> %s: %d vertices, %s %d step%s for noise %.3g mean edges in %.2f s%s\n",
                o->pos[0], o->pos[1], res->nv, mcf_scheme_get(p->flow.scheme)->name, st->steps,
                st->steps == 1 ? "" : "s", st->noise, res->flow_s, nwarn ? " (with warnings)" : "");
    } else {
        char strength[48] = "";
        if (st->strength > 0)
            snprintf(strength, sizeof strength, ", strength %.3g mean edges", st->strength);
        fprintf(stderr, "mcf: %s -> %s: %d vertices, %d step%s to t = %.4g%s in %.2f s%s\n",
                o->pos[0], o->pos[1], res->nv, st->steps, st->steps == 1 ? "" : "s",
                st->t_final, strength, res->flow_s, nwarn ? " (with warnings)" : "");
    }
}

/* The job (api_job_run) on IN's bytes (and --target's), OUT and the
 * metrics file written by the tool. */
static int run_smooth(const cli_opts *o, api_params *p, const api_limits *lim)
{
    api_job_request rq;
    api_job_hooks h;
    api_job_result res;
    smooth_ctx sc;
    char *in = NULL, *tg = NULL, *s;
    size_t in_len = 0, tg_len = 0;
    double t0 = now();
    struct sigaction sa;
    int rc;

    api_job_request_init(&rq);
    api_job_result_init(&res);
    if ((rc = read_all(o->pos[0], lim->max_input_bytes, &in, &in_len)) != 0 ||
        (o->target && (rc = read_all(o->target, lim->max_input_bytes, &tg, &tg_len)) != 0))
        goto done;
    rq.read_s = now() - t0;
    rq.input = in;
    rq.input_len = in_len;
    rq.target = tg;
    rq.target_len = tg_len;
    rq.free_bytes = 1;
    in = tg = NULL;
    rq.lim = lim;
    rq.metrics = o->metrics != NULL;
    rq.input_name = o->pos[0];
    rq.output_name = o->pos[1];
    rq.target_name = o->target;
    rq.process_rss = 1;
    rq.threads = o->threads;

    /* progress: a bar on a terminal, plain lines with --progress
     * elsewhere; cancel on SIGINT/SIGTERM */
    memset(&sc, 0, sizeof sc);
    sc.o = o;
    sc.ps.bar = isatty(STDERR_FILENO);
    sc.show = !o->quiet && (sc.ps.bar || o->progress);
    sc.ps.total_time = p->time_set ? p->flow.time : 0;
    sc.ps.total_steps = p->flow.iterations > 0 ? p->flow.iterations : MCF_DEFAULT_STEPS;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    memset(&h, 0, sizeof h);
    h.ctx = &sc;
    h.decode = hook_decode;
    /* no progress shown, none asked of the core (its energy, the area,
     * is a pass over the faces after every step) */
    h.progress = sc.show ? hook_progress : NULL;
    h.flowed = hook_flowed;
    h.store = hook_store;
    h.cancel = &cancel_flag;

    if (api_job_run(&rq, p, &h, &res) != MCF_OK) {
        if (sc.show)
            progress_clear(&sc.ps);
        rc = job_failed(&res, o);
        goto done;
    }
    if (o->metrics) {
        s = api_json_print(res.metrics, 1);
        if (!s) {
            rc = fail(1, "metrics: out of memory");
            goto done;
        }
        rc = write_all(o->metrics, s, strlen(s));
        free(s);
        if (rc)
            goto done;
    }
    if (res.withheld) {
        rc = fail(EXIT_STRICT, "--strict: the result has %d warning%s (above): '%s' not written",
                  sc.nwarn, sc.nwarn > 1 ? "s" : "", o->pos[1]);
        goto done;
    }
    if (!o->quiet)
        print_summary(o, p, &res, sc.nwarn);
    rc = 0;
done:
    api_job_result_free(&res);
    free(rq.input);
    free(rq.target);
    free(in);
    free(tg);
    return rc;
}

/* The cores this process may run on (1 when that cannot be told), at
 * most 64: the default of --threads. */
static int online_cores(void)
{
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n < 1 ? 1 : n > 64 ? 64 : (int)n;
}

static int cmd_smooth(int argc, char **argv)
{
    api_limits lim;
    api_params p;
    cli_opts o;
    cJSON *table;
    int rc;

    memset(&o, 0, sizeof o);
    o.threads = online_cores();
    cli_limits(&lim);
    api_params_init(&p);
    if (!(table = param_table()))
        return 1;
    if ((rc = parse_args("smooth", argc, argv, 2, &p, &lim, &o, table)) == 0 &&
        (rc = output_format(&p, o.pos[1])) == 0 &&
        (!o.fix_file || (rc = fix_vertices(&p, o.fix_file, &lim)) == 0))
        rc = run_smooth(&o, &p, &lim);
    cJSON_Delete(table);
    api_params_free(&p);
    return rc;
}

/* ------------------------------------------------------------------- info */

static int cmd_info(int argc, char **argv)
{
    api_limits lim;
    mcf_mesh *m = NULL;
    mcf_error err = {MCF_OK, ""};
    mcf_curvature_summary cs;
    api_format fmt = API_FMT_UNKNOWN;
    size_t bytes = 0;
    cJSON *j = NULL;
    char *s = NULL;
    int rc;

    if (argc != 3 || (argv[2][0] == '-' && argv[2][1] != '\0'))
        return fail(EXIT_USAGE, "info: needs exactly one input file (try mcf --help)");
    cli_limits(&lim);
    if ((rc = load_mesh(argv[2], &lim, &m, &fmt, &bytes, NULL, NULL)) != 0)
        return rc;
    rc = 1;
    if (mcf_curvature_summarize(m, &cs, &err) != MCF_OK || !(j = info_json(m, &cs, &err))) {
        fail(1, "info: %s", err.msg[0] ? err.msg : "out of memory");
        goto done;
    }
    add(j, "format", cJSON_CreateString(api_format_name(fmt)));
    add(j, "bytes", cJSON_CreateNumber((double)bytes));
    if (!(s = api_json_print(j, 1))) {
        fail(1, "info: out of memory");
        goto done;
    }
    if (printf("%s\n", s) < 0 || fflush(stdout) != 0) {
        fail(1, "cannot write to stdout: %s", strerror(errno));
        goto done;
    }
    rc = 0;
done:
    free(s);
    cJSON_Delete(j);
    mcf_mesh_free(m);
    return rc;
}

/* ------------------------------------------------------- schemes, params */

/* `mcf schemes` and `mcf params`: a document of the libraries, printed
 * as JSON on stdout (j is taken and freed; NULL: out of memory). */
static int print_document(const char *cmd, int argc, cJSON *j)
{
    char *s;
    int rc = 0;

    if (argc != 2) {
        cJSON_Delete(j);
        return fail(EXIT_USAGE, "%s: takes no arguments", cmd);
    }
    s = j ? api_json_print(j, 1) : NULL;
    cJSON_Delete(j);
    if (!s)
        return fail(1, "%s: out of memory", cmd);
    if (printf("%s\n", s) < 0 || fflush(stdout) != 0)
        rc = fail(1, "cannot write to stdout: %s", strerror(errno));
    free(s);
    return rc;
}

/* ---------------------------------------------------------------- convert */

static int cmd_convert(int argc, char **argv)
{
    api_limits lim;
    api_params p;
    cli_opts o;
    mcf_mesh *m = NULL;
    api_attrs *attrs = NULL;
    cJSON *table = param_table();
    int rc;

    if (!table)
        return 1;
    memset(&o, 0, sizeof o);
    cli_limits(&lim);
    api_params_init(&p);
    if ((rc = parse_args("convert", argc, argv, 2, &p, &lim, &o, table)) == 0
        && (rc = output_format(&p, o.pos[1])) == 0
        && (rc = load_mesh_attrs(o.pos[0], &lim, &m, &attrs, NULL, NULL, NULL, NULL)) == 0) {
        p.encode.attrs = attrs;
        rc = save_mesh(m, &p.encode, o.pos[1], NULL, NULL, NULL, NULL);
    }
    mcf_mesh_free(m);
    api_attrs_free(attrs);
    api_params_free(&p);
    cJSON_Delete(table);
    return rc;
}

/* A command's --help (argv[1] is the command; "help" and --help alone give
 * the overview). */
static int command_help(const char *cmd)
{
    if (!strcmp(cmd, "smooth"))
        return print_help(smooth_head, 1, smooth_tail);
    if (!strcmp(cmd, "convert"))
        return print_help(convert_head, 0, "");
    fputs(!strcmp(cmd, "info") ? info_usage : !strcmp(cmd, "schemes") ? schemes_usage
          : !strcmp(cmd, "params") ? params_usage : usage_text, stdout);
    return 0;
}

int main(int argc, char **argv)
{
    const char *cmd = argc > 1 ? argv[1] : NULL;
    static const char *const commands[] = {"smooth", "info", "schemes", "params", "convert", NULL};
    int i, known = 0;

    prog_bound_blas_threads(argv);
    if (!cmd)
        return fail(EXIT_USAGE, "missing command: smooth, info, schemes, params or convert "
                    "(try mcf --help)");
    if (!strcmp(cmd, "--help") || !strcmp(cmd, "-h") || !strcmp(cmd, "help"))
        return command_help(argc > 2 && strcmp(cmd, "help") == 0 ? argv[2] : "");
    if (!strcmp(cmd, "--version") || !strcmp(cmd, "-V")) {
        printf("mcf %s\n", API_VERSION);
        return fflush(stdout) == 0 ? 0 : 1;
    }
    for (i = 0; commands[i]; i++)
        known |= !strcmp(cmd, commands[i]);
    if (!known)
        return fail(EXIT_USAGE, "unknown command '%s' (try mcf --help)", cmd);
    for (i = 2; i < argc; i++)
        if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h"))
            return command_help(cmd);
    if (!strcmp(cmd, "smooth"))
        return cmd_smooth(argc, argv);
    if (!strcmp(cmd, "info"))
        return cmd_info(argc, argv);
    if (!strcmp(cmd, "schemes"))
        return print_document(cmd, argc, api_json_schemes());
    if (!strcmp(cmd, "params"))
        return print_document(cmd, argc, api_params_describe(NULL));
    return cmd_convert(argc, argv);
}
