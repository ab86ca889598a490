/* SPDX-License-Identifier: MIT */
/*
 * bench_quality.c - `make quality` (issues 16 and 31): how close to the
 * clean surface a noisy scan comes back, for the default request and the
 * anchors (Taubin and Open3D's Taubin at their best pass count, bilateral
 * normal filtering at its best parameters), all on the same noisy inputs.
 *
 * Cases: every mesh of the list (default: the shared meshes, each tagged
 * organic or CAD: --cad names the CAD parts) x noise model x rho (mean
 * edges h of the clean mesh; default 0.1, 0.25, 0.5) x seed (1..N,
 * default 1). The models (quality_noise.c defines them exactly; only the
 * vertices a default run moves get noise):
 *   normal  Gaussian along the vertex normals, sigma = rho h
 *           (mcf_flow_add_noise; bit-identical to issue 16's)
 *   iso     isotropic Gaussian, sigma = rho h per coordinate (issue 16's)
 *   view    Gaussian along one unit vector drawn from the seed
 *   corr    N(0,1) per vertex smoothed by 9 one-ring averages, unit RMS,
 *           along the normals
 *   out     `normal` plus 1% of the vertices moved 3-5 h along the normal
 *   quant   positions rounded to a grid of step rho h, offset from the seed
 *   clean   rho 0, once per mesh and seed: how far a method moves a mesh
 *           without noise, as a ratio of the error of `normal` at 0.1 h
 *           (same seed); only the requests (default, auto:S, fixed) run
 *
 * Methods (one row each per case in quality.csv; --methods picks them):
 *   default      api_params_init + api_params_finish with nothing set:
 *                whatever the service does with `curl -F mesh=@scan /smooth`
 *   auto:S       the request `scheme=S` and no amount (S: desbrun2,
 *                desbrun, ros2, richardson, cmcf, linear, taubin and every
 *                scheme whose name starts with "fairing")
 *   fixed        desbrun2, strength 0.33, 10 steps (the old default)
 *   taubin_best  scheme taubin at its best pass count (an oracle that
 *                knows the clean mesh: passes 1 .. 500 cumulatively on a
 *                growing schedule, stopped 5% past the minimum at twice
 *                the best count)
 *   o3d_default  Open3D's mesh.filter_smooth_taubin() (1 iteration;
 *                Debian's python3-open3d through o3d_taubin.py, a coprocess)
 *   o3d_best     the same at its best pass count (the same oracle)
 *   bnf_best     bilateral normal filtering (Zheng et al. 2011, Sun et
 *                al. 2007's vertex update; quality_bnf.c) at the best point
 *                of an 80-point grid (an oracle)
 * Default: default, taubin_best, o3d_default, o3d_best, bnf_best.
 *
 * Metrics per result: the per-vertex error (mcf_compare's area-weighted
 * RMS distance to the clean vertex) and the surface error (symmetric RMS
 * point-to-surface distance, quality_geom.c), each as a ratio of the
 * noisy input's; flips (faces whose normal points against the clean
 * mesh's, dot < 0; the input's count beside); drift (volume of closed
 * meshes, area of open ones, vs clean); CPU time of the one run (this
 * process's, or the coprocess's for Open3D); for the requests, the noise
 * level the run read (mcf_flow_stats.noise, mean edges); for `default`,
 * its CPU time against --baseline's (a quality.csv of an earlier run: the
 * same mesh, model, rho and seed).
 *
 * Output (--out, lab/results/quality by default): quality.csv (every run),
 * quality.md (per model: the default against the input and the anchors,
 * organic and CAD apart, median and worst; flips; CPU against the
 * baseline; every method's summary; the clean meshes; every case), and
 * renders (render_quality.py, matplotlib): the case where the default
 * does worst against taubin_best per model, and any --render case.
 * Single-threaded (lab/Makefile pins OpenBLAS and OpenMP to one thread).
 * Exit status 1 on an error, 2 on a usage error.
 */
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "api.h"
#include "bench_common.h"
#include "lab.h"
#include "mcf.h"
#include "quality_bnf.h"
#include "quality_geom.h"
#include "quality_noise.h"

#define PROG "bench_quality"
#define MAXMESH 32
#define MAXNOISE 6
#define MAXSEED 5
#define MAXMETHOD 20
#define MAXRENDER 8

typedef enum { K_DEFAULT, K_AUTO, K_FIXED, K_TAUBIN_BEST, K_O3D_DEFAULT, K_O3D_BEST, K_BNF_BEST } method_kind;

typedef struct {
    char name[32];
    method_kind kind;
    char scheme[24];
} method;

typedef struct {
    int ok, skipped;     /* skipped: not run on this case (the oracles on `clean`) */
    double ratio;        /* per-vertex error / the input's */
    double sratio;       /* surface error / the input's */
    int flips;           /* faces against the clean mesh (dot < 0) */
    int folds_off;       /* of them, away from the clean mesh's creases */
    double drift;
    double cpu, wall;    /* seconds */
    double param;        /* t/h^2 for MCF, passes for the filters, steps for fairing, normal iterations for bnf */
    double reading;      /* the requests: the noise level read (mean edges), else NaN */
    double base_cpu;     /* default, taubin_best: the baseline's CPU time on this case, else NaN */
    double cost;         /* wall seconds of the whole evaluation (oracle search and measures included) */
    char note[200];
} result;

/* One noisy input. */
typedef struct {
    int mesh;
    qn_model model;
    double rho;
    int seed;
    double e0, s0;       /* the input's vertex and surface errors (clean: those of normal 0.1 h) */
    int flips0, outliers;
} qcase;

/* Taubin pass counts evaluated (cumulative) for the oracle. */
static const int g_passes[] = {1, 2, 3, 4, 5, 6, 8, 10, 12, 15, 20, 25, 30, 40, 50, 60,
                               80, 100, 120, 150, 200, 250, 300, 400, 500};
#define NPASSES ((int)(sizeof g_passes / sizeof g_passes[0]))

/* ------------------------------------------------------------ helpers */

static void die(const char *what, const mcf_error *e)
{
    fprintf(stderr, PROG ": %s: %s\n", what, e ? e->msg : "failed");
    exit(1);
}

static double cpu_now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

