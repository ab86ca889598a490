/*
 * mcf_experiment.c - `mcf experiment STUDY`: the article's experiments done
 * properly (../shared/MATH.md, last two sections), written as CSV files and
 * rendered by gnuplot to PNG and SVG.
 *
 *   dt-sweep   a clean target, a noisy copy (Gaussian along the normals,
 *              sigma = rho * mean edge, seeded), every chosen scheme over a
 *              log-spaced dt range, a fixed number of iterations (10, as
 *              the article) or a fixed final time. Per run: M-weighted RMS,
 *              Frobenius, normal angle error, volume and area drift,
 *              NaN/inverted faces, status, wall time, solves.
 *   stability  per scheme, the largest dt whose run ends without failure,
 *              NaN or inverted faces and with an error under a threshold,
 *              next to the theory (2/lambda_max, 1/lambda_max for neumann2,
 *              unconditional for the implicit schemes).
 *   order      error at a fixed final time against a fine reference run,
 *              fitted slope per scheme (the MATH.md protocol).
 *   sphere     R(t) and V(t) of each scheme against sqrt(R0^2 - 4t).
 *
 * Units: a mesh read from a file is centred on its area centroid and scaled
 * to unit area once, up front (what `mcf smooth` does by default), and every
 * run then flows with normalize off. So dt, time, lambda_max and the errors
 * share the unit-area units of `mcf smooth --dt`, and dt * lambda_max reads
 * directly against the explicit bounds. An icosphere (--sphere LEVEL) keeps
 * its radius (default 1): the radius law is stated in those units.
 *
 * A run of the flow that fails (ENUMERIC, ENOCONV, ELIMIT, ...) is a data
 * point, written with its status; only I/O, memory and usage errors end a
 * study. Each figure is a self-contained gnuplot script (data inline)
 * written to a temporary file in the output folder and run as a
 * subprocess there; without gnuplot the CSV files are still written and one
 * line says the plots were skipped.
 */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include "api.h"
#include "mcf_experiment.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define EXIT_USAGE 2
#define MAX_DT 512          /* points of a dt grid */
#define MAX_LIST 24         /* entries of a --steps list */
#define SERIES_POINTS 120   /* sphere: rows kept per scheme (CSV and plot) */

const char mcf_experiment_usage[] =
    "  mcf experiment STUDY --out DIR [--mesh FILE | --sphere LEVEL [--radius R]] [--name NAME]\n"
    "                 [--schemes all|flows|explicit|implicit|S1,S2,...] [--noise RHO] [--seed K]\n"
    "                 [--dt-min D] [--dt-max D] [--per-decade N] [--iterations N | --time T]\n"
    "                 [--threshold E] [--bisect N] [--boundary fixed|free] [--steps N1,N2,...]\n"
    "                 [--ref-scheme S] [--ref-factor F] [--presmooth T0] [--picard-maxit N]\n"
    "                 [--max-steps N] [--no-plots] [--keep-scripts] [--quiet]\n"
    "                       STUDY: dt-sweep, stability, order or sphere. CSV files and\n"
    "                       gnuplot PNG/SVG plots in DIR; D may be written 0.5/lambda\n"
    "                       (a multiple of 1/lambda_max). See README, Results.\n";

/* ---------------------------------------------------------------- messages */

