/*
 * bench_quality.c - `make quality` (issue 12, section 5): how much closer
 * to the clean surface a noisy scan comes back.
 *
 * For every mesh x noise level (rho = 0.1, 0.25, 0.5 mean edges, Gaussian
 * along the normals by mcf_mesh_add_noise) x seed (1, 2, 3), the error of
 * a result is the area-weighted RMS distance to the clean mesh (mcf_compare
 * rms_m, same connectivity), reported as a ratio against the noisy input's
 * error (< 1: better than the input). Four smoothers:
 *
 *   default  api_params_init + api_params_finish with nothing set, then
 *            mcf_flow_run: whatever the service's defaults are when this
 *            runs (the request `curl -F mesh=@scan /smooth` makes).
 *   auto     the same with api_params_set(p, "strength", "auto"); the
 *            column is skipped (said once) when the key is refused.
 *   oracle   desbrun2, 10 steps, at the best total time t = c h^2 (h: the
 *            noisy input's mean edge after normalization to unit area,
 *            i.e. mean_edge / sqrt(area)), c on the grid 0.02, 0.05, 0.1,
 *            0.2, 0.3, 0.5, 1, 2, 5: 0.1 .. 0.5 always (--oracle-grid
 *            full: 0.05 .. 1), then the neighbours of the minimum until it
 *            is bracketed, then one parabola step in log c. Each point is
 *            its own 10-step run (dt differs, so no factorization is
 *            shared between points).
 *   taubin   scheme taubin (lambda 0.5, mu -0.53) at its best pass count:
 *            passes are applied cumulatively (1, 2, ..., 500 on a growing
 *            schedule, stopped once the error is 5% past its minimum at
 *            twice the best count), then the best count is run again in
 *            one call for its metrics and wall time.
 *
 * For each result: folds beyond the input's (mcf_compare inverted_faces
 * against the clean mesh, minus the noisy input's; also counted away from
 * the clean mesh's own creases, see crease_mask), drift (volume on
 * closed meshes, area on open ones, relative to the clean mesh's; the
 * noisy input's drift is in the CSV too), the largest vertex displacement
 * from the input in (clean) mean edges, and wall time of the one run.
 *
 * Output: docs/quality/quality.csv (one row per case x method),
 * docs/quality/oracle-sweep.csv (every oracle point), a table of medians
 * over seeds on stdout, the goals as PASS/FAIL lines (and the same
 * checks for the other methods as a reference), an oracle summary
 * (--oracle-out, rewritten after every mesh), and two figures (clean /
 * noisy / smoothed renders of one case, whole and zoomed: gnuplot `with
 * polygons` and pm3d lighting) in docs/quality/.
 *
 * Run single-threaded (bench/Makefile sets OPENBLAS_NUM_THREADS=1
 * OMP_THREAD_LIMIT=1). Exit status 1 on an error; a FAIL goal is a result.
 */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "api.h"
#include "bench_common.h"
#include "mcf.h"

#define PROG "bench_quality"
#define MAXMESH 16
#define MAXNOISE 4
#define MAXSEED 5
#define NGRID 9

enum { M_DEFAULT, M_AUTO, M_ORACLE, M_TAUBIN, NMETHOD };
static const char *const method_names[NMETHOD] = {"default", "auto", "oracle", "taubin"};

/* The oracle grid in units of h^2; 0.1 .. 1 always evaluated. */
static const double g_grid[NGRID] = {0.02, 0.05, 0.1, 0.2, 0.3, 0.5, 1.0, 2.0, 5.0};
/* Columns of the oracle summary: ratio at these c. */
static const double g_report_c[5] = {0.1, 0.2, 0.3, 0.5, 1.0};

/* Taubin pass counts evaluated (cumulative). */
static const int g_passes[] = {1, 2, 3, 4, 5, 6, 8, 10, 12, 15, 20, 25, 30, 40, 50, 60,
                               80, 100, 120, 150, 200, 250, 300, 400, 500};
#define NPASSES ((int)(sizeof g_passes / sizeof g_passes[0]))

typedef struct {
    int ok;              /* the run succeeded */
    double ratio;        /* rms_m(result, clean) / rms_m(noisy, clean) */
    int folds;           /* inverted vs clean, minus the input's */
    int folds_off;       /* the same away from the clean mesh's creases */
    double drift;        /* (V or A result - clean) / clean */
    double maxdisp;      /* max |result - noisy| / clean mean edge */
    double wall;         /* seconds, the one run */
    double param;        /* oracle: c; taubin: passes; default/auto: t/h^2 */
    char note[320];      /* failure text */
} result;

typedef struct {
    const mcf_mesh *clean, *noisy;
    double e0;           /* rms_m(noisy, clean) */
    int fold0;
    const unsigned char *crease; /* per face: at a crease of the clean mesh */
    int fold0_off;       /* the input's inverted faces away from creases */
    double ref_size;     /* clean volume (closed) or area (open) */
    int closed;
    double edge;         /* clean mean edge, input units */
    double h;            /* noisy mean edge / sqrt(noisy area) */
} case_ctx;

/* ------------------------------------------------------------ helpers */

static void die(const char *what, const mcf_error *e)
{
    fprintf(stderr, PROG ": %s: %s\n", what, e ? e->msg : "failed");
    exit(1);
}

static int mkdir_p(const char *dir)
{
    char tmp[4096];
    snprintf(tmp, sizeof tmp, "%s", dir);
    for (char *p = tmp + 1; *p; p++)
        if (*p == '/') {
            *p = 0;
            if (mkdir(tmp, 0777) != 0 && errno != EEXIST)
                return -1;
            *p = '/';
        }
    return mkdir(tmp, 0777) != 0 && errno != EEXIST ? -1 : 0;
}

static FILE *open_out(const char *dir, const char *name)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "w");
    if (!f) {
        fprintf(stderr, PROG ": cannot write %s: %s\n", path, strerror(errno));
        exit(1);
    }
    return f;
}

/* Runs gnuplot on dir/script (in dir). Returns 0 when it succeeded. */
static int gnuplot(const char *dir, const char *script)
{
    fflush(stdout);
    pid_t pid = fork();
    if (pid < 0)
        return -1;
    if (pid == 0) {
        if (chdir(dir) != 0)
            _exit(127);
        execlp("gnuplot", "gnuplot", script, (char *)NULL);
        _exit(127);
    }
    int status = 0;
    if (waitpid(pid, &status, 0) < 0)
        return -1;
    return WIFEXITED(status) && WEXITSTATUS(status) == 0 ? 0 : -1;
}

