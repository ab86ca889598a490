/* SPDX-License-Identifier: MIT */
/*
 * mcf_fairing.c - the fairing denoiser, the product's default filter:
 * implicit bi-Laplacian steps on the uniform graph Laplacian (`fairing`)
 * or uniform lambda|mu passes (`fairing_explicit`), as many as Stein's
 * unbiased risk estimate (SURE) says, applied along the normals only and
 * kept from folding faces.
 *
 * Notation: free vertices F, fixed B (mcf_flow_run's fixed set, plus
 * vertices without an edge), A the adjacency with weight 1 per edge, D the
 * degrees, L = D - A (mcf_graph.c). One implicit step is
 *     (D_F + L_FF D_F^-1 L_FF) x_F' = D_F x_F - L_FF D_F^-1 L_FB X0_B,
 * the minimizer of |x - x_F|^2_D + |(L x)_F|^2_D^-1: gain 1 / (1 + k^2)
 * on an eigenvalue k in [0, 2] of D^-1 L, flat at the lowest frequencies
 * (no shrinking, no pole). With N = D_F^-1/2 L_FF D_F^-1/2 and y =
 * D_F^1/2 x the system is (I + N N') y' = y - N u, u = D_F^-1/2 L_FB X0_B:
 * I + N N' (N is symmetric: I + N^2, on the free 2-rings) is assembled
 * and factored once per run by mcf_cholesky.c, as every SPD system in
 * core; each step is one solve of all the columns. One explicit pass is Taubin's
 * pair x += 0.5 (avg - x), x += -0.53 (avg - x) on the free vertices.
 *
 * The amount: after K steps the displacement along the noisy mesh's
 * normals n0 is r_i = n0_i . (Y_i - X0_i). For noise of deviation s along
 * the normals (mcf__noise_level) and the smoother T (one step, acting on
 * each coordinate), SURE(K) = sum w r^2 - s^2 sum w + 2 s^2 sum w_i
 * (T^K)_ii estimates sum w (error)^2 without the clean mesh; w are the
 * barycentric vertex areas over their mean. The weighted trace comes from
 * six Rademacher probes (three on a mesh of over a million free vertices:
 * PROBES_FEW_ABOVE) (Hutchinson), carried through the explicit passes as
 * extra columns; for the implicit step T = D^-1/2 R D^1/2, R = (I +
 * NN')^-1, so a probe's estimate is z' W R^K z, read by Lanczos quadrature
 * on N (mcf_fairing_trace.c) while the steps solve the coordinates only;
 * the default request's explicit passes after its implicit steps read
 * z' W P(N)^K z on the same Lanczos runs (P the pass's gain) and move the
 * coordinates only. The run stops at the first power of
 * two past K* + 5 (K* the best so far: sure_stop) or at the cap. It keeps the displacements Y_k - X0
 * after the last COMB_J powers of two k of steps; the combination X0 +
 * sum_j c_j (Y_kj - X0) whose SURE is least (a 4 x 4 linear system:
 * combine) replaces Y at K* when its SURE is lower still.
 *
 * The output moves each free vertex along the normal n of Y only,
 * X_i = X0_i + n_i <n_i, Y_i - X0_i>, so vertices stay where the scanner
 * put them along the surface. Tangential noise (isotropic scanner noise)
 * is removed by a second SURE over the same steps for the tangential part
 * of the displacement, moved in the tangent planes and put back on the
 * surface (tangential_output). Creases found on the smoothed input are
 * smoothed along and held (mcf__creases, mcf_creases.c). A guard (mcf__unfold, mcf_folds.c)
 * then takes back every face of X the run folded (turned against the
 * input's same face and lying backwards in its neighbourhood): Y's
 * positions first, then halfway to the input, then the input's.
 * docs/fairing.md has the math in words.
 *
 * Pure C11; the factorization by mcf_cholesky.c; no globals.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_fairing_ctx.h"

#define TANGENTIAL_FLOOR 0.12
/* isotropic noise reads at least the normal level in the tangent planes
 * (reading^2 = b^2 + s^2, b the triangulation's own irregularity); a
 * reading under TANGENTIAL_GATE_LO times the normal level is b alone
 * (noise along the normals: the 435k dragon's marching-cubes triangles
 * read b = 0.204 under noise 0.232), none counts, and the whole of it
 * counts from TANGENTIAL_GATE_HI on, linearly between. Measured
 * 2026-11-29 (docs/fairing.md): reading / level 0.97-1.78 under
 * isotropic noise 0.1-0.5 on the shared scans, 0.12-0.62 under noise
 * 0.25-0.5 along the normals, 0.88 on the 435k dragon at 0.25 */
#define TANGENTIAL_GATE_LO 0.9
#define TANGENTIAL_GATE_HI 0.95
/* A level read below NOISE_FLOOR mean edges is the coordinates' rounding,
 * not noise: a clean box (the tests' box_mesh(8), every coordinate a
 * multiple of 1/8) read 6e-17 h along one direction and ran 447 steps
 * that moved no coordinate (0.016 s, 8x the same box turned off its
 * axes, which reads 0). A double's rounding (2^-53 of the coordinate)
 * stays under it while the mesh lies within 9e6 mean edges of the origin,
 * and no noise a user could see is near it (the no-harm bar is 0.01 h).
 * Not applied to a level the request gives. */
#define NOISE_FLOOR 1e-9
/* the relative standard error of the noise level's square, times
 * sqrt(n): the estimate is a ratio of two medians of |high-pass| over
 * about n = nfree vertices, each with a relative standard error of
 * 1.166 / sqrt(n) (a median m of |Gaussian| values: 1 / (2 f(m) sqrt(n))
 * over m, m = 0.6745, f(m) = 0.636), so sqrt(2) 1.166 on s, twice that on
 * s^2 */
#define S2_REL_SQRT_N 3.3
/* The default request takes the RMS reading of the noise (mcf__noise_shape)
 * when the high-pass vectors share one direction (their largest
 * eigenvalue's share at least VIEW_SHARE) and the RMS reading is at least
 * VIEW_RATIO of the median one. Measured in numpy (2026-11-28, seed 1,
 * spot, fertility, bunny_npm_closed, knot1, car, blade, sphere_cgal,
 * couplingdown_sub2): one viewpoint's noise of 0.25 and 0.5 h shares
 * 0.75-1.00 (car 0.50-0.53, couplingdown 0.62 at 0.25) with ratios
 * 1.12-1.41; clean meshes share 0.33-0.58 (ratios up to 1.41), noise
 * along the normals 0.34-0.60 except blade's 0.86-0.94 (a thin part: its
 * normals two directions) with ratios 0.96-1.09, isotropic 0.34-0.54,
 * quantization 0.35-0.63: none of those switches */
