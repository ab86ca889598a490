/* SPDX-License-Identifier: MIT */
/*
 * study.c - what the flow studies of mcflab share (study.h): options, one
 * run of the flow watched step by step, CSV rows, the study meshes and the
 * figures' per-scheme styles.
 */
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

#include "study.h"

const char study_usage[] =
    "  mcflab STUDY --out DIR [--mesh FILE | --sphere LEVEL [--radius R]] [--name NAME]\n"
    "               [--schemes all|flows|explicit|implicit|S1,S2,...] [--noise RHO] [--seed K]\n"
    "               [--dt-min D] [--dt-max D] [--per-decade N] [--iterations N | --time T]\n"
    "               [--threshold E] [--bisect N] [--boundary fixed|free] [--steps N1,N2,...]\n"
    "               [--ref-scheme S] [--ref-factor F] [--presmooth T0] [--picard-maxit N]\n"
    "               [--max-steps N] [--no-plots] [--keep-scripts] [--quiet]\n"
    "                       STUDY: dt-sweep, stability, order or sphere. CSV files and\n"
    "                       gnuplot PNG/SVG plots in DIR; D may be written 0.5/lambda\n"
    "                       (a multiple of 1/lambda_max). See lab/README.md.\n";

/* ----------------------------------------------------------------- options */

void note(const xopts *o, const char *fmt, ...)
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
        return lab_fail(LAB_EXIT_USAGE, "--%s: not a number: '%s'", flag, s);
    if (per_lambda) {
        *per_lambda = 0;
        if (strcmp(end, "/lambda") == 0) {
            *per_lambda = 1;
            end += strlen("/lambda");
        }
    }
    if (*end != '\0' || !isfinite(x))
        return lab_fail(LAB_EXIT_USAGE, "--%s: not a finite number: '%s'", flag, s);
    *v = x;
    return 0;
}

static int parse_int(const char *flag, const char *s, long lo, long hi, int *v)
{
    char *end;
    errno = 0;
    long x = strtol(s, &end, 10);
    if (end == s || *end != '\0' || errno != 0 || x < lo || x > hi)
        return lab_fail(LAB_EXIT_USAGE, "--%s: expected an integer in [%ld, %ld], got '%s'", flag, lo, hi, s);
    *v = (int)x;
    return 0;
}

int is_filter(mcf_scheme s)
{
    return mcf_scheme_get(s)->order == 0;
}

/* "all" (the flows and taubin, the baseline filter), "flows", "explicit"
 * or "implicit" (flows), or a comma list of any schemes. */