/* v printed into b (16 bytes) with digits as %.*f, or %.*g when g; "-"
 * when NaN. */
static const char *fmt(char b[16], int digits, int g, double v)
{
    if (isnan(v))
        snprintf(b, 16, "-");
    else if (g)
        snprintf(b, 16, "%.*g", digits, v);
    else
        snprintf(b, 16, "%.*f", digits, v);
    return b;
}

static double median_of(const double *v, int n)
{
    double tmp[64];
    int k = 0;
    for (int i = 0; i < n && k < 64; i++)
        if (!isnan(v[i]))
            tmp[k++] = v[i];
    return k ? bench_median(tmp, k) : NAN;
}

static double max_of(const double *v, int n)
{
    double m = -INFINITY;
    for (int i = 0; i < n; i++)
        m = isnan(v[i]) ? INFINITY : (v[i] > m ? v[i] : m);
    return m;
}

/* The clean mesh's own near-reversals: mask[f] = 1 when face f shares an
 * edge with a face whose normal is turned by more than 120 degrees from
 * its own, or has an edge with more than two faces. Models like snowden
 * (thin fins, fold-overs) and the crudely decimated dragon have thousands;
 * any smoothing flattens them, which turns such faces by over 90 degrees
 * against the clean normals, so the folds there are counted apart. */
typedef struct {
    int a, b, f;
} edge_ref;

static int cmp_edge(const void *x, const void *y)
{
    const edge_ref *p = x, *q = y;
    return p->a != q->a ? (p->a > q->a) - (p->a < q->a) : (p->b > q->b) - (p->b < q->b);
}

static void face_normal(const double *X, const int32_t *t, double n[3])
{
    const double *p = X + 3 * (size_t)t[0], *q = X + 3 * (size_t)t[1], *r = X + 3 * (size_t)t[2];
    double u[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]}, v[3] = {r[0] - p[0], r[1] - p[1], r[2] - p[2]};
    n[0] = u[1] * v[2] - u[2] * v[1];
    n[1] = u[2] * v[0] - u[0] * v[2];
    n[2] = u[0] * v[1] - u[1] * v[0];
}

static unsigned char *crease_mask(const mcf_mesh *m, int *count)
{
    int nf = mcf_mesh_nfaces(m);
    const int32_t *F = mcf_mesh_faces(m);
    const double *X = mcf_mesh_positions(m);
    edge_ref *E = malloc(3 * (size_t)nf * sizeof *E);
    unsigned char *mask = calloc((size_t)nf, 1);
    if (!E || !mask) {
        fprintf(stderr, PROG ": out of memory\n");
        exit(1);
    }
    for (int f = 0; f < nf; f++)
        for (int k = 0; k < 3; k++) {
            int a = F[3 * f + k], b = F[3 * f + (k + 1) % 3];
            E[3 * f + k] = (edge_ref){a < b ? a : b, a < b ? b : a, f};
        }
    qsort(E, 3 * (size_t)nf, sizeof *E, cmp_edge);
    for (size_t i = 0, j; i < 3 * (size_t)nf; i = j) {
        for (j = i + 1; j < 3 * (size_t)nf && E[j].a == E[i].a && E[j].b == E[i].b; j++)
            ;
        if (j - i > 2)
            for (size_t k = i; k < j; k++)
                mask[E[k].f] = 1;
        else if (j - i == 2) {
            double n1[3], n2[3];
            face_normal(X, F + 3 * E[i].f, n1);
            face_normal(X, F + 3 * E[i + 1].f, n2);
            double d = n1[0] * n2[0] + n1[1] * n2[1] + n1[2] * n2[2];
            double l = sqrt((n1[0] * n1[0] + n1[1] * n1[1] + n1[2] * n1[2]) *
                            (n2[0] * n2[0] + n2[1] * n2[1] + n2[2] * n2[2]));
            if (l > 0 && d < -0.5 * l)
                mask[E[i].f] = mask[E[i + 1].f] = 1;
        }
    }
    free(E);
    *count = 0;
    for (int f = 0; f < nf; f++)
        *count += mask[f];
    return mask;
}

/* Faces of x inverted against target (normals more than 90 degrees apart,
 * as mcf_compare counts them) that are not in the crease mask. */
static int inverted_off_crease(const mcf_mesh *x, const mcf_mesh *target, const unsigned char *mask)
{
    int nf = mcf_mesh_nfaces(x), n = 0;
    const int32_t *F = mcf_mesh_faces(x);
    for (int f = 0; f < nf; f++) {
        double a[3], b[3];
        if (mask[f])
            continue;
        face_normal(mcf_mesh_positions(x), F + 3 * f, a);
        face_normal(mcf_mesh_positions(target), F + 3 * f, b);
        double la = a[0] * a[0] + a[1] * a[1] + a[2] * a[2], lb = b[0] * b[0] + b[1] * b[1] + b[2] * b[2];
        if (la > 0 && lb > 0 && a[0] * b[0] + a[1] * b[1] + a[2] * b[2] < 0)
            n++;
    }
    return n;
}

/* Fills r's error metrics for result m (a smoothed copy of c->noisy). */
static void measure(const case_ctx *c, const mcf_mesh *m, result *r)
{
    mcf_compare_result a, d;
    mcf_error e = {0};
    if (mcf_compare(m, c->clean, &a, &e) != MCF_OK || mcf_compare(m, c->noisy, &d, &e) != MCF_OK)
        die("mcf_compare", &e);
    r->ratio = a.rms_m / c->e0;
    r->folds = a.inverted_faces - c->fold0;
    r->folds_off = inverted_off_crease(m, c->clean, c->crease) - c->fold0_off;
    double s = c->closed ? mcf_mesh_volume(m) : mcf_mesh_area(m);
    r->drift = (s - c->ref_size) / fabs(c->ref_size);
    r->maxdisp = d.max_err / c->edge;
}

static void failed(result *r, const char *what, const mcf_error *e)
{
    r->ok = 0;
    r->ratio = NAN;
    r->drift = NAN;
    r->maxdisp = NAN;
    r->folds = -1;
    r->folds_off = -1;
    snprintf(r->note, sizeof r->note, "%s: %s", what, e->msg);
    for (char *q = r->note; *q; q++)
        if (*q == '"')
            *q = '\''; /* the CSV quotes the note */
}

/* One request through the api layer's parameters: nothing set (default)
 * or strength=auto. *out (may be NULL) receives the result mesh. */