#define VIEW_SHARE 0.7
#define VIEW_RATIO 1.15
/* ... or the deviation read along that direction is VIEW_DIR times the
 * median one along the normals: on a thin part, normals +-z, the RMS
 * reading equals the median one (docs/fairing.md, "One viewpoint") */
#define VIEW_DIR 2.0
/* Is there noise at all? Noise is white: its high-pass correlates with its
 * own 1-ring average as the calibration noise's does (mcf__noise_shape:
 * corr_noise, -0.29 to -0.32 on the shared meshes), while a clean
 * surface's high-pass (its curvature, its triangles' irregularity) is
 * smoother: the correlation is higher. The default request reads no noise
 * when corr exceeds corr_noise by more than WHITE_GAP. Measured
 * (2026-11-28, mcf smooth, seed 1): clean meshes exceed it by 0.12-1.7
 * (sphere_cgal, spot, fertility, bunny_npm_closed, knot1, armadillo,
 * snowden, stanford-bunny, bunny.drc), the CAD parts by 0.04-0.08 (car,
 * blade, couplingdown_sub2: those the reading and SURE leave nearly
 * alone, below 0.13 of the error of 0.1 h noise); Gaussian noise along
 * the normals of 0.05 h by at most 0.07, of 0.1 h by at most 0.06 (car),
 * one viewpoint's of 0.1 h by at most 0.06. Before, the default moved
 * fertility, bunny_npm_closed and armadillo 0.11, 0.23 and 0.28 of the
 * error of 0.1 h noise */
#define WHITE_GAP 0.1
/* c's arrays (its graph is mcf__fairing's, lent to every run) */
void mcf__fair_free(fair_ctx *c)
{
    free(c->X0);
    free(c->Y);
    free(c->Ybest);
    free(c->Yt);
    free(c->Xin);
    free(c->crease);
    free(c->chains);
    free(c->fx);
    free(c->vert);
    free(c->fid);
    free(c->sq);
    free(c->w);
    free(c->n0);
    free(c->probe);
    free(c->Z);
    free(c->tmp);
    free(c->b);
    mcf__chol_free(c->chol);
    mcf__pattern_free(&c->apat);
    free(c->ax);
    free(c->Yc);
    mcf__fair_lz_free(c->lz);
    for (int j = 0; j < COMB_J; j++)
        free(c->dk[j]);
}

/* The explicit engine's Z and tmp once its run is done (nothing reads
 * them after run_steps): the bytes freed. */
static size_t drop_engine(fair_ctx *c)
{
    size_t n = c->Z ? 2 * sizeof(double) * (size_t)c->nv * (size_t)c->ncol : 0;
    free(c->Z);
    free(c->tmp);
    c->Z = c->tmp = NULL;
    return n;
}

double *mcf__fair_alloc(fair_ctx *c, size_t n)
{
    c->bytes += n * sizeof(double);
    return mcf__malloc(n ? n : 1, sizeof(double));
}

/* The run's share of work done (mcf_work_fn): f of this filter's window
 * [w0, w1]. Within a filter, the milestones before its steps (WORK_AT,
 * for the implicit filter measured on the 35k bunny and 43k armadillo,
 * for the explicit one on the 435k dragon with noise 0.3, 2026-11-28:
 * 1.9 s of set-up, 2.3 s of noise reading, 0.2 s of probes, 19.4 s of 64
 * passes): the graph, the creases, the set-up's end, the noise reading,
 * the factorization or the probes; the steps the rest, counted against
 * the steps SURE will run (sure_stop(K*), K* its best so far, at most the
 * cap; run_steps). Of the run: the default's spike repair first
 * WORK_REPAIR, the default's second filter WORK_PICK, the output (guard
 * and unfolding) WORK_OUTPUT. The share never decreases (mcf_work_fn). */
enum { AT_GRAPH, AT_CREASES, AT_SETUP, AT_NOISE, AT_INIT };
static const double WORK_AT[2][5] = {{0.03, 0.17, 0.2, 0.45, 0.55},  /* implicit */
                                     {0.01, 0.06, 0.08, 0.18, 0.2}}; /* explicit */
#define AT(c, m) WORK_AT[(c)->is_explicit ? 1 : 0][m]
/* The steps SURE's stop is expected at before it says (implicit,
 * explicit): the 43k armadillo's implicit run with noise 0.3 stops at 16
 * steps, the 435k dragon's explicit one at 64 passes. */
static const int WORK_STEPS_PRIOR[2] = {16, 64};
#define WORK_REPAIR 0.06
#define WORK_PICK 0.15
#define WORK_OUTPUT 0.12
static void work(fair_ctx *c, const char *phase, double f)
{
    double done = c->w0 + fmin(1.0, f) * (c->w1 - c->w0);

    /* mcf_work_fn promises a share that never decreases: a phase's
     * estimate below the last one reported holds it */
    if (done < c->work_done)
        done = c->work_done;
    c->work_done = done;
    if (c->p->work)
        c->p->work(c->p->progress_ctx, phase, done);
}

/* The run's cancel flag between the phases (mcf__cancel_set): the set-up
 * of a big scan (the graph, the spike repair, the creases, the noise
 * reading, the probes) reports no step for minutes; a run stopped in it
 * stops at the next phase, named in the message. */
static mcf_status phase_cancel(const mcf_flow_params *p, const char *next, mcf_error *err)
{
    return mcf__cancel_set(p->cancel) ? mcf__fail(err, MCF_ECANCELED, "canceled before %s", next) : MCF_OK;
}

/* A long phase's own milestones (mcf__tick) mapped into [a, b] of the
 * filter's window. */
typedef struct {
    fair_ctx *c;
    double a, b;
} work_span;

static void span_tick(void *ctx, const char *phase, double f)
{
    work_span *s = ctx;
    work(s->c, phase, s->a + f * (s->b - s->a));
}

/* The set-up of run f (setup()'s arrays and figures) into c: the same
 * input, fixed set and graph give the same set-up, found once
 * (mcf__creases was 2% of the default request's CPU on armadillo.obj
 * normal 0.25 h for each run that found it: perf, 2026-11-29). */