static int parse_schemes(const char *s, xopts *o)
{
    o->nschemes = 0;
    if (!strcmp(s, "all") || !strcmp(s, "flows") || !strcmp(s, "explicit") || !strcmp(s, "implicit")) {
        for (int k = 0; k < MCF_NSCHEMES; k++) {
            const mcf_scheme_info *si = mcf_scheme_get((mcf_scheme)k);
            if (is_filter((mcf_scheme)k) && !(!strcmp(s, "all") && k == MCF_TAUBIN))
                continue;
            if (!strcmp(s, "explicit") && !si->is_explicit)
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
            return lab_fail(LAB_EXIT_USAGE, "--schemes: bad list '%s'", s);
        memcpy(name, p, n);
        name[n] = '\0';
        if (mcf_scheme_from_name(name, &sc) != MCF_OK)
            return lab_fail(LAB_EXIT_USAGE, "--schemes: unknown scheme '%s' (see mcf schemes)", name);
        for (int k = 0; k < o->nschemes; k++)
            if (o->schemes[k] == sc)
                return lab_fail(LAB_EXIT_USAGE, "--schemes: '%s' given twice", name);
        o->schemes[o->nschemes++] = sc;
        p += n;
        if (*p == ',' && *++p == '\0')
            return lab_fail(LAB_EXIT_USAGE, "--schemes: bad list '%s'", s);
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
            return lab_fail(LAB_EXIT_USAGE, "--steps: expected up to %d increasing integers >= 1 separated by commas, got '%s'",
                            MAX_LIST, s);
        o->steps[o->nsteps++] = (int)v;
        p = *end == ',' ? end + 1 : end;
    }
    if (o->nsteps == 0)
        return lab_fail(LAB_EXIT_USAGE, "--steps: empty list");
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

int study_parse(int argc, char **argv, xopts *o)
{
    int rc, given_dt_min = 0, given_dt_max = 0, given_time = 0, given_steps = 0, given_schemes = 0;
    int given_threshold = 0, given_iterations = 0, given_name = 0;

    memset(o, 0, sizeof *o);
    o->study_name = argv[1];
    if (!strcmp(argv[1], "dt-sweep"))
        o->study = ST_DTSWEEP;
    else if (!strcmp(argv[1], "stability"))
        o->study = ST_STABILITY;
    else if (!strcmp(argv[1], "order"))
        o->study = ST_ORDER;
    else if (!strcmp(argv[1], "sphere"))
        o->study = ST_SPHERE;
    else
        return lab_fail(LAB_EXIT_USAGE, "unknown study '%s': dt-sweep, stability, order or sphere", argv[1]);
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
    o->plot.enabled = 1;

    for (int i = 2; i < argc; i++) {
        const char *a = argv[i];
        if (strncmp(a, "--", 2) != 0)
            return lab_fail(LAB_EXIT_USAGE, "unexpected argument '%s'", a);
        const char *f = a + 2;
        if (!strcmp(f, "no-plots")) { o->plot.enabled = 0; continue; }
        if (!strcmp(f, "keep-scripts")) { o->plot.keep_scripts = 1; continue; }
        if (!strcmp(f, "quiet")) { o->quiet = 1; continue; }
        if (i + 1 >= argc)
            return lab_fail(LAB_EXIT_USAGE, "%s needs a value", a);
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
                rc = lab_fail(LAB_EXIT_USAGE, "--radius: must be > 0");
        } else if (!strcmp(f, "name")) {
            if (!*v || strlen(v) >= sizeof o->name || strpbrk(v, "/\"'\\"))
                return lab_fail(LAB_EXIT_USAGE, "--name: 1 to %zu characters, no slash or quote", sizeof o->name - 1);
            snprintf(o->name, sizeof o->name, "%s", v);
            given_name = 1;
        } else if (!strcmp(f, "schemes")) {
            rc = parse_schemes(v, o);
            given_schemes = 1;
        } else if (!strcmp(f, "noise")) {
            if (!(rc = parse_double(f, v, &o->rho, NULL)) && !(o->rho >= 0 && o->rho <= 10))
                rc = lab_fail(LAB_EXIT_USAGE, "--noise: must be in [0, 10]");
        } else if (!strcmp(f, "seed")) {
            char *end;
            errno = 0;
            unsigned long long s = strtoull(v, &end, 10);
            if (end == v || *end || errno || v[0] == '-')
                rc = lab_fail(LAB_EXIT_USAGE, "--seed: expected a non-negative integer, got '%s'", v);
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
                rc = lab_fail(LAB_EXIT_USAGE, "--time: must be > 0");
            given_time = 1;
        } else if (!strcmp(f, "threshold")) {
            if (!(rc = parse_double(f, v, &o->threshold, NULL)) && !(o->threshold > 0))
                rc = lab_fail(LAB_EXIT_USAGE, "--threshold: must be > 0");
            given_threshold = 1;
        } else if (!strcmp(f, "bisect"))
            rc = parse_int(f, v, 0, 30, &o->bisect);
        else if (!strcmp(f, "boundary")) {
            if (!strcmp(v, "fixed"))
                o->boundary = MCF_BOUNDARY_FIXED;
            else if (!strcmp(v, "free"))
                o->boundary = MCF_BOUNDARY_FREE;
            else
                rc = lab_fail(LAB_EXIT_USAGE, "--boundary: fixed or free, got '%s'", v);
        } else if (!strcmp(f, "steps")) {
            rc = parse_steps(v, o);
            given_steps = 1;
        } else if (!strcmp(f, "ref-scheme")) {
            if (mcf_scheme_from_name(v, &o->ref_scheme) != MCF_OK || is_filter(o->ref_scheme))
                rc = lab_fail(LAB_EXIT_USAGE, "--ref-scheme: unknown flow scheme '%s'", v);
        } else if (!strcmp(f, "ref-factor"))
            rc = parse_int(f, v, 2, 1024, &o->ref_factor);
        else if (!strcmp(f, "presmooth")) {
            if (!(rc = parse_double(f, v, &o->presmooth, NULL)) && !(o->presmooth >= 0))
                rc = lab_fail(LAB_EXIT_USAGE, "--presmooth: must be >= 0");
        } else if (!strcmp(f, "picard-maxit"))
            rc = parse_int(f, v, 1, 100000, &o->picard_maxit);
        else if (!strcmp(f, "max-steps"))
            rc = parse_int(f, v, 1, 100000000, &o->max_steps);
        else
            return lab_fail(LAB_EXIT_USAGE, "unknown flag '%s' (try mcflab --help)", a);
        if (rc)
            return rc;
    }
    if (!o->out)
        return lab_fail(LAB_EXIT_USAGE, "--out DIR is required");
    o->plot.dir = o->out;
    o->plot.quiet = o->quiet;
    if (o->mesh_path && o->level >= 0)
        return lab_fail(LAB_EXIT_USAGE, "--mesh and --sphere exclude each other");
    if (o->study == ST_SPHERE && o->mesh_path)
        return lab_fail(LAB_EXIT_USAGE, "sphere: the study runs on an icosphere (--sphere LEVEL), not --mesh");
    if (!o->mesh_path && o->level < 0)
        o->level = o->study == ST_SPHERE ? 4 : 3;
    if (given_time && given_iterations && o->study == ST_DTSWEEP)
        return lab_fail(LAB_EXIT_USAGE, "--iterations and --time exclude each other");
    o->units = o->mesh_path ? "unit-area units" : "units of the radius squared";
    if (!given_name) {
        if (o->mesh_path)
            base_name(o->mesh_path, o->name, sizeof o->name);
        else
            snprintf(o->name, sizeof o->name, "icosphere%d", o->level);
    }
    if (!given_schemes) {
        /* a filter has no dt, no stability limit, no order */
        parse_schemes(o->study == ST_DTSWEEP ? "all" : "flows", o);
    }
    if (o->study != ST_DTSWEEP)
        for (int k = 0; k < o->nschemes; k++)
            if (is_filter(o->schemes[k]))
                return lab_fail(LAB_EXIT_USAGE, "%s: %s is a filter without a time step; leave it out", o->study_name,
                                mcf_scheme_get(o->schemes[k])->name);
    if (!given_dt_min) {
        o->dt_min = o->study == ST_STABILITY ? 0.1 : 0.05;
        o->dt_min_lam = 1;
    }
    if (!given_dt_max) {
        o->dt_max = o->study == ST_STABILITY ? 1e4 : 1e3;
        o->dt_max_lam = 1;
    }
    if (!(o->dt_min > 0) || !(o->dt_max > 0))
        return lab_fail(LAB_EXIT_USAGE, "--dt-min and --dt-max must be > 0");
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
            return lab_fail(LAB_EXIT_USAGE, "sphere: --time must be below the extinction time R0^2/4 = %g",
                            0.25 * o->radius * o->radius);
        if (!given_steps) {
            o->steps[0] = 100;
            o->nsteps = 1;
        } else if (o->nsteps != 1)
            return lab_fail(LAB_EXIT_USAGE, "sphere: --steps takes one count (implicit schemes' steps)");
    }
    snprintf(o->plot_header, sizeof o->plot_header, "%s: mcflab %s", o->name, o->study_name);
    o->plot.header = o->plot_header;
    return 0;
}