static void run_request(const case_ctx *c, int with_auto, result *r, mcf_mesh **out)
{
    api_limits lim;
    api_params p;
    mcf_error e = {0};
    mcf_flow_stats st;
    mcf_mesh *m = bench_dup_mesh(PROG, c->noisy);

    memset(r, 0, sizeof *r);
    memset(&st, 0, sizeof st);
    api_limits_default(&lim);
    api_params_init(&p);
    if (with_auto && api_params_set(&p, "strength", "auto", &lim, &e) != MCF_OK) {
        failed(r, "strength=auto", &e);
        goto done;
    }
    double t0 = mcf_now();
    if (api_params_finish(&p, mcf_mesh_nvertices(m), &lim, &e) != MCF_OK) {
        failed(r, "api_params_finish", &e);
        goto done;
    }
    if (mcf_flow_run(m, &p.flow, &st, &e) != MCF_OK) {
        r->wall = mcf_now() - t0;
        failed(r, "mcf_flow_run", &e);
        goto done;
    }
    r->wall = mcf_now() - t0;
    r->ok = 1;
    r->param = st.t_final / (c->h * c->h);
    measure(c, m, r);
done:
    mcf_flow_stats_free(&st);
    api_params_free(&p);
    if (out && r->ok)
        *out = m;
    else
        mcf_mesh_free(m);
}

/* desbrun2, 10 steps to total time c h^2. */
static void run_oracle_point(const case_ctx *c, double cc, result *r, mcf_mesh **out)
{
    mcf_flow_params p;
    mcf_error e = {0};
    mcf_mesh *m = bench_dup_mesh(PROG, c->noisy);

    memset(r, 0, sizeof *r);
    mcf_flow_params_init(&p);
    p.scheme = MCF_DESBRUN2;
    p.iterations = 10;
    p.time = 0.0;
    p.dt = cc * c->h * c->h / 10.0;
    double t0 = mcf_now();
    mcf_status s = mcf_flow_run(m, &p, NULL, &e);
    r->wall = mcf_now() - t0;
    r->param = cc;
    if (s != MCF_OK)
        failed(r, "desbrun2", &e);
    else {
        r->ok = 1;
        measure(c, m, r);
    }
    if (out && r->ok)
        *out = m;
    else
        mcf_mesh_free(m);
}

/* 1: every grid point from 0.05 to 1 (the oracle summary's columns);
 * 0: 0.1 .. 0.5 and what bracketing the minimum needs (--oracle-grid). */
static int g_full_grid = 0;

static int better(const result *a, const result *b)
{
    return a->ok && (!b->ok || a->ratio < b->ratio);
}

/* The oracle sweep; every point goes to sweep_csv. Returns the best. */
static void run_oracle(const case_ctx *c, FILE *sweep_csv, const char *label, double rho,
                       int seed, result *best, result at_report[5], mcf_mesh **out)
{
    result pts[NGRID + 1];
    int done[NGRID] = {0}, ib = -1;
    for (int i = 0; i < 5; i++)
        at_report[i].ok = 0;
    /* the required points first (g_full_grid: 0.05 .. 1, else 0.1 .. 0.5),
     * then the neighbours of the minimum until it is bracketed */
    for (int i = g_full_grid ? 1 : 2; i <= (g_full_grid ? 6 : 5); i++) {
        run_oracle_point(c, g_grid[i], &pts[i], NULL);
        done[i] = 1;
        if (ib < 0 || better(&pts[i], &pts[ib]))
            ib = i;
    }
    for (;;) {
        int next = ib > 0 && !done[ib - 1] ? ib - 1 : ib < NGRID - 1 && !done[ib + 1] ? ib + 1 : -1;
        if (next < 0)
            break;
        run_oracle_point(c, g_grid[next], &pts[next], NULL);
        done[next] = 1;
        if (better(&pts[next], &pts[ib]))
            ib = next;
    }
    for (int i = 0; i < NGRID; i++) {
        if (!done[i])
            continue;
        for (int k = 0; k < 5; k++)
            if (g_grid[i] == g_report_c[k])
                at_report[k] = pts[i];
        fprintf(sweep_csv, "%s,%g,%d,%.6g,%d,%.6g,%d,%.6g,%.4g,%.4f\n", label, rho, seed, g_grid[i],
                pts[i].ok, pts[i].ratio, pts[i].folds, pts[i].drift, pts[i].maxdisp, pts[i].wall);
    }
    *best = pts[ib];
    /* one parabola step in log c through the best and its neighbours */
    if (ib > 0 && ib < NGRID - 1 && done[ib - 1] && done[ib + 1] && pts[ib - 1].ok &&
        pts[ib + 1].ok && pts[ib].ok) {
        double x0 = log(g_grid[ib - 1]), x1 = log(g_grid[ib]), x2 = log(g_grid[ib + 1]);
        double y0 = pts[ib - 1].ratio, y1 = pts[ib].ratio, y2 = pts[ib + 1].ratio;
        double num = (x1 - x0) * (x1 - x0) * (y1 - y2) - (x1 - x2) * (x1 - x2) * (y1 - y0);
        double den = (x1 - x0) * (y1 - y2) - (x1 - x2) * (y1 - y0);
        if (den != 0.0) {
            double xv = x1 - 0.5 * num / den;
            if (xv > x0 && xv < x2 && fabs(xv - x1) > 0.02) {
                result r;
                run_oracle_point(c, exp(xv), &r, NULL);
                fprintf(sweep_csv, "%s,%g,%d,%.6g,%d,%.6g,%d,%.6g,%.4g,%.4f\n", label, rho, seed,
                        exp(xv), r.ok, r.ratio, r.folds, r.drift, r.maxdisp, r.wall);
                if (better(&r, best))
                    *best = r;
            }
        }
    }
    if (out)
        run_oracle_point(c, best->param, best, out);
}

/* Taubin at its best pass count (see the file comment). */
static void run_taubin(const case_ctx *c, result *best, mcf_mesh **out)
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
        result r;
        measure(c, m, &r);
        if (r.ratio < bestr) {
            bestr = r.ratio;
            bestp = have;
        }
        if ((r.ratio > 1.05 * bestr && have >= 2 * bestp) || r.ratio > 1.5 * bestr)
            break;
    }
    mcf_mesh_free(m);
    memset(best, 0, sizeof *best);
    if (bestp == 0) {
        failed(best, "taubin", &e);
        return;
    }
    m = bench_dup_mesh(PROG, c->noisy);
    p.iterations = bestp;
    double t0 = mcf_now();
    mcf_status s = mcf_flow_run(m, &p, NULL, &e);
    best->wall = mcf_now() - t0;
    best->param = bestp;
    if (s != MCF_OK)
        failed(best, "taubin", &e);
    else {
        best->ok = 1;
        measure(c, m, best);
    }
    if (out && best->ok)
        *out = m;
    else
        mcf_mesh_free(m);
}