static mcf_status setup_copy(fair_ctx *c, const fair_ctx *f, mcf_error *err)
{
    size_t nv = (size_t)c->nv, ne = (size_t)c->g.ptr[nv];
    c->fx = mcf__malloc(nv, 1);
    c->fid = mcf__malloc(nv, sizeof(int));
    c->vert = mcf__malloc(nv, sizeof(int));
    c->w = mcf__fair_alloc(c, nv);
    c->n0 = mcf__fair_alloc(c, 3 * nv);
    c->sq = mcf__fair_alloc(c, nv);
    c->crease = mcf__malloc(nv, 1);
    c->Xin = mcf__fair_alloc(c, 3 * nv);
    c->chains = mcf__malloc(ne + 1, 1);
    c->bytes += ne;
    if (!c->fx || !c->fid || !c->vert || !c->w || !c->n0 || !c->sq || !c->crease || !c->Xin || !c->chains)
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d vertices)", c->nv);
    memcpy(c->fx, f->fx, nv);
    memcpy(c->fid, f->fid, nv * sizeof(int));
    memcpy(c->vert, f->vert, (size_t)f->nfree * sizeof(int));
    memcpy(c->w, f->w, nv * sizeof(double));
    memcpy(c->n0, f->n0, 3 * nv * sizeof(double));
    memcpy(c->sq, f->sq, (size_t)f->nfree * sizeof(double));
    memcpy(c->crease, f->crease, nv);
    memcpy(c->Xin, f->Xin, 3 * nv * sizeof(double));
    memcpy(c->chains, f->chains, ne);
    memcpy(c->X0, f->X0, 3 * nv * sizeof(double));
    c->nfree = f->nfree;
    c->sumw2 = f->sumw2;
    c->st->crease_vertices = f->st->crease_vertices;
    return MCF_OK;
}

/* The free set, degrees, weights, the input's normals and the probes, on
 * the graph c->g (mcf__fairing's). */
static mcf_status setup(fair_ctx *c, const unsigned char *fixed, mcf_error *err)
{
    int nv = c->nv;
    work(c, "graph", AT(c, AT_GRAPH));
    if (c->setup_from)
        return setup_copy(c, c->setup_from, err);
    c->fx = mcf__malloc((size_t)nv, 1);
    c->fid = mcf__malloc((size_t)nv, sizeof(int));
    c->vert = mcf__malloc((size_t)nv, sizeof(int));
    c->w = mcf__fair_alloc(c, (size_t)nv);
    c->n0 = mcf__fair_alloc(c, 3 * (size_t)nv);
    c->sq = mcf__fair_alloc(c, (size_t)nv);
    if (!c->fx || !c->fid || !c->vert || !c->w || !c->n0 || !c->sq)
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d vertices)", nv);
    /* the creases: held for the surface's filter, smoothed along */
    unsigned char *crease = c->crease = mcf__calloc((size_t)nv, 1);
    c->Xin = mcf__fair_alloc(c, 3 * (size_t)nv);
    if (c->Xin)
        memcpy(c->Xin, c->X0, 3 * sizeof(double) * (size_t)nv);
    work_span span = {c, AT(c, AT_GRAPH), AT(c, AT_CREASES)};
    mcf__tick tick = {span_tick, &span};
    c->chains = mcf__calloc((size_t)c->g.ptr[nv] + 1, 1);
    c->bytes += (size_t)c->g.ptr[nv];
    int ncrease = -1;
    if (crease && c->Xin && c->chains && c->given_crease) {
        memcpy(crease, c->given_crease, (size_t)nv);
        memcpy(c->chains, c->given_chains, (size_t)c->g.ptr[nv]);
        memcpy(c->X0, c->given_X0, 3 * sizeof(double) * (size_t)nv);
        ncrease = 0;
        for (int i = 0; i < nv; i++)
            ncrease += crease[i];
    } else if (crease && c->Xin && c->chains) {
        ncrease = c->no_creases ? 0
                                : mcf__creases(&c->g, c->F, c->nf, nv, fixed, c->X0, crease, c->chains, &tick);
    }
    if (ncrease < 0)
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d vertices)", nv);
    c->st->crease_vertices = ncrease;
    c->nfree = 0;
    for (int i = 0; i < nv; i++) {
        int d = c->g.ptr[i + 1] - c->g.ptr[i];
        c->fx[i] = fixed[i] || d == 0 || crease[i];
        c->fid[i] = c->fx[i] ? -1 : c->nfree;
        if (!c->fx[i]) {
            c->sq[c->nfree] = sqrt((double)d);
            c->vert[c->nfree++] = i;
        }
    }
    mcf__vertex_normals(c->X0, c->F, c->nf, nv, c->n0);
    /* barycentric areas over their mean on the free vertices */
    memset(c->w, 0, sizeof(double) * (size_t)nv);
    for (int f = 0; f < c->nf; f++) {
        const int32_t *t = c->F + 3 * (size_t)f;
        double e1[3], e2[3], cr[3];
        mcf__sub3(c->X0 + 3 * (size_t)t[1], c->X0 + 3 * (size_t)t[0], e1);
        mcf__sub3(c->X0 + 3 * (size_t)t[2], c->X0 + 3 * (size_t)t[0], e2);
        mcf__cross3(e1, e2, cr);
        double a = sqrt(mcf__dot3(cr, cr)) / 6.0;
        for (int k = 0; k < 3; k++)
            c->w[t[k]] += a;
    }
    double sum = 0.0;
    for (int i = 0; i < nv; i++)
        sum += c->fx[i] ? 0.0 : c->w[i];
    c->sumw2 = 0.0;
    for (int i = 0; i < nv; i++) {
        c->w[i] = c->fx[i] || !(sum > 0.0) ? (c->fx[i] ? 0.0 : 1.0) : c->w[i] * c->nfree / sum;
        c->sumw2 += c->w[i] * c->w[i];
    }
    return MCF_OK;
}

/* Rademacher probes; a second run (c->like) takes the first run's on the
 * vertices both move, so that the difference of their traces is read
 * with little spread, and draws the rest past the first run's indices. */
static void init_probes(fair_ctx *c)
{
    const fair_share *l = c->like;
    for (int q = 0; q < c->nprobe; q++)
        for (int k = 0; k < c->nfree; k++) {
            int j = l ? l->fid[c->vert[k]] : -1;
            uint64_t idx = l ? (uint64_t)l->nfree + (uint64_t)k : (uint64_t)k;
            c->probe[(size_t)q * c->nfree + k] =
                j >= 0 ? l->probe[(size_t)q * l->nfree + (size_t)j]
                       : (mcf__mix64((uint64_t)q * 0x9e3779b97f4a7c15ULL + idx + 1) >> 63) ? 1.0 : -1.0;
        }
}

/* ----------------------------------------------------- explicit engine */