/* ------------------------------------------------------------- files, meshes */

FILE *study_csv_open(const xopts *o, const char *suffix, char *path, size_t size)
{
    snprintf(path, size, "%s/%s-%s", o->out, o->name, suffix);
    return lab_csv_open(path);
}

/* Centres m on its area centroid and scales it to unit area: the flow's
 * working units (mcf_mesh_area_centroid). */
static int normalize_unit_area(mcf_mesh *m)
{
    double *X = mcf_mesh_positions_mut(m);
    int nv = mcf_mesh_nvertices(m);
    double c[3], area = mcf_mesh_area_centroid(m, c);
    if (!(area > 0))
        return lab_fail(1, "the mesh has zero area");
    double s = 1.0 / sqrt(area);
    for (int i = 0; i < nv; i++)
        for (int k = 0; k < 3; k++)
            X[3 * i + k] = (X[3 * i + k] - c[k]) * s;
    return 0;
}

int study_mesh(const xopts *o, mcf_mesh **out)
{
    mcf_error err = {MCF_OK, ""};
    if (!o->mesh_path) {
        *out = mcf_mesh_new_icosphere(o->level, o->radius, &err);
        return *out ? 0 : lab_fail(1, "icosphere: %s", err.msg);
    }
    if (lab_load_mesh(o->mesh_path, out) != 0)
        return 1;
    if (normalize_unit_area(*out) != 0) {
        mcf_mesh_free(*out);
        *out = NULL;
        return 1;
    }
    return 0;
}