/* ------------------------------------------------------------ figure */

/* Writes the triangles of m (those whose centroid passes the crop box,
 * when crop) as gnuplot polygon blocks with a Lambert grey per face from a
 * fixed light, in the view frame given by the rotation R (3x3 row-major). */
static void write_tris(const char *dir, const char *name, const mcf_mesh *m, const double R[9],
                       const double *crop)
{
    FILE *f = open_out(dir, name);
    const double *X = mcf_mesh_positions(m);
    const int32_t *F = mcf_mesh_faces(m);
    int nf = mcf_mesh_nfaces(m);
    const double L[3] = {0.35, 0.45, 0.82}; /* view frame: toward the viewer, up-right */
    fprintf(f, "# %s: one triangle per block, x y z rgb (view frame)\n", name);
    for (int t = 0; t < nf; t++) {
        double P[3][3];
        for (int k = 0; k < 3; k++) {
            const double *x = X + 3 * (size_t)F[3 * t + k];
            for (int r = 0; r < 3; r++)
                P[k][r] = R[3 * r] * x[0] + R[3 * r + 1] * x[1] + R[3 * r + 2] * x[2];
        }
        if (crop) {
            double cx = (P[0][0] + P[1][0] + P[2][0]) / 3, cy = (P[0][1] + P[1][1] + P[2][1]) / 3;
            if (cx < crop[0] || cx > crop[1] || cy < crop[2] || cy > crop[3])
                continue;
        }
        double u[3], v[3], n[3];
        for (int r = 0; r < 3; r++) {
            u[r] = P[1][r] - P[0][r];
            v[r] = P[2][r] - P[0][r];
        }
        n[0] = u[1] * v[2] - u[2] * v[1];
        n[1] = u[2] * v[0] - u[0] * v[2];
        n[2] = u[0] * v[1] - u[1] * v[0];
        double nn = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (nn == 0)
            continue;
        double lam = (n[0] * L[0] + n[1] * L[1] + n[2] * L[2]) / nn;
        /* two-sided, a little ambient so back faces are not black */
        double g = 0.12 + 0.88 * fabs(lam);
        if (n[2] < 0)
            g *= 0.75; /* back-facing: darker */
        int gi = (int)(255 * g);
        int rgb = (gi * 235 / 255) << 16 | (gi * 225 / 255) << 8 | (gi * 205 / 255);
        for (int k = 0; k < 3; k++)
            fprintf(f, "%.6g %.6g %.6g %d\n", P[k][0], P[k][1], P[k][2], rgb);
        fprintf(f, "\n");
    }
    fclose(f);
}

typedef struct {
    const char *mesh;
    double rho;
    int seed;
    double view_rot_y; /* degrees about the vertical axis */
    double crop[4];    /* fraction of the bounding box in the view frame: x0 x1 y0 y1 */
} figure_spec;

/* A view rotation: about x by ax degrees (y up -> the mesh's up axis),
 * then about the vertical axis by ay degrees. */
static void view_matrix(double ax, double ay, double R[9])
{
    const double deg = 3.14159265358979323846 / 180;
    double a = ax * deg, b = ay * deg;
    double Rx[9] = {1, 0, 0, 0, cos(a), -sin(a), 0, sin(a), cos(a)};
    double Ry[9] = {cos(b), 0, sin(b), 0, 1, 0, -sin(b), 0, cos(b)};
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double s = 0;
            for (int k = 0; k < 3; k++)
                s += Ry[3 * i + k] * Rx[3 * k + j];
            R[3 * i + j] = s;
        }
}

static void figure(const char *out, const char *stem, const figure_spec *fs,
                   const mcf_mesh *const ms[], const char *const titles[], int n)
{
    double R[9], lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY}, crop[4];
    view_matrix(0, fs->view_rot_y, R);
    const double *X = mcf_mesh_positions(ms[0]);
    for (int i = 0; i < mcf_mesh_nvertices(ms[0]); i++)
        for (int r = 0; r < 2; r++) {
            double y = R[3 * r] * X[3 * i] + R[3 * r + 1] * X[3 * i + 1] + R[3 * r + 2] * X[3 * i + 2];
            lo[r] = y < lo[r] ? y : lo[r];
            hi[r] = y > hi[r] ? y : hi[r];
        }
    crop[0] = lo[0] + fs->crop[0] * (hi[0] - lo[0]);
    crop[1] = lo[0] + fs->crop[1] * (hi[0] - lo[0]);
    crop[2] = lo[1] + fs->crop[2] * (hi[1] - lo[1]);
    crop[3] = lo[1] + fs->crop[3] * (hi[1] - lo[1]);
    char gp[256], png[256];
    int rows = n > 3 ? 2 : 1, cols = (n + rows - 1) / rows;
    double aspect = (crop[3] - crop[2]) / (crop[1] - crop[0]);
    snprintf(gp, sizeof gp, "%s.gp", stem);
    snprintf(png, sizeof png, "%s.png", stem);
    FILE *g = open_out(out, gp);
    fprintf(g, "# bench_quality: clean / noisy / smoothed renders of %s at noise %g (seed %d)\n"
               "# run in this folder: gnuplot %s (needs the render-*.dat files bench_quality\n"
               "# writes and removes; rerun bench_quality to regenerate)\n"
               "set terminal pngcairo size %d,%d font 'sans,11'\n"
               "set output '%s'\n"
               "set multiplot layout %d,%d title '%s, noise %g mean edges (seed %d): clean, noisy, smoothed "
               "(error / noisy error)' noenhanced\n"
               "set view 0,0,1.4\nset view equal xy\nset size ratio -1\nunset border\nunset tics\nunset key\nunset colorbox\n"
               "set xrange [%.9g:%.9g]\nset yrange [%.9g:%.9g]\n"
               "set pm3d depthorder lighting primary 0.45 specular 0.15 spec2 0.25\n"
               "set style fill solid noborder\n",
            fs->mesh, fs->rho, fs->seed, gp, 420 * cols, (int)(rows * (420 * aspect + 40) + 40), png,
            rows, cols, fs->mesh, fs->rho, fs->seed, crop[0], crop[1], crop[2], crop[3]);
    for (int i = 0; i < n; i++) {
        char name[64];
        snprintf(name, sizeof name, "render-%d.dat", i);
        write_tris(out, name, ms[i], R, crop);
        fprintf(g, "set title '%s' noenhanced\nsplot '%s' using 1:2:3 with polygons fc rgb '#e0d4bc'\n",
                titles[i], name);
    }
    fprintf(g, "unset multiplot\n");
    fclose(g);
    if (gnuplot(out, gp) == 0)
        printf("figure: %s/%s\n", out, png);
    else
        printf("figure: gnuplot failed or is missing (%s/%s written)\n", out, gp);
    for (int i = 0; i < n; i++) {
        char path[4096];
        snprintf(path, sizeof path, "%s/render-%d.dat", out, i);
        remove(path);
    }
}