static mcf_status explicit_init(fair_ctx *c, mcf_error *err)
{
    size_t nv = (size_t)c->nv, nc = (size_t)c->ncol;
    c->Z = mcf__fair_alloc(c, nv * nc);
    c->tmp = mcf__fair_alloc(c, nv * nc);
    if (!c->Z || !c->tmp)
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d vertices)", c->nv);
    for (size_t i = 0; i < nv; i++) {
        for (int d = 0; d < 3; d++)
            c->Z[nc * i + d] = c->X0[3 * i + d];
        for (size_t q = 3; q < nc; q++)
            c->Z[nc * i + q] = c->fid[i] >= 0 ? c->probe[(q - 3) * (size_t)c->nfree + (size_t)c->fid[i]] : 0.0;
    }
    return MCF_OK;
}

/* ------------------------------------------------------------- driver */

/* The positions after the steps so far (3*nv, fixed rows X0). */
static void positions(const fair_ctx *c, double *Y)
{
    if (c->is_explicit) {
        for (int i = 0; i < c->nv; i++)
            for (int d = 0; d < 3; d++)
                Y[3 * (size_t)i + d] = c->Z[(size_t)c->ncol * i + d];
        return;
    }
    memcpy(Y, c->X0, 3 * sizeof(double) * (size_t)c->nv);
    const double *y = c->Yc;
    for (int k = 0; k < c->nfree; k++)
        for (int d = 0; d < 3; d++)
            Y[3 * (size_t)c->vert[k] + d] = y[(size_t)d * c->nfree + k] / c->sq[k];
}

/* The amount: iterations steps, or SURE with the noise level (c->s,
 * c->s_t) read off the mesh or given; c->sure, c->cap. */
static mcf_status plan_amount(fair_ctx *c, mcf_error *err)
{
    const mcf_flow_params *p = c->p;
    mcf_flow_stats *st = c->st;
    double hbar = c->hbar;
    mcf_status rc;
    c->sure = p->iterations <= 0;
    c->cap = p->iterations > 0 ? p->iterations
             : (c->is_explicit ? MCF_FAIRING_MAX_PASSES : MCF_FAIRING_MAX_STEPS);
    if (c->cap > p->max_steps && !(p->iterations > 0))
        c->cap = p->max_steps;
    if (p->scheme == MCF_FAIRING_FEATURE)
        c->cap = 0; /* no linear steps: the noise level, weights and probes
                       for the feature stage (mcf__fair_feature) */
    c->s = c->s_t = 0.0;
    if (c->sure && c->like) { /* the same levels as the run compared with */
        c->s = c->like->s;
        c->s_t = c->like->s_t;
        c->s2_rel = c->like->s2_rel;
        /* as below (the run with no creases held has none to bound; a
         * set-up taken from a run clamped its X0 at this level) */
        if (!c->setup_from)
            mcf__fair_clamp_moves(c, c->X0, CREASE_MAX_MOVE * c->s, c->crease);
        if (!(c->s > 0.0) || c->nfree == 0)
            c->cap = 0;
    } else if (c->sure) {
        double s_est = 0.0, s_t = 0.0, s;
        mcf__noise_shape shape = {0};
        int robust = p->fairing_robust && !(p->noise_sigma > 0.0);
        work_span span = {c, AT(c, AT_SETUP), AT(c, AT_NOISE)};
        mcf__tick tick = {span_tick, &span};
        if ((rc = mcf__noise_levels(&c->g, c->X0, c->F, c->nf, c->nv, c->fx, &s_est, &s_t, robust ? &shape : NULL,
                                    &tick, err)) != MCF_OK)
            return rc;
        s = p->noise_sigma > 0.0 ? p->noise_sigma * hbar : s_est;
        /* the default request: noise along one direction (one viewpoint),
         * the high-pass vectors sharing one direction and the RMS reading
         * above the median one or the direction's reading far above it
         * (VIEW_SHARE, VIEW_RATIO, VIEW_DIR), is read along
         * that direction and split into its parts along the normals and
         * in the tangent planes (mcf__noise_shape) */
        int grid = robust && c->grid[0] > 0.0;
        int view = robust && !grid && shape.direction_share >= VIEW_SHARE &&
                   (shape.sigma_rms >= VIEW_RATIO * s_est || shape.sigma_dir >= VIEW_DIR * s_est);
        if (grid)
            s = mcf__fair_grid_level(c->grid);
        else if (view)
            s = shape.sigma_view;
        else if (robust && (shape.corr > shape.corr_noise + WHITE_GAP || c->exact))
            s = 0.0; /* no noise: the high-pass is the surface's (WHITE_GAP),
                        or the positions are exact (FLAT_SHARE) */
        if (!(p->noise_sigma > 0.0) && s < NOISE_FLOOR * hbar) {
            s = 0.0; /* rounding, not noise (NOISE_FLOOR) */
            view = 0;
        }
        /* the tangential noise: what the tangential reading shows beyond
         * TANGENTIAL_FLOOR mean edges, which clean scans' own irregular
         * triangles read as (0.02-0.12 on the shared scans: noise below
         * it cannot be told from the mesh), and at most the normal
         * noise (scanners' noise is isotropic at most), and none when
         * the reading stays under the normal level (TANGENTIAL_GATE_LO:
         * the triangles' own irregularity, not noise); one viewpoint's
         * noise: its part in the tangent planes, which is most of it
         * (two thirds of its variance for a direction at random) */
        double gate = s_est > 0.0 ? (s_t / s_est - TANGENTIAL_GATE_LO) / (TANGENTIAL_GATE_HI - TANGENTIAL_GATE_LO)
                                  : 0.0;
        s_t = grid   ? s
              : view ? shape.sigma_view_t
                     : fmin(sqrt(fmax(0.0, s_t * s_t - TANGENTIAL_FLOOR * TANGENTIAL_FLOOR * hbar * hbar)), s) *
                           fmax(0.0, fmin(1.0, gate));
        st->noise = hbar > 0.0 ? s / hbar : 0.0;
        st->noise_tangential = hbar > 0.0 ? s_t / hbar : 0.0;
        st->noise_share = shape.direction_share;
        st->noise_kind = p->noise_sigma > 0.0 ? MCF_NOISE_GIVEN
                         : view               ? MCF_NOISE_ONE_DIRECTION
                         : s_t > 0.0          ? MCF_NOISE_ISOTROPIC
                                              : MCF_NOISE_NORMAL;
        if (view)
            memcpy(st->noise_direction, shape.direction, sizeof shape.direction);
        /* the creases' smoothing along them moves a vertex by at most
         * CREASE_MAX_MOVE noise levels: more is the shape, not the noise
         * (a coarse mesh's zigzag "chains", car.drc: 0.27 units for noise
         * of 0.016) */
        mcf__fair_clamp_moves(c, c->X0, CREASE_MAX_MOVE * s, c->crease);
        /* no noise (or nothing free): nothing to remove */
        if (!(s > 0.0) || c->nfree == 0)
            c->cap = 0;
        c->s = s;
        c->s_t = s_t;
        /* the estimate's uncertainty (S2_REL_SQRT_N); none when the
         * level is given */
        c->s2_rel = p->noise_sigma > 0.0 || grid || c->nfree == 0 ? 0.0
                    : S2_REL_SQRT_N / sqrt((double)c->nfree);
    }
    c->share.s = c->s;
    c->share.s_t = c->s_t;
    c->share.s2_rel = c->s2_rel;
    st->t_target = c->cap;
    return MCF_OK;
}