static int xfail(int code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

/* The one error line ("mcf: experiment: ..."), then the exit status. */
static int xfail(int code, const char *fmt, ...)
{
    char msg[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    for (size_t i = 0; msg[i]; i++)
        if (msg[i] == '\n' || msg[i] == '\r')
            msg[i] = ' ';
    fprintf(stderr, "mcf: experiment: %s\n", msg);
    return code;
}

/* ----------------------------------------------------------------- options */

typedef enum { ST_DTSWEEP, ST_STABILITY, ST_ORDER, ST_SPHERE } study_kind;

typedef struct {
    study_kind study;
    const char *study_name;
    const char *mesh_path;      /* NULL: an icosphere */
    int level;                  /* icosphere level */
    double radius;              /* icosphere radius */
    char name[128];             /* prefix of every output file */
    const char *out;
    mcf_scheme schemes[MCF_NSCHEMES];
    int nschemes;
    double rho;
    uint64_t seed;
    double dt_min, dt_max;      /* absolute, or multiples of 1/lambda */
    int dt_min_lam, dt_max_lam; /* 1: the value is a multiple of 1/lambda */
    int per_decade;
    int iterations;
    double time;                /* > 0: fixed final time */
    double threshold;           /* stability: largest acceptable rms_rel */
    int bisect;
    mcf_boundary boundary;
    int steps[MAX_LIST];
    int nsteps;
    mcf_scheme ref_scheme;
    int ref_factor;
    double presmooth;           /* order: time of a desbrun2 pre-smoothing */
    int picard_maxit;
    int max_steps;
    int plots, keep_scripts, quiet;
    const char *units;          /* how dt and time are measured, for labels */
} xopts;

/* Progress lines on stderr, unless --quiet. */
static void note(const xopts *o, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

static void note(const xopts *o, const char *fmt, ...)
{
    va_list ap;
    if (o->quiet)
        return;
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fflush(stderr);
}

/* A finite number; with per_lambda, an optional "/lambda" suffix. */
static int parse_double(const char *flag, const char *s, double *v, int *per_lambda)
{
    char *end;
    errno = 0;
    double x = strtod(s, &end);
    if (end == s || errno != 0)
        return xfail(EXIT_USAGE, "--%s: not a number: '%s'", flag, s);
    if (per_lambda) {
        *per_lambda = 0;
        if (strcmp(end, "/lambda") == 0) {
            *per_lambda = 1;
            end += strlen("/lambda");
        }
    }
    if (*end != '\0' || !isfinite(x))
        return xfail(EXIT_USAGE, "--%s: not a finite number: '%s'", flag, s);
    *v = x;
    return 0;
}

static int parse_int(const char *flag, const char *s, long lo, long hi, int *v)
{
    char *end;
    errno = 0;
    long x = strtol(s, &end, 10);
    if (end == s || *end != '\0' || errno != 0 || x < lo || x > hi)
        return xfail(EXIT_USAGE, "--%s: expected an integer in [%ld, %ld], got '%s'", flag, lo, hi, s);
    *v = (int)x;
    return 0;
}

/* "all", "flows" (all but taubin), "explicit", "implicit" or a comma list. */
static int parse_schemes(const char *s, xopts *o)
{
    o->nschemes = 0;
    if (!strcmp(s, "all") || !strcmp(s, "flows") || !strcmp(s, "explicit") || !strcmp(s, "implicit")) {
        for (int k = 0; k < MCF_NSCHEMES; k++) {
            const mcf_scheme_info *si = mcf_scheme_get((mcf_scheme)k);
            if (!strcmp(s, "flows") && k == MCF_TAUBIN)
                continue;
            if (!strcmp(s, "explicit") && (!si->is_explicit || k == MCF_TAUBIN))
                continue;
            if (!strcmp(s, "implicit") && si->is_explicit)
                continue;
            o->schemes[o->nschemes++] = (mcf_scheme)k;
        }
        return 0;
    }
    const char *p = s;
    while (*p) {
        char name[32];
        size_t n = strcspn(p, ",");
        mcf_scheme sc;
        if (n == 0 || n >= sizeof name)
            return xfail(EXIT_USAGE, "--schemes: bad list '%s'", s);
        memcpy(name, p, n);
        name[n] = '\0';
        if (mcf_scheme_from_name(name, &sc) != MCF_OK)
            return xfail(EXIT_USAGE, "--schemes: unknown scheme '%s' (see mcf schemes)", name);
        for (int k = 0; k < o->nschemes; k++)
            if (o->schemes[k] == sc)
                return xfail(EXIT_USAGE, "--schemes: '%s' given twice", name);
        o->schemes[o->nschemes++] = sc;
        p += n;
        if (*p == ',' && *++p == '\0')
            return xfail(EXIT_USAGE, "--schemes: bad list '%s'", s);
    }
    return 0;
}

/* An increasing list of step counts "32,64,128". */
static int parse_steps(const char *s, xopts *o)
{
    const char *p = s;
    o->nsteps = 0;
    while (*p) {
        char *end;
        errno = 0;
        long v = strtol(p, &end, 10);
        if (end == p || errno != 0 || v < 1 || v > 10000000 || (*end != ',' && *end != '\0') ||
            o->nsteps == MAX_LIST || (o->nsteps > 0 && v <= o->steps[o->nsteps - 1]))
            return xfail(EXIT_USAGE, "--steps: expected up to %d increasing integers >= 1 separated by commas, got '%s'",
                         MAX_LIST, s);
        o->steps[o->nsteps++] = (int)v;
        p = *end == ',' ? end + 1 : end;
    }
    if (o->nsteps == 0)
        return xfail(EXIT_USAGE, "--steps: empty list");
    return 0;
}

static const char *base_name(const char *path, char *buf, size_t size)
{
    const char *b = strrchr(path, '/');
    b = b ? b + 1 : path;
    snprintf(buf, size, "%s", b);
    char *dot = strrchr(buf, '.');
    if (dot && dot != buf)
        *dot = '\0';
    return buf;
}

/* Parses argv[2..]; fills the per-study defaults of what was not given. */
static int parse_opts(int argc, char **argv, xopts *o)
{
    int rc, given_dt_min = 0, given_dt_max = 0, given_time = 0, given_steps = 0, given_schemes = 0;
    int given_threshold = 0, given_iterations = 0, given_name = 0;

    memset(o, 0, sizeof *o);
    o->study_name = argv[2];
    if (!strcmp(argv[2], "dt-sweep"))
        o->study = ST_DTSWEEP;
    else if (!strcmp(argv[2], "stability"))
        o->study = ST_STABILITY;
    else if (!strcmp(argv[2], "order"))
        o->study = ST_ORDER;
    else if (!strcmp(argv[2], "sphere"))
        o->study = ST_SPHERE;
    else
        return xfail(EXIT_USAGE, "unknown study '%s': dt-sweep, stability, order or sphere", argv[2]);
    o->level = -1;
    o->radius = 1.0;
    o->rho = 0.2;
    o->seed = 1;
    o->per_decade = 3;
    o->iterations = 10;
    o->bisect = 6;
    o->boundary = MCF_BOUNDARY_FIXED;
    o->ref_scheme = MCF_RICHARDSON;
    o->ref_factor = 16;
    o->picard_maxit = 200;
    o->max_steps = 100000;
    o->plots = 1;

    for (int i = 3; i < argc; i++) {
        const char *a = argv[i];
        if (strncmp(a, "--", 2) != 0)
            return xfail(EXIT_USAGE, "unexpected argument '%s'", a);
        const char *f = a + 2;
        if (!strcmp(f, "no-plots")) { o->plots = 0; continue; }
        if (!strcmp(f, "keep-scripts")) { o->keep_scripts = 1; continue; }
        if (!strcmp(f, "quiet")) { o->quiet = 1; continue; }
        if (i + 1 >= argc)
            return xfail(EXIT_USAGE, "%s needs a value", a);
        const char *v = argv[++i];
        rc = 0;
        if (!strcmp(f, "out"))
            o->out = v;
        else if (!strcmp(f, "mesh"))
            o->mesh_path = v;
        else if (!strcmp(f, "sphere"))
            rc = parse_int(f, v, 0, 8, &o->level);
        else if (!strcmp(f, "radius")) {
            if (!(rc = parse_double(f, v, &o->radius, NULL)) && !(o->radius > 0))
                rc = xfail(EXIT_USAGE, "--radius: must be > 0");
        } else if (!strcmp(f, "name")) {
            if (!*v || strlen(v) >= sizeof o->name || strpbrk(v, "/\"'\\"))
                return xfail(EXIT_USAGE, "--name: 1 to %zu characters, no slash or quote", sizeof o->name - 1);
            snprintf(o->name, sizeof o->name, "%s", v);
            given_name = 1;
        } else if (!strcmp(f, "schemes")) {
            rc = parse_schemes(v, o);
            given_schemes = 1;
        } else if (!strcmp(f, "noise")) {
            if (!(rc = parse_double(f, v, &o->rho, NULL)) && !(o->rho >= 0 && o->rho <= 10))
                rc = xfail(EXIT_USAGE, "--noise: must be in [0, 10]");
        } else if (!strcmp(f, "seed")) {
            char *end;
            errno = 0;
            unsigned long long s = strtoull(v, &end, 10);
            if (end == v || *end || errno || v[0] == '-')
                rc = xfail(EXIT_USAGE, "--seed: expected a non-negative integer, got '%s'", v);
            o->seed = (uint64_t)s;
        } else if (!strcmp(f, "dt-min")) {
            rc = parse_double(f, v, &o->dt_min, &o->dt_min_lam);
            given_dt_min = 1;
        } else if (!strcmp(f, "dt-max")) {
            rc = parse_double(f, v, &o->dt_max, &o->dt_max_lam);
            given_dt_max = 1;
        } else if (!strcmp(f, "per-decade"))
            rc = parse_int(f, v, 1, 50, &o->per_decade);
        else if (!strcmp(f, "iterations")) {
            rc = parse_int(f, v, 1, 10000000, &o->iterations);
            given_iterations = 1;
        } else if (!strcmp(f, "time")) {
            if (!(rc = parse_double(f, v, &o->time, NULL)) && !(o->time > 0))
                rc = xfail(EXIT_USAGE, "--time: must be > 0");
            given_time = 1;
        } else if (!strcmp(f, "threshold")) {
            if (!(rc = parse_double(f, v, &o->threshold, NULL)) && !(o->threshold > 0))
                rc = xfail(EXIT_USAGE, "--threshold: must be > 0");
            given_threshold = 1;
        } else if (!strcmp(f, "bisect"))
            rc = parse_int(f, v, 0, 30, &o->bisect);
        else if (!strcmp(f, "boundary")) {
            if (!strcmp(v, "fixed"))
                o->boundary = MCF_BOUNDARY_FIXED;
            else if (!strcmp(v, "free"))
                o->boundary = MCF_BOUNDARY_FREE;
            else
                rc = xfail(EXIT_USAGE, "--boundary: fixed or free, got '%s'", v);
        } else if (!strcmp(f, "steps")) {
            rc = parse_steps(v, o);
            given_steps = 1;
        } else if (!strcmp(f, "ref-scheme")) {
            if (mcf_scheme_from_name(v, &o->ref_scheme) != MCF_OK || o->ref_scheme == MCF_TAUBIN)
                rc = xfail(EXIT_USAGE, "--ref-scheme: unknown flow scheme '%s'", v);
        } else if (!strcmp(f, "ref-factor"))
            rc = parse_int(f, v, 2, 1024, &o->ref_factor);
        else if (!strcmp(f, "presmooth")) {
            if (!(rc = parse_double(f, v, &o->presmooth, NULL)) && !(o->presmooth >= 0))
                rc = xfail(EXIT_USAGE, "--presmooth: must be >= 0");
        } else if (!strcmp(f, "picard-maxit"))
            rc = parse_int(f, v, 1, 100000, &o->picard_maxit);
        else if (!strcmp(f, "max-steps"))
            rc = parse_int(f, v, 1, 100000000, &o->max_steps);
        else
            return xfail(EXIT_USAGE, "unknown flag '%s' (try mcf --help)", a);
        if (rc)
            return rc;
    }
    if (!o->out)
        return xfail(EXIT_USAGE, "--out DIR is required");
    if (o->mesh_path && o->level >= 0)
        return xfail(EXIT_USAGE, "--mesh and --sphere exclude each other");
    if (o->study == ST_SPHERE && o->mesh_path)
        return xfail(EXIT_USAGE, "sphere: the study runs on an icosphere (--sphere LEVEL), not --mesh");
    if (!o->mesh_path && o->level < 0)
        o->level = o->study == ST_SPHERE ? 4 : 3;
    if (given_time && given_iterations && o->study == ST_DTSWEEP)
        return xfail(EXIT_USAGE, "--iterations and --time exclude each other");
    o->units = o->mesh_path ? "unit-area units" : "units of the radius squared";
    if (!given_name) {
        if (o->mesh_path)
            base_name(o->mesh_path, o->name, sizeof o->name);
        else
            snprintf(o->name, sizeof o->name, "icosphere%d", o->level);
    }
    if (!given_schemes) {
        /* taubin is a filter: it has no dt, no stability limit, no order */
        parse_schemes(o->study == ST_DTSWEEP ? "all" : "flows", o);
    }
    if (o->study != ST_DTSWEEP)
        for (int k = 0; k < o->nschemes; k++)
            if (o->schemes[k] == MCF_TAUBIN)
                return xfail(EXIT_USAGE, "%s: taubin is a filter without a time step; leave it out", o->study_name);
    if (!given_dt_min) {
        o->dt_min = o->study == ST_STABILITY ? 0.1 : 0.05;
        o->dt_min_lam = 1;
    }
    if (!given_dt_max) {
        o->dt_max = o->study == ST_STABILITY ? 1e4 : 1e3;
        o->dt_max_lam = 1;
    }
    if (!(o->dt_min > 0) || !(o->dt_max > 0))
        return xfail(EXIT_USAGE, "--dt-min and --dt-max must be > 0");
    if (!given_threshold)
        o->threshold = 1.0;
    if (o->study == ST_ORDER && !given_time)
        o->time = 0.01;
    if (o->study == ST_ORDER && !given_steps) {
        static const int def[] = {32, 64, 128, 256};
        o->nsteps = 4;
        memcpy(o->steps, def, sizeof def);
    }
    if (o->study == ST_SPHERE) {
        if (!given_time)
            o->time = 0.2 * o->radius * o->radius;
        if (!(o->time < 0.25 * o->radius * o->radius))
            return xfail(EXIT_USAGE, "sphere: --time must be below the extinction time R0^2/4 = %g",
                         0.25 * o->radius * o->radius);
        if (!given_steps) {
            o->steps[0] = 100;
            o->nsteps = 1;
        } else if (o->nsteps != 1)
            return xfail(EXIT_USAGE, "sphere: --steps takes one count (implicit schemes' steps)");
    }
    return 0;
}

/* ------------------------------------------------------------------- files */

static int mkdir_p(const char *dir)
{
    char path[4096];
    if (snprintf(path, sizeof path, "%s", dir) >= (int)sizeof path)
        return xfail(1, "--out: path too long");
    for (char *p = path + 1; ; p++) {
        if (*p == '/' || *p == '\0') {
            char c = *p;
            *p = '\0';
            if (mkdir(path, 0777) != 0 && errno != EEXIST)
                return xfail(1, "cannot create '%s': %s", path, strerror(errno));
            *p = c;
            if (c == '\0')
                break;
        }
    }
    struct stat sb;
    if (stat(dir, &sb) != 0 || !S_ISDIR(sb.st_mode))
        return xfail(1, "'%s' is not a folder", dir);
    return 0;
}

/* OUT/NAME-suffix into buf. */
static void out_path(const xopts *o, const char *suffix, char *buf, size_t size)
{
    snprintf(buf, size, "%s/%s-%s", o->out, o->name, suffix);
}

static FILE *csv_open(const xopts *o, const char *suffix, char *path, size_t size)
{
    out_path(o, suffix, path, size);
    FILE *f = fopen(path, "w");
    if (!f)
        xfail(1, "cannot write '%s': %s", path, strerror(errno));
    return f;
}

static int csv_close(FILE *f, const char *path)
{
    int bad = ferror(f);
    if (fclose(f) != 0 || bad)
        return xfail(1, "cannot write '%s'", path);
    return 0;
}

/* A message made safe for one CSV field: no comma, quote or newline. */
static void csv_clean(const char *in, char *out, size_t size)
{
    size_t i;
    for (i = 0; in[i] && i + 1 < size; i++)
        out[i] = (in[i] == ',' || in[i] == '"' || in[i] == '\n' || in[i] == '\r') ? ';' : in[i];
    out[i] = '\0';
}

/* Reads a whole file and decodes it under the default limits. */
static int load_file_mesh(const char *path, mcf_mesh **out)
{
    api_limits lim;
    mcf_error err = {MCF_OK, ""};
    FILE *f = fopen(path, "rb");
    char *buf = NULL;
    size_t n = 0, cap = 0;
    int rc = 1;

    api_limits_default(&lim);
    if (!f)
        return xfail(1, "cannot read '%s': %s", path, strerror(errno));
    for (;;) {
        if (cap - n < 65536) {
            size_t ncap = cap ? 2 * cap : 1 << 20;
            char *p = ncap > lim.max_input_bytes + 65536 ? NULL : realloc(buf, ncap);
            if (!p) {
                xfail(1, "'%s': too large or out of memory", path);
                goto done;
            }
            buf = p;
            cap = ncap;
        }
        size_t got = fread(buf + n, 1, cap - n, f);
        n += got;
        if (got == 0) {
            if (ferror(f)) {
                xfail(1, "cannot read '%s': %s", path, strerror(errno));
                goto done;
            }
            break;
        }
    }
    if (api_mesh_decode(buf, n, &lim, out, NULL, &err) != MCF_OK) {
        xfail(1, "%s: %s", path, err.msg);
        goto done;
    }
    rc = 0;
done:
    free(buf);
    fclose(f);
    return rc;
}

/* Centres m on its area centroid and scales it to unit area: the flow's
 * working units (mcf_mesh_area_centroid). */
static int normalize_unit_area(mcf_mesh *m)
{
    double *X = mcf_mesh_positions_mut(m);
    int nv = mcf_mesh_nvertices(m);
    double c[3], area = mcf_mesh_area_centroid(m, c);
    if (!(area > 0))
        return xfail(1, "the mesh has zero area");
    double s = 1.0 / sqrt(area);
    for (int i = 0; i < nv; i++)
        for (int k = 0; k < 3; k++)
            X[3 * i + k] = (X[3 * i + k] - c[k]) * s;
    return 0;
}

/* The study's clean mesh: the file at unit area, or the icosphere. */
static int study_mesh(const xopts *o, mcf_mesh **out)
{
    mcf_error err = {MCF_OK, ""};
    if (!o->mesh_path) {
        *out = mcf_mesh_new_icosphere(o->level, o->radius, &err);
        return *out ? 0 : xfail(1, "icosphere: %s", err.msg);
    }
    if (load_file_mesh(o->mesh_path, out) != 0)
        return 1;
    if (normalize_unit_area(*out) != 0) {
        mcf_mesh_free(*out);
        *out = NULL;
        return 1;
    }
    return 0;
}

/* --------------------------------------------------------------------- runs */

typedef struct {
    mcf_scheme scheme;
    double dt;                /* the step taken (dt_first) */
    double dt_req;            /* the step asked for */
    int iterations;           /* asked for (0: fixed time) */
    mcf_status status;
    char msg[MCF_ERRMSG_SIZE];
    int steps;
    double t_final;
    mcf_compare_result cmp;   /* against the target (zero without one) */
    int flipped;              /* faces turned > 90 degrees from the start;
                                 smoothing also unfolds faces the noise
                                 folded, so this is not a defect count */
    int folded, folded_steps; /* see step_watch */
    int nonfinite;            /* non-finite coordinates in the result */
    double area_drift, volume_drift; /* relative to the run's start */
    double wall;
    int solves, factorizations, picard;
} xrun;

static void flow_params(const xopts *o, mcf_scheme s, double dt, int iters, double T, mcf_flow_params *p)
{
    mcf_flow_params_init(p);
    p->scheme = s;
    p->dt = dt;
    p->iterations = iters;
    p->time = T;
    p->boundary = o->boundary;
    p->normalize = 0;
    p->implicit_maxit = o->picard_maxit;
    p->max_steps = o->max_steps;
}

/* Watches a run step by step (through the progress callback, which may
 * read the working positions): faces whose normal turns by more than 90
 * degrees within one step and end it turned against the target (or the
 * start): a stable step never folds a face, an unstable one flips faces
 * back and forth. A face the noise folded and the step unfolds is not
 * counted. The flow checks for any flip itself, for the explicit schemes
 * only (and fails); here folds are counted for every scheme. */
typedef struct {
    const mcf_mesh *m;
    double *fn;               /* 3 * nf face normals after the last step */
    double *ref;              /* 3 * nf normals of the target (or start) */
    int folded;               /* sum over steps of faces folded in a step */
    int folded_steps;         /* steps that folded at least one face */
} step_watch;

static void face_normals(const mcf_mesh *m, double *fn)
{
    const double *X = mcf_mesh_positions(m);
    const int32_t *F = mcf_mesh_faces(m);
    for (int f = 0; f < mcf_mesh_nfaces(m); f++) {
        const double *a = X + 3 * F[3 * f], *b = X + 3 * F[3 * f + 1], *c = X + 3 * F[3 * f + 2];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        fn[3 * f] = u[1] * w[2] - u[2] * w[1];
        fn[3 * f + 1] = u[2] * w[0] - u[0] * w[2];
        fn[3 * f + 2] = u[0] * w[1] - u[1] * w[0];
    }
}

static int watch_step(void *ctx, int step, double t, double dt, double energy)
{
    step_watch *w = ctx;
    const double *X = mcf_mesh_positions(w->m);
    const int32_t *F = mcf_mesh_faces(w->m);
    int folded = 0;
    (void)step, (void)t, (void)dt, (void)energy;
    for (int f = 0; f < mcf_mesh_nfaces(w->m); f++) {
        const double *a = X + 3 * F[3 * f], *b = X + 3 * F[3 * f + 1], *c = X + 3 * F[3 * f + 2];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
        double *o = w->fn + 3 * f;
        const double *g = w->ref + 3 * f;
        /* a fold, not the repair of a face the noise folded: the face
         * ends the step against the target too */
        if (n[0] * o[0] + n[1] * o[1] + n[2] * o[2] < 0 && n[0] * g[0] + n[1] * g[1] + n[2] * g[2] < 0)
            folded++;
        o[0] = n[0];
        o[1] = n[1];
        o[2] = n[2];
    }
    w->folded += folded;
    w->folded_steps += folded > 0;
    return 0;
}

/* Runs scheme s from a copy of start, with iters steps of dt or (T > 0)
 * to time T; compares the result with target (may be NULL). The flow's
 * failure is recorded in r. *out (may be NULL) receives the final mesh,
 * stats (may be NULL) the flow statistics (caller frees them). Returns 0,
 * or 1 after an error line when memory runs out. */
static int run_flow(const xopts *o, const mcf_mesh *start, const mcf_mesh *target, mcf_scheme s, double dt,
                    int iters, double T, int log_steps, xrun *r, mcf_mesh **out, mcf_flow_stats *stats)
{
    mcf_error err = {MCF_OK, ""};
    mcf_flow_params p;
    mcf_flow_stats st;
    mcf_mesh *m = mcf_mesh_dup(start, &err);

    memset(r, 0, sizeof *r);
    r->scheme = s;
    r->dt_req = dt;
    r->iterations = T > 0 ? 0 : iters;
    if (!m)
        return xfail(1, "%s", err.msg);
    size_t n3 = 3 * (size_t)mcf_mesh_nfaces(m);
    step_watch w = {m, malloc(n3 * sizeof(double)), malloc(n3 * sizeof(double)), 0, 0};
    if (!w.fn || !w.ref) {
        free(w.fn);
        free(w.ref);
        mcf_mesh_free(m);
        return xfail(1, "out of memory");
    }
    face_normals(m, w.fn);
    face_normals(target ? target : start, w.ref);
    flow_params(o, s, dt, iters, T, &p);
    p.log_steps = log_steps;
    p.progress = watch_step;
    p.progress_ctx = &w;
    r->status = mcf_flow_run(m, &p, &st, &err);
    free(w.fn);
    free(w.ref);
    r->folded = w.folded;
    r->folded_steps = w.folded_steps;
    if (r->status == MCF_ENOMEM) {
        mcf_flow_stats_free(&st);
        mcf_mesh_free(m);
        return xfail(1, "%s", err.msg);
    }
    if (r->status != MCF_OK)
        snprintf(r->msg, sizeof r->msg, "%s", err.msg);
    r->dt = st.dt_first > 0 ? st.dt_first : dt;
    r->steps = st.steps;
    r->t_final = st.t_final;
    r->wall = st.time_total;
    r->solves = st.solves;
    r->factorizations = st.factorizations;
    r->picard = st.picard_iterations;
    r->area_drift = st.area0 != 0 ? st.area1 / st.area0 - 1.0 : NAN;
    r->volume_drift = st.volume0 != 0 ? st.volume1 / st.volume0 - 1.0 : NAN;
    const double *X = mcf_mesh_positions(m);
    for (long i = 0; i < 3L * mcf_mesh_nvertices(m); i++)
        if (!isfinite(X[i])) {
            r->nonfinite = 1;
            break;
        }
    if (!r->nonfinite) {
        mcf_compare_result c;
        if (mcf_compare(m, start, &c, &err) == MCF_OK)
            r->flipped = c.inverted_faces;
        if (target && mcf_compare(m, target, &r->cmp, &err) != MCF_OK) {
            mcf_flow_stats_free(&st);
            mcf_mesh_free(m);
            return xfail(1, "compare: %s", err.msg);
        }
    } else {
        r->cmp.rms_rel = r->cmp.frobenius = r->cmp.normal_angle_deg = r->cmp.max_err = NAN;
    }
    if (stats)
        *stats = st;
    else
        mcf_flow_stats_free(&st);
    if (out)
        *out = m;
    else
        mcf_mesh_free(m);
    return 0;
}

static int run_ok(const xrun *r)
{
    return r->status == MCF_OK && !r->nonfinite;
}

static void run_note(const xopts *o, const xrun *r)
{
    note(o, "%s %-10s dt %-10.4g steps %-6d rms_rel %-10.4g %-9s %.2f s%s%s\n", o->name,
         mcf_scheme_get(r->scheme)->name, r->dt, r->steps, r->cmp.rms_rel, mcf_status_name(r->status), r->wall,
         r->msg[0] ? "  " : "", r->msg);
}

static const char run_csv_header[] =
    "mesh,scheme,explicit,dt,dt_lambda,iterations,steps,t_final,status,rms_rel,frobenius,normal_angle_deg,"
    "max_err,inverted_faces,flipped_from_start,folded_in_a_step,steps_that_folded,nonfinite,area_drift,volume_drift,wall_s,solves,factorizations,picard_iterations,"
    "message";

/* One row of run_csv_header, without the line end. */
static void run_csv_fields(FILE *f, const xopts *o, const xrun *r, double lam)
{
    char msg[MCF_ERRMSG_SIZE];
    const mcf_scheme_info *si = mcf_scheme_get(r->scheme);
    csv_clean(r->msg, msg, sizeof msg);
    fprintf(f, "%s,%s,%d,%.9g,%.6g,%d,%d,%.9g,%s,%.9g,%.9g,%.9g,%.9g,%d,%d,%d,%d,%d,%.9g,%.9g,%.6f,%d,%d,%d,%s", o->name,
            si->name, si->is_explicit, r->dt, r->dt * lam, r->iterations, r->steps, r->t_final,
            mcf_status_name(r->status), r->cmp.rms_rel, r->cmp.frobenius, r->cmp.normal_angle_deg, r->cmp.max_err,
            r->cmp.inverted_faces, r->flipped, r->folded, r->folded_steps, r->nonfinite, r->area_drift, r->volume_drift, r->wall, r->solves, r->factorizations,
            r->picard, msg);
}

static void run_csv_row(FILE *f, const xopts *o, const xrun *r, double lam)
{
    run_csv_fields(f, o, r, lam);
    fputc('\n', f);
}

/* ------------------------------------------------------------------ fitting */

/* Least-squares slope of log y against log x over the n points with both
 * positive and finite; NAN when fewer than two. */
static double fit_loglog(const double *x, const double *y, int n, int *used)
{
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    int k = 0;
    for (int i = 0; i < n; i++) {
        if (!(x[i] > 0 && y[i] > 0 && isfinite(x[i]) && isfinite(y[i])))
            continue;
        double lx = log(x[i]), ly = log(y[i]);
        sx += lx;
        sy += ly;
        sxx += lx * lx;
        sxy += lx * ly;
        k++;
    }
    if (used)
        *used = k;
    if (k < 2)
        return NAN;
    double den = k * sxx - sx * sx;
    return den > 0 ? (k * sxy - sx * sy) / den : NAN;
}

/* ------------------------------------------------------------------ gnuplot */

/* One colour per scheme, the same in every figure; explicit schemes are
 * dashed, implicit ones solid. */
static const char *const scheme_color[MCF_NSCHEMES] = {
    [MCF_EULER] = "#1f77b4",    [MCF_TAYLOR2] = "#17becf", [MCF_DESBRUN] = "#2ca02c",
    [MCF_NEUMANN2] = "#9467bd", [MCF_DESBRUN2] = "#d62728", [MCF_ROS2] = "#ff7f0e",
    [MCF_RICHARDSON] = "#8c564b", [MCF_IMPLICIT] = "#7f7f7f", [MCF_HUISKEN2] = "#bcbd22",
    [MCF_ARC] = "#e377c2",      [MCF_CMCF] = "#006400",    [MCF_LINEAR] = "#000080",
    [MCF_TAUBIN] = "#000000"};

static void gp_style(api_buf *b, mcf_scheme s, int points)
{
    const mcf_scheme_info *si = mcf_scheme_get(s);
    api_buf_printf(b, "lc rgb \"%s\" lw 2 dt %d", scheme_color[s], si->is_explicit ? 2 : 1);
    if (points)
        api_buf_printf(b, " pt %d ps 1.1", 1 + (int)s % 13);
}

/* Text for a double-quoted gnuplot string: backslash and quote escaped,
 * a newline written as \n (a line break in titles). */
static void gp_str(api_buf *b, const char *s)
{
    api_buf_append(b, "\"", 1);
    for (; *s; s++) {
        if (*s == '\n') {
            api_buf_append(b, "\\n", 2);
            continue;
        }
        if (*s == '"' || *s == '\\')
            api_buf_append(b, "\\", 1);
        api_buf_append(b, s, 1);
    }
    api_buf_append(b, "\"", 1);
}

/* Axes, grid, legend and title shared by the figures. */
static void gp_axes(api_buf *b, const char *title, const char *xlabel, const char *ylabel, int logx, int logy)
{
    api_buf_printf(b, "set title ");
    gp_str(b, title);
    api_buf_printf(b, "\nset xlabel ");
    gp_str(b, xlabel);
    api_buf_printf(b, "\nset ylabel ");
    gp_str(b, ylabel);
    api_buf_printf(b, "\nset grid xtics ytics mxtics mytics lc rgb \"#e0e0e0\" lw 1, lc rgb \"#f2f2f2\" lw 1\n"
                      "set key outside right top spacing 1.15 box lc rgb \"#bbbbbb\"\n"
                      "set border lw 1.2\nset tics nomirror\n");
    if (logx)
        api_buf_printf(b, "set logscale x\nset format x \"10^{%%L}\"\n");
    if (logy)
        api_buf_printf(b, "set logscale y\nset format y \"10^{%%L}\"\n");
}

/* A data block $name with rows of columns. */
static void gp_block_begin(api_buf *b, const char *name)
{
    api_buf_printf(b, "$%s << EOD\n", name);
}

static void gp_block_end(api_buf *b)
{
    api_buf_printf(b, "EOD\n");
}

/* Renders body to OUT/NAME-suffix.png and .svg through a script in OUT;
 * returns 0 (also when gnuplot is absent: one line says so and plotting
 * is turned off for the rest of the study), 1 on a gnuplot error. */
static int gp_render(xopts *o, const char *suffix, const api_buf *body)
{
    char script[4096], png[512], svg[512];
    int fd, rc = 0;
    FILE *f;

    if (!o->plots)
        return 0;
    snprintf(png, sizeof png, "%s-%s.png", o->name, suffix);
    snprintf(svg, sizeof svg, "%s-%s.svg", o->name, suffix);
    if (o->keep_scripts) {
        snprintf(script, sizeof script, "%s/%s-%s.gp", o->out, o->name, suffix);
        fd = open(script, O_WRONLY | O_CREAT | O_TRUNC, 0666);
    } else {
        snprintf(script, sizeof script, "%s/.mcf-plot-XXXXXX", o->out);
        fd = mkstemp(script);
    }
    if (fd < 0)
        return xfail(1, "cannot write a gnuplot script in '%s': %s", o->out, strerror(errno));
    f = fdopen(fd, "w");
    if (!f) {
        close(fd);
        return xfail(1, "cannot write a gnuplot script: %s", strerror(errno));
    }
    fprintf(f, "# %s: mcf experiment %s; run in this folder: gnuplot %s-%s.gp\n", o->name, o->study_name,
            o->name, suffix);
    fprintf(f, "set encoding utf8\n"
               "set terminal pngcairo size 1200,720 enhanced font \"DejaVu Sans,13\" background rgb \"white\"\n"
               "set output \"%s\"\n%s\nunset output\n",
            png, body->data);
    fprintf(f, "set terminal svg size 1200,720 dynamic enhanced font \"DejaVu Sans,13\" background rgb \"white\"\n"
               "set output \"%s\"\nreplot\nunset output\n",
            svg);
    if (fclose(f) != 0) {
        remove(script);
        return xfail(1, "cannot write the gnuplot script '%s'", script);
    }
    pid_t pid = fork();
    if (pid < 0) {
        rc = xfail(1, "fork: %s", strerror(errno));
    } else if (pid == 0) {
        const char *base = strrchr(script, '/') + 1;
        if (chdir(o->out) != 0)
            _exit(126);
        execlp("gnuplot", "gnuplot", base, (char *)NULL);
        _exit(127);
    } else {
        int ws;
        while (waitpid(pid, &ws, 0) < 0)
            if (errno != EINTR) {
                ws = -1;
                break;
            }
        if (ws != -1 && WIFEXITED(ws) && WEXITSTATUS(ws) == 127) {
            o->plots = 0; /* once is enough: the rest of the study skips plots */
            fprintf(stderr, "mcf: experiment: gnuplot not found on the PATH: plots skipped, CSV files written\n");
        } else if (ws == -1 || !WIFEXITED(ws) || WEXITSTATUS(ws) != 0) {
            rc = xfail(1, "gnuplot failed on %s (script %s)", png, script);
        } else {
            note(o, "wrote %s/%s and .svg\n", o->out, png);
        }
    }
    if (!o->keep_scripts && rc == 0)
        remove(script);
    return rc;
}

/* A plot line "$block using ... with ... title ..." with the scheme's style. */
static void gp_series(api_buf *b, int *first, const char *block, const char *using, const char *with, mcf_scheme s,
                      const char *title)
{
    api_buf_printf(b, "%s $%s using %s with %s ", *first ? "plot" : ", \\\n    ", block, using, with);
    gp_style(b, s, strstr(with, "points") != NULL);
    api_buf_printf(b, " title ");
    gp_str(b, title);
    *first = 0;
}

/* --------------------------------------------------------------- dt-sweep */

typedef struct {
    int best;          /* index into the scheme's runs, -1: none OK */
    double slope;      /* log-log slope right of the minimum */
    int slope_points;
    int ok, failed;
    double largest_ok_dt;
} sweep_summary;

static void summarize_sweep(const xrun *rs, int n, sweep_summary *s)
{
    double x[MAX_DT], y[MAX_DT];
    int k = 0;
    memset(s, 0, sizeof *s);
    s->best = -1;
    s->slope = NAN;
    for (int i = 0; i < n; i++) {
        if (!run_ok(&rs[i])) {
            s->failed++;
            continue;
        }
        s->ok++;
        if (rs[i].dt > s->largest_ok_dt)
            s->largest_ok_dt = rs[i].dt;
        if (s->best < 0 || rs[i].cmp.rms_rel < rs[s->best].cmp.rms_rel)
            s->best = i;
    }
    if (s->best < 0)
        return;
    /* the rising branch: from the best dt on, until the error reaches half
     * of the largest one (past it the mesh has collapsed: it saturates) */
    double emax = 0;
    for (int i = 0; i < n; i++)
        if (run_ok(&rs[i]) && rs[i].cmp.rms_rel > emax)
            emax = rs[i].cmp.rms_rel;
    for (int i = s->best; i < n; i++)
        if (run_ok(&rs[i])) {
            x[k] = rs[i].dt;
            y[k] = rs[i].cmp.rms_rel;
            k++;
            if (rs[i].cmp.rms_rel >= 0.5 * emax)
                break;
        }
    if (k >= 3)
        s->slope = fit_loglog(x, y, k, &s->slope_points);
}

/* The mesh of a dt study: the study mesh (*target), a copy of it with the
 * noise of o->rho and o->seed (*noisy), their comparison (*c0) and the
 * noisy mesh's lambda_max (*lam). Returns 0, or 1 after xfail; on failure
 * *target and *noisy may still hold meshes: the caller frees both. */
static int noisy_study_mesh(const xopts *o, mcf_mesh **target, mcf_mesh **noisy, mcf_compare_result *c0, double *lam)
{
    mcf_error err = {MCF_OK, ""};
    if (study_mesh(o, target) != 0)
        return 1;
    if (!(*noisy = mcf_mesh_dup(*target, &err)) || mcf_mesh_add_noise(*noisy, o->rho, o->seed, &err) != MCF_OK ||
        mcf_compare(*noisy, *target, c0, &err) != MCF_OK ||
        mcf_lambda_max(*noisy, MCF_LAPLACIAN_COTAN, MCF_MASS_BARYCENTRIC, lam, &err) != MCF_OK) {
        xfail(1, "%s", err.msg);
        return 1;
    }
    return 0;
}

/* The dt range [*lo, *hi] of o in time units: --dt-min and --dt-max given
 * as multiples of 1/lambda_max are divided by lam. Returns 0, or 1 after
 * xfail(EXIT_USAGE) when the range is empty: hi < lo, or hi == lo unless
 * one_point (a single dt is then a valid range). */
static int dt_range(const xopts *o, double lam, int one_point, double *lo, double *hi)
{
    *lo = o->dt_min_lam ? o->dt_min / lam : o->dt_min;
    *hi = o->dt_max_lam ? o->dt_max / lam : o->dt_max;
    if (one_point ? !(*hi >= *lo) : !(*hi > *lo)) {
        xfail(EXIT_USAGE, "dt range [%g, %g] is empty (lambda_max %g)", *lo, *hi, lam);
        return 1;
    }
    return 0;
}

static int study_dt_sweep(xopts *o)
{
    mcf_mesh *target = NULL, *noisy = NULL;
    xrun *runs = NULL;
    int *first = NULL, *count = NULL;
    double dts[MAX_DT], lam = 0;
    int ndt = 0, nruns = 0, rc = 1;
    mcf_compare_result c0;
    api_buf b;
    FILE *f = NULL;
    char path[4096];

    api_buf_init(&b, 64u << 20);
    if (noisy_study_mesh(o, &target, &noisy, &c0, &lam) != 0)
        goto done;
    double lo, hi;
    if (dt_range(o, lam, 1, &lo, &hi) != 0) {
        rc = EXIT_USAGE;
        goto done;
    }
    for (ndt = 0; ndt < MAX_DT - 1; ndt++) {
        double dt = lo * pow(10.0, (double)ndt / o->per_decade);
        if (dt > hi * (1 + 1e-9))
            break;
        dts[ndt] = dt;
    }
    /* the end of the range is always a point (at a fixed time: one step) */
    if (dts[ndt - 1] < hi * (1 - 1e-9))
        dts[ndt++] = hi;
    note(o, "%s: %d vertices, noise rho %g seed %llu: rms_rel %.4g; lambda_max %.6g (2/lambda %.4g); %d dt values "
            "%.3g..%.3g, %s %g\n",
         o->name, mcf_mesh_nvertices(target), o->rho, (unsigned long long)o->seed, c0.rms_rel, lam, 2 / lam, ndt,
         dts[0], dts[ndt - 1], o->time > 0 ? "time" : "iterations", o->time > 0 ? o->time : (double)o->iterations);

    runs = calloc((size_t)o->nschemes * (size_t)ndt, sizeof *runs);
    first = calloc((size_t)o->nschemes, sizeof *first);
    count = calloc((size_t)o->nschemes, sizeof *count);
    if (!runs || !first || !count) {
        xfail(1, "out of memory");
        goto done;
    }
    for (int k = 0; k < o->nschemes; k++) {
        mcf_scheme s = o->schemes[k];
        first[k] = nruns;
        if (s == MCF_TAUBIN) {
            /* a filter: no dt, a number of passes; at a fixed time it has
             * no equivalent and is left out */
            if (o->time > 0)
                continue;
            if (run_flow(o, noisy, target, s, 1e-4, o->iterations, 0, 0, &runs[nruns], NULL, NULL) != 0)
                goto done;
            runs[nruns].dt = runs[nruns].dt_req = runs[nruns].t_final = NAN;
            run_note(o, &runs[nruns]);
            nruns++;
        } else {
            for (int i = 0; i < ndt; i++) {
                if (run_flow(o, noisy, target, s, dts[i], o->iterations, o->time, 0, &runs[nruns], NULL, NULL) != 0)
                    goto done;
                run_note(o, &runs[nruns]);
                nruns++;
            }
        }
        count[k] = nruns - first[k];
    }

    /* the runs */
    if (!(f = csv_open(o, "dt-sweep.csv", path, sizeof path)))
        goto done;
    fprintf(f, "%s\n", run_csv_header);
    for (int i = 0; i < nruns; i++)
        run_csv_row(f, o, &runs[i], lam);
    if (csv_close(f, path) != 0) {
        f = NULL;
        goto done;
    }
    /* per scheme: the best dt, its time and the slope right of it */
    if (!(f = csv_open(o, "dt-sweep-summary.csv", path, sizeof path)))
        goto done;
    fprintf(f, "mesh,scheme,lambda_max,noise_rho,seed,noisy_rms_rel,noisy_frobenius,noisy_normal_angle_deg,"
               "noisy_inverted_faces,"
               "iterations,time,best_dt,best_dt_lambda,best_time,best_rms_rel,best_frobenius,"
               "best_normal_angle_deg,rising_slope,slope_points,largest_ok_dt,ok_runs,failed_runs\n");
    sweep_summary *sum = calloc((size_t)o->nschemes, sizeof *sum);
    if (!sum) {
        fclose(f);
        f = NULL;
        xfail(1, "out of memory");
        goto done;
    }
    for (int k = 0; k < o->nschemes; k++) {
        const xrun *rs = runs + first[k];
        summarize_sweep(rs, count[k], &sum[k]);
        if (count[k] == 0)
            continue;
        const xrun *bst = sum[k].best >= 0 ? &rs[sum[k].best] : NULL;
        fprintf(f, "%s,%s,%.9g,%g,%llu,%.9g,%.9g,%.9g,%d,%d,%.9g,%.9g,%.6g,%.9g,%.9g,%.9g,%.9g,%.4f,%d,%.9g,%d,%d\n",
                o->name, mcf_scheme_get(o->schemes[k])->name, lam, o->rho, (unsigned long long)o->seed, c0.rms_rel,
                c0.frobenius, c0.normal_angle_deg, c0.inverted_faces, o->time > 0 ? 0 : o->iterations, o->time,
                bst ? bst->dt : NAN, bst ? bst->dt * lam : NAN, bst ? bst->t_final : NAN,
                bst ? bst->cmp.rms_rel : NAN, bst ? bst->cmp.frobenius : NAN, bst ? bst->cmp.normal_angle_deg : NAN,
                sum[k].slope, sum[k].slope_points, sum[k].largest_ok_dt, sum[k].ok, sum[k].failed);
    }
    if (csv_close(f, path) != 0) {
        f = NULL;
        free(sum);
        goto done;
    }
    f = NULL;

    /* error against dt, and wall time against dt (not when no run of a
     * flow succeeded: nothing to draw) */
    int drawable = 0;
    for (int k = 0; k < o->nschemes; k++)
        drawable += o->schemes[k] != MCF_TAUBIN && sum[k].ok > 0;
    if (!drawable)
        note(o, "%s: no successful run of a flow: no dt-sweep plots\n", o->name);
    for (int fig = 0; fig < 2 && drawable; fig++) {
        char title[512], blk[32], leg[160];
        int plot_first = 1;
        b.len = 0;
        char what[96];
        if (o->time > 0)
            snprintf(what, sizeof what, "after a fixed time T = %g", o->time);
        else
            snprintf(what, sizeof what, "after %d steps of dt", o->iterations);
        snprintf(title, sizeof title,
                 "%s: %s %s\n{/*0.85 %d vertices; noise %g × mean edge (seed %llu): error %.3g; λ_{max} = %.4g}",
                 o->name, fig == 0 ? "error" : "wall time", what, mcf_mesh_nvertices(target), o->rho,
                 (unsigned long long)o->seed, c0.rms_rel, lam);
        char xl[160];
        snprintf(xl, sizeof xl, o->time > 0 ? "time step dt (%s)" : "time step dt (%s; total time = iterations × dt)",
                 o->units);
        gp_axes(&b, title, xl,
                fig == 0 ? "error vs clean target: M-weighted RMS / sqrt(area)" : "wall time per run (s)", 1, 1);
        api_buf_printf(&b, "set xrange [%.9g:%.9g]\nset x2range [%.9g:%.9g]\nset logscale x2\n"
                           "set x2tics\nset x2label \"dt × λ_{max}\" offset 0,-0.4\nset tmargin 6.5\n"
                           "set format x2 \"10^{%%L}\"\n",
                       dts[0] / 1.5, dts[ndt - 1] * 1.5, dts[0] / 1.5 * lam, dts[ndt - 1] * 1.5 * lam);
        api_buf_printf(&b, "set arrow from %.9g, graph 0 to %.9g, graph 1 nohead lc rgb \"#555555\" dt 3 lw 1.5\n"
                           "set label \"2/λ_{max}\" at %.9g, graph 0.04 offset 0.5,0 textcolor rgb \"#555555\"\n",
                       2 / lam, 2 / lam, 2 / lam);
        for (int k = 0; k < o->nschemes; k++) {
            const xrun *rs = runs + first[k];
            int any = 0;
            if (o->schemes[k] == MCF_TAUBIN)
                continue;
            snprintf(blk, sizeof blk, "s%d", k);
            gp_block_begin(&b, blk);
            for (int i = 0; i < count[k]; i++)
                if (run_ok(&rs[i])) {
                    api_buf_printf(&b, "%.9g %.9g\n", rs[i].dt, fig == 0 ? rs[i].cmp.rms_rel : rs[i].wall);
                    any = 1;
                }
            gp_block_end(&b);
            if (!any)
                api_buf_printf(&b, "$%s << EOD\nNaN NaN\nEOD\n", blk);
        }
        for (int k = 0; k < o->nschemes; k++) {
            mcf_scheme s = o->schemes[k];
            const char *nm = mcf_scheme_get(s)->name;
            const xrun *rs = runs + first[k];
            if (s == MCF_TAUBIN) {
                if (count[k] == 0 || !run_ok(&rs[0]))
                    continue;
                snprintf(leg, sizeof leg, "taubin (a filter, no dt): %d passes", o->iterations);
                api_buf_printf(&b, "%s %.9g with lines ", plot_first ? "plot" : ", \\\n    ",
                               fig == 0 ? rs[0].cmp.rms_rel : rs[0].wall);
                gp_style(&b, s, 0);
                api_buf_printf(&b, " title ");
                gp_str(&b, leg);
                plot_first = 0;
                continue;
            }
            snprintf(blk, sizeof blk, "s%d", k);
            if (sum[k].ok == 0)
                snprintf(leg, sizeof leg, "%s: every run failed", nm);
            else if (fig == 0 && isfinite(sum[k].slope))
                snprintf(leg, sizeof leg, "%s (rising slope %.2f)", nm, sum[k].slope);
            else
                snprintf(leg, sizeof leg, "%s", nm);
            gp_series(&b, &plot_first, blk, "1:2", "linespoints", s, leg);
        }
        if (fig == 0) {
            api_buf_printf(&b, ", \\\n    %.9g with lines lc rgb \"#000000\" dt 3 lw 2 title \"noisy input\"",
                           c0.rms_rel);
        }
        api_buf_printf(&b, "\n");
        if (gp_render(o, fig == 0 ? "dt-sweep-error" : "dt-sweep-runtime", &b) != 0) {
            free(sum);
            goto done;
        }
    }
    free(sum);
    rc = 0;
done:
    if (f)
        fclose(f);
    api_buf_free(&b);
    free(runs);
    free(first);
    free(count);
    mcf_mesh_free(target);
    mcf_mesh_free(noisy);
    return rc;
}

/* --------------------------------------------------------------- stability */

/* Why a stability run is not acceptable ("" when it is): the flow failed
 * or left NaN, a step folded a face (turned its normal by more than 90
 * degrees: what an unstable step does, and what the flow itself refuses
 * for the explicit schemes), or the error is over the threshold. Faces
 * inverted against the clean target are not a criterion: noise folds a
 * few slivers, and a long smoothing legitimately turns faces at sharp
 * features; they are in the CSV. */
static const char *stab_reason(const xrun *r, double threshold)
{
    if (r->nonfinite)
        return "NaN";
    if (r->status != MCF_OK)
        return mcf_status_name(r->status);
    if (r->folded > 0)
        return "face folded in a step";
    if (!(r->cmp.rms_rel <= threshold))
        return "error over threshold";
    return "";
}

typedef struct {
    mcf_scheme scheme;
    double measured;        /* largest acceptable dt found (0: none) */
    double first_fail;      /* smallest unacceptable dt found (0: none) */
    char reason[64];        /* why first_fail was not acceptable */
    int censored;           /* acceptable up to the top of the range */
    int runs;
} stab_result;

/* One stability run of sr's scheme at dt, written to f with its phase. */
static int stab_run(const xopts *o, const mcf_mesh *noisy, const mcf_mesh *target, double lam, double dt,
                    const char *phase, FILE *f, xrun *r, stab_result *sr)
{
    char why[64];
    if (run_flow(o, noisy, target, sr->scheme, dt, o->iterations, 0, 0, r, NULL, NULL) != 0)
        return 1;
    sr->runs++;
    run_note(o, r);
    csv_clean(stab_reason(r, o->threshold), why, sizeof why);
    run_csv_fields(f, o, r, lam);
    fprintf(f, ",%s,%d,%s\n", phase, why[0] == '\0', why);
    return 0;
}

static int study_stability(xopts *o)
{
    mcf_mesh *target = NULL, *noisy = NULL;
    stab_result *res = NULL;
    double lam = 0;
    int rc = 1;
    mcf_compare_result c0;
    api_buf b;
    FILE *f = NULL;
    char path[4096];

    api_buf_init(&b, 16u << 20);
    if (noisy_study_mesh(o, &target, &noisy, &c0, &lam) != 0)
        goto done;
    double lo, hi;
    if (dt_range(o, lam, 0, &lo, &hi) != 0) {
        rc = EXIT_USAGE;
        goto done;
    }
    note(o, "%s: stability, %d steps, threshold rms_rel %g (noisy input %.4g), lambda_max %.6g, dt %.3g..%.3g\n",
         o->name, o->iterations, o->threshold, c0.rms_rel, lam, lo, hi);
    res = calloc((size_t)o->nschemes, sizeof *res);
    if (!res) {
        xfail(1, "out of memory");
        goto done;
    }
    if (!(f = csv_open(o, "stability-runs.csv", path, sizeof path)))
        goto done;
    fprintf(f, "%s,phase,acceptable,reason\n", run_csv_header);

    /* Per scheme: the top of the range first (an unconditionally stable
     * scheme needs one run), then doublings up from the bottom until a run
     * is not acceptable, then geometric bisection of that bracket. */
    for (int k = 0; k < o->nschemes; k++) {
        stab_result *sr = &res[k];
        xrun r;
        double good = 0, bad = 0;
        sr->scheme = o->schemes[k];
        if (stab_run(o, noisy, target, lam, hi, "top", f, &r, sr) != 0)
            goto done;
        if (stab_reason(&r, o->threshold)[0] == '\0') {
            sr->measured = hi;
            sr->censored = 1;
            continue;
        }
        bad = hi;
        snprintf(sr->reason, sizeof sr->reason, "%s", stab_reason(&r, o->threshold));
        for (double dt = lo; dt < hi; dt *= 2) {
            if (stab_run(o, noisy, target, lam, dt, "scan", f, &r, sr) != 0)
                goto done;
            if (stab_reason(&r, o->threshold)[0] != '\0') {
                bad = dt;
                snprintf(sr->reason, sizeof sr->reason, "%s", stab_reason(&r, o->threshold));
                break;
            }
            good = dt;
        }
        for (int it = 0; good > 0 && it < o->bisect; it++) {
            double mid = sqrt(good * bad);
            if (stab_run(o, noisy, target, lam, mid, "bisect", f, &r, sr) != 0)
                goto done;
            if (stab_reason(&r, o->threshold)[0] == '\0') {
                good = mid;
            } else {
                bad = mid;
                snprintf(sr->reason, sizeof sr->reason, "%s", stab_reason(&r, o->threshold));
            }
        }
        sr->measured = good;
        sr->first_fail = bad;
    }
    if (csv_close(f, path) != 0) {
        f = NULL;
        goto done;
    }
    f = NULL;

    if (!(f = csv_open(o, "stability.csv", path, sizeof path)))
        goto done;
    fprintf(f, "mesh,scheme,explicit,lambda_max,theory,theory_dt_lambda,theory_dt,measured_dt,measured_dt_lambda,"
               "censored,first_failing_dt,first_failing_dt_lambda,failure,threshold,noisy_rms_rel,noisy_inverted_faces,"
               "iterations,runs\n");
    for (int k = 0; k < o->nschemes; k++) {
        const stab_result *sr = &res[k];
        const mcf_scheme_info *si = mcf_scheme_get(sr->scheme);
        char theory[32];
        if (si->stability > 0)
            snprintf(theory, sizeof theory, "%g/lambda_max", si->stability);
        else
            snprintf(theory, sizeof theory, "unconditional");
        fprintf(f, "%s,%s,%d,%.9g,%s,%.9g,%.9g,%.9g,%.6g,%d,%.9g,%.6g,%s,%g,%.9g,%d,%d,%d\n", o->name, si->name,
                si->is_explicit, lam, theory, si->stability > 0 ? si->stability : NAN,
                si->stability > 0 ? si->stability / lam : NAN, sr->measured, sr->measured * lam, sr->censored,
                sr->first_fail > 0 ? sr->first_fail : NAN, sr->first_fail > 0 ? sr->first_fail * lam : NAN,
                sr->censored ? "none" : sr->reason, o->threshold, c0.rms_rel, c0.inverted_faces, o->iterations,
                sr->runs);
    }
    if (csv_close(f, path) != 0) {
        f = NULL;
        goto done;
    }
    f = NULL;

    /* bars: measured dt * lambda_max next to the theory */
    {
        char title[512];
        /* up to the top of the range when a scheme is unconditional (its
         * theory bar reaches it), else just above the tallest bar */
        double ylo = lo * lam / 2, top = 0;
        int uncond = 0;
        for (int k = 0; k < o->nschemes; k++) {
            double th = mcf_scheme_get(res[k].scheme)->stability;
            uncond |= !(th > 0);
            top = fmax(top, fmax(res[k].measured * lam, th > 0 ? th : 0));
        }
        double yhi = uncond ? hi * lam * 4 : top * 8;
        snprintf(title, sizeof title,
                 "%s: largest acceptable dt in %d steps, and what failed above it\n{/*0.85 %d vertices, noise %g × mean "
                 "edge; acceptable: no failure, NaN or face folded in a step, RMS error ≤ %g; small print: "
                 "what failed next}",
                 o->name, o->iterations, mcf_mesh_nvertices(target), o->rho, o->threshold);
        gp_axes(&b, title, "", "dt × λ_{max}  (dimensionless)", 0, 1);
        api_buf_printf(&b, "set xrange [-0.7:%d.7]\nset yrange [%.9g:%.9g]\nset xtics rotate by -30 (", o->nschemes - 1,
                       ylo, yhi);
        for (int k = 0; k < o->nschemes; k++)
            api_buf_printf(&b, "%s\"%s\" %d", k ? ", " : "", mcf_scheme_get(o->schemes[k])->name, k);
        api_buf_printf(&b, ")\nset grid noxtics nomxtics\nset key outside below center horizontal\n"
                           "set style fill solid 0.85 border rgb \"#333333\"\n"
                           "set style textbox opaque noborder margins 1,1\n");
        gp_block_begin(&b, "bars");
        for (int k = 0; k < o->nschemes; k++) {
            const mcf_scheme_info *si = mcf_scheme_get(res[k].scheme);
            double m = res[k].measured * lam;
            double th = si->stability > 0 ? si->stability : yhi;
            /* short: a label must fit over its bar */
            const char *why = res[k].censored ? "none" : res[k].reason;
            if (!strcmp(why, "ENUMERIC"))
                why = "fold (flow)";
            else if (!strcmp(why, "ENOCONV"))
                why = "no conv.";
            else if (!strcmp(why, "face folded in a step"))
                why = "fold";
            else if (!strcmp(why, "error over threshold"))
                why = "error";
            api_buf_printf(&b, "%d %.9g %.9g \"%s%.3g\" %d \"%s\"\n", k, m > 0 ? m : ylo, th,
                           res[k].censored ? "≥" : "", m, si->stability > 0, m > 0 ? why : "none ok");
        }
        gp_block_end(&b);
        api_buf_printf(&b,
                       "plot $bars using 1:2:($1-0.38):($1):(%.9g):2 with boxxyerror lc rgb \"#3b75af\" "
                       "title \"measured\", \\\n"
                       "    $bars using ($1+0.19):($5 > 0 ? $3 : NaN):($1):($1+0.38):(%.9g):3 with boxxyerror "
                       "fs solid 0.5 lc rgb \"#999999\" title \"theory (explicit bound)\"",
                       ylo, ylo);
        if (uncond)
            api_buf_printf(&b, ", \\\n    $bars using ($1+0.19):($5 > 0 ? NaN : $3):($1):($1+0.38):(%.9g):3 with "
                               "boxxyerror fs pattern 4 lc rgb \"#999999\" title \"theory: unconditional\"",
                           ylo);
        /* the labels last, over the bars; on a white box so the hatching
         * does not cross them */
        api_buf_printf(&b, ", \\\n    $bars using ($1-0.19):2:4 with labels offset 0,0.8 font \",11\" boxed notitle"
                           ", \\\n    $bars using ($1-0.19):2:6 with labels offset 0,2.1 font \",9\" tc rgb \"#444444\" "
                           "boxed notitle\n");
        if (gp_render(o, "stability", &b) != 0)
            goto done;
    }
    rc = 0;
done:
    if (f)
        fclose(f);
    api_buf_free(&b);
    free(res);
    mcf_mesh_free(target);
    mcf_mesh_free(noisy);
    return rc;
}

/* ------------------------------------------------------------------- order */

/* Whether scheme s integrates MCF itself. cmcf (L from the input) and
 * linear (L and M from the input) integrate other flows: their error is
 * measured against their own fine run. */
static int same_flow(mcf_scheme s)
{
    return s != MCF_CMCF && s != MCF_LINEAR;
}

static int study_order(xopts *o)
{
    mcf_mesh *start = NULL, *ref = NULL, **sol = NULL;
    mcf_mesh *own_ref = NULL; /* cmcf, linear: their own fine run */
    mcf_error err = {MCF_OK, ""};
    xrun *runs = NULL;
    double *e = NULL, lam = 0;
    int rc = 1, n = o->nsteps, nmax = o->steps[o->nsteps - 1];
    api_buf b;
    FILE *f = NULL;
    char path[4096];
    double *slope = NULL;

    api_buf_init(&b, 16u << 20);
    if (study_mesh(o, &start) != 0)
        goto done;
    if (o->presmooth > 0) {
        /* smooth data: the highest modes of a scan would reduce the order */
        xrun pr;
        mcf_mesh *sm = NULL;
        if (run_flow(o, start, NULL, MCF_DESBRUN2, o->presmooth / 10, 10, 0, 0, &pr, &sm, NULL) != 0)
            goto done;
        if (!run_ok(&pr)) {
            mcf_mesh_free(sm);
            xfail(1, "pre-smoothing failed: %s", pr.msg);
            goto done;
        }
        mcf_mesh_free(start);
        start = sm;
    }
    if (mcf_lambda_max(start, MCF_LAPLACIAN_COTAN, MCF_MASS_BARYCENTRIC, &lam, &err) != MCF_OK) {
        xfail(1, "%s", err.msg);
        goto done;
    }
    int nref = o->ref_factor * nmax;
    note(o, "%s: order at T = %g, %d..%d steps, reference %s at %d steps, lambda_max %.6g (T lambda %.3g)\n",
         o->name, o->time, o->steps[0], nmax, mcf_scheme_get(o->ref_scheme)->name, nref, lam, o->time * lam);
    {
        xrun rr;
        if (run_flow(o, start, NULL, o->ref_scheme, o->time / nref, nref, 0, 0, &rr, &ref, NULL) != 0)
            goto done;
        note(o, "reference: %s, %.2f s\n", mcf_status_name(rr.status), rr.wall);
        if (!run_ok(&rr)) {
            xfail(1, "the reference run failed: %s", rr.msg);
            goto done;
        }
    }
    runs = calloc((size_t)o->nschemes * n, sizeof *runs);
    e = calloc((size_t)o->nschemes * n, sizeof *e);
    sol = calloc((size_t)n, sizeof *sol);
    slope = calloc((size_t)o->nschemes, sizeof *slope);
    if (!runs || !e || !sol || !slope) {
        xfail(1, "out of memory");
        goto done;
    }
    if (!(f = csv_open(o, "order.csv", path, sizeof path)))
        goto done;
    fprintf(f, "mesh,scheme,explicit,T,steps,dt,dt_lambda,status,error,local_order,reference_free_order,wall_s,"
               "solves,factorizations,message\n");
    for (int k = 0; k < o->nschemes; k++) {
        mcf_scheme s = o->schemes[k];
        xrun *rs = runs + (size_t)k * n;
        double *ek = e + (size_t)k * n, dtv[MAX_LIST];
        const mcf_mesh *rk = ref;
        if (!same_flow(s)) {
            /* a different flow: its limit is its own, not MCF's */
            xrun rr;
            mcf_mesh_free(own_ref);
            own_ref = NULL;
            if (run_flow(o, start, NULL, s, o->time / nref, nref, 0, 0, &rr, &own_ref, NULL) != 0)
                goto done;
            if (!run_ok(&rr)) {
                xfail(1, "the reference run of %s failed: %s", mcf_scheme_get(s)->name, rr.msg);
                goto done;
            }
            rk = own_ref;
        }
        for (int i = 0; i < n; i++) {
            mcf_compare_result c;
            if (run_flow(o, start, NULL, s, o->time / o->steps[i], o->steps[i], 0, 0, &rs[i], &sol[i], NULL) != 0)
                goto done;
            ek[i] = NAN;
            if (run_ok(&rs[i])) {
                if (mcf_compare(sol[i], rk, &c, &err) != MCF_OK) {
                    xfail(1, "compare: %s", err.msg);
                    goto done;
                }
                ek[i] = c.rms_rel;
            }
            dtv[i] = o->time / o->steps[i];
            note(o, "%s %-10s steps %-6d error %-11.4g %s %.2f s\n", o->name, mcf_scheme_get(s)->name, o->steps[i],
                 ek[i], mcf_status_name(rs[i].status), rs[i].wall);
        }
        int used;
        slope[k] = fit_loglog(dtv, ek, n, &used);
        for (int i = 0; i < n; i++) {
            char msg[MCF_ERRMSG_SIZE];
            double local = NAN, free_p = NAN;
            if (i > 0 && isfinite(ek[i]) && isfinite(ek[i - 1]) && ek[i] > 0)
                local = log(ek[i - 1] / ek[i]) / log(dtv[i - 1] / dtv[i]);
            /* reference-free: log2 |X_dt - X_dt/2| / |X_dt/2 - X_dt/4| */
            if (i >= 2 && o->steps[i] == 2 * o->steps[i - 1] && o->steps[i - 1] == 2 * o->steps[i - 2] &&
                run_ok(&rs[i]) && run_ok(&rs[i - 1]) && run_ok(&rs[i - 2])) {
                mcf_compare_result c1, c2;
                if (mcf_compare(sol[i - 2], sol[i - 1], &c1, NULL) == MCF_OK &&
                    mcf_compare(sol[i - 1], sol[i], &c2, NULL) == MCF_OK && c2.rms_rel > 0)
                    free_p = log2(c1.rms_rel / c2.rms_rel);
            }
            csv_clean(rs[i].msg, msg, sizeof msg);
            fprintf(f, "%s,%s,%d,%.9g,%d,%.9g,%.6g,%s,%.9g,%.4f,%.4f,%.6f,%d,%d,%s\n", o->name,
                    mcf_scheme_get(s)->name, mcf_scheme_get(s)->is_explicit, o->time, o->steps[i], dtv[i],
                    dtv[i] * lam, mcf_status_name(rs[i].status), ek[i], local, free_p, rs[i].wall, rs[i].solves,
                    rs[i].factorizations, msg);
        }
        for (int i = 0; i < n; i++) {
            mcf_mesh_free(sol[i]);
            sol[i] = NULL;
        }
        note(o, "%s %-10s fitted slope %.3f over %d points\n", o->name, mcf_scheme_get(s)->name, slope[k], used);
    }
    if (csv_close(f, path) != 0) {
        f = NULL;
        goto done;
    }
    f = NULL;
    if (!(f = csv_open(o, "order-summary.csv", path, sizeof path)))
        goto done;
    fprintf(f, "mesh,scheme,explicit,expected_order,T,presmooth,lambda_max,steps_min,steps_max,reference,"
               "reference_steps,fitted_slope,points,last_local_order\n");
    for (int k = 0; k < o->nschemes; k++) {
        const mcf_scheme_info *si = mcf_scheme_get(o->schemes[k]);
        const double *ek = e + (size_t)k * n;
        int pts = 0;
        for (int i = 0; i < n; i++)
            pts += isfinite(ek[i]) && ek[i] > 0;
        double last = n >= 2 && isfinite(ek[n - 1]) && isfinite(ek[n - 2]) && ek[n - 1] > 0
                          ? log(ek[n - 2] / ek[n - 1]) / log((double)o->steps[n - 1] / o->steps[n - 2])
                          : NAN;
        fprintf(f, "%s,%s,%d,%d,%.9g,%.9g,%.9g,%d,%d,%s,%d,%.4f,%d,%.4f\n", o->name, si->name, si->is_explicit,
                si->order, o->time, o->presmooth, lam, o->steps[0], nmax,
                same_flow(o->schemes[k]) ? mcf_scheme_get(o->ref_scheme)->name : si->name, nref,
                slope[k], pts, last);
    }
    if (csv_close(f, path) != 0) {
        f = NULL;
        goto done;
    }
    f = NULL;

    {
        char title[512], blk[32], leg[160];
        int pf = 1;
        char pre[64] = "";
        if (o->presmooth > 0)
            snprintf(pre, sizeof pre, ", pre-smoothed to t = %g", o->presmooth);
        snprintf(title, sizeof title,
                 "%s: error at a fixed time T = %g against a fine reference\n{/*0.85 %d vertices%s; reference: %s with "
                 "%d steps (cmcf, linear: their own); T × λ_{max} = %.3g}",
                 o->name, o->time, mcf_mesh_nvertices(start), pre, mcf_scheme_get(o->ref_scheme)->name, nref,
                 o->time * lam);
        gp_axes(&b, title, "time step dt = T / steps", "error: M-weighted RMS / sqrt(area)", 1, 1);
        double d0 = o->time / nmax, d1 = o->time / o->steps[0];
        api_buf_printf(&b, "set xrange [%.9g:%.9g]\nset xtics (", d0 / 1.5, d1 * 1.5);
        for (int i = 0; i < n; i++) {
            char num[32], *ex;
            snprintf(num, sizeof num, "%.2e", o->time / o->steps[i]);
            ex = strchr(num, 'e');
            *ex = '\0';
            api_buf_printf(&b, "%s\"%s·10^{%d}\\n%d steps\" %.9g", i ? ", " : "", num, atoi(ex + 1), o->steps[i],
                           o->time / o->steps[i]);
        }
        api_buf_printf(&b, ")\nset bmargin 6\nset xlabel offset 0,-1.2\n");
        for (int k = 0; k < o->nschemes; k++) {
            snprintf(blk, sizeof blk, "o%d", k);
            gp_block_begin(&b, blk);
            int any = 0;
            for (int i = 0; i < n; i++)
                if (isfinite(e[(size_t)k * n + i]) && e[(size_t)k * n + i] > 0) {
                    api_buf_printf(&b, "%.9g %.9g\n", o->time / o->steps[i], e[(size_t)k * n + i]);
                    any = 1;
                }
            if (!any)
                api_buf_printf(&b, "NaN NaN\n");
            gp_block_end(&b);
        }
        for (int k = 0; k < o->nschemes; k++) {
            const char *nm = mcf_scheme_get(o->schemes[k])->name;
            snprintf(blk, sizeof blk, "o%d", k);
            if (isfinite(slope[k]))
                snprintf(leg, sizeof leg, "%s (slope %.2f)", nm, slope[k]);
            else
                snprintf(leg, sizeof leg, "%s: unstable at every dt", nm);
            gp_series(&b, &pf, blk, "1:2", "linespoints", o->schemes[k], leg);
        }
        /* guides through the smallest plotted error at the finest dt */
        double emin = INFINITY;
        for (int k = 0; k < o->nschemes * n; k++)
            if (isfinite(e[k]) && e[k] > 0 && e[k] < emin)
                emin = e[k];
        if (isfinite(emin)) {
            api_buf_printf(&b, ", \\\n    (x >= %.9g && x <= %.9g ? %.9g*(x/%.9g) : NaN) with lines lc rgb \"#444444\" "
                               "dt 3 lw 1.5 title \"slope 1\"",
                           d0, d1, emin / 3, d0);
            api_buf_printf(&b, ", \\\n    (x >= %.9g && x <= %.9g ? %.9g*(x/%.9g)**2 : NaN) with lines lc rgb \"#444444\" "
                               "dt 4 lw 1.5 title \"slope 2\"",
                           d0, d1, emin / 3, d0);
        }
        api_buf_printf(&b, "\n");
        if (gp_render(o, "order", &b) != 0)
            goto done;
    }
    rc = 0;
done:
    if (f)
        fclose(f);
    if (sol)
        for (int i = 0; i < n; i++)
            mcf_mesh_free(sol[i]);
    free(sol);
    free(runs);
    free(e);
    free(slope);
    api_buf_free(&b);
    mcf_mesh_free(start);
    mcf_mesh_free(ref);
    mcf_mesh_free(own_ref);
    return rc;
}

/* ------------------------------------------------------------------ sphere */

static double r_of_volume(double v)
{
    return cbrt(3.0 * v / (4.0 * M_PI));
}

static int study_sphere(xopts *o)
{
    mcf_mesh *start = NULL;
    mcf_error err = {MCF_OK, ""};
    mcf_flow_stats *st = NULL;
    xrun *runs = NULL;
    double lam = 0;
    int rc = 1;
    api_buf b;
    FILE *f = NULL;
    char path[4096];

    api_buf_init(&b, 32u << 20);
    if (study_mesh(o, &start) != 0)
        goto done;
    if (mcf_lambda_max(start, MCF_LAPLACIAN_COTAN, MCF_MASS_BARYCENTRIC, &lam, &err) != MCF_OK) {
        xfail(1, "%s", err.msg);
        goto done;
    }
    double V0 = mcf_mesh_volume(start), R0 = r_of_volume(V0), T = o->time;
    double RT2 = R0 * R0 - 4 * T;
    if (!(RT2 > 0)) {
        xfail(EXIT_USAGE, "sphere: T = %g is past the extinction of the discrete sphere (R0 %.6g)", T, R0);
        rc = EXIT_USAGE;
        goto done;
    }
    /* lambda grows like 1/R^2: explicit schemes take half their bound at
     * the final radius */
    double lam_end = lam * R0 * R0 / RT2;
    note(o, "%s: %d vertices, R0 (volume) %.6f, T %g, R(T) exact %.6f, lambda_max %.6g -> %.6g at T\n", o->name,
         mcf_mesh_nvertices(start), R0, T, sqrt(RT2), lam, lam_end);
    runs = calloc((size_t)o->nschemes, sizeof *runs);
    st = calloc((size_t)o->nschemes, sizeof *st);
    if (!runs || !st) {
        xfail(1, "out of memory");
        goto done;
    }
    for (int k = 0; k < o->nschemes; k++) {
        const mcf_scheme_info *si = mcf_scheme_get(o->schemes[k]);
        int steps = o->steps[0];
        if (si->is_explicit)
            steps = (int)ceil(T / (0.5 * si->stability / lam_end));
        if (run_flow(o, start, NULL, o->schemes[k], T / steps, steps, 0, 1, &runs[k], NULL, &st[k]) != 0)
            goto done;
        note(o, "%s %-10s steps %-6d R(T) %.6f %s %.2f s\n", o->name, si->name, runs[k].steps,
             st[k].nlog > 0 ? r_of_volume(st[k].log[st[k].nlog - 1].volume) : NAN, mcf_status_name(runs[k].status),
             runs[k].wall);
    }

    if (!(f = csv_open(o, "sphere.csv", path, sizeof path)))
        goto done;
    fprintf(f, "mesh,scheme,step,t,area,volume,r_volume,r_area,r_exact,v_exact,r_rel_error,v_rel_error\n");
    for (int k = 0; k < o->nschemes; k++) {
        const mcf_flow_stats *s = &st[k];
        int stride = s->nlog > SERIES_POINTS ? (s->nlog + SERIES_POINTS - 1) / SERIES_POINTS : 1;
        fprintf(f, "%s,%s,0,0,%.12g,%.12g,%.12g,%.12g,%.12g,%.12g,0,0\n", o->name,
                mcf_scheme_get(o->schemes[k])->name, s->area0, V0, R0, sqrt(s->area0 / (4 * M_PI)), R0, V0);
        for (int i = 0; i < s->nlog; i++) {
            if ((i + 1) % stride != 0 && i != s->nlog - 1)
                continue;
            const mcf_step_log *lg = &s->log[i];
            double re = sqrt(fmax(R0 * R0 - 4 * lg->t, 0)), ve = 4.0 / 3.0 * M_PI * re * re * re;
            double rv = r_of_volume(lg->volume);
            fprintf(f, "%s,%s,%d,%.12g,%.12g,%.12g,%.12g,%.12g,%.12g,%.12g,%.6g,%.6g\n", o->name,
                    mcf_scheme_get(o->schemes[k])->name, i + 1, lg->t, lg->area, lg->volume, rv,
                    sqrt(lg->area / (4 * M_PI)), re, ve, fabs(rv - re) / re, fabs(lg->volume - ve) / ve);
        }
    }
    if (csv_close(f, path) != 0) {
        f = NULL;
        goto done;
    }
    f = NULL;
    if (!(f = csv_open(o, "sphere-summary.csv", path, sizeof path)))
        goto done;
    fprintf(f, "mesh,scheme,explicit,status,steps,dt,dt_lambda0,T,r0,r_final,r_exact,r_rel_error,v_final,v_exact,"
               "v_rel_error,max_r_rel_error,wall_s,solves,factorizations\n");
    for (int k = 0; k < o->nschemes; k++) {
        const mcf_flow_stats *s = &st[k];
        const mcf_scheme_info *si = mcf_scheme_get(o->schemes[k]);
        double rf = NAN, vf = NAN, re = NAN, ve = NAN, maxe = 0;
        for (int i = 0; i < s->nlog; i++) {
            double r = r_of_volume(s->log[i].volume), x = sqrt(fmax(R0 * R0 - 4 * s->log[i].t, 0));
            maxe = fmax(maxe, fabs(r - x) / x);
        }
        if (s->nlog > 0) {
            vf = s->log[s->nlog - 1].volume;
            rf = r_of_volume(vf);
            re = sqrt(fmax(R0 * R0 - 4 * s->log[s->nlog - 1].t, 0));
            ve = 4.0 / 3.0 * M_PI * re * re * re;
        }
        fprintf(f, "%s,%s,%d,%s,%d,%.9g,%.6g,%.9g,%.12g,%.12g,%.12g,%.6g,%.12g,%.12g,%.6g,%.6g,%.6f,%d,%d\n", o->name,
                si->name, si->is_explicit, mcf_status_name(runs[k].status), runs[k].steps, runs[k].dt,
                runs[k].dt * lam, T, R0, rf, re, fabs(rf - re) / re, vf, ve, fabs(vf - ve) / ve, maxe, runs[k].wall,
                runs[k].solves, runs[k].factorizations);
    }
    if (csv_close(f, path) != 0) {
        f = NULL;
        goto done;
    }
    f = NULL;

    for (int fig = 0; fig < 3; fig++) {
        static const char *const suffix[3] = {"sphere-radius", "sphere-volume", "sphere-error"};
        char title[512], blk[32];
        int pf = 1;
        b.len = 0;
        static const char *const what[3] = {"volume-equivalent radius R = (3V/4π)^{1/3} against sqrt(R_0^2 - 4t)",
                                            "enclosed volume V against 4/3 π (R_0^2 - 4t)^{3/2}",
                                            "relative radius error |R - sqrt(R_0^2 - 4t)| / sqrt(R_0^2 - 4t)"};
        snprintf(title, sizeof title, "%s: %s\n{/*0.85 %d vertices, radius %g; R_0 = %.5f, its volume-equivalent radius}",
                 o->name, what[fig], mcf_mesh_nvertices(start), o->radius, R0);
        gp_axes(&b, title, "time t (same units as the radius squared)",
                fig == 0 ? "volume-equivalent radius R" : fig == 1 ? "enclosed volume V" : "relative radius error",
                0, fig == 2);
        api_buf_printf(&b, "set xrange [0:%.9g]\n", T * 1.02);
        if (fig == 2)
            api_buf_printf(&b, "set xrange [%.9g:%.9g]\n", T / 50, T * 1.02);
        for (int k = 0; k < o->nschemes; k++) {
            const mcf_flow_stats *s = &st[k];
            int stride = s->nlog > SERIES_POINTS ? (s->nlog + SERIES_POINTS - 1) / SERIES_POINTS : 1;
            snprintf(blk, sizeof blk, "r%d", k);
            gp_block_begin(&b, blk);
            if (fig < 2)
                api_buf_printf(&b, "0 %.12g\n", fig == 0 ? R0 : V0);
            for (int i = 0; i < s->nlog; i++) {
                if ((i + 1) % stride != 0 && i != s->nlog - 1)
                    continue;
                double t = s->log[i].t, r = r_of_volume(s->log[i].volume), x = sqrt(fmax(R0 * R0 - 4 * t, 0));
                double y = fig == 0 ? r : fig == 1 ? s->log[i].volume : fabs(r - x) / x;
                api_buf_printf(&b, "%.12g %.12g\n", t, y);
            }
            if (s->nlog == 0)
                api_buf_printf(&b, "NaN NaN\n");
            gp_block_end(&b);
        }
        for (int k = 0; k < o->nschemes; k++) {
            char leg[128];
            const mcf_scheme_info *si = mcf_scheme_get(o->schemes[k]);
            snprintf(blk, sizeof blk, "r%d", k);
            snprintf(leg, sizeof leg, "%s, %d steps%s", si->name, runs[k].steps,
                     runs[k].status == MCF_OK ? "" : " (failed)");
            gp_series(&b, &pf, blk, "1:2", "lines", o->schemes[k], leg);
        }
        if (fig == 0)
            api_buf_printf(&b, ", \\\n    sqrt(%.12g - 4*x) with lines lc rgb \"#000000\" dt 3 lw 2.5 title "
                               "\"exact sqrt(R_0^2 - 4t)\"",
                           R0 * R0);
        else if (fig == 1)
            api_buf_printf(&b, ", \\\n    4.0/3*pi*(%.12g - 4*x)**1.5 with lines lc rgb \"#000000\" dt 3 lw 2.5 "
                               "title \"exact\"",
                           R0 * R0);
        api_buf_printf(&b, "\n");
        if (gp_render(o, suffix[fig], &b) != 0)
            goto done;
    }
    rc = 0;
done:
    if (f)
        fclose(f);
    if (st)
        for (int k = 0; k < o->nschemes; k++)
            mcf_flow_stats_free(&st[k]);
    free(st);
    free(runs);
    api_buf_free(&b);
    mcf_mesh_free(start);
    return rc;
}

/* ------------------------------------------------------------------- entry */

int mcf_experiment_main(int argc, char **argv)
{
    xopts o;
    int rc;

    if (argc < 3)
        return xfail(EXIT_USAGE, "missing study: dt-sweep, stability, order or sphere (try mcf --help)");
    if ((rc = parse_opts(argc, argv, &o)) != 0)
        return rc;
    if ((rc = mkdir_p(o.out)) != 0)
        return rc;
    switch (o.study) {
    case ST_DTSWEEP:
        return study_dt_sweep(&o);
    case ST_STABILITY:
        return study_stability(&o);
    case ST_ORDER:
        return study_order(&o);
    case ST_SPHERE:
        return study_sphere(&o);
    }
    return 1;
}