/* ------------------------------------------------------------ main */

typedef struct {
    char name[64];
    int nv, dense, closed;
    int ncrease;        /* faces at creases of the clean mesh (crease_mask) */
    /* [noise][seed][method] */
    result r[MAXNOISE][MAXSEED][NMETHOD];
    result at_c[MAXNOISE][MAXSEED][5]; /* oracle points at g_report_c */
    double wall;
} mesh_rows;

static void split(char *s, char **out, int max, int *n)
{
    *n = 0;
    for (char *t = strtok(s, ","); t && *n < max; t = strtok(NULL, ","))
        out[(*n)++] = t;
}

static void write_oracle_summary(const char *path, const mesh_rows *mr, int nm, const double *rho,
                                 int nr, int ns)
{
    if (!path)
        return;
    char tmp[4200];
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    FILE *f = fopen(tmp, "w");
    if (!f) {
        fprintf(stderr, PROG ": cannot write %s: %s\n", tmp, strerror(errno));
        return;
    }
    fprintf(f, "# bench_quality oracle: desbrun2, 10 steps, total time t = c h^2 (h = mean edge / sqrt(area)\n"
               "# of the noisy input, i.e. after normalization to unit area); error = area-weighted RMS distance\n"
               "# to the clean mesh as a ratio against the noisy input's (< 1 is better). Medians over %d seeds;\n"
               "# best c is the median of the per-seed best, [min..max] (grid %s, bracketed, then one\n"
               "# parabola step in log c); '-': a c the sweep did not need.\n",
            ns, g_full_grid ? "0.05..1 always" : "0.1..0.5 always");
    fprintf(f, "%-22s %7s %5s | %6s %13s %7s | %6s %6s %6s %6s %6s\n", "mesh", "nv", "noise", "best c",
            "[min..max]", "ratio*", "c=0.1", "c=0.2", "c=0.3", "c=0.5", "c=1.0");
    for (int m = 0; m < nm; m++)
        for (int k = 0; k < nr; k++) {
            double cb[MAXSEED], rb[MAXSEED], at[5][MAXSEED];
            for (int s = 0; s < ns; s++) {
                const result *o = &mr[m].r[k][s][M_ORACLE];
                cb[s] = o->ok ? o->param : NAN;
                rb[s] = o->ok ? o->ratio : NAN;
                for (int j = 0; j < 5; j++)
                    at[j][s] = mr[m].at_c[k][s][j].ok ? mr[m].at_c[k][s][j].ratio : NAN;
            }
            double mn = INFINITY, mx = -INFINITY;
            for (int s = 0; s < ns; s++) {
                mn = cb[s] < mn ? cb[s] : mn;
                mx = cb[s] > mx ? cb[s] : mx;
            }
            char range[32];
            snprintf(range, sizeof range, "[%.3g..%.3g]", mn, mx);
            char b[6][16];
            fprintf(f, "%-22s %7d %5g | %6.3g %13s %7.3f | %6s %6s %6s %6s %6s\n", mr[m].name, mr[m].nv,
                    rho[k], median_of(cb, ns), range, median_of(rb, ns), fmt(b[0], 3, 0, median_of(at[0], ns)),
                    fmt(b[1], 3, 0, median_of(at[1], ns)), fmt(b[2], 3, 0, median_of(at[2], ns)),
                    fmt(b[3], 3, 0, median_of(at[3], ns)), fmt(b[4], 3, 0, median_of(at[4], ns)));
        }
    fprintf(f, "\n# worst seed at each c (what a fixed default would do): largest ratio, most negative drift\n"
               "# in %% (volume closed, area open, vs clean), most new folds (0 when none added)\n");
    fprintf(f, "%-22s %5s |", "mesh", "noise");
    for (int j = 0; j < 5; j++)
        fprintf(f, "  c=%-4g ratio drift%% fold |", g_report_c[j]);
    fprintf(f, "\n");
    for (int m = 0; m < nm; m++)
        for (int k = 0; k < nr; k++) {
            fprintf(f, "%-22s %5g |", mr[m].name, rho[k]);
            for (int j = 0; j < 5; j++) {
                double wr = -INFINITY, wd = INFINITY;
                int wf = 0, any = 0;
                for (int s = 0; s < ns; s++) {
                    const result *r = &mr[m].at_c[k][s][j];
                    if (!r->ok)
                        continue;
                    any = 1;
                    wr = r->ratio > wr ? r->ratio : wr;
                    wd = r->drift < wd ? r->drift : wd;
                    wf = r->folds > wf ? r->folds : wf;
                }
                if (any)
                    fprintf(f, "       %6.3f %6.2f %4d |", wr, 100 * wd, wf);
                else
                    fprintf(f, "       %6s %6s %4s |", "-", "-", "-");
            }
            fprintf(f, "\n");
        }
    fclose(f);
    rename(tmp, path);
}