/* The run's arrays, the probes, the SURE curve and the engine. */
static mcf_status run_init(fair_ctx *c, mcf_error *err)
{
    int nv = c->nv;
    c->nprobe = c->nfree > PROBES_FEW_ABOVE ? NPROBE_FEW : NPROBE;
    if (c->like && c->like->nprobe < c->nprobe)
        c->nprobe = c->like->nprobe;
    c->probe = c->sure ? mcf__fair_alloc(c, (size_t)c->nprobe * (c->nfree ? (size_t)c->nfree : 1)) : NULL;
    if (c->sure && !c->probe)
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d vertices)", nv);
    if (c->sure) {
        init_probes(c);
        c->st->sure = mcf__malloc((size_t)c->cap + 1, sizeof(double));
        if (!c->st->sure)
            return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory for the SURE curve");
    }
    /* the implicit steps solve the coordinates only, the probes' traces by
     * Lanczos quadrature (mcf_fairing_trace.c; filter_steps); the default
     * request's explicit run continues its implicit run's Lanczos runs (the
     * same N and probes) and moves the coordinates only; the explicit
     * passes alone carry the probes as columns: a Lanczos run of its own
     * cost them more than the columns (the 435k dragon at noise 0.25, 64
     * passes: 48 Lanczos steps a run, 5.5-6.5 s of CPU with the columns,
     * 7.6-7.9 s without; lab/results/quality/issue27-pick) */
    if (c->cap > 0 && c->sure && c->lz_from && mcf__fair_lz_fits(c, c->lz_from)) {
        c->lz = c->lz_from->lz;
        c->lz_from->lz = NULL;
    }
    c->ncol = c->sure && c->is_explicit && !c->lz ? 3 + c->nprobe : 3;
    return MCF_OK;
}

/* The last step SURE runs with K* its best so far: the first power of two
 * past K* + 5. The combination keeps only powers of two, and the next one
 * (twice that) lies past 2 K* + 10, where the rule before this one stopped:
 * the same kept iterates, so the same result unless SURE finds a lower
 * minimum between this stop and 2 K* + 10 (on a scan its curve is smooth
 * and rises from K* on: the 1.74M dragon's K* 40 stops at 64, not 91,
 * its output unchanged). */
static int sure_stop(int kstar)
{
    int k = 1;
    while (k <= kstar + 5)
        k *= 2;
    return k;
}

static void swap_ptr(double **a, double **b)
{
    double *t = *a;
    *a = *b;
    *b = t;
}

/* The steps, SURE after each (the normal and the tangential part), until
 * sure_stop(K*) or the cap: c->Ybest, c->Yt at c->kbest, c->kbest_t. */
static mcf_status run_steps(fair_ctx *c, mcf__step_hook hook, void *hook_ctx, mcf_error *err)
{
    mcf_flow_stats *st = c->st;
    double s = c->s, s_t = c->s_t, hbar = c->hbar, *Y = c->Y;
    double sumw = (double)c->nfree, best = 0.0, best_t = 0.0;
    mcf_status rc;
    if (c->sure) {
        best = s * s * sumw; /* SURE(0): the input, trace sum w */
        best_t = 2.0 * s_t * s_t * sumw;
        st->sure[0] = best / sumw / (hbar * hbar);
        st->nsure = 1;
    }
    /* the steps' share of the filter's work (work()): f after step k,
     * f0 after step k0, when the last step planned became kplan */
    double f = AT(c, AT_INIT), f0 = f;
    int k0 = 0, kplan = -1;
    for (int k = 1; k <= c->cap; k++) {
        if (hook && hook(hook_ctx, k - 1, NULL))
            return mcf__fail(err, MCF_ECANCELED, "canceled at step %d", k - 1);
        if (c->is_explicit) {
            double t0 = mcf_now();
            mcf__graph_taubin(&c->g, c->fx, c->Z, c->ncol, 1, c->tmp, c->p->threads,
                              c->threads_cpu_s);
            st->time_solve += mcf_now() - t0;
        } else if ((rc = mcf__fair_implicit_step(c, err)) != MCF_OK) {
            return rc;
        }
        if (!c->sure || !c->is_explicit)
            positions(c, Y); /* else in the moments' sweep, below */
        const double *cur = Y; /* this step's positions */
        if (!c->sure) {
            c->kbest = k;
        } else {
            double mo[6], vtr, zn, zt, est[NPROBE];
            mcf__fair_step_moments(c, Y, est, mo);
            if (c->lz && (rc = mcf__fair_lz_trace(c, k, est, err)) != MCF_OK)
                return rc;
            double tr = mcf__fair_mean_trace(est, c->nprobe, &vtr);
            double risk = mcf__fair_sure_of(c, 1, s, mo, tr, vtr, &zn);
            /* the tangential part: two directions, the same smoother */
            double risk_t = mcf__fair_sure_of(c, 2, s_t, mo + 3, tr, vtr, &zt);
            st->sure[st->nsure++] = risk / sumw / (hbar * hbar);
            /* a step counts only when SURE's gain over the input stands
             * out of its own uncertainty (SURE_MIN_GAIN) */
            int nb = risk < best && zn >= SURE_MIN_GAIN, nt = risk_t < best_t && zt >= SURE_MIN_GAIN;
            if (nb) {
                best = risk;
                c->kbest = k;
                memcpy(c->trbest, est, sizeof est);
            }
            if (nt) {
                best_t = risk_t;
                c->kbest_t = k;
            }
            /* the best positions taken by swapping buffers, not copying
             * them (the next step rewrites Y's free rows, and the fixed
             * rows of all three are X0's): a
             * copy at most, when both parts gain at once */
            if (nb) {
                swap_ptr(&c->Y, &c->Ybest);
                cur = c->Ybest;
                if (nt)
                    memcpy(c->Yt, c->Ybest, 3 * sizeof(double) * (size_t)c->nv);
            } else if (nt) {
                swap_ptr(&c->Y, &c->Yt);
                cur = c->Yt;
            }
            Y = c->Y;
            if ((k & (k - 1)) == 0)
                mcf__fair_keep_iterate(c, k, cur, est);
        }
        if (hook && hook(hook_ctx, k, c->quiet ? NULL : cur))
            return mcf__fail(err, MCF_ECANCELED, "canceled after step %d", k);
        int kend = c->sure ? sure_stop(c->kbest > c->kbest_t ? c->kbest : c->kbest_t) : c->cap;
        /* the steps' share, counted against the last step planned, at
         * least WORK_STEPS_PRIOR (SURE stops early on a clean mesh: the
         * share then jumps); when SURE's K* grows (a later stop), the
         * share so far stays and the rest spreads over the steps still to
         * run (no share held for many steps: the 435k noisy dragon's 26
         * of 64 before) */
        int prior = WORK_STEPS_PRIOR[c->is_explicit ? 1 : 0];
        int klast = kend > prior ? kend : prior;
        if (klast > c->cap)
            klast = c->cap; /* >= k: the loop ends at kend */
        if (klast != kplan) {
            kplan = klast;
            k0 = k - 1;
            f0 = f;
        }
        f = f0 + (1.0 - f0) * (k - k0) / (double)(klast - k0);
        work(c, c->is_explicit ? "passes" : "steps", f);
        if (c->sure && k >= kend)
            break;
    }
    if (!c->sure && c->cap > 0)
        memcpy(c->Ybest, Y, 3 * sizeof(double) * (size_t)c->nv);
    c->risk = best;
    return MCF_OK;
}