int noisy_study_mesh(const xopts *o, mcf_mesh **target, mcf_mesh **noisy, mcf_compare_result *c0, double *lam)
{
    mcf_error err = {MCF_OK, ""};
    if (study_mesh(o, target) != 0)
        return 1;
    if (!(*noisy = mcf_mesh_dup(*target, &err)) || mcf_mesh_add_noise(*noisy, o->rho, o->seed, &err) != MCF_OK ||
        mcf_compare(*noisy, *target, c0, &err) != MCF_OK ||
        mcf_lambda_max(*noisy, MCF_LAPLACIAN_COTAN, MCF_MASS_BARYCENTRIC, lam, &err) != MCF_OK) {
        lab_fail(1, "%s", err.msg);
        return 1;
    }
    return 0;
}

int dt_range(const xopts *o, double lam, int one_point, double *lo, double *hi)
{
    *lo = o->dt_min_lam ? o->dt_min / lam : o->dt_min;
    *hi = o->dt_max_lam ? o->dt_max / lam : o->dt_max;
    if (one_point ? !(*hi >= *lo) : !(*hi > *lo)) {
        lab_fail(LAB_EXIT_USAGE, "dt range [%g, %g] is empty (lambda_max %g)", *lo, *hi, lam);
        return 1;
    }
    return 0;
}

/* -------------------------------------------------------------------- runs */

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