static void check_goals(const mesh_rows *mr, int nm, const double *rho, int nr, int nseeds, int j)
{
    double worst = -INFINITY, worst_dense = -INFINITY, worst_drift = 0;
    int folds = 0, nf_runs = 0, folds_off = 0, nf_off_runs = 0;
    char wname[160] = "", dname[160] = "", drname[160] = "";
    for (int m = 0; m < nm; m++)
        for (int k = 0; k < nr; k++) {
            double v[MAXSEED];
            for (int s = 0; s < nseeds; s++) {
                const result *r = &mr[m].r[k][s][j];
                v[s] = r->ok ? r->ratio : NAN;
                if (!r->ok || r->ratio > worst) {
                    worst = r->ok ? r->ratio : INFINITY;
                    snprintf(wname, sizeof wname, "%s noise %g seed %d", mr[m].name, rho[k], s + 1);
                }
                if (!r->ok || r->folds > 0) {
                    folds += r->ok ? r->folds : 0;
                    nf_runs++;
                }
                if (!r->ok || r->folds_off > 0) {
                    folds_off += r->ok ? r->folds_off : 0;
                    nf_off_runs++;
                }
                /* open meshes: only a loss of area counts (noise adds area; what
                 * is left of it above the clean area is roughness, which the
                 * error ratio measures); closed: the volume either way */
                double dv = !r->ok ? INFINITY : mr[m].closed ? r->drift : fmin(r->drift, 0.0);
                if (fabs(dv) > fabs(worst_drift)) {
                    worst_drift = dv;
                    snprintf(drname, sizeof drname, "%s noise %g seed %d", mr[m].name, rho[k], s + 1);
                }
            }
            double med = median_of(v, nseeds);
            if (mr[m].dense && rho[k] >= 0.25 && (max_of(v, nseeds) == INFINITY || med > worst_dense)) {
                worst_dense = max_of(v, nseeds) == INFINITY ? INFINITY : med;
                snprintf(dname, sizeof dname, "%s noise %g", mr[m].name, rho[k]);
            }
        }
    const char *w = method_names[j], *tag = j == M_DEFAULT ? "" : "(ref) ";
    printf("%s  %s%s never worse than its input (ratio <= 1 in every run): worst %.3f (%s)\n",
           worst <= 1.0 ? "PASS" : "FAIL", tag, w, worst, wname);
    printf("%s  %s%s removes >= 1/5 of the error on dense scans at noise >= 0.25 (median ratio <= 0.8): worst %.3f (%s)\n",
           !dname[0] ? "SKIP" : worst_dense <= 0.8 ? "PASS" : "FAIL", tag, w, worst_dense,
           dname[0] ? dname : "no dense scan in the list");
    printf("%s  %s%s folds no face beyond the input's: %d run(s) with new folds, %d new folds in all\n",
           nf_runs == 0 ? "PASS" : "FAIL", tag, w, nf_runs, folds);
    printf("      (away from the clean meshes' own creases, i.e. faces next to a face turned > 120 degrees or\n"
           "       at a non-manifold edge: %d run(s) with new folds, %d new folds in all)\n", nf_off_runs, folds_off);
    printf("%s  %s%s drifts <= 3%% (volume of closed meshes, loss of area of open ones, vs clean): worst %+.2f%% (%s)\n",
           fabs(worst_drift) <= 0.03 ? "PASS" : "FAIL", tag, w, 100 * worst_drift, drname);
}

static void usage(void)
{
    fprintf(stderr,
            "usage: bench_quality [--meshes DIR] [--out DIR] [--list a.obj,b.drc,...] [--noise 0.1,0.25,0.5]\n"
            "                     [--seeds N] [--methods default,auto,oracle,taubin] [--oracle-out FILE]\n"
            "                     [--no-figure | --figure MESH[,NOISE[,SEED]]] [--oracle-grid lean|full]\n");
    exit(2);
}