/* A filter's run up to its passes or steps (its noise levels, probes and
 * SURE curve set: the share a second run takes); c->is_explicit,
 * c->quiet set by the caller; g the graph of F (borrowed: every run of a
 * request shares one). */
static mcf_status filter_begin(fair_ctx *c, const mcf__graph *g, const double *X, const int32_t *F, int nf, int nv,
                               const unsigned char *fixed, const mcf_flow_params *p, double hbar,
                               mcf_flow_stats *st, mcf_error *err)
{
    mcf_status rc;
    c->p = p;
    c->nv = nv;
    c->nf = nf;
    c->F = F;
    c->st = st;
    c->hbar = hbar;
    c->g = *g;
    c->X0 = mcf__malloc(3 * (size_t)nv, sizeof(double));
    c->bytes += 3 * sizeof(double) * (size_t)nv;
    if (!c->X0)
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d vertices)", nv);
    memcpy(c->X0, X, 3 * sizeof(double) * (size_t)nv);
    if ((rc = phase_cancel(p, "the creases", err)) != MCF_OK || (rc = setup(c, fixed, err)) != MCF_OK)
        return rc;
    work(c, "setup", AT(c, AT_SETUP));
    if ((rc = phase_cancel(p, "the noise reading", err)) != MCF_OK || (rc = plan_amount(c, err)) != MCF_OK)
        return rc;
    work(c, "noise", AT(c, AT_NOISE));
    if ((rc = phase_cancel(p, "the probes", err)) != MCF_OK)
        return rc;
    return run_init(c, err);
}

/* The rest of a run filter_begin began: the positions' arrays, the
 * engine, the steps, the combination (c->Ybest, c->risk). */
static mcf_status filter_steps(fair_ctx *c, mcf__step_hook hook, void *hook_ctx, mcf_error *err)
{
    mcf_status rc = MCF_OK;
    size_t nv = (size_t)c->nv;
    c->Y = mcf__fair_alloc(c, 3 * nv);
    c->Ybest = mcf__fair_alloc(c, 3 * nv);
    c->Yt = mcf__fair_alloc(c, 3 * nv);
    if (!c->Y || !c->Ybest || !c->Yt)
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d vertices)", c->nv);
    /* the three hold X0 on the fixed rows, which the explicit engine's
     * moments sweep never writes (mcf__fair_step_moments) */
    memcpy(c->Y, c->X0, 3 * sizeof(double) * nv);
    memcpy(c->Ybest, c->X0, 3 * sizeof(double) * nv);
    memcpy(c->Yt, c->X0, 3 * sizeof(double) * nv);
    for (int j = 0; c->sure && j < COMB_J; j++) {
        c->dk[j] = mcf__malloc(3 * (size_t)(c->nfree ? c->nfree : 1), sizeof(float));
        c->bytes += 3 * sizeof(float) * (size_t)c->nfree;
        if (!c->dk[j])
            return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d vertices)", c->nv);
    }
    if ((rc = phase_cancel(c->p, c->is_explicit ? "the passes" : "the factorization", err)) != MCF_OK)
        return rc;
    if (c->cap > 0 && c->sure && !c->is_explicit)
        rc = mcf__fair_lz_new(c, err);
    if (rc == MCF_OK && c->cap > 0)
        rc = c->is_explicit ? explicit_init(c, err) : mcf__fair_implicit_init(c, err);
    if (rc != MCF_OK)
        return rc;
    work(c, c->is_explicit ? "probes" : "factor", AT(c, AT_INIT));
    if ((rc = run_steps(c, hook, hook_ctx, err)) == MCF_OK && c->sure)
        mcf__fair_combine(c);
    return rc;
}

mcf_status mcf__fair_filter_run(fair_ctx *c, const mcf__graph *g, const double *X, const int32_t *F, int nf, int nv,
                                const unsigned char *fixed, const mcf_flow_params *p, double hbar,
                                mcf_flow_stats *st, mcf__step_hook hook, void *hook_ctx, mcf_error *err)
{
    mcf_status rc = filter_begin(c, g, X, F, nf, nv, fixed, p, hbar, st, err);
    return rc == MCF_OK ? filter_steps(c, hook, hook_ctx, err) : rc;
}

/* A second run's figures (se) into st when it won (its SURE curve,
 * amount, combination); its curve freed when it lost. */
static void take_stats(mcf_flow_stats *st, mcf_flow_stats *se, int won, int is_explicit)
{
    st->time_solve += se->time_solve;
    if (!won) {
        free(se->sure);
        return;
    }
    free(st->sure);
    st->sure = se->sure;
    st->nsure = se->nsure;
    st->t_target = se->t_target;
    st->ncomb = se->ncomb;
    memcpy(st->comb_steps, se->comb_steps, sizeof st->comb_steps);
    memcpy(st->comb_weight, se->comb_weight, sizeof st->comb_weight);
    st->filter_explicit = is_explicit;
}

/* The feature-aware stage (mcf__fair_feature) on c's result, its
 * figures into st; *peak the bytes at most (ci, ce the first runs). */