static int cmp_d(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Median and maximum of the non-NaN values of v (NaN when none; an
 * infinity, a failed run, counts as the worst); v is sorted in place. */
static double median_max(double *v, int n, double *mx)
{
    int k = 0;
    for (int i = 0; i < n; i++)
        if (!isnan(v[i]))
            v[k++] = v[i];
    qsort(v, (size_t)k, sizeof *v, cmp_d);
    *mx = k ? v[k - 1] : NAN;
    return k ? (k % 2 ? v[k / 2] : 0.5 * (v[k / 2 - 1] + v[k / 2])) : NAN;
}

static mcf_mesh *noisy_or_die(const mcf_mesh *clean, qn_model k, double rho, int seed, int *outliers)
{
    mcf_error e = {0};
    mcf_mesh *m = qn_make(clean, k, rho, seed, outliers, &e);
    if (!m)
        die(qn_name(k), &e);
    return m;
}

/* ------------------------------------------------------------ cases */

typedef struct {
    const mcf_mesh *clean, *noisy;
    const qg_grid *gclean;
    double e0, s0;       /* the noisy input's vertex and surface errors */
    const unsigned char *crease, *movable;
    int fold0_off;
    double ref_size;     /* clean volume (closed) or area (open) */
    int closed;
    double h;            /* noisy mean edge / sqrt(noisy area): the t/h^2 unit */
} case_ctx;

/* --surface: the surface error of every method (else of `default` only:
 * it costs about as much as a method's run on the large scans). */
static int g_surface_all;

/* Fills r's error metrics for result m (a smoothed copy of c->noisy); the
 * surface error when surface (else NaN). */
static void measure(const case_ctx *c, const mcf_mesh *m, result *r, int surface)
{
    mcf_compare_result a;
    mcf_error e = {0};
    if (mcf_compare(m, c->clean, &a, &e) != MCF_OK)
        die("mcf_compare", &e);
    r->ratio = a.rms_m / c->e0;
    r->sratio = surface ? qg_surface_error(m, c->clean, c->gclean) / c->s0 : NAN;
    r->flips = qg_flips(m, c->clean);
    r->folds_off = qg_inverted_off_crease(m, c->clean, c->crease) - c->fold0_off;
    double s = c->closed ? mcf_mesh_volume(m) : mcf_mesh_area(m);
    r->drift = (s - c->ref_size) / fabs(c->ref_size);
}

static void failed(result *r, const char *what, const char *msg)
{
    r->ok = 0;
    r->ratio = r->sratio = r->drift = INFINITY;
    r->flips = r->folds_off = -1;
    snprintf(r->note, sizeof r->note, "%s: %s", what, msg);
    for (char *q = r->note; *q; q++)
        if (*q == '"' || *q == '\n')
            *q = '\'';
}

/* A request through the api layer's parameters: nothing set (default),
 * scheme=S alone (auto) or desbrun2 strength 0.33 (fixed). */
static void run_request(const case_ctx *c, const method *md, result *r, mcf_mesh **out)
{
    api_limits lim;
    api_params p;
    mcf_error e = {0};
    mcf_flow_stats st;
    mcf_mesh *m = bench_dup_mesh(PROG, c->noisy);
    memset(&st, 0, sizeof st);
    api_limits_default(&lim);
    api_params_init(&p);
    if ((md->kind == K_AUTO && api_params_set(&p, "scheme", md->scheme, &lim, &e) != MCF_OK) ||
        (md->kind == K_FIXED && (api_params_set(&p, "scheme", "desbrun2", &lim, &e) != MCF_OK ||
                                 api_params_set(&p, "strength", "0.33", &lim, &e) != MCF_OK))) {
        failed(r, md->name, e.msg);
        goto done;
    }
    double c0 = cpu_now(), w0 = mcf_now();
    if (api_params_finish(&p, mcf_mesh_nvertices(m), &lim, &e) != MCF_OK ||
        mcf_flow_run(m, &p.flow, &st, &e) != MCF_OK) {
        failed(r, md->name, e.msg);
        goto done;
    }
    r->cpu = cpu_now() - c0;
    r->wall = mcf_now() - w0;
    r->ok = 1;
    const mcf_scheme_info *si = mcf_scheme_get(p.flow.scheme);
    r->param = p.flow.scheme == MCF_TAUBIN || (si && si->order == 0) ? st.steps : st.t_final / (c->h * c->h);
    r->reading = st.noise > 0 ? st.noise : NAN;
    measure(c, m, r, md->kind == K_DEFAULT || g_surface_all);
done:
    mcf_flow_stats_free(&st);
    api_params_free(&p);
    if (out && r->ok)
        *out = m;
    else
        mcf_mesh_free(m);
}

/* Taubin at its best pass count (see the file comment). */
static void run_taubin_best(const case_ctx *c, result *best, mcf_mesh **out)
{
    mcf_flow_params p;
    mcf_error e = {0};
    mcf_mesh *m = bench_dup_mesh(PROG, c->noisy);
    int have = 0, bestp = 0;
    double bestr = INFINITY;
    mcf_flow_params_init(&p);
    p.scheme = MCF_TAUBIN;
    for (int i = 0; i < NPASSES; i++) {
        p.iterations = g_passes[i] - have;
        if (mcf_flow_run(m, &p, NULL, &e) != MCF_OK)
            break;
        have = g_passes[i];
        mcf_compare_result a;
        if (mcf_compare(m, c->clean, &a, &e) != MCF_OK)
            die("mcf_compare", &e);
        if (a.rms_m < bestr) {
            bestr = a.rms_m;
            bestp = have;
        }
        if ((a.rms_m > 1.05 * bestr && have >= 2 * bestp) || a.rms_m > 1.5 * bestr)
            break;
    }
    mcf_mesh_free(m);
    if (bestp == 0) {
        failed(best, "taubin_best", e.msg);
        return;
    }
    m = bench_dup_mesh(PROG, c->noisy);
    p.iterations = bestp;
    double c0 = cpu_now(), w0 = mcf_now();
    mcf_status s = mcf_flow_run(m, &p, NULL, &e);
    best->cpu = cpu_now() - c0;
    best->wall = mcf_now() - w0;
    best->param = bestp;
    if (s != MCF_OK)
        failed(best, "taubin_best", e.msg);
    else {
        best->ok = 1;
        measure(c, m, best, g_surface_all);
    }
    if (out && best->ok)
        *out = m;
    else
        mcf_mesh_free(m);
}

/* Bilateral normal filtering at its best grid point; the CPU time is that
 * of one run at those parameters (not the search's). */
static void run_bnf_best(const case_ctx *c, result *r, mcf_mesh **out)
{
    bnf_params bp;
    mcf_mesh *m = NULL;
    if (bnf_oracle(c->noisy, c->clean, c->movable, &bp, NULL) != 0) {
        failed(r, "bnf_best", "out of memory");
        return;
    }
    m = bench_dup_mesh(PROG, c->noisy);
    double c0 = cpu_now(), w0 = mcf_now();
    if (bnf_filter(m, c->movable, &bp) != 0) {
        mcf_mesh_free(m);
        failed(r, "bnf_best", "out of memory");
        return;
    }
    r->cpu = cpu_now() - c0;
    r->wall = mcf_now() - w0;
    r->ok = 1;
    r->param = bp.normal_iters;
    snprintf(r->note, sizeof r->note, "sigma_r %g, %d normal, %d vertex iterations", bp.sigma_r, bp.normal_iters,
             bp.vertex_iters);
    measure(c, m, r, g_surface_all);
    if (out)
        *out = m;
    else
        mcf_mesh_free(m);
}

/* ------------------------------------------------------------ Open3D */

/* The coprocess (lab/bench/o3d_taubin.py): pid, its stdin and stdout. */
static struct {
    pid_t pid;
    FILE *to, *from;
    char version[64];
} g_o3d;
static char g_tmp[256];

static void o3d_start(const char *script)
{
    int in[2], outp[2];
    if (pipe(in) != 0 || pipe(outp) != 0)
        return;
    pid_t pid = fork();
    if (pid < 0)
        return;
    if (pid == 0) {
        dup2(in[0], 0);
        dup2(outp[1], 1);
        close(in[1]);
        close(outp[0]);
        setenv("OMP_NUM_THREADS", "1", 1);
        execl("/usr/bin/python3", "python3", script, (char *)NULL);
        _exit(127);
    }
    close(in[0]);
    close(outp[1]);
    g_o3d.pid = pid;
    g_o3d.to = fdopen(in[1], "w");
    g_o3d.from = fdopen(outp[0], "r");
    char line[256];
    if (!g_o3d.from || !fgets(line, sizeof line, g_o3d.from) || strncmp(line, "ready ", 6) != 0) {
        fprintf(stderr, PROG ": %s did not start (python3-open3d missing?): the Open3D columns are skipped\n", script);
        if (g_o3d.to)
            fclose(g_o3d.to);
        if (g_o3d.from)
            fclose(g_o3d.from);
        waitpid(pid, NULL, 0);
        memset(&g_o3d, 0, sizeof g_o3d);
        return;
    }
    line[strcspn(line, "\n")] = 0;
    snprintf(g_o3d.version, sizeof g_o3d.version, "%.60s", line + 6);
}

static void o3d_stop(void)
{
    if (!g_o3d.pid)
        return;
    fclose(g_o3d.to);
    fclose(g_o3d.from);
    waitpid(g_o3d.pid, NULL, 0);
    g_o3d.pid = 0;
}

static void write_raw(const char *path, const mcf_mesh *m)
{
    FILE *f = fopen(path, "wb");
    int32_t n[2] = {mcf_mesh_nvertices(m), mcf_mesh_nfaces(m)};
    if (!f || fwrite(n, sizeof n, 1, f) != 1 ||
        fwrite(mcf_mesh_positions(m), 3 * sizeof(double), (size_t)n[0], f) != (size_t)n[0] ||
        fwrite(mcf_mesh_faces(m), 3 * sizeof(int32_t), (size_t)n[1], f) != (size_t)n[1] || fclose(f) != 0) {
        fprintf(stderr, PROG ": cannot write %s\n", path);
        exit(1);
    }
}

/* Open3D's default and best on c->noisy into r[0] and r[1]. */
static void run_o3d(const case_ctx *c, result r[2], mcf_mesh *out[2])
{
    char pn[300], pc[300], po[300], line[512];
    if (!g_o3d.pid) {
        failed(&r[0], "o3d_default", "python3-open3d not available");
        failed(&r[1], "o3d_best", "python3-open3d not available");
        return;
    }
    snprintf(pn, sizeof pn, "%s/noisy.bin", g_tmp);
    snprintf(pc, sizeof pc, "%s/clean.bin", g_tmp);
    snprintf(po, sizeof po, "%s/out.bin", g_tmp);
    write_raw(pn, c->noisy);
    write_raw(pc, c->clean);
    fprintf(g_o3d.to, "%s %s %s\n", pn, pc, po);
    fflush(g_o3d.to);
    if (!fgets(line, sizeof line, g_o3d.from) || strncmp(line, "ok", 2) != 0) {
        line[strcspn(line, "\n")] = 0;
        failed(&r[0], "o3d_default", line);
        failed(&r[1], "o3d_best", line);
        return;
    }
    FILE *f = fopen(po, "rb");
    int nv = mcf_mesh_nvertices(c->noisy);
    int32_t passes = 0;
    double cpu[2];
    mcf_mesh *m[2] = {bench_dup_mesh(PROG, c->noisy), bench_dup_mesh(PROG, c->noisy)};
    if (!f || fread(&passes, sizeof passes, 1, f) != 1 || fread(cpu, sizeof cpu, 1, f) != 1 ||
        fread(mcf_mesh_positions_mut(m[0]), 3 * sizeof(double), (size_t)nv, f) != (size_t)nv ||
        fread(mcf_mesh_positions_mut(m[1]), 3 * sizeof(double), (size_t)nv, f) != (size_t)nv) {
        fprintf(stderr, PROG ": cannot read %s\n", po);
        exit(1);
    }
    fclose(f);
    for (int k = 0; k < 2; k++) {
        r[k].ok = 1;
        r[k].cpu = r[k].wall = cpu[k];
        r[k].param = k ? passes : 1;
        measure(c, m[k], &r[k], g_surface_all);
        if (out)
            out[k] = m[k];
        else
            mcf_mesh_free(m[k]);
    }
}
/* ------------------------------------------------------------ renders */

/* Renders the meshes ms (same connectivity; ms[0] the clean one) side by
 * side into out/stem.png with render_quality.py: each written as a raw
 * mesh (write_raw) into the scratch folder, removed afterwards. */
static void render(const char *script, const char *out, const char *stem, const char *title,
                   const mcf_mesh *const ms[], const char *const labels[], int n)
{
    char paths[8][300], args[8][600], png[4096], scr[1024], ttl[256], py[] = "python3", o[] = "--out",
        t[] = "--title";
    char *argv[24];
    int a = 0;
    snprintf(scr, sizeof scr, "%s", script);
    snprintf(ttl, sizeof ttl, "%s", title);
    argv[a++] = py;
    argv[a++] = scr;
    snprintf(png, sizeof png, "%s/%s.png", out, stem);
    argv[a++] = o;
    argv[a++] = png;
    argv[a++] = t;
    argv[a++] = ttl;
    for (int i = 0; i < n && i < 8; i++) {
        snprintf(paths[i], sizeof paths[i], "%s/render-%d.bin", g_tmp, i);
        write_raw(paths[i], ms[i]);
        snprintf(args[i], sizeof args[i], "%.290s=%.200s", paths[i], labels[i]);
        argv[a++] = args[i];
    }
    argv[a] = NULL;
    fflush(stdout);
    pid_t pid = fork();
    if (pid == 0) {
        setenv("OMP_NUM_THREADS", "1", 1);
        execv("/usr/bin/python3", argv);
        _exit(127);
    }
    int st = -1;
    if (pid > 0)
        waitpid(pid, &st, 0);
    if (pid > 0 && WIFEXITED(st) && WEXITSTATUS(st) == 0)
        printf("render: %s\n", png);
    else
        printf("render: %s failed (python3-matplotlib missing?)\n", png);
    for (int i = 0; i < n && i < 8; i++)
        remove(paths[i]);
}

/* ------------------------------------------------------------ tables */

static void split(char *s, char **out, int max, int *n)
{
    *n = 0;
    for (char *t = strtok(s, ","); t && *n < max; t = strtok(NULL, ","))
        out[(*n)++] = t;
}

static void usage(void)
{
    fprintf(stderr,
            "usage: bench_quality [--meshes DIR] [--out DIR] [--list a.obj,b.drc,...] [--cad a.obj,...]\n"
            "                     [--models normal,iso,view,corr,out,quant,clean] [--rho 0.1,0.25,0.5]\n"
            "                     [--seeds N] [--methods NAME,...] [--baseline quality.csv] [--o3d SCRIPT]\n"
            "                     [--render-script SCRIPT] [--render MESH:MODEL:RHO[:SEED]]... [--no-figure]\n"
            "                     [--surface] [--tables-from a.csv,b.csv]\n"
            "  methods: default, auto:SCHEME, fixed, taubin_best, o3d_default, o3d_best, bnf_best\n"
            "  (default: default,taubin_best,o3d_default,o3d_best,bnf_best); --kinds and --noise are\n"
            "  the old names of --models and --rho. --surface: every method's surface error (default's\n"
            "  only without). --tables-from: the tables and renders of earlier runs' quality.csv files\n"
            "  (e.g. a matrix split over two processes), no run.\n");
    exit(2);
}

/* The run's cases and results: g_res[case * g_nmeth + method]. */
static qcase *g_case;
static result *g_res;
static int g_ncase, g_nmeth;
static int g_cad[MAXMESH]; /* 1: the mesh is a CAD part */
static result *RES(int c, int q)
{
    return &g_res[(size_t)c * g_nmeth + q];
}

/* Does case c match: model k, level rho (NaN: any), class cls (-1: any,
 * 0 organic, 1 CAD)? */
static int match(int c, qn_model k, double rho, int cls)
{
    const qcase *x = &g_case[c];
    return x->model == k && (isnan(rho) || x->rho == rho) && (cls < 0 || g_cad[x->mesh] == cls);
}

/* Median and worst over the matching cases of method q's vertex error
 * against the input (peer INPUT) or against method peer's (none, NaN,
 * when peer is another negative: a method not in the run); n: cases. */
#define INPUT (-100)
static int versus(qn_model k, double rho, int cls, int q, int peer, double *med, double *worst)
{
    double *v = malloc(sizeof(double) * (size_t)g_ncase + 1);
    int n = 0;
    for (int c = 0; c < g_ncase; c++) {
        if (!match(c, k, rho, cls) || q < 0 || (peer < 0 && peer != INPUT))
            continue;
        const result *a = RES(c, q), *b = peer >= 0 ? RES(c, peer) : NULL;
        if (a->skipped || (b && (b->skipped || !b->ok)))
            continue;
        v[n++] = !a->ok ? INFINITY : a->ratio / (b ? b->ratio : 1.0);
    }
    *med = median_max(v, n, worst);
    free(v);
    return n;
}

/* "0.412 (0.73)", or "-" */
static const char *mw(char *b, size_t len, double med, double worst)
{
    if (isnan(med))
        snprintf(b, len, "-");
    else if (fabs(med) < 0.01 && fabs(worst) < 0.01) /* the clean meshes: small */
        snprintf(b, len, "%.2g (%.2g)", med, worst);
    else
        snprintf(b, len, "%.3f (%.2f)", med, worst);
    return b;
}

/* Flips over the matching cases: the input's sum, method q's, and how
 * many cases q leaves with more than its input. */
static void flips(qn_model k, double rho, int cls, int q, long *in, long *out, int *up)
{
    *in = *out = *up = 0;
    for (int c = 0; c < g_ncase; c++) {
        if (q < 0 || !match(c, k, rho, cls) || RES(c, q)->skipped || !RES(c, q)->ok)
            continue;
        *in += g_case[c].flips0;
        *out += RES(c, q)->flips;
        *up += RES(c, q)->flips > g_case[c].flips0;
    }
}

/* Median (and worst) of the default's reading / rho, and of its CPU time
 * against the baseline's. */
static void reading_cpu(qn_model k, double rho, int cls, int q, double r[2], double cpu[2])
{
    double *a = malloc(sizeof(double) * (size_t)g_ncase + 1), *b = malloc(sizeof(double) * (size_t)g_ncase + 1);
    int na = 0, nb = 0;
    for (int c = 0; c < g_ncase; c++) {
        if (q < 0 || !match(c, k, rho, cls) || !RES(c, q)->ok)
            continue;
        if (g_case[c].rho > 0 && !isnan(RES(c, q)->reading))
            a[na++] = RES(c, q)->reading / g_case[c].rho;
        if (RES(c, q)->base_cpu > 0)
            b[nb++] = RES(c, q)->cpu / RES(c, q)->base_cpu;
    }
    r[0] = median_max(a, na, &r[1]);
    cpu[0] = median_max(b, nb, &cpu[1]);
    free(a);
    free(b);
}

/* ------------------------------------------------------------ baseline */

typedef struct {
    char key[160];
    double cpu;
} base_row;
static base_row *g_base;
static int g_nbase;

static void case_key(char *k, size_t len, const char *mesh, const char *model, double rho, int seed,
                     const char *meth_name)
{
    snprintf(k, len, "%s|%s|%g|%d|%s", mesh, model, rho, seed, meth_name);
}

/* The CPU time per case of `default` and `taubin_best` (the machine's
 * speed then: the same passes on the same input) from an earlier
 * quality.csv (columns mesh, model, rho, seed, method, cpu_s). */
static void load_baseline(const char *path)
{
    char *buf;
    size_t len;
    if (bench_read_file(path, &buf, &len) != 0) {
        printf("baseline: cannot read %s: no CPU ratios\n", path);
        return;
    }
    int col[6] = {-1, -1, -1, -1, -1, -1}, nline = 0;
    static const char *const want[6] = {"mesh", "model", "rho", "seed", "method", "cpu_s"};
    for (char *line = buf, *next; line && *line; line = next, nline++) {
        next = strchr(line, '\n');
        if (next)
            *next++ = 0;
        char *f[32];
        int nf = 0;
        for (char *t = line; nf < 32;) {
            f[nf++] = t;
            char *cm = strchr(t, ',');
            if (!cm)
                break;
            *cm = 0;
            t = cm + 1;
        }
        if (nline == 0) {
            for (int i = 0; i < nf; i++)
                for (int w = 0; w < 6; w++)
                    if (!strcmp(f[i], want[w]))
                        col[w] = i;
            for (int w = 0; w < 6; w++)
                if (col[w] < 0) {
                    printf("baseline: %s has no column %s: no CPU ratios\n", path, want[w]);
                    free(buf);
                    return;
                }
            continue;
        }
        int mx = 0;
        for (int w = 0; w < 6; w++)
            mx = col[w] > mx ? col[w] : mx;
        if (nf <= mx || (strcmp(f[col[4]], "default") && strcmp(f[col[4]], "taubin_best")))
            continue;
        base_row *nb = realloc(g_base, sizeof *g_base * (size_t)(g_nbase + 1));
        if (!nb)
            die("baseline", NULL);
        g_base = nb;
        case_key(g_base[g_nbase].key, sizeof g_base[0].key, f[col[0]], f[col[1]], atof(f[col[2]]), atoi(f[col[3]]),
                 f[col[4]]);
        g_base[g_nbase++].cpu = atof(f[col[5]]);
    }
    free(buf);
    printf("baseline: %d default and taubin_best runs from %s\n", g_nbase, path);
}

static double base_cpu(const char *mesh, qn_model k, double rho, int seed, const char *meth_name)
{
    char key[160];
    case_key(key, sizeof key, mesh, qn_name(k), rho, seed, meth_name);
    for (int i = 0; i < g_nbase; i++)
        if (!strcmp(g_base[i].key, key))
            return g_base[i].cpu;
    return NAN;
}


/* ------------------------------------------------------------ --tables-from */

/* Splits one CSV line in place into at most max fields (a field that
 * starts with a double quote runs to the next one, commas included);
 * returns the count. */
static int csv_fields(char *line, char **f, int max)
{
    int n = 0;
    char *p = line;
    while (n < max) {
        if (*p == '"') {
            f[n++] = ++p;
            char *q = strchr(p, '"');
            if (!q)
                break;
            *q = 0;
            p = q + 1;
        } else {
            f[n++] = p;
            p += strcspn(p, ",");
        }
        if (*p != ',')
            break;
        *p++ = 0;
    }
    return n;
}

/* The cases and results of earlier runs' quality.csv files (comma-
 * separated paths), in place of a run: meshes, models, levels, seeds and
 * methods as those files have them (methods in the order of `all`). The
 * file buffers stay allocated: names point into them. */
static void load_tables(char *files, const method *all, int nall, method *meth, int *nmeth, char **names, int *nm,
                        qn_model *models, int *nk, double *rho, char **ntext, int *nr, int *ns)
{
    static char rho_text[MAXNOISE][24];
    static const char *const want[] = {"mesh", "class", "model", "rho", "seed", "e0", "s0", "flips0", "outliers",
                                       "method", "param", "ok", "skipped", "ratio", "surface_ratio", "flips",
                                       "new_flips_off_crease", "drift", "reading", "cpu_s", "wall_s",
                                       "base_cpu_s", "cost_s", "note"};
    enum { NW = sizeof want / sizeof want[0] };
    int have_model[QN_COUNT] = {0}, have_method[MAXMETHOD] = {0}, nrho = 0;
    double rhos[MAXNOISE];
    *nm = *ns = 0;
    for (char *path = strtok(files, ","); path; path = strtok(NULL, ",")) {
        char *buf;
        size_t len;
        if (bench_read_file(path, &buf, &len) != 0) {
            fprintf(stderr, PROG ": cannot read %s: %s\n", path, strerror(errno));
            exit(1);
        }
        int col[NW], nline = 0;
        char *save = NULL;
        for (char *line = strtok_r(buf, "\n", &save); line; line = strtok_r(NULL, "\n", &save), nline++) {
            char *f[40];
            int nf = csv_fields(line, f, 40);
            if (nline == 0) {
                for (int w = 0; w < NW; w++) {
                    col[w] = -1;
                    for (int i = 0; i < nf; i++)
                        if (!strcmp(f[i], want[w]))
                            col[w] = i;
                    if (col[w] < 0) {
                        fprintf(stderr, PROG ": %s has no column %s\n", path, want[w]);
                        exit(1);
                    }
                }
                continue;
            }
            if (nf < NW)
                continue;
#define F(w) f[col[w]]
            int mesh = -1, q = -1, k = qn_parse(F(2)), seed = atoi(F(4));
            double r = atof(F(3));
            for (int m = 0; m < *nm; m++)
                if (!strcmp(names[m], F(0)))
                    mesh = m;
            if (mesh < 0 && *nm < MAXMESH) {
                mesh = (*nm)++;
                names[mesh] = F(0);
                g_cad[mesh] = !strcmp(F(1), "CAD");
            }
            for (int a = 0; a < nall; a++)
                if (!strcmp(all[a].name, F(9)))
                    q = a;
            if (mesh < 0 || q < 0 || k < 0 || seed < 1 || seed > MAXSEED) {
                fprintf(stderr, PROG ": %s line %d: unknown mesh, method or model, or bad seed\n", path, nline + 1);
                exit(1);
            }
            have_model[k] = 1;
            have_method[q] = 1;
            *ns = seed > *ns ? seed : *ns;
            int known = 0;
            for (int j = 0; j < nrho; j++)
                known |= rhos[j] == r;
            if (!known && r > 0 && nrho < MAXNOISE)
                rhos[nrho++] = r;
            int c = -1;
            for (int i = 0; i < g_ncase; i++)
                if (g_case[i].mesh == mesh && g_case[i].model == (qn_model)k && g_case[i].rho == r &&
                    g_case[i].seed == seed)
                    c = i;
            if (c < 0) {
                c = g_ncase++;
                g_case[c] = (qcase){mesh, (qn_model)k, r, seed, atof(F(5)), atof(F(6)), atoi(F(7)), atoi(F(8))};
            }
            result *x = RES(c, q); /* the stride is MAXMETHOD here: q indexes `all` for now */
            x->param = atof(F(10));
            x->ok = atoi(F(11));
            x->skipped = atoi(F(12));
            x->ratio = strtod(F(13), NULL);
            x->sratio = strtod(F(14), NULL);
            x->flips = atoi(F(15));
            x->folds_off = atoi(F(16));
            x->drift = strtod(F(17), NULL);
            x->reading = strtod(F(18), NULL);
            x->cpu = atof(F(19));
            x->wall = atof(F(20));
            x->base_cpu = strtod(F(21), NULL);
            x->cost = atof(F(22));
            snprintf(x->note, sizeof x->note, "%s", F(23));
#undef F
        }
    }
    /* the methods in `all`'s order; results moved from `all`'s index to the new one */
    *nmeth = 0;
    for (int a = 0; a < nall; a++)
        if (have_method[a]) {
            for (int c = 0; c < g_ncase; c++)
                *RES(c, *nmeth) = *RES(c, a);
            meth[(*nmeth)++] = all[a];
        }
    *nk = 0;
    for (int k = 0; k < QN_COUNT; k++)
        if (have_model[k])
            models[(*nk)++] = (qn_model)k;
    qsort(rhos, (size_t)nrho, sizeof *rhos, cmp_d);
    for (int j = 0; j < nrho; j++) {
        rho[j] = rhos[j];
        snprintf(rho_text[j], sizeof rho_text[j], "%g", rhos[j]);
        ntext[j] = rho_text[j];
    }
    *nr = nrho;
    printf("tables from %d cases, %d meshes, %d methods\n", g_ncase, *nm, *nmeth);
}

/* ------------------------------------------------------------ main */

int main(int argc, char **argv)
{
    const char *meshes = "../shared/meshes", *out = "lab/results/quality", *o3d_script = "o3d_taubin.py";
    const char *render_script = "render_quality.py", *baseline = NULL;
    char *from = NULL;
    char list_buf[1024] = "sphere_cgal.obj,bunny_npm_closed.obj,spot.obj,knot1.obj,fertility.obj,"
                          "stanford-bunny.obj,bunny.drc,armadillo.obj,snowden.obj,dragon_vrip_res2.obj,"
                          "car.drc,couplingdown_sub2.obj,blade.obj";
    char cad_buf[1024] = "car.drc,couplingdown_sub2.obj,blade.obj";
    char noise_buf[256] = "0.1,0.25,0.5", models_buf[128] = "normal,iso,view,corr,out,quant,clean";
    char methods_buf[512] = "default,taubin_best,o3d_default,o3d_best,bnf_best";
    char *render_spec[MAXRENDER];
    int nrender = 0, do_figure = 1, ns = 1;
    double t_start = mcf_now();
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        char *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--meshes") && v)
            meshes = v, i++;
        else if (!strcmp(a, "--out") && v)
            out = v, i++;
        else if (!strcmp(a, "--list") && v)
            snprintf(list_buf, sizeof list_buf, "%s", v), i++;
        else if (!strcmp(a, "--cad") && v)
            snprintf(cad_buf, sizeof cad_buf, "%s", v), i++;
        else if ((!strcmp(a, "--rho") || !strcmp(a, "--noise")) && v)
            snprintf(noise_buf, sizeof noise_buf, "%s", v), i++;
        else if ((!strcmp(a, "--models") || !strcmp(a, "--kinds")) && v)
            snprintf(models_buf, sizeof models_buf, "%s", v), i++;
        else if (!strcmp(a, "--methods") && v)
            snprintf(methods_buf, sizeof methods_buf, "%s", v), i++;
        else if (!strcmp(a, "--seeds") && v)
            ns = atoi(v), i++;
        else if (!strcmp(a, "--baseline") && v)
            baseline = v, i++;
        else if (!strcmp(a, "--o3d") && v)
            o3d_script = v, i++;
        else if (!strcmp(a, "--render-script") && v)
            render_script = v, i++;
        else if (!strcmp(a, "--render") && v && nrender < MAXRENDER)
            render_spec[nrender++] = v, i++;
        else if (!strcmp(a, "--tables-from") && v)
            from = v, i++;
        else if (!strcmp(a, "--no-figure"))
            do_figure = 0;
        else if (!strcmp(a, "--surface"))
            g_surface_all = 1;
        else
            usage();
    }
    if (ns < 1 || ns > MAXSEED)
        usage();

    /* the methods: those named, in the order of this list */
    method all[MAXMETHOD], meth[MAXMETHOD];
    int nall = 0, nmeth = 0;
    all[nall++] = (method){"default", K_DEFAULT, ""};
    static const char *const autos[] = {"desbrun2", "desbrun", "ros2", "richardson", "cmcf", "linear", "taubin"};
    for (int s = 0; s < MCF_NSCHEMES + 8; s++) {
        const mcf_scheme_info *si = mcf_scheme_get((mcf_scheme)s);
        if (si && !strncmp(si->name, "fairing", 7) && nall < MAXMETHOD - 12) {
            all[nall] = (method){"", K_AUTO, ""};
            snprintf(all[nall].name, sizeof all[nall].name, "auto:%s", si->name);
            snprintf(all[nall++].scheme, sizeof all[0].scheme, "%s", si->name);
        }
    }
    for (size_t s = 0; s < sizeof autos / sizeof autos[0]; s++) {
        all[nall] = (method){"", K_AUTO, ""};
        snprintf(all[nall].name, sizeof all[nall].name, "auto:%s", autos[s]);
        snprintf(all[nall++].scheme, sizeof all[0].scheme, "%s", autos[s]);
    }
    all[nall++] = (method){"fixed", K_FIXED, ""};
    all[nall++] = (method){"taubin_best", K_TAUBIN_BEST, ""};
    all[nall++] = (method){"o3d_default", K_O3D_DEFAULT, ""};
    all[nall++] = (method){"o3d_best", K_O3D_BEST, ""};
    all[nall++] = (method){"bnf_best", K_BNF_BEST, ""};
    {
        char *mt[MAXMETHOD];
        int nmt;
        split(methods_buf, mt, MAXMETHOD, &nmt);
        for (int k = 0; k < nmt; k++) {
            int found = 0;
            for (int q = 0; q < nall; q++)
                if (!strcmp(mt[k], all[q].name)) {
                    meth[nmeth++] = all[q];
                    found = 1;
                }
            if (!found) {
                fprintf(stderr, PROG ": unknown method %s\n", mt[k]);
                usage();
            }
        }
    }

    char *names[MAXMESH], *ntext[MAXNOISE], *mtext[QN_COUNT], *cads[MAXMESH];
    int nm, nr, nk, ncad;
    qn_model models[QN_COUNT];
    double rho[MAXNOISE];
    char noise_given[sizeof noise_buf], models_given[sizeof models_buf], list_given[sizeof list_buf];
    memcpy(noise_given, noise_buf, sizeof noise_buf);
    memcpy(models_given, models_buf, sizeof models_buf);
    memcpy(list_given, list_buf, sizeof list_buf);
    split(list_buf, names, MAXMESH, &nm);
    split(cad_buf, cads, MAXMESH, &ncad);
    split(noise_buf, ntext, MAXNOISE, &nr);
    split(models_buf, mtext, QN_COUNT, &nk);
    for (int j = 0; j < nr; j++)
        if (!((rho[j] = atof(ntext[j])) > 0))
            usage();
    for (int k = 0; k < nk; k++) {
        int m = qn_parse(mtext[k]);
        if (m < 0) {
            fprintf(stderr, PROG ": unknown noise model %s\n", mtext[k]);
            usage();
        }
        models[k] = (qn_model)m;
    }
    for (int m = 0; m < nm; m++) {
        g_cad[m] = 0;
        for (int c = 0; c < ncad; c++)
            g_cad[m] |= !strcmp(names[m], cads[c]);
    }

    if (from) {
        size_t mx = (size_t)MAXMESH * QN_COUNT * MAXNOISE * MAXSEED;
        g_case = calloc(mx, sizeof *g_case);
        g_res = calloc(mx * MAXMETHOD, sizeof(result));
        if (!g_case || !g_res)
            die("calloc", NULL);
        g_nmeth = MAXMETHOD;
        for (size_t i = 0; i < mx * MAXMETHOD; i++) /* what no file has: not run (a split run's methods may differ) */
            g_res[i] = (result){.skipped = 1, .ratio = NAN, .sratio = NAN, .reading = NAN, .base_cpu = NAN};
        char files[4096]; /* load_tables cuts its copy up */
        snprintf(files, sizeof files, "%s", from);
        load_tables(files, all, nall, meth, &nmeth, names, &nm, models, &nk, rho, ntext, &nr, &ns);
        snprintf(list_given, sizeof list_given, "of %.1000s", from);
        snprintf(models_given, sizeof models_given, "(as in the files)");
        snprintf(noise_given, sizeof noise_given, "(as in the files)");
    }
    int q_default = -1, q_tb = -1, q_od = -1, q_ob = -1, q_bnf = -1;
    for (int q = 0; q < nmeth; q++)
        switch (meth[q].kind) {
        case K_DEFAULT: q_default = q; break;
        case K_TAUBIN_BEST: q_tb = q; break;
        case K_O3D_DEFAULT: q_od = q; break;
        case K_O3D_BEST: q_ob = q; break;
        case K_BNF_BEST: q_bnf = q; break;
        default: break;
        }
    if (!from)
        g_nmeth = nmeth;

    bench_print_machine();
    lab_prog = PROG;
    if (lab_mkdir_p(out) != 0)
        return 1;
    {
        api_params p;
        api_params_init(&p);
        api_params_finish(&p, 1000, NULL, NULL);
        printf("default request: scheme %s, automatic amount %s\n", mcf_scheme_get(p.flow.scheme)->name,
               p.flow.strength_auto ? "yes" : "no");
        api_params_free(&p);
    }
    if (baseline)
        load_baseline(baseline);
    for (int c = 0; c < g_ncase && from && g_nbase > 0; c++)
        for (int q = 0; q < nmeth; q++)
            if (q == q_default || q == q_tb)
                RES(c, q)->base_cpu = base_cpu(names[g_case[c].mesh], g_case[c].model, g_case[c].rho,
                                               g_case[c].seed, meth[q].name);
    snprintf(g_tmp, sizeof g_tmp, "/tmp/bench_quality.%d", (int)getpid());
    if (lab_mkdir_p(g_tmp) != 0)
        return 1;
    if (!from && (q_od >= 0 || q_ob >= 0)) {
        o3d_start(o3d_script);
        if (g_o3d.pid)
            printf("Open3D %s (coprocess %s)\n", g_o3d.version, o3d_script);
    }
    signal(SIGPIPE, SIG_IGN);

    size_t maxcase = (size_t)nm * nk * nr * ns;
    if (!from) {
        g_case = calloc(maxcase, sizeof *g_case);
        g_res = calloc(maxcase * (size_t)nmeth, sizeof(result));
    }
    if (!g_case || !g_res)
        die("calloc", NULL);
    FILE *csv = bench_open_out(out, "quality.csv");
    fprintf(csv, "mesh,class,nv,nf,closed,model,rho,seed,e0,s0,flips0,outliers,method,param,ok,skipped,ratio,"
                 "surface_ratio,flips,new_flips_off_crease,drift,reading,cpu_s,wall_s,base_cpu_s,cost_s,note\n");
    /* the worst case per model of the default against taubin_best (clean:
     * against nothing), for the renders */
    double worst_vs[QN_COUNT];
    int worst_case[QN_COUNT];
    for (int k = 0; k < QN_COUNT; k++)
        worst_vs[k] = -INFINITY, worst_case[k] = -1;

    if (from) /* the files, one header */
        for (char *p = from, *end; *p; p = *end ? end + 1 : end) {
            char path[4096], *buf, *body;
            size_t len;
            end = p + strcspn(p, ",");
            snprintf(path, sizeof path, "%.*s", (int)(end - p), p);
            if (bench_read_file(path, &buf, &len) != 0)
                die(path, NULL);
            body = strchr(buf, '\n');
            fputs(p == from ? buf : body ? body + 1 : "", csv);
            free(buf);
        }
    for (int mi = 0; mi < nm && !from; mi++) {
        double tm0 = mcf_now(), mesh_cost[MAXMETHOD] = {0};
        mcf_mesh *clean = bench_load_mesh(PROG, meshes, names[mi]);
        mcf_mesh_info ci;
        mcf_error e = {0};
        if (mcf_mesh_inspect(clean, &ci, &e) != MCF_OK)
            die("mcf_mesh_inspect", &e);
        int closed = ci.boundary_edges == 0, ncrease;
        unsigned char *crease = qg_crease_mask(clean, &ncrease);
        unsigned char *movable = malloc((size_t)ci.nv + 1);
        int nmoved = movable ? qn_moved(clean, movable, &e) : -1;
        if (nmoved < 0)
            die("qn_moved", &e);
        qg_grid gclean;
        qg_grid_build(&gclean, clean);
        printf("\n%s (%s): %d vertices (%d move), %d faces, %s%s, %d faces at creases\n", names[mi],
               g_cad[mi] ? "CAD" : "organic", ci.nv, nmoved, ci.nf, closed ? "closed" : "open",
               ci.manifold ? "" : ", non-manifold", ncrease);
        fflush(stdout);
        for (int k = 0; k < nk; k++)
            for (int j = 0; j < (models[k] == QN_CLEAN ? 1 : nr); j++)
                for (int s = 0; s < ns; s++) {
                    qn_model model = models[k];
                    double r = model == QN_CLEAN ? 0.0 : rho[j];
                    int cidx = g_ncase++, outliers = 0;
                    qcase *qc = &g_case[cidx];
                    mcf_mesh *noisy = noisy_or_die(clean, model, r, s + 1, &outliers);
                    mcf_mesh *ref = model == QN_CLEAN ? noisy_or_die(clean, QN_NORMAL, 0.1, s + 1, NULL) : NULL;
                    mcf_mesh_info ni;
                    mcf_compare_result c0;
                    if (mcf_mesh_inspect(noisy, &ni, &e) != MCF_OK ||
                        mcf_compare(ref ? ref : noisy, clean, &c0, &e) != MCF_OK)
                        die("noisy input", &e);
                    *qc = (qcase){mi, model, r, s + 1, c0.rms_m, qg_surface_error(ref ? ref : noisy, clean, &gclean),
                                  qg_flips(noisy, clean), outliers};
                    mcf_mesh_free(ref);
                    case_ctx c = {clean, noisy, &gclean, qc->e0, qc->s0, crease, movable,
                                  qg_inverted_off_crease(noisy, clean, crease),
                                  closed ? ci.volume : ci.area, closed, ni.mean_edge / sqrt(ni.area)};
                    int o3d_done = 0;
                    for (int q = 0; q < nmeth; q++) {
                        result *rs = RES(cidx, q);
                        double w0 = mcf_now();
                        rs->reading = rs->base_cpu = NAN;
                        int request = meth[q].kind == K_DEFAULT || meth[q].kind == K_AUTO || meth[q].kind == K_FIXED;
                        if (model == QN_CLEAN && !request) {
                            rs->skipped = 1;
                            rs->ratio = rs->sratio = rs->drift = NAN;
                            snprintf(rs->note, sizeof rs->note, "not run on the clean mesh");
                        } else if (request)
                            run_request(&c, &meth[q], rs, NULL);
                        else if (meth[q].kind == K_TAUBIN_BEST)
                            run_taubin_best(&c, rs, NULL);
                        else if (meth[q].kind == K_BNF_BEST)
                            run_bnf_best(&c, rs, NULL);
                        else if (!o3d_done) {
                            result two[2];
                            memset(two, 0, sizeof two);
                            two[0].reading = two[1].reading = two[0].base_cpu = two[1].base_cpu = NAN;
                            run_o3d(&c, two, NULL);
                            if (q_od >= 0)
                                *RES(cidx, q_od) = two[0];
                            if (q_ob >= 0)
                                *RES(cidx, q_ob) = two[1];
                            o3d_done = 1;
                        }
                        rs->cost = mcf_now() - w0;
                        mesh_cost[q] += rs->cost;
                    }
                    for (int q = 0; q < nmeth; q++)
                        if (q == q_default || q == q_tb)
                            RES(cidx, q)->base_cpu = base_cpu(names[mi], model, r, s + 1, meth[q].name);
                    printf("  %-6s %4g s%d:", qn_name(model), r, s + 1);
                    for (int q = 0; q < nmeth; q++) {
                        const result *rs = RES(cidx, q);
                        fprintf(csv, "%s,%s,%d,%d,%d,%s,%g,%d,%.9g,%.9g,%d,%d,%s,%.6g,%d,%d,%.9g,%.9g,%d,%d,%.6g,%.6g,"
                                     "%.5f,%.5f,%.5f,%.3f,\"%s\"\n",
                                names[mi], g_cad[mi] ? "CAD" : "organic", ci.nv, ci.nf, closed, qn_name(model), r,
                                s + 1, qc->e0, qc->s0, qc->flips0, qc->outliers, meth[q].name, rs->param,
                                rs->ok, rs->skipped, rs->ratio, rs->sratio, rs->flips, rs->folds_off, rs->drift, rs->reading,
                                rs->cpu, rs->wall, rs->base_cpu, rs->cost, rs->note);
                        if (!rs->skipped)
                            printf(" %s %.3f", meth[q].name, rs->ratio);
                    }
                    if (q_default >= 0 && RES(cidx, q_default)->ok)
                        printf(" | flips %d -> %d, read %.3g h", qc->flips0, RES(cidx, q_default)->flips,
                               RES(cidx, q_default)->reading);
                    printf("\n");
                    for (int q = 0; q < nmeth; q++)
                        if (!RES(cidx, q)->ok && !RES(cidx, q)->skipped)
                            printf("    %s failed: %s\n", meth[q].name, RES(cidx, q)->note);
                    fflush(stdout);
                    fflush(csv);
                    mcf_mesh_free(noisy);
                }
        printf("  (%.1f s; wall s per method:", mcf_now() - tm0);
        for (int q = 0; q < nmeth; q++)
            printf(" %s %.1f", meth[q].name, mesh_cost[q]);
        printf(")\n");
        fflush(stdout);
        qg_grid_free(&gclean);
        free(crease);
        free(movable);
        mcf_mesh_free(clean);
    }
    fclose(csv);
    for (int c = 0; c < g_ncase && q_default >= 0; c++) {
        const result *d = RES(c, q_default);
        const result *t = q_tb >= 0 && g_case[c].model != QN_CLEAN ? RES(c, q_tb) : NULL;
        double vs = !d->ok ? INFINITY : t ? (t->ok ? d->ratio / t->ratio : NAN) : d->ratio;
        if (vs > worst_vs[g_case[c].model]) {
            worst_vs[g_case[c].model] = vs;
            worst_case[g_case[c].model] = c;
        }
    }

    /* ---- the tables (quality.md; the summary also on stdout) */
    FILE *md = bench_open_out(out, "quality.md");
    static const char *const cls_name[3] = {"all", "organic", "CAD"};
    char b[8][48];
    fprintf(md, "# make quality (lab/bench/bench_quality.c)\n\n"
                "Meshes %s (CAD: %s) x noise models %s x rho %s mean edges (clean: rho 0) x %d seed(s); %d cases.\n"
                "Error = area-weighted RMS distance to the clean vertex, as a ratio of the noisy input's; `x / P` is\n"
                "that ratio over method P's in the same case (taubin_best, o3d_best, bnf_best: oracles at their\n"
                "best parameters against the clean mesh). Cells: median (worst) over the cases. Flips: faces whose\n"
                "normal points against the clean mesh's (dot < 0), summed over the cases, input -> result, and in\n"
                "brackets the cases the result has more than its input. read / rho: the noise level the default\n"
                "read, in mean edges, over the true rho. CPU / baseline: the default's CPU time over the\n"
                "baseline's on the same case (%s).%s\n",
            list_given, cad_buf, models_given, noise_given, ns, g_ncase, baseline ? baseline : "no baseline given",
            g_o3d.pid || (q_od < 0 && q_ob < 0) ? "" : " Open3D was not available: its columns are empty.");

    /* the summary: one line per model, every level pooled (issue 31's table) */
    fprintf(md, "\n## Summary: the default request per noise model (all levels)\n\n"
                "| noise | default / input | / taubin_best | / o3d_best | / bnf_best: all | organic | CAD | "
                "flips input -> default | read / rho | CPU / baseline |\n|---|---|---|---|---|---|---|---|---|---|\n");
    printf("\n== the default request per noise model (median (worst) over the cases, all levels)\n"
           "%-6s | %-15s %-15s %-15s %-15s %-15s %-15s | %-22s | %-14s | %s\n", "noise", "/ input", "/ taubin_best",
           "/ o3d_best", "/ bnf_best", "bnf organic", "bnf CAD", "flips in -> default", "read / rho", "CPU / base");
    for (int k = 0; k < nk; k++) {
        qn_model mdl = models[k];
        if (mdl == QN_CLEAN)
            continue;
        double v[6][2], rd[2], cp[2];
        long fi, fo;
        int up;
        versus(mdl, NAN, -1, q_default, INPUT, &v[0][0], &v[0][1]);
        versus(mdl, NAN, -1, q_default, q_tb, &v[1][0], &v[1][1]);
        versus(mdl, NAN, -1, q_default, q_ob, &v[2][0], &v[2][1]);
        versus(mdl, NAN, -1, q_default, q_bnf, &v[3][0], &v[3][1]);
        versus(mdl, NAN, 0, q_default, q_bnf, &v[4][0], &v[4][1]);
        versus(mdl, NAN, 1, q_default, q_bnf, &v[5][0], &v[5][1]);
        flips(mdl, NAN, -1, q_default, &fi, &fo, &up);
        reading_cpu(mdl, NAN, -1, q_default, rd, cp);
        for (int x = 0; x < 6; x++)
            mw(b[x], sizeof b[x], v[x][0], v[x][1]);
        char fl[64], rr[48], cc[48];
        snprintf(fl, sizeof fl, "%ld -> %ld (%d up)", fi, fo, up);
        mw(rr, sizeof rr, rd[0], rd[1]);
        mw(cc, sizeof cc, cp[0], cp[1]);
        fprintf(md, "| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |\n", qn_name(mdl), b[0], b[1], b[2], b[3], b[4],
                b[5], fl, rr, cc);
        printf("%-6s | %-15s %-15s %-15s %-15s %-15s %-15s | %-22s | %-14s | %s\n", qn_name(mdl), b[0], b[1], b[2],
               b[3], b[4], b[5], fl, rr, cc);
    }

    /* the clean meshes */
    int have_clean = 0;
    for (int c = 0; c < g_ncase; c++)
        have_clean |= g_case[c].model == QN_CLEAN;
    if (have_clean) {
        fprintf(md, "\n## Clean meshes (rho 0): how far each request moves them, as a ratio of the error of `normal`\n"
                    "noise at 0.1 h (same seed); flips against the clean mesh\n\n| mesh | class |");
        for (int q = 0; q < nmeth; q++)
            if (meth[q].kind == K_DEFAULT || meth[q].kind == K_AUTO || meth[q].kind == K_FIXED)
                fprintf(md, " %s: moved / e(0.1 h) | flips |", meth[q].name);
        fprintf(md, "\n|---|---|");
        for (int q = 0; q < nmeth; q++)
            if (meth[q].kind == K_DEFAULT || meth[q].kind == K_AUTO || meth[q].kind == K_FIXED)
                fprintf(md, "---|---|");
        fprintf(md, "\n");
        printf("\n== clean meshes: moved / error of 0.1 h normal noise (default)\n");
        for (int c = 0; c < g_ncase; c++) {
            if (g_case[c].model != QN_CLEAN)
                continue;
            fprintf(md, "| %s (seed %d) | %s |", names[g_case[c].mesh], g_case[c].seed, g_cad[g_case[c].mesh] ? "CAD" : "organic");
            for (int q = 0; q < nmeth; q++)
                if (!RES(c, q)->skipped)
                    fprintf(md, RES(c, q)->ok ? " %.3g | %d |" : " failed | - |", RES(c, q)->ratio, RES(c, q)->flips);
            fprintf(md, "\n");
            if (q_default >= 0)
                printf("  %-24s %.3g (flips %d)\n", names[g_case[c].mesh], RES(c, q_default)->ratio,
                       RES(c, q_default)->flips);
        }
        double med, worst;
        if (q_default >= 0 && versus(QN_CLEAN, NAN, -1, q_default, INPUT, &med, &worst) > 0) {
            fprintf(md, "\ndefault: median %.3g, worst %.3g\n", med, worst);
            printf("  default: median %.3g, worst %.3g\n", med, worst);
        }
    }

    /* issue 31's thresholds on this run */
    if (q_default >= 0) {
        fprintf(md, "\n## Issue 31's done-when on this run\n\n| threshold | measured | holds |\n|---|---|---|\n");
        printf("\n== issue 31's done-when on this run\n");
        struct {
            const char *what;
            qn_model k;
            double rho;
            int cls, peer, worst;
            double limit;
        } th[] = {
            {"normal, organic: median default / taubin_best <= 0.65", QN_NORMAL, NAN, 0, q_tb, 0, 0.65},
            {"out: median default / input <= 0.55", QN_OUT, NAN, -1, INPUT, 0, 0.55},
            {"out: median default / o3d_best <= 1.25", QN_OUT, NAN, -1, q_ob, 0, 1.25},
            {"view: median default / taubin_best <= 1.0", QN_VIEW, NAN, -1, q_tb, 0, 1.0},
            {"clean: worst moved / e(0.1 h normal) <= 0.1", QN_CLEAN, NAN, -1, INPUT, 1, 0.1},
        };
        for (size_t t = 0; t < sizeof th / sizeof th[0]; t++) {
            double med, worst;
            int n = versus(th[t].k, th[t].rho, th[t].cls, q_default, th[t].peer, &med, &worst);
            double x = th[t].worst ? worst : med;
            const char *holds = n == 0 ? "not measured" : x <= th[t].limit ? "yes" : "NO";
            fprintf(md, "| %s | %s | %s |\n", th[t].what, n ? mw(b[0], sizeof b[0], med, worst) : "-", holds);
            printf("  %-55s %-16s %s\n", th[t].what, n ? mw(b[0], sizeof b[0], med, worst) : "-", holds);
        }
        /* CAD parts against the BNF oracle, every model pooled */
        {
            double *v = malloc(sizeof(double) * (size_t)g_ncase + 1), med, worst;
            int n = 0;
            for (int c = 0; c < g_ncase && q_bnf >= 0; c++)
                if (g_cad[g_case[c].mesh] && g_case[c].model != QN_CLEAN && RES(c, q_bnf)->ok)
                    v[n++] = RES(c, q_default)->ok ? RES(c, q_default)->ratio / RES(c, q_bnf)->ratio : INFINITY;
            med = median_max(v, n, &worst);
            free(v);
            const char *holds = n == 0 ? "not measured" : med <= 1.0 && worst <= 1.4 ? "yes" : "NO";
            fprintf(md, "| CAD parts, every model: default / bnf_best median <= 1.0, worst <= 1.4 | %s | %s |\n",
                    n ? mw(b[0], sizeof b[0], med, worst) : "-", holds);
            printf("  %-55s %-16s %s\n", "CAD, every model: / bnf_best median <= 1.0, worst <= 1.4",
                   n ? mw(b[0], sizeof b[0], med, worst) : "-", holds);
        }
        /* quantization 0.5 h: no more flips than the input, case by case */
        {
            long fi, fo;
            int up, n = 0;
            for (int c = 0; c < g_ncase; c++)
                n += g_case[c].model == QN_QUANT && g_case[c].rho == 0.5;
            flips(QN_QUANT, 0.5, -1, q_default, &fi, &fo, &up);
            char fl[64];
            snprintf(fl, sizeof fl, "%ld -> %ld, %d of %d cases up", fi, fo, up, n);
            const char *holds = n == 0 ? "not measured" : up == 0 ? "yes" : "NO";
            fprintf(md, "| quant 0.5 h: no case with more flips than its input | %s | %s |\n", n ? fl : "-", holds);
            printf("  %-55s %-16s %s\n", "quant 0.5 h: no case with more flips than its input", n ? fl : "-", holds);
        }
        {
            double cp[2], *v = malloc(sizeof(double) * (size_t)g_ncase + 1);
            int n = 0;
            for (int c = 0; c < g_ncase; c++)
                if (RES(c, q_default)->ok && RES(c, q_default)->base_cpu > 0)
                    v[n++] = RES(c, q_default)->cpu / RES(c, q_default)->base_cpu;
            cp[0] = median_max(v, n, &cp[1]);
            /* the machine then and now: taubin_best's final run does the
             * same passes on the same input in both runs */
            int nt = 0;
            double mx, fac = NAN;
            for (int c = 0; c < g_ncase && q_tb >= 0; c++)
                if (RES(c, q_tb)->ok && RES(c, q_tb)->base_cpu > 0 && RES(c, q_tb)->cpu > 0)
                    v[nt++] = RES(c, q_tb)->cpu / RES(c, q_tb)->base_cpu;
            fac = nt ? median_max(v, nt, &mx) : NAN;
            free(v);
            const char *holds = n == 0 ? "not measured" : cp[0] <= 1.5 ? "yes (median)" : "NO (median)";
            char fs[96] = "";
            if (nt)
                snprintf(fs, sizeof fs, "; %.2f over the machine factor %.2f (taubin_best now / then, median)",
                         cp[0] / fac, fac);
            fprintf(md, "| CPU <= 1.5x the baseline's default, same cases | %s over %d cases%s | %s |\n",
                    n ? mw(b[0], sizeof b[0], cp[0], cp[1]) : "-", n, fs, holds);
            printf("  %-55s %-16s %s%s\n", "CPU <= 1.5x the baseline's default (median over cases)",
                   n ? mw(b[0], sizeof b[0], cp[0], cp[1]) : "-", holds, fs);
        }
    }

    /* per model: levels x classes for the default */
    for (int k = 0; k < nk; k++) {
        qn_model mdl = models[k];
        if (mdl == QN_CLEAN || q_default < 0)
            continue;
        fprintf(md, "\n## %s: the default request by level and class\n\n| rho | class | cases | default / input | "
                    "/ taubin_best | / o3d_best | / bnf_best | flips input -> default | read / rho | CPU / baseline |\n"
                    "|---|---|---|---|---|---|---|---|---|---|\n", qn_name(mdl));
        for (int j = 0; j <= nr; j++)
            for (int cls = -1; cls <= 1; cls++) {
                double rr = j < nr ? rho[j] : NAN, v[4][2], rd[2], cp[2];
                long fi, fo;
                int up;
                int n = versus(mdl, rr, cls, q_default, INPUT, &v[0][0], &v[0][1]);
                if (n == 0)
                    continue;
                versus(mdl, rr, cls, q_default, q_tb, &v[1][0], &v[1][1]);
                versus(mdl, rr, cls, q_default, q_ob, &v[2][0], &v[2][1]);
                versus(mdl, rr, cls, q_default, q_bnf, &v[3][0], &v[3][1]);
                flips(mdl, rr, cls, q_default, &fi, &fo, &up);
                reading_cpu(mdl, rr, cls, q_default, rd, cp);
                for (int x = 0; x < 4; x++)
                    mw(b[x], sizeof b[x], v[x][0], v[x][1]);
                fprintf(md, "| %s | %s | %d | %s | %s | %s | %s | %ld -> %ld (%d up) | %s | %s |\n",
                        j < nr ? ntext[j] : "all", cls_name[cls + 1], n, b[0], b[1], b[2], b[3], fi, fo, up,
                        mw(b[4], sizeof b[4], rd[0], rd[1]), mw(b[5], sizeof b[5], cp[0], cp[1]));
            }
    }

    /* every method, per model */
    fprintf(md, "\n## Every method per noise model (all levels and meshes)\n\n| noise | method | / input | / taubin_best "
                "| / o3d_best | / bnf_best | flips input -> method | > input | CPU s (median) |\n"
                "|---|---|---|---|---|---|---|---|---|\n");
    for (int k = 0; k < nk; k++)
        for (int q = 0; q < nmeth; q++) {
            qn_model mdl = models[k];
            double v[4][2];
            long fi, fo;
            int up, worse = 0, n = versus(mdl, NAN, -1, q, INPUT, &v[0][0], &v[0][1]);
            if (n == 0)
                continue;
            versus(mdl, NAN, -1, q, q_tb, &v[1][0], &v[1][1]);
            versus(mdl, NAN, -1, q, q_ob, &v[2][0], &v[2][1]);
            versus(mdl, NAN, -1, q, q_bnf, &v[3][0], &v[3][1]);
            flips(mdl, NAN, -1, q, &fi, &fo, &up);
            double *cv = malloc(sizeof(double) * (size_t)g_ncase + 1), cmx;
            int ncv = 0;
            for (int c = 0; c < g_ncase; c++)
                if (match(c, mdl, NAN, -1) && RES(c, q)->ok) {
                    cv[ncv++] = RES(c, q)->cpu;
                    worse += mdl != QN_CLEAN && RES(c, q)->ratio > 1.0;
                }
            double cmed = median_max(cv, ncv, &cmx);
            free(cv);
            for (int x = 0; x < 4; x++)
                mw(b[x], sizeof b[x], v[x][0], v[x][1]);
            fprintf(md, "| %s | %s | %s | %s | %s | %s | %ld -> %ld (%d up) | %d of %d | %.3f |\n", qn_name(mdl),
                    meth[q].name, b[0], b[1], b[2], b[3], fi, fo, up, worse, n, cmed);
        }

    /* every case */
    fprintf(md, "\n## Every case (vertex error / input's; the default's surface error in brackets)\n\n"
                "| mesh | model | rho | seed | default | taubin_best | o3d_best | bnf_best | flips input / "
                "default / bnf | default read (h) | bnf_best parameters |\n|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (int c = 0; c < g_ncase; c++) {
        const qcase *x = &g_case[c];
        int qs[4] = {q_default, q_tb, q_ob, q_bnf};
        fprintf(md, "| %s | %s | %g | %d |", names[x->mesh], qn_name(x->model), x->rho, x->seed);
        for (int i = 0; i < 4; i++) {
            const result *r = qs[i] >= 0 ? RES(c, qs[i]) : NULL;
            if (!r || r->skipped)
                fprintf(md, " - |");
            else if (!r->ok)
                fprintf(md, " failed |");
            else if (i == 0)
                fprintf(md, " %.3f (%.3f) |", r->ratio, r->sratio);
            else
                fprintf(md, " %.3f |", r->ratio);
        }
        const result *d = q_default >= 0 ? RES(c, q_default) : NULL, *bn = q_bnf >= 0 ? RES(c, q_bnf) : NULL;
        fprintf(md, " %d / %d / %d | %.3g | %s |\n", x->flips0, d && d->ok ? d->flips : -1,
                bn && bn->ok ? bn->flips : -1, d ? d->reading : NAN, bn && bn->ok ? bn->note : "-");
    }
    fclose(md);

    /* ---- renders: the worst case per model, and those asked for */
    int nrc = 0, rcase[QN_COUNT + MAXRENDER];
    char rstem[QN_COUNT + MAXRENDER][64];
    if (do_figure)
        for (int k = 0; k < QN_COUNT; k++)
            if (worst_case[k] >= 0) {
                snprintf(rstem[nrc], sizeof rstem[0], "worst-%s", qn_name((qn_model)k));
                rcase[nrc++] = worst_case[k];
            }
    /* --render MESH:MODEL:RHO[:SEED]: those not among the run's cases become new ones (no results) */
    qcase extra[MAXRENDER];
    for (int i = 0; i < nrender; i++) {
        char spec[256], *p[4];
        int n = 0;
        snprintf(spec, sizeof spec, "%s", render_spec[i]);
        for (char *t = strtok(spec, ":"); t && n < 4; t = strtok(NULL, ":"))
            p[n++] = t;
        int mk = n >= 3 ? qn_parse(p[1]) : -1, mesh = -1;
        for (int m = 0; m < nm; m++)
            if (n >= 1 && !strcmp(names[m], p[0]))
                mesh = m;
        if (mk < 0 || mesh < 0) {
            printf("render: %s: want MESH:MODEL:RHO[:SEED] with MESH in --list\n", render_spec[i]);
            continue;
        }
        extra[i] = (qcase){mesh, (qn_model)mk, mk == QN_CLEAN ? 0.0 : atof(p[2]), n == 4 ? atoi(p[3]) : 1, 0, 0, 0, 0};
        snprintf(rstem[nrc], sizeof rstem[0], "case-%d", i + 1);
        rcase[nrc++] = -1 - i;
    }
    for (int i = 0; i < nrc; i++) {
        const qcase *x = rcase[i] >= 0 ? &g_case[rcase[i]] : &extra[-1 - rcase[i]];
        mcf_error e = {0};
        mcf_mesh *clean = bench_load_mesh(PROG, meshes, names[x->mesh]);
        mcf_mesh_info ci, ni;
        int ncrease;
        unsigned char *crease = qg_crease_mask(clean, &ncrease);
        unsigned char *movable = malloc((size_t)mcf_mesh_nvertices(clean) + 1);
        if (!movable || qn_moved(clean, movable, &e) < 0)
            die("qn_moved", &e);
        qg_grid gclean;
        qg_grid_build(&gclean, clean);
        mcf_mesh *noisy = noisy_or_die(clean, x->model, x->rho, x->seed, NULL);
        mcf_mesh *ref = x->model == QN_CLEAN ? noisy_or_die(clean, QN_NORMAL, 0.1, x->seed, NULL) : NULL;
        mcf_compare_result c0;
        mcf_mesh_inspect(clean, &ci, &e);
        mcf_mesh_inspect(noisy, &ni, &e);
        mcf_compare(ref ? ref : noisy, clean, &c0, &e);
        case_ctx c = {clean, noisy, &gclean, c0.rms_m, qg_surface_error(ref ? ref : noisy, clean, &gclean), crease,
                      movable, qg_inverted_off_crease(noisy, clean, crease),
                      ci.boundary_edges == 0 ? ci.volume : ci.area, ci.boundary_edges == 0,
                      ni.mean_edge / sqrt(ni.area)};
        const mcf_mesh *ms[5] = {clean, ref ? ref : noisy};
        char lb[5][128];
        const char *labels[5] = {"clean", lb[1]};
        snprintf(lb[1], sizeof lb[1], x->model == QN_CLEAN ? "(normal 0.1 h, for scale): flips %d"
                                                           : "noisy: flips %d", qg_flips(ref ? ref : noisy, clean));
        mcf_mesh *res[3] = {0};
        result r[3];
        memset(r, 0, sizeof r);
        int n = 2;
        method dm = {"default", K_DEFAULT, ""};
        run_request(&c, &dm, &r[0], &res[0]);
        if (x->model != QN_CLEAN) {
            run_taubin_best(&c, &r[1], &res[1]);
            run_bnf_best(&c, &r[2], &res[2]);
        }
        static const char *const what[3] = {"default", "taubin_best", "bnf_best"};
        for (int q = 0; q < 3; q++)
            if (res[q]) {
                snprintf(lb[n], sizeof lb[n], "%s: %.2f of the input, flips %d", what[q], r[q].ratio, r[q].flips);
                labels[n] = lb[n];
                ms[n++] = res[q];
            }
        if (x->model == QN_CLEAN)
            snprintf(lb[2], sizeof lb[2], "default: moved %.3f x e(0.1 h), flips %d", r[0].ratio, r[0].flips);
        char title[256];
        snprintf(title, sizeof title, "%s, %s noise %g h, seed %d", names[x->mesh], qn_name(x->model), x->rho, x->seed);
        render(render_script, out, rstem[i], title, ms, labels, n);
        for (int q = 0; q < 3; q++)
            mcf_mesh_free(res[q]);
        mcf_mesh_free(ref);
        mcf_mesh_free(noisy);
        qg_grid_free(&gclean);
        free(crease);
        free(movable);
        mcf_mesh_free(clean);
    }

    o3d_stop();
    char p1[300], p2[300], p3[300];
    snprintf(p1, sizeof p1, "%s/noisy.bin", g_tmp);
    snprintf(p2, sizeof p2, "%s/clean.bin", g_tmp);
    snprintf(p3, sizeof p3, "%s/out.bin", g_tmp);
    remove(p1);
    remove(p2);
    remove(p3);
    rmdir(g_tmp);
    printf("\nCSV: %s/quality.csv, tables: %s/quality.md; run time %.0f s\n", out, out, mcf_now() - t_start);
    free(g_res);
    free(g_case);
    free(g_base);
    return 0;
}