int main(int argc, char **argv)
{
    const char *meshes = "../shared/meshes", *out = "docs/quality", *oracle_out = NULL;
    char list_buf[1024] = "stanford-bunny.obj,bunny.drc,snowden.obj,dragon_vrip_res2.obj,armadillo.obj,"
                          "spot.obj,fertility.obj,bunny_npm_closed.obj,knot1.obj";
    char noise_buf[256] = "0.1,0.25,0.5", methods_buf[256] = "default,auto,oracle,taubin";
    int nseeds = 3, do_figure = 1, fig_seed = 1;
    const char *fig_mesh = "stanford-bunny.obj";
    double fig_rho = 0.25;
    /* the zoomed figure: the stanford bunny's head in the default view */
    double fig_crop[4] = {0.0, 0.62, 0.38, 1.0};
    double t_start = mcf_now();

    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--meshes") && v)
            meshes = v, i++;
        else if (!strcmp(a, "--out") && v)
            out = v, i++;
        else if (!strcmp(a, "--list") && v)
            snprintf(list_buf, sizeof list_buf, "%s", v), i++;
        else if (!strcmp(a, "--noise") && v)
            snprintf(noise_buf, sizeof noise_buf, "%s", v), i++;
        else if (!strcmp(a, "--methods") && v)
            snprintf(methods_buf, sizeof methods_buf, "%s", v), i++;
        else if (!strcmp(a, "--seeds") && v)
            nseeds = atoi(v), i++;
        else if (!strcmp(a, "--oracle-out") && v)
            oracle_out = v, i++;
        else if (!strcmp(a, "--no-figure"))
            do_figure = 0;
        else if (!strcmp(a, "--oracle-grid") && v && (!strcmp(v, "full") || !strcmp(v, "lean")))
            g_full_grid = !strcmp(v, "full"), i++;
        else if (!strcmp(a, "--figure") && v) {
            /* NAME[,NOISE[,SEED]] */
            static char fbuf[256];
            snprintf(fbuf, sizeof fbuf, "%s", v);
            i++;
            char *c1 = strchr(fbuf, ',');
            if (c1) {
                *c1++ = 0;
                fig_rho = atof(c1);
                char *c2 = strchr(c1, ',');
                if (c2)
                    fig_seed = atoi(c2 + 1);
            }
            fig_mesh = fbuf;
        }
        else
            usage();
    }
    if (nseeds < 1 || nseeds > MAXSEED)
        usage();
    char *names[MAXMESH], *ntext[MAXNOISE], *mtext[NMETHOD];
    int nm, nr, nmeth;
    double rho[MAXNOISE];
    int want[NMETHOD] = {0};
    split(list_buf, names, MAXMESH, &nm);
    split(noise_buf, ntext, MAXNOISE, &nr);
    split(methods_buf, mtext, NMETHOD, &nmeth);
    for (int k = 0; k < nr; k++)
        rho[k] = atof(ntext[k]);
    for (int k = 0; k < nmeth; k++)
        for (int j = 0; j < NMETHOD; j++)
            if (!strcmp(mtext[k], method_names[j]))
                want[j] = 1;

    bench_print_machine();
    if (mkdir_p(out) != 0) {
        fprintf(stderr, PROG ": cannot create %s: %s\n", out, strerror(errno));
        return 1;
    }

    /* Does the api know strength=auto? */
    char auto_note[300] = "";
    if (want[M_AUTO]) {
        api_params p;
        api_limits lim;
        mcf_error e = {0};
        api_limits_default(&lim);
        api_params_init(&p);
        if (api_params_set(&p, "strength", "auto", &lim, &e) != MCF_OK) {
            want[M_AUTO] = 0;
            snprintf(auto_note, sizeof auto_note, "strength=auto refused (%s: %s): column skipped",
                     mcf_status_name(e.status), e.msg);
            printf("%s\n", auto_note);
        }
        api_params_free(&p);
    }
    {
        api_params p;
        api_params_init(&p);
        cJSON *j = api_params_to_json(&p);
        char *s = j ? api_json_print(j, 0) : NULL;
        printf("default request: %s\n", s ? s : "?");
        free(s);
        cJSON_Delete(j);
        api_params_free(&p);
    }

    FILE *csv = open_out(out, "quality.csv");
    FILE *sweep = open_out(out, "oracle-sweep.csv");
    fprintf(csv, "mesh,nv,nf,closed,dense,noise,seed,h,e0,input_folds,input_drift,method,param,ok,ratio,"
                 "new_folds,new_folds_off_crease,drift,max_disp_edges,wall_s,note\n");
    fprintf(sweep, "mesh,noise,seed,c,ok,ratio,new_folds,drift,max_disp_edges,wall_s\n");

    mesh_rows *mr = calloc((size_t)nm, sizeof *mr);
    if (!mr)
        die("calloc", NULL);
    figure_spec fs = {fig_mesh, fig_rho, fig_seed, 0, {0.0, 1.0, 0.0, 1.0}};
    const mcf_mesh *fig_ms[6] = {0};
    const char *fig_titles[6];
    char fig_title_buf[6][96];
    int fig_n = 0;

    for (int mi = 0; mi < nm; mi++) {
        double tm0 = mcf_now();
        mcf_mesh *clean = bench_load_mesh(PROG, meshes, names[mi]);
        mcf_mesh_info ci;
        mcf_error e = {0};
        if (mcf_mesh_inspect(clean, &ci, &e) != MCF_OK)
            die("mcf_mesh_inspect", &e);
        mesh_rows *row = &mr[mi];
        snprintf(row->name, sizeof row->name, "%s", names[mi]);
        row->nv = ci.nv;
        row->closed = ci.boundary_edges == 0;
        row->dense = ci.nv - ci.unreferenced >= 20000;
        unsigned char *crease = crease_mask(clean, &row->ncrease);
        printf("\n%s: %d vertices, %d faces, %s%s, mean edge %.4g, %s, %d faces at creases\n", names[mi],
               ci.nv, ci.nf, row->closed ? "closed" : "open", ci.manifold ? "" : ", non-manifold", ci.mean_edge,
               row->dense ? "dense scan" : "small mesh", row->ncrease);
        fflush(stdout);
        for (int k = 0; k < nr; k++)
            for (int s = 0; s < nseeds; s++) {
                mcf_mesh *noisy = bench_dup_mesh(PROG, clean);
                mcf_mesh_info ni;
                mcf_compare_result c0;
                if (mcf_mesh_add_noise(noisy, rho[k], (uint64_t)(s + 1), &e) != MCF_OK)
                    die("mcf_mesh_add_noise", &e);
                if (mcf_mesh_inspect(noisy, &ni, &e) != MCF_OK || mcf_compare(noisy, clean, &c0, &e) != MCF_OK)
                    die("noisy input", &e);
                case_ctx c = {clean, noisy, c0.rms_m, c0.inverted_faces, crease,
                              inverted_off_crease(noisy, clean, crease),
                              row->closed ? ci.volume : ci.area, row->closed, ci.mean_edge,
                              ni.mean_edge / sqrt(ni.area)};
                double in_drift = ((row->closed ? ni.volume : ni.area) - c.ref_size) / fabs(c.ref_size);
                int fig = do_figure && !strcmp(names[mi], fs.mesh) && rho[k] == fs.rho && s + 1 == fs.seed;
                mcf_mesh *res[NMETHOD] = {0};
                for (int j = 0; j < NMETHOD; j++) {
                    result *r = &row->r[k][s][j];
                    memset(r, 0, sizeof *r);
                    r->ratio = NAN;
                    if (!want[j])
                        continue;
                    mcf_mesh **o = fig ? &res[j] : NULL;
                    if (j == M_DEFAULT || j == M_AUTO)
                        run_request(&c, j == M_AUTO, r, o);
                    else if (j == M_ORACLE)
                        run_oracle(&c, sweep, names[mi], rho[k], s + 1, r, row->at_c[k][s], o);
                    else
                        run_taubin(&c, r, o);
                    fprintf(csv, "%s,%d,%d,%d,%d,%g,%d,%.6g,%.6g,%d,%.6g,%s,%.6g,%d,%.6g,%d,%d,%.6g,%.4g,%.4f,\"%s\"\n",
                            names[mi], ci.nv, ci.nf, row->closed, row->dense, rho[k], s + 1, c.h, c.e0,
                            c.fold0, in_drift, method_names[j], r->param, r->ok, r->ratio, r->folds, r->folds_off,
                            r->drift, r->maxdisp, r->wall, r->note);
                    if (!r->ok)
                        printf("  %s noise %g seed %d: %s\n", method_names[j], rho[k], s + 1, r->note);
                }
                fflush(csv);
                fflush(sweep);
                if (fig) {
                    fig_ms[fig_n] = bench_dup_mesh(PROG, clean);
                    fig_titles[fig_n++] = "clean";
                    fig_ms[fig_n] = noisy;
                    snprintf(fig_title_buf[1], 96, "noisy (%.3g mean edges)", rho[k]);
                    fig_titles[fig_n++] = fig_title_buf[1];
                    noisy = NULL;
                    for (int j = 0; j < NMETHOD; j++)
                        if (res[j]) {
                            const result *r = &row->r[k][s][j];
                            if (j == M_ORACLE)
                                snprintf(fig_title_buf[fig_n], 96, "oracle desbrun2 t=%.2fh^2: %.2f", r->param, r->ratio);
                            else if (j == M_TAUBIN)
                                snprintf(fig_title_buf[fig_n], 96, "taubin %d passes: %.2f", (int)r->param, r->ratio);
                            else
                                snprintf(fig_title_buf[fig_n], 96, "%s (t=%.2fh^2): %.2f", method_names[j], r->param, r->ratio);
                            fig_titles[fig_n] = fig_title_buf[fig_n];
                            fig_ms[fig_n++] = res[j];
                            res[j] = NULL;
                        }
                }
                for (int j = 0; j < NMETHOD; j++)
                    mcf_mesh_free(res[j]);
                mcf_mesh_free(noisy);
            }
        row->wall = mcf_now() - tm0;
        printf("  %-5s | %-19s | %-19s | %-19s | %-19s\n", "noise", "default (t/h^2)", "auto (t/h^2)",
               "oracle (c)", "taubin (passes)");
        for (int k = 0; k < nr; k++) {
            char b[NMETHOD][2][16];
            printf("  %-5g |", rho[k]);
            for (int j = 0; j < NMETHOD; j++) {
                double v[MAXSEED], q[MAXSEED];
                for (int s = 0; s < nseeds; s++) {
                    const result *r = &row->r[k][s][j];
                    v[s] = r->ok ? r->ratio : NAN;
                    q[s] = r->ok ? r->param : NAN;
                }
                printf(" %7s (%7s)  |", fmt(b[j][0], 3, 0, median_of(v, nseeds)),
                       fmt(b[j][1], 3, 1, median_of(q, nseeds)));
            }
            printf("\n");
        }
        printf("  (%.1f s)\n", row->wall);
        fflush(stdout);
        if (want[M_ORACLE])
            write_oracle_summary(oracle_out, mr, mi + 1, rho, nr, nseeds);
        mcf_mesh_free(clean);
        free(crease);
    }
    fclose(csv);
    fclose(sweep);

    /* ---- the table: medians over seeds */
    printf("\n== scan quality: error / noisy input's error, median over %d seeds (folds: most new folds of a seed,\n"
           "   all / away from the clean mesh's creases; drift: median, volume if closed else area, vs clean;\n"
           "   disp: max displacement in mean edges; wall: seconds)\n",
           nseeds);
    printf("%-21s %5s | %6s %9s %6s %5s %6s %6s | %6s %6s %9s | %6s %6s | %6s %5s\n", "mesh", "noise",
           "deflt", "folds", "drift%", "disp", "wall", "t/h^2", "auto", "t/h^2", "folds", "oracle", "c*",
           "taubin", "pass");
    for (int m = 0; m < nm; m++)
        for (int k = 0; k < nr; k++) {
            double v[NMETHOD][MAXSEED], d[MAXSEED], dp[MAXSEED], w[MAXSEED], pa[NMETHOD][MAXSEED];
            int fm[NMETHOD] = {0}, fo[NMETHOD] = {0}, any[NMETHOD] = {0};
            char b[14][16], fb[2][24];
            for (int j = 0; j < NMETHOD; j++)
                for (int s = 0; s < nseeds; s++) {
                    const result *r = &mr[m].r[k][s][j];
                    v[j][s] = r->ok ? r->ratio : NAN;
                    pa[j][s] = r->ok ? r->param : NAN;
                    any[j] |= r->ok;
                    if (r->folds > fm[j])
                        fm[j] = r->folds;
                    if (r->folds_off > fo[j])
                        fo[j] = r->folds_off;
                    if (j == M_DEFAULT) {
                        d[s] = r->ok ? 100 * r->drift : NAN;
                        dp[s] = r->ok ? r->maxdisp : NAN;
                        w[s] = r->ok ? r->wall : NAN;
                    }
                }
            snprintf(fb[0], sizeof fb[0], "%d/%d", fm[0], fo[0]);
            snprintf(fb[1], sizeof fb[1], "%d/%d", fm[1], fo[1]);
            printf("%-21s %5g | %6s %9s %6s %5s %6s %6s | %6s %6s %9s | %6s %6s | %6s %5s\n", mr[m].name, rho[k],
                   fmt(b[0], 3, 0, median_of(v[0], nseeds)), any[0] ? fb[0] : "-",
                   fmt(b[2], 2, 0, median_of(d, nseeds)), fmt(b[3], 2, 0, median_of(dp, nseeds)),
                   fmt(b[4], 3, 0, median_of(w, nseeds)), fmt(b[5], 3, 1, median_of(pa[0], nseeds)),
                   fmt(b[6], 3, 0, median_of(v[1], nseeds)), fmt(b[7], 3, 1, median_of(pa[1], nseeds)),
                   any[1] ? fb[1] : "-", fmt(b[9], 3, 0, median_of(v[2], nseeds)),
                   fmt(b[10], 3, 1, median_of(pa[2], nseeds)), fmt(b[11], 3, 0, median_of(v[3], nseeds)),
                   fmt(b[12], 0, 0, median_of(pa[3], nseeds)));
        }

    /* ---- goals (issue 12, section 5) */
    printf("\n== goals (issue 12, section 5): the default request; the same checks for the others as reference\n");
    for (int j = 0; j < NMETHOD; j++)
        if (want[j])
            check_goals(mr, nm, rho, nr, nseeds, j);
    if (want[M_AUTO] && want[M_TAUBIN]) {
        /* per mesh: median over noise x seed of auto / taubin; then the median mesh */
        double per[MAXMESH];
        for (int m = 0; m < nm; m++) {
            double q[MAXNOISE * MAXSEED];
            int n = 0;
            for (int k = 0; k < nr; k++)
                for (int s = 0; s < nseeds; s++) {
                    const result *a = &mr[m].r[k][s][M_AUTO], *t = &mr[m].r[k][s][M_TAUBIN];
                    q[n++] = a->ok && t->ok ? a->ratio / t->ratio : INFINITY;
                }
            per[m] = bench_median(q, n);
        }
        double med = bench_median(per, nm);
        printf("%s  moonshot: strength=auto at or below Taubin's best on the median mesh: auto/taubin %.3f\n",
               med <= 1.0 ? "PASS" : "FAIL", med);
    } else
        printf("SKIP  moonshot (strength=auto vs Taubin's best): %s\n",
               auto_note[0] ? auto_note : "auto or taubin not run");

    if (do_figure && fig_n > 0) {
        figure(out, "renders", &fs, fig_ms, fig_titles, fig_n);
        figure_spec zoom = fs;
        memcpy(zoom.crop, fig_crop, sizeof zoom.crop);
        figure(out, "renders-zoom", &zoom, fig_ms, fig_titles, fig_n);
        for (int i = 0; i < fig_n; i++)
            mcf_mesh_free((mcf_mesh *)(uintptr_t)fig_ms[i]);
    }
    if (want[M_ORACLE])
        write_oracle_summary(oracle_out, mr, nm, rho, nr, nseeds);
    printf("\nCSV: %s/quality.csv, %s/oracle-sweep.csv; run time %.0f s\n", out, out, mcf_now() - t_start);
    free(mr);
    return 0;
}