int run_flow(const xopts *o, const mcf_mesh *start, const mcf_mesh *target, mcf_scheme s, double dt,
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
        return lab_fail(1, "%s", err.msg);
    size_t n3 = 3 * (size_t)mcf_mesh_nfaces(m);
    step_watch w = {m, malloc(n3 * sizeof(double)), malloc(n3 * sizeof(double)), 0, 0};
    if (!w.fn || !w.ref) {
        free(w.fn);
        free(w.ref);
        mcf_mesh_free(m);
        return lab_fail(1, "out of memory");
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
        return lab_fail(1, "%s", err.msg);
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
            return lab_fail(1, "compare: %s", err.msg);
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

int run_ok(const xrun *r)
{
    return r->status == MCF_OK && !r->nonfinite;
}

void run_note(const xopts *o, const xrun *r)
{
    note(o, "%s %-10s dt %-10.4g steps %-6d rms_rel %-10.4g %-9s %.2f s%s%s\n", o->name,
         mcf_scheme_get(r->scheme)->name, r->dt, r->steps, r->cmp.rms_rel, mcf_status_name(r->status), r->wall,
         r->msg[0] ? "  " : "", r->msg);
}

const char run_csv_header[] =
    "mesh,scheme,explicit,dt,dt_lambda,iterations,steps,t_final,status,rms_rel,frobenius,normal_angle_deg,"
    "max_err,inverted_faces,flipped_from_start,folded_in_a_step,steps_that_folded,nonfinite,area_drift,volume_drift,wall_s,solves,factorizations,picard_iterations,"
    "message";

/* One row of run_csv_header, without the line end. */
void run_csv_fields(FILE *f, const xopts *o, const xrun *r, double lam)
{
    char msg[MCF_ERRMSG_SIZE];
    const mcf_scheme_info *si = mcf_scheme_get(r->scheme);
    lab_csv_clean(r->msg, msg, sizeof msg);
    fprintf(f, "%s,%s,%d,%.9g,%.6g,%d,%d,%.9g,%s,%.9g,%.9g,%.9g,%.9g,%d,%d,%d,%d,%d,%.9g,%.9g,%.6f,%d,%d,%d,%s", o->name,
            si->name, si->is_explicit, r->dt, r->dt * lam, r->iterations, r->steps, r->t_final,
            mcf_status_name(r->status), r->cmp.rms_rel, r->cmp.frobenius, r->cmp.normal_angle_deg, r->cmp.max_err,
            r->cmp.inverted_faces, r->flipped, r->folded, r->folded_steps, r->nonfinite, r->area_drift, r->volume_drift, r->wall, r->solves, r->factorizations,
            r->picard, msg);
}

void run_csv_row(FILE *f, const xopts *o, const xrun *r, double lam)
{
    run_csv_fields(f, o, r, lam);
    fputc('\n', f);
}

/* ------------------------------------------------------------------ fitting */

double fit_loglog(const double *x, const double *y, int n, int *used)
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

/* ------------------------------------------------------------------ figures */

/* One colour per scheme, the same in every figure; explicit schemes are
 * dashed, implicit ones solid. */
static const char *const scheme_color[MCF_NSCHEMES] = {
    [MCF_EULER] = "#1f77b4",    [MCF_TAYLOR2] = "#17becf", [MCF_DESBRUN] = "#2ca02c",
    [MCF_NEUMANN2] = "#9467bd", [MCF_DESBRUN2] = "#d62728", [MCF_ROS2] = "#ff7f0e",
    [MCF_RICHARDSON] = "#8c564b", [MCF_IMPLICIT] = "#7f7f7f", [MCF_HUISKEN2] = "#bcbd22",
    [MCF_ARC] = "#e377c2",      [MCF_CMCF] = "#006400",    [MCF_LINEAR] = "#000080",
    [MCF_TAUBIN] = "#000000",   [MCF_FAIRING] = "#555555", [MCF_FAIRING_EXPLICIT] = "#aaaaaa"};

void gp_style(api_buf *b, mcf_scheme s, int points)
{
    const mcf_scheme_info *si = mcf_scheme_get(s);
    api_buf_printf(b, "lc rgb \"%s\" lw 2 dt %d", scheme_color[s], si->is_explicit ? 2 : 1);
    if (points)
        api_buf_printf(b, " pt %d ps 1.1", 1 + (int)s % 13);
}

void gp_series(api_buf *b, int *first, const char *block, const char *using, const char *with, mcf_scheme s,
                      const char *title)
{
    api_buf_printf(b, "%s $%s using %s with %s ", *first ? "plot" : ", \\\n    ", block, using, with);
    gp_style(b, s, strstr(with, "points") != NULL);
    api_buf_printf(b, " title ");
    lab_gp_str(b, title);
    *first = 0;
}

int gp_render(xopts *o, const char *suffix, const api_buf *body)
{
    char stem[300];
    snprintf(stem, sizeof stem, "%s-%s", o->name, suffix);
    return lab_plot_render(&o->plot, stem, body);
}