static mcf_status feature_stage(fair_ctx *c, const fair_ctx *ci, const fair_ctx *ce, const mcf_flow_params *p,
                                int vs, mcf_flow_stats *st, const unsigned char *fixed, double *X, int *feat, size_t *peak,
                                mcf_error *err)
{
    c->st = st;
    st->steps = c->kbest;
    mcf__chol_free(c->chol); /* the factor is done with */
    c->chol = NULL;
    size_t before = c->bytes;
    mcf_status rc = mcf__fair_feature(c, p->scheme == MCF_FAIRING_FEATURE ? FEAT_VS_INPUT : vs, fixed, X, feat, err);
    if (ci->bytes + ce->bytes > *peak)
        *peak = ci->bytes + ce->bytes;
    c->bytes = before;
    return rc;
}

mcf_status mcf__fairing(double *X, const int32_t *F, int nf, int nv, const unsigned char *fixed,
                        const mcf_flow_params *p, double hbar, mcf_flow_stats *st,
                        mcf__step_hook hook, void *hook_ctx, mcf_error *err)
{
    fair_ctx ci, ce, cn, *c = &ci;
    mcf_flow_stats se;
    mcf__graph g;
    /* the graph, built once: the spike repair and every filter run take
     * it (it was built three times on the 1.74M scan, about 2% of the
     * request's CPU; perf, 2026-11-29); counted in the first run's bytes */
    mcf_status rc = mcf__graph_build(F, nf, nv, &g, err);
    if (rc != MCF_OK)
        return rc;
    if ((rc = phase_cancel(p, "the spike repair", err)) != MCF_OK) {
        mcf__graph_free(&g);
        return rc;
    }
    memset(&ci, 0, sizeof ci);
    memset(&ce, 0, sizeof ce);
    memset(&cn, 0, sizeof cn);
    ci.threads_cpu_s = ce.threads_cpu_s = cn.threads_cpu_s = &st->threads_cpu_s;
    ci.is_explicit = p->scheme == MCF_FAIRING_EXPLICIT;
    st->filter_explicit = ci.is_explicit;
    /* the shares of work (work()): the default's pick runs the explicit
     * passes after the implicit filter, the output last */
    int pick = p->fairing_pick && !ci.is_explicit && p->iterations <= 0;
    ci.w1 = pick ? 1.0 - WORK_OUTPUT - WORK_PICK : 1.0 - WORK_OUTPUT;
    ce.w0 = ci.w1;
    ce.w1 = 1.0 - WORK_OUTPUT;
    ci.bytes = sizeof(int) * ((size_t)nv + 1 + (size_t)g.ptr[nv]);
    /* the default request: the spikes repaired first (mcf_spikes.c); the
     * filter then takes the repaired mesh as its input */
    double *Xs = NULL;
    st->robust = p->fairing_robust && p->iterations <= 0;
    if ((st->robust && (rc = mcf__fair_read_input(&g, X, F, nf, nv, fixed, hbar, ci.grid, &ci.exact, st, &Xs,
                                                  err)) != MCF_OK) ||
        (rc = phase_cancel(p, "the filter", err)) != MCF_OK) {
        free(Xs);
        mcf__graph_free(&g);
        return rc;
    }
    if (st->robust) {
        ci.w0 = WORK_REPAIR;
        if (p->work)
            p->work(p->progress_ctx, "spikes", WORK_REPAIR);
    }
    ce.exact = cn.exact = ci.exact;
    memcpy(ce.grid, ci.grid, sizeof ci.grid);
    memcpy(cn.grid, ci.grid, sizeof ci.grid);
    const double *Xf = Xs ? Xs : X;
    /* the request's input's face normals: the fold guard judges the
     * output against them too (the repair turns the faces at a spike; the
     * `folds` warning counts against the request's input) */
    double *fn_orig = Xs ? mcf__malloc(3 * (size_t)nf + 1, sizeof(double)) : NULL;
    if (Xs && !fn_orig) {
        free(Xs);
        mcf__graph_free(&g);
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d faces)", nf);
    }
    if (fn_orig)
        mcf__face_normals(X, F, nf, fn_orig);
    ci.fn_orig = ce.fn_orig = cn.fn_orig = fn_orig;
    /* the default request's passes (fairing_explicit: above 150,000
     * vertices) with the automatic amount: the run holding the creases is
     * begun, and its passes made once the second look (below) is judged
     * near the creases and keeps them, or is judged on the whole mesh */
    int defer = ci.is_explicit && p->fairing_robust && p->iterations <= 0 && p->scheme != MCF_FAIRING_FEATURE;
    rc = defer ? filter_begin(&ci, &g, Xf, F, nf, nv, fixed, p, hbar, st, err)
               : mcf__fair_filter_run(&ci, &g, Xf, F, nf, nv, fixed, p, hbar, st, hook, hook_ctx, err);
    size_t extra = Xs ? 3 * sizeof(double) * ((size_t)nv + (size_t)nf) : 0;
    size_t peak = ci.bytes + mcf__chol_bytes(ci.chol) + extra;
    /* the default request's `fairing` (fairing_pick) with the automatic
     * amount: the explicit passes too, the lower SURE taken
     * (pick_explicit); the factor freed first */
    if (rc == MCF_OK && p->fairing_pick && !ci.is_explicit && ci.sure && ci.cap > 0) {
        mcf__chol_free(ci.chol);
        ci.chol = NULL;
        memset(&se, 0, sizeof se);
        ce.is_explicit = ce.quiet = 1;
        /* the implicit run's noise levels (the same reading of the same
         * input: about 5% of the request's CPU, read twice before) and
         * probes, and its Lanczos runs (run_init) */
        ci.share.probe = ci.probe;
        ci.share.fid = ci.fid;
        ci.share.nfree = ci.nfree;
        ci.share.nprobe = ci.nprobe;
        ce.like = &ci.share;
        ce.lz_from = &ci;
        ce.setup_from = &ci;
        rc = mcf__fair_filter_run(&ce, &g, Xf, F, nf, nv, fixed, p, hbar, &se, hook, hook_ctx, err);
        int won = rc == MCF_OK && mcf__fair_pick_explicit(&ci, &ce);
        take_stats(st, &se, won, 1);
        c = won ? &ce : &ci;
        /* the tangential step stays the implicit run's: the passes' own
         * (one pass of tangential SURE gain) read the coarse torus's
         * uneven triangles as tangential noise (test_coarse_torus_taubin,
         * noise 0.1 seeds 1 and 3: 1.13x and 1.23x the input's error
         * with it, 0.66x and 0.72x with the implicit run's) */
        if (won) {
            memcpy(ce.Yt, ci.Yt, 3 * sizeof(double) * (size_t)nv);
            ce.kbest_t = ci.kbest_t;
        }
        if (ci.bytes + ce.bytes > peak)
            peak = ci.bytes + ce.bytes;
    }
    /* the default request on a mesh with creases: the same filter again
     * with none held, taken when SURE says so (mcf__fair_pick_uncreased):
     * an organic scan's sharpest ridges pass the crease test, and holding
     * them, noise and all, cost it up to 9% of error (docs/fairing.md,
     * "Creases"); and the feature-aware stage: the named `fairing_feature`
     * alone, the default request's against the linear result on meshes
     * with creases (FEATURE_CREASE_SHARE of those found), unless the noise
     * reads as one viewpoint's: the stage moves along the normals, and
     * most of that noise lies in the tangent planes (docs/fairing.md) */
    int found = st->crease_vertices, feat = 0;
    double moving = (double)c->nfree + found;
    int creased = found > 0 && found >= FEATURE_CREASE_SHARE * moving && found <= FEATURE_CREASE_MAX * moving &&
                  st->noise_kind != MCF_NOISE_ONE_DIRECTION;
    int uncrease = rc == MCF_OK && p->fairing_robust && p->scheme != MCF_FAIRING_FEATURE && c->sure && c->cap > 0 &&
                   found > 0;
    int staged = rc == MCF_OK && c->sure && (p->scheme == MCF_FAIRING_FEATURE || (p->fairing_pick && creased));
    /* The passes' second look judged near the creases
     * (mcf_fairing_sub.c): judged 1, the passes with none held are the
     * request's only ones; 0, the held run's; -1 (the creases' submesh is
     * most of the mesh, the feature stage goes first, or tangential noise,
     * whose step is the held run's: mcf__fair_output), both runs in full
     * and SURE's pick on the whole mesh, as below 150,000 vertices. When
     * both judgements agree the output is the same to the bit */
    int judged = -1;
    if (defer) {
        size_t jb = 0;
        int sampled = 0;
        if (rc == MCF_OK && uncrease && !staged && !(ci.s_t > 0.0) && !p->fairing_look_whole)
            rc = mcf__fair_judge_near_creases(&ci, Xf, fixed, hook, hook_ctx, &judged, &sampled, &jb, err);
        st->crease_look_near = judged < 0 ? 0 : sampled ? 2 : 1;
        if (rc == MCF_OK && judged != 1)
            rc = filter_steps(&ci, hook, hook_ctx, err);
        if (ci.bytes + extra + jb > peak)
            peak = ci.bytes + extra + jb;
    }
    /* Both: the stage first, against the result with the creases held
     * (FEATURE_HELD_GAIN); taken, the run with none held is not made (on
     * couplingdown_sub2 a factorization of the whole mesh, where the held
     * creases cut it into patches: up to 0.8 s of CPU of 2-3 s);
     * not taken, that run is made and the stage not again: the opponent
     * only got better (docs/fairing.md, "Creases") */
    if (staged && uncrease) {
        rc = feature_stage(c, &ci, &ce, p, FEAT_VS_HELD, st, fixed, X, &feat, &peak, err);
        staged = 0;
    }
    if (rc == MCF_OK && uncrease && !feat && judged != 0) {
        mcf__chol_free(c->chol);
        c->chol = NULL;
        /* the first runs' passes are done: their Z and tmp (167 MB on the
         * 1.74M scan) need not live through this one */
        size_t dropped = drop_engine(&ci) + drop_engine(&ce);
        memset(&se, 0, sizeof se);
        cn.is_explicit = c->is_explicit;
        cn.no_creases = 1;
        cn.quiet = judged != 1; /* else its passes are the request's */
        c->share.probe = c->probe;
        c->share.fid = c->fid;
        c->share.nfree = c->nfree;
        c->share.nprobe = c->nprobe;
        cn.like = &c->share;
        cn.w0 = judged == 1 ? c->work_done : 1.0 - WORK_OUTPUT;
        cn.w1 = judged == 1 ? c->w1 : 1.0 - WORK_OUTPUT;
        rc = mcf__fair_filter_run(&cn, &g, Xf, F, nf, nv, fixed, p, hbar, &se, hook, hook_ctx, err);
        size_t both = ci.bytes + ce.bytes - dropped + cn.bytes + mcf__chol_bytes(cn.chol);
        if (both > peak)
            peak = both;
        mcf__chol_free(cn.chol);
        cn.chol = NULL;
        double kdiv[NPROBE];
        int won = judged == 1 ? rc == MCF_OK && cn.kbest > 0
                              : rc == MCF_OK && mcf__fair_crease_divergence(c, &cn, fixed, kdiv) &&
                                    mcf__fair_pick_uncreased(c, &cn, kdiv, NULL);
        if (rc == MCF_OK && !won && judged == 1) { /* none held found nothing: the held run's passes after all */
            c->quiet = 1;
            rc = filter_steps(c, hook, hook_ctx, err);
        }
        take_stats(st, &se, won, cn.is_explicit);
        if (won) {
            /* the first run's tangential step, as above: the implicit
             * run's below 150,000 vertices; above, where the default is
             * fairing_explicit, the creased passes' own (none when they
             * were not made: judged near the creases, with no tangential
             * noise) */
            if (cn.is_explicit && ci.Yt) {
                memcpy(cn.Yt, ci.Yt, 3 * sizeof(double) * (size_t)nv);
                cn.kbest_t = ci.kbest_t;
            }
            st->crease_vertices = 0;
            c = &cn;
        }
    }
    c->st = st; /* the second runs' own figures were taken above: the
                   feature stage's and the output's go to the caller's */
    st->steps = c->kbest;
    if (rc == MCF_OK && staged)
        rc = feature_stage(c, &ci, &ce, p, FEAT_VS_LINEAR, st, fixed, X, &feat, &peak, err);
    if (rc == MCF_OK)
        rc = phase_cancel(p, "the output", err);
    if (rc == MCF_OK && !feat) {
        st->tangential_steps = c->kbest_t;
        size_t before = c->bytes;
        /* the output's figures (the guard's, the flips') are the run's:
         * the explicit passes ran with their own stats (se) */
        c->st = st;
        rc = mcf__fair_output(c, X, err);
        peak += c->bytes - before; /* the guard's arrays */
    }
    /* the output is done (the feature stage writes its own) */
    if (rc == MCF_OK) {
        c->w0 = 0.0;
        c->w1 = 1.0;
        work(c, "output", 1.0);
    }
    if (p->scheme != MCF_FAIRING_FEATURE)
        st->filter = feat ? MCF_FAIRING_FEATURE : c->is_explicit ? MCF_FAIRING_EXPLICIT : MCF_FAIRING;
    st->peak_bytes = peak;
    free(Xs);
    free(fn_orig);
    mcf__fair_free(&ci);
    mcf__fair_free(&ce);
    mcf__fair_free(&cn);
    mcf__graph_free(&g);
    return rc;
}
