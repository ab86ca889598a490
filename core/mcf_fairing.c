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
 * six Rademacher probes carried through the same steps as extra columns
 * (Hutchinson); for the implicit step T = D^-1/2 R D^1/2, R = (I + NN')^-1,
 * so the probes run through R in y. The run stops once K > 2 K* + 10 (K*
 * the best so far) or at the cap. It keeps the displacements Y_k - X0
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

#include "mcf_internal.h"

enum { NPROBE = 6, NCOL = 3 + NPROBE };
#define TANGENTIAL_FLOOR 0.12
/* the creases' smoothing along them moves a vertex by at most one noise
 * level: on car.drc's coarse chains (hubs of 11-12 edges) it took shape
 * away at 2 (normal noise 0.25, seeds 1-3: 0.959, 0.853, 0.973 of the
 * input's error; 1: 0.852, 0.831, 0.900); the box of test_creases_kept
 * and the shared scans change by less than 1% */
#define CREASE_MAX_MOVE 1.0
/* the largest move of a vertex from the input, in noise levels: Gaussian
 * noise moves a vertex further than 3 of its deviations along the normal
 * once in 370; a filter that moves it further takes away shape (the
 * coarse car.drc, noise 0.1 mean edges: error 2.63x the input's without
 * the two bounds, 1.31x with them; snowden (seed 1) and dragon_vrip_res2
 * (seed 2) at 0.1: 0.573 -> 0.547 and 0.561 -> 0.547 of the input's; no
 * shared scan worse, 8 meshes x 3 levels of noise along the normals and
 * 3 meshes x 3 isotropic measured; 4 deviations: car 1.46x). Beyond it a
 * move is taken back linearly, to none at MAX_MOVE (1 + MOVE_TAPER): a
 * move that long is a feature the filter removes, which clamping keeps
 * removing by MAX_MOVE (car.drc, isotropic noise 0.1, seeds 2-3: 1.010
 * and 1.024 of the input's error clamped, 0.988 and 0.996 tapered) */
#define MAX_MOVE 3.0
#define MOVE_TAPER 2.0
/* the least gain of SURE over the input, in its standard errors
 * (sure_of), for a step to count: one-sided, 2 leaves about 2% of the
 * steps that gain nothing; the gain's error is small on a scan (one step
 * count of the 180 `make quality` cases changed, by one), of the gain's size on
 * a coarse mesh (car.drc: 300 free vertices, a few 15x the mean area) */
#define SURE_MIN_GAIN 2.0
/* the relative standard error of the noise level's square, times
 * sqrt(n): the estimate is a ratio of two medians of |high-pass| over
 * about n = nfree vertices, each with a relative standard error of
 * 1.166 / sqrt(n) (a median m of |Gaussian| values: 1 / (2 f(m) sqrt(n))
 * over m, m = 0.6745, f(m) = 0.636), so sqrt(2) 1.166 on s, twice that on
 * s^2 */
#define S2_REL_SQRT_N 3.3
/* the guard's positions move a vertex along the surface by at most one
 * noise level (guard_positions) */
#define GUARD_TANGENTIAL 1.0
/* The combination (combine): the iterates after the last COMB_J powers
 * of two of steps, e.g. 2, 4, 8 and 16 for a run that stops at 21.
 * Measured in numpy (normal noise 0.1 and 0.25, seed 1, against the
 * product's cotan Taubin at its best pass count; the filter alone, without
 * the creases, bounds and guard): 4 iterates 0.72-1.03 (spot 0.25 0.846
 * -> 0.796, knot1 0.1 0.874 -> 0.721, armadillo 0.1 0.943 -> 0.898,
 * fertility 0.25 0.719 -> 0.727, the one worse case of 16); 2 iterates
 * gain half as much, 3 nearly as much; every power of two and every
 * k = 2^a, 3 2^a up to the stop the same within 1%; coefficients of the
 * powers of two stay within +-11 (consecutive k: up to +-35). */
#define COMB_J MCF_FAIRING_COMB
/* SURE is unbiased for fixed weights; weights fitted to it on the same
 * data see it low by about 2 s^2 per weight (in sum w units, as for a
 * least-squares fit of COMB_J parameters): charged before the comparison
 * with the best single step, a few percent of the risk on a 300-vertex
 * mesh, nothing on a scan */
#define COMB_PENALTY 2.0
/* The combination's gain 1 + sum_j c_j (g(k)^kj - 1) on the spectrum
 * k in [0, 2] stays within [COMB_GAIN_MIN, COMB_GAIN_MAX]: a denoiser
 * does not amplify, nor turn a frequency over by more than half. The
 * combinations SURE chose on the shared scans (numpy, noise 0.1 and
 * 0.25) stay within -0.22 .. 1.015; a clean sphere told noise 0.5
 * (strength 0.5: SURE's model wrong, the iterates nearly equal) got
 * weights of +-250,000, a gain of -32,575 .. 6,893, and vertices moved by
 * 0.16 of its radius (0.01 at K*) */
/* The explicit passes replace the implicit steps (pick_explicit) when
 * SURE's gain over them is at least PICK_MIN_GAIN of its standard error:
 * both results already passed SURE_MIN_GAIN against the input, so a
 * wrong pick trades one denoised result for another rather than harming
 * the mesh; one standard error (one-sided, 84%) bounds the pick's
 * selection bias (a minimum of two estimates reads low by at most 0.4 of
 * the difference's standard error) to what the gain shows. The error is
 * mostly the noise level's (s2_rel: 0.21 on 250 vertices); the even
 * coarse torus of test_coarse_torus_taubin at noise 0.25, seed 1, gains
 * 1.37 standard errors: 2 kept the implicit steps, 1.24x the uniform
 * Taubin oracle. */
#define PICK_MIN_GAIN 1.0
#define COMB_GAIN_MIN (-0.5)
#define COMB_GAIN_MAX 1.1

typedef struct {
    const mcf_flow_params *p;
    int nv, nf, nfree;
    const int32_t *F;
    double *X0;                /* a copy of the input, working units
                                  (crease vertices smoothed along) */
    double *Xin;               /* the input itself where X0 differs
                                  (creases), else NULL */
    unsigned char *crease;     /* nv: on a kept crease */
    unsigned char *fx;         /* nv: fixed, or no edge */
    mcf__graph g;
    int *vert;                 /* nfree: free index -> vertex */
    int *fid;                  /* nv: vertex -> free index, -1 fixed */
    double *sq;                /* nfree: sqrt(D) */
    double *w;                 /* nv: area weights (0 on fixed) */
    double *n0;                /* 3*nv: normals of X0 */
    double *probe;             /* NPROBE * nfree: the Rademacher probes */
    int ncol;                  /* 3, or 9 with the probes */
    int is_explicit;
    int quiet;                 /* the hook sees no steps (cancel only) */
    double w0, w1;             /* its share of the run's work (work()) */
    /* explicit: Z (nv x ncol, row-major), tmp the same */
    double *Z, *tmp;
    /* implicit */
    mcf__pattern apat;         /* I + N N' (upper triangle) */
    double *ax;                /* its values */
    mcf__chol *chol;
    double *Yc;                /* nfree x ncol, column-major: y, the probes */
    double *b;                 /* 3 * nfree: N u, column-major */
    size_t bytes;
    mcf_flow_stats *st;
    /* the run (mcf__fairing's phases) */
    double hbar;               /* the mean edge */
    int sure;                  /* the amount by SURE (else iterations) */
    int cap;                   /* the most steps */
    double s, s_t;             /* the noise levels, normal and tangential */
    double *Y, *Ybest, *Yt;    /* 3*nv: the last step, SURE's best (normal,
                                  tangential) */
    int kbest, kbest_t;        /* their steps */
    double risk;               /* SURE at kbest (sum w units) */
    double trbest[NPROBE];     /* its probes' weighted traces */
    float *dk[COMB_J];         /* 3*nfree: Y_k - X0 on the free vertices
                                  after the last powers of two k, oldest
                                  first */
    int kk[COMB_J], nk;        /* their k, how many */
    double trq[COMB_J][NPROBE]; /* their probes' weighted traces */
    double sumw2;              /* sum_F w^2 (sum_F w = nfree) */
    double s2_rel;             /* relative standard error of s^2 */
} fair_ctx;

static void fair_free(fair_ctx *c)
{
    mcf__graph_free(&c->g);
    free(c->X0);
    free(c->Y);
    free(c->Ybest);
    free(c->Yt);
    free(c->Xin);
    free(c->crease);
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
    for (int j = 0; j < COMB_J; j++)
        free(c->dk[j]);
}

static double *alloc_d(fair_ctx *c, size_t n)
{
    c->bytes += n * sizeof(double);
    return mcf__malloc(n ? n : 1, sizeof(double));
}

/* The free set, degrees, weights, the input's normals and the probes. */
static mcf_status setup(fair_ctx *c, const unsigned char *fixed, mcf_error *err)
{
    int nv = c->nv;
    mcf_status rc = mcf__graph_build(c->F, c->nf, nv, &c->g, err);
    if (rc != MCF_OK)
        return rc;
    c->bytes += sizeof(int) * ((size_t)nv + 1 + (size_t)c->g.ptr[nv]);
    c->fx = mcf__malloc((size_t)nv, 1);
    c->fid = mcf__malloc((size_t)nv, sizeof(int));
    c->vert = mcf__malloc((size_t)nv, sizeof(int));
    c->w = alloc_d(c, (size_t)nv);
    c->n0 = alloc_d(c, 3 * (size_t)nv);
    c->sq = alloc_d(c, (size_t)nv);
    if (!c->fx || !c->fid || !c->vert || !c->w || !c->n0 || !c->sq)
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d vertices)", nv);
    /* the creases: held for the surface's filter, smoothed along */
    unsigned char *crease = c->crease = mcf__calloc((size_t)nv, 1);
    c->Xin = alloc_d(c, 3 * (size_t)nv);
    if (c->Xin)
        memcpy(c->Xin, c->X0, 3 * sizeof(double) * (size_t)nv);
    int ncrease = crease && c->Xin ? mcf__creases(&c->g, c->F, c->nf, nv, fixed, c->X0, crease) : -1;
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

static void init_probes(fair_ctx *c)
{
    for (int q = 0; q < NPROBE; q++)
        for (int k = 0; k < c->nfree; k++)
            c->probe[(size_t)q * c->nfree + k] =
                (mcf__mix64((uint64_t)q * 0x9e3779b97f4a7c15ULL + (uint64_t)k + 1) >> 63) ? 1.0 : -1.0;
}

/* ----------------------------------------------------- implicit engine */

/* The entries of column k of N = D^-1/2 L_FF D^-1/2 (symmetric): the
 * free neighbours of vert[k] and k itself, ascending, into row/val;
 * returns their count. */
static int n_column(const fair_ctx *c, int k, int *row, double *val)
{
    int i = c->vert[k], q = 0, placed = 0;
    for (int t = c->g.ptr[i]; t <= c->g.ptr[i + 1]; t++) {
        int j = t < c->g.ptr[i + 1] ? c->g.adj[t] : -1;
        if (!placed && (j < 0 || j > i)) {
            row[q] = k;
            val[q++] = 1.0;
            placed = 1;
        }
        if (j >= 0 && c->fid[j] >= 0) {
            row[q] = c->fid[j];
            val[q++] = -1.0 / (c->sq[k] * c->sq[c->fid[j]]);
        }
    }
    return q;
}

/* A = I + N N' = I + N^2, its upper triangle by columns (rows ascending,
 * the diagonal last) into c->apat and c->ax: column j gathers N_ik N_kj
 * over the entries k of N's column j and i <= j of N's column k (the free
 * 2-ring of j). N by columns first (np, nr, nx), then two passes: the
 * counts, then the entries. */
static mcf_status assemble(fair_ctx *c, mcf_error *err)
{
    int n = c->nfree;
    size_t nnz_n = (size_t)n;
    for (int k = 0; k < n; k++)
        nnz_n += (size_t)(c->g.ptr[c->vert[k] + 1] - c->g.ptr[c->vert[k]]);
    int *mark = mcf__malloc((size_t)n, sizeof(int)), *list = mcf__malloc((size_t)n, sizeof(int));
    int *np = mcf__malloc((size_t)n + 1, sizeof(int)), *nr = mcf__malloc(nnz_n, sizeof(int));
    double *acc = mcf__malloc((size_t)n, sizeof(double)), *nx = mcf__malloc(nnz_n, sizeof(double));
    int *cp = c->apat.colptr = mcf__malloc((size_t)n + 1, sizeof(int));
    mcf_status rc = MCF_OK;
    if (!mark || !list || !np || !nr || !acc || !nx || !cp) {
        rc = mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d free vertices)", n);
        goto done;
    }
    np[0] = 0;
    for (int k = 0; k < n; k++)
        np[k + 1] = np[k] + n_column(c, k, nr + np[k], nx + np[k]);
    c->apat.n = n;
    for (int pass = 0; pass < 2; pass++) {
        for (int i = 0; i < n; i++)
            mark[i] = -1;
        size_t q = 0;
        for (int j = 0; j < n; j++) {
            int m = 0;
            cp[j] = (int)q;
            for (int a = np[j]; a < np[j + 1]; a++) {
                int k = nr[a];
                for (int b = np[k]; b < np[k + 1] && nr[b] <= j; b++) {
                    int i = nr[b];
                    if (mark[i] != j) {
                        mark[i] = j;
                        acc[i] = 0.0;
                        list[m++] = i;
                    }
                    acc[i] += nx[b] * nx[a];
                }
            }
            if (pass == 1) {
                for (int a = 1; a < m; a++) /* insertion sort: a 2-ring */
                    for (int b = a; b > 0 && list[b - 1] > list[b]; b--) {
                        int t = list[b];
                        list[b] = list[b - 1];
                        list[b - 1] = t;
                    }
                for (int a = 0; a < m; a++) {
                    c->apat.rowind[q + (size_t)a] = list[a];
                    c->ax[q + (size_t)a] = acc[list[a]] + (list[a] == j ? 1.0 : 0.0);
                }
            }
            q += (size_t)m;
        }
        cp[n] = (int)q;
        if (pass == 0) {
            if (q > (size_t)INT32_MAX) {
                rc = mcf__fail(err, MCF_ELIMIT, "fairing: the system of %d free vertices is too large", n);
                goto done;
            }
            c->apat.nnz = (int)q;
            c->apat.rowind = mcf__malloc(q ? q : 1, sizeof(int));
            c->ax = alloc_d(c, q);
            c->bytes += sizeof(int) * (q + (size_t)n + 1);
            if (!c->apat.rowind || !c->ax) {
                rc = mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d free vertices)", n);
                goto done;
            }
        }
    }
done:
    free(mark);
    free(list);
    free(np);
    free(nr);
    free(acc);
    free(nx);
    return rc;
}

static mcf_status implicit_init(fair_ctx *c, mcf_error *err)
{
    int n = c->nfree;
    mcf_status rc;
    c->Yc = alloc_d(c, (size_t)c->ncol * (size_t)n);
    c->b = alloc_d(c, 3 * (size_t)n);
    if (!c->Yc || !c->b)
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d free vertices)", n);
    if ((rc = assemble(c, err)) != MCF_OK || !(c->chol = mcf__chol_new(&c->apat, c->ncol, err)))
        return rc != MCF_OK ? rc : MCF_ENOMEM;
    double t0 = mcf_now();
    rc = mcf__chol_analyze(c->chol, err);
    c->st->time_analyze += mcf_now() - t0;
    if (rc != MCF_OK)
        return rc;
    t0 = mcf_now();
    rc = mcf__chol_factorize(c->chol, c->ax, err);
    c->st->time_factorize += mcf_now() - t0;
    c->st->factorizations++;
    if (rc != MCF_OK)
        return rc;
    /* b = N u, u_k = -D_k^-1/2 sum of the fixed neighbours' positions */
    double *u = c->b, *y = c->Yc;
    for (int k = 0; k < n; k++) {
        int i = c->vert[k];
        double s[3] = {0, 0, 0};
        for (int t = c->g.ptr[i]; t < c->g.ptr[i + 1]; t++)
            if (c->fid[c->g.adj[t]] < 0)
                for (int d = 0; d < 3; d++)
                    s[d] += c->X0[3 * (size_t)c->g.adj[t] + d];
        for (int d = 0; d < 3; d++)
            y[(size_t)d * n + k] = -s[d] / c->sq[k]; /* u, in Yc for now */
    }
    for (int k = 0; k < n; k++) {
        int i = c->vert[k];
        for (int d = 0; d < 3; d++) {
            double s = y[(size_t)d * n + k];
            for (int t = c->g.ptr[i]; t < c->g.ptr[i + 1]; t++) {
                int l = c->fid[c->g.adj[t]];
                if (l >= 0)
                    s -= y[(size_t)d * n + l] / (c->sq[k] * c->sq[l]);
            }
            u[(size_t)d * n + k] = s;
        }
    }
    /* y0 = D^1/2 x0, then the probes */
    for (int k = 0; k < n; k++)
        for (int d = 0; d < 3; d++)
            y[(size_t)d * n + k] = c->sq[k] * c->X0[3 * (size_t)c->vert[k] + d];
    if (c->ncol > 3)
        memcpy(y + 3 * (size_t)n, c->probe, sizeof(double) * NPROBE * (size_t)n);
    return MCF_OK;
}

static mcf_status implicit_step(fair_ctx *c, mcf_error *err)
{
    int n = c->nfree;
    double t0 = mcf_now();
    double *y = c->Yc;
    for (size_t q = 0; q < 3 * (size_t)n; q++)
        y[q] -= c->b[q];
    mcf_status rc = mcf__chol_solve(c->chol, c->ncol, y, 1, (size_t)n, y, err);
    if (rc != MCF_OK)
        return rc;
    c->st->time_solve += mcf_now() - t0;
    c->st->solves += c->ncol / 3;
    return MCF_OK;
}

/* ----------------------------------------------------- explicit engine */

static mcf_status explicit_init(fair_ctx *c, mcf_error *err)
{
    size_t nv = (size_t)c->nv, nc = (size_t)c->ncol;
    c->Z = alloc_d(c, nv * nc);
    c->tmp = alloc_d(c, nv * nc);
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

/* The probes' estimates of sum_i w_i (T^K)_ii into est. */
static void probe_traces(const fair_ctx *c, double est[NPROBE])
{
    for (int q = 0; q < NPROBE; q++) {
        est[q] = 0.0;
        for (int k = 0; k < c->nfree; k++) {
            int i = c->vert[k];
            double z = c->probe[(size_t)q * c->nfree + k];
            double y = c->is_explicit ? c->Z[(size_t)c->ncol * i + 3 + q]
                                      : c->Yc[(size_t)(3 + q) * c->nfree + k];
            est[q] += c->w[i] * z * y;
        }
    }
}

/* The mean of the probes' estimates est, and the variance of that mean
 * (*var). */
static double mean_trace(const double est[NPROBE], double *var)
{
    double tr = 0.0, v = 0.0;
    for (int q = 0; q < NPROBE; q++)
        tr += est[q] / NPROBE;
    for (int q = 0; q < NPROBE; q++)
        v += (est[q] - tr) * (est[q] - tr);
    *var = v / ((NPROBE - 1) * NPROBE);
    return tr;
}

/* The displacement's moments for SURE, r along n0 and t its part in the
 * tangent planes of n0: m[0] = sum_F w r^2, m[1] = sum w^2 r^2, m[2] =
 * sum w^2 r^4, and m[3..5] the same of |t|. */
static void weighted_r2(const fair_ctx *c, const double *Y, double m[6])
{
    memset(m, 0, 6 * sizeof(double));
    for (int k = 0; k < c->nfree; k++) {
        size_t i = (size_t)c->vert[k];
        double d[3];
        mcf__sub3(Y + 3 * i, c->X0 + 3 * i, d);
        double r = mcf__dot3(c->n0 + 3 * i, d), r2 = r * r, t2 = fmax(0.0, mcf__dot3(d, d) - r2);
        double w = c->w[i];
        m[0] += w * r2;
        m[1] += w * w * r2;
        m[2] += w * w * r2 * r2;
        m[3] += w * t2;
        m[4] += w * w * t2;
        m[5] += w * w * t2 * t2;
    }
}

/* The variance of a SURE gain (over the input, or of one result over
 * another: the same input, weights and probes) with v the noise variance
 * it is scaled by: the gain is a sum over the n free vertices of terms
 * with sum sd and sum of squares sd2, whose spread is taken as that of n
 * independent terms; the traces' difference dtr enters with 2 v (the
 * probes' variance vtr); and the gain grows with v as 2 dtr, v being
 * estimated with a relative standard error c->s2_rel. */
static double gain_var(const fair_ctx *c, double v, int n, double sd, double sd2, double dtr,
                       double vtr)
{
    double ds = 2.0 * dtr * v * c->s2_rel;
    double spread = n > 1 ? fmax(0.0, sd2 - sd * sd / n) * n / (n - 1.0) : 0.0;
    return spread + (4.0 * v * v * vtr + ds * ds);
}

/* SURE(K) for dim directions of noise level sig (1 along the normals, 2
 * in the tangent planes) from the moments mo (sum w rho^2, sum w^2 rho^2,
 * sum w^2 rho^4) and the trace tr (its probe variance vtr). *z gets the
 * gain over SURE(0) = dim sig^2 sum w in its standard errors (gain_var):
 * the gain is a sum over the free vertices of d_i = w_i (2 dim sig^2 (1 -
 * tr / sum w) - rho_i^2), and the traces' difference is sum w - tr. */
static double sure_of(const fair_ctx *c, int dim, double sig, const double *mo, double tr, double vtr,
                      double *z)
{
    double sw = (double)c->nfree, v = dim * sig * sig;
    double risk = mo[0] - v * sw + 2.0 * v * tr, gain = v * sw - risk;
    double cc = 2.0 * v * (1.0 - tr / sw);
    double sd2 = cc * cc * c->sumw2 - 2.0 * cc * mo[1] + mo[2]; /* sum d_i^2 */
    double var = gain_var(c, v, c->nfree, gain, sd2, sw - tr, vtr);
    *z = var > 0.0 ? gain / sqrt(var) : (gain > 0.0 ? INFINITY : 0.0);
    return risk;
}

/* The closest point to p on triangle (a, b, c) (Ericson, Real-Time
 * Collision Detection, 5.1.5) into q. */
static void closest_on_triangle(const double *p, const double *a, const double *b, const double *c,
                                double *q)
{
    double ab[3], ac[3], ap[3], bp[3], cp[3];
    mcf__sub3(b, a, ab);
    mcf__sub3(c, a, ac);
    mcf__sub3(p, a, ap);
    double d1 = mcf__dot3(ab, ap), d2 = mcf__dot3(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0) {
        memcpy(q, a, 3 * sizeof(double));
        return;
    }
    mcf__sub3(p, b, bp);
    double d3 = mcf__dot3(ab, bp), d4 = mcf__dot3(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) {
        memcpy(q, b, 3 * sizeof(double));
        return;
    }
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        double v = d1 / (d1 - d3);
        for (int e = 0; e < 3; e++)
            q[e] = a[e] + v * ab[e];
        return;
    }
    mcf__sub3(p, c, cp);
    double d5 = mcf__dot3(ab, cp), d6 = mcf__dot3(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) {
        memcpy(q, c, 3 * sizeof(double));
        return;
    }
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        double w = d2 / (d2 - d6);
        for (int e = 0; e < 3; e++)
            q[e] = a[e] + w * ac[e];
        return;
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        for (int e = 0; e < 3; e++)
            q[e] = b[e] + w * (c[e] - b[e]);
        return;
    }
    double den = va + vb + vc;
    if (!(den > 0.0)) { /* degenerate triangle: its first corner */
        memcpy(q, a, 3 * sizeof(double));
        return;
    }
    double v = vb / den, w = vc / den;
    for (int e = 0; e < 3; e++)
        q[e] = a[e] + v * ab[e] + w * ac[e];
}

/* The tangential relaxation: every free vertex of X moves by the part of
 * Yt - X0 in its tangent plane (normals N), then back onto the surface X
 * had: to the closest point of the faces around it and its neighbours.
 * ENOMEM only. */
static mcf_status tangential_output(fair_ctx *c, const double *Yt, const double *N, double *X,
                                    mcf_error *err)
{
    int nv = c->nv;
    int *vp = mcf__calloc((size_t)nv + 1, sizeof(int)), *vf = mcf__malloc(3 * (size_t)c->nf + 1, sizeof(int));
    double *S = mcf__malloc(3 * (size_t)nv, sizeof(double));
    c->bytes += sizeof(int) * (4 * (size_t)nv + 3 * (size_t)c->nf);
    if (!vp || !vf || !S) {
        free(vp);
        free(vf);
        free(S);
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d faces)", c->nf);
    }
    for (size_t q = 0; q < 3 * (size_t)c->nf; q++)
        vp[c->F[q] + 1]++;
    for (int i = 0; i < nv; i++)
        vp[i + 1] += vp[i];
    for (int f = 0; f < c->nf; f++)
        for (int k = 0; k < 3; k++)
            vf[vp[c->F[3 * f + k]]++] = f;
    for (int i = nv; i > 0; i--)
        vp[i] = vp[i - 1];
    vp[0] = 0;
    memcpy(S, X, 3 * sizeof(double) * (size_t)nv);
    for (int k = 0; k < c->nfree; k++) {
        int i = c->vert[k];
        const double *n = N + 3 * (size_t)i;
        double d[3], p[3], best = INFINITY, q[3], bq[3];
        mcf__sub3(Yt + 3 * (size_t)i, c->X0 + 3 * (size_t)i, d);
        double a = mcf__dot3(n, d);
        for (int e = 0; e < 3; e++)
            p[e] = S[3 * (size_t)i + e] + d[e] - a * n[e];
        memcpy(bq, S + 3 * (size_t)i, 3 * sizeof(double));
        for (int t = c->g.ptr[i] - 1; t < c->g.ptr[i + 1]; t++) {
            int v = t < c->g.ptr[i] ? i : c->g.adj[t];
            for (int r = vp[v]; r < vp[v + 1]; r++) {
                const int32_t *tri = c->F + 3 * (size_t)vf[r];
                closest_on_triangle(p, S + 3 * (size_t)tri[0], S + 3 * (size_t)tri[1], S + 3 * (size_t)tri[2], q);
                double e3[3];
                mcf__sub3(q, p, e3);
                double dd = mcf__dot3(e3, e3);
                if (dd < best) {
                    best = dd;
                    memcpy(bq, q, sizeof q);
                }
            }
        }
        memcpy(X + 3 * (size_t)i, bq, sizeof bq);
    }
    free(vp);
    free(vf);
    free(S);
    return MCF_OK;
}

/* X = X0 + n <n, Y - X0> on the free vertices, n the normals of Y, into
 * X; N (3*nv) gets those normals. */
static void normal_output(fair_ctx *c, const double *Y, double *X, double *N)
{
    mcf__vertex_normals(Y, c->F, c->nf, c->nv, N);
    memcpy(X, c->X0, 3 * sizeof(double) * (size_t)c->nv);
    for (int k = 0; k < c->nfree; k++) {
        size_t i = (size_t)c->vert[k];
        double d[3];
        mcf__sub3(Y + 3 * i, c->X0 + 3 * i, d);
        double a = mcf__dot3(N + 3 * i, d);
        for (int e = 0; e < 3; e++)
            X[3 * i + e] += a * N[3 * i + e];
    }
}

/* Moves from the input longer than rmax taken back (the noise does not
 * move a vertex that far: what the filter takes beyond it is the shape):
 * a move of length l > rmax to rmax - (l - rmax) / MOVE_TAPER, none
 * from rmax (1 + MOVE_TAPER) on; on the vertices marked in only (NULL:
 * all). */
static void clamp_moves(const fair_ctx *c, double *X, double rmax, const unsigned char *only)
{
    for (int i = 0; i < c->nv; i++) {
        if (only && !only[i])
            continue;
        double d[3], *x = X + 3 * (size_t)i;
        const double *x0 = c->Xin + 3 * (size_t)i;
        mcf__sub3(x, x0, d);
        double l = sqrt(mcf__dot3(d, d));
        if (l > rmax)
            for (int e = 0; e < 3; e++)
                x[e] = x0[e] + d[e] * (fmax(0.0, rmax - (l - rmax) / MOVE_TAPER) / l);
    }
}

/* The run's share of work done (mcf_work_fn): f of this filter's window
 * [w0, w1]. Within a filter (measured on the 435k dragon, explicit, and
 * the 35k bunny, implicit): the set-up (graph, creases) WORK_SETUP, the
 * noise reading up to WORK_NOISE, the
 * factorization up to WORK_INIT, the steps the rest, counted against the
 * steps SURE will run (2 K* + 11, K* its best so far, at most the cap).
 * Of the run: the default's second filter WORK_PICK, the output (guard
 * and unfolding) WORK_OUTPUT. */
#define WORK_SETUP 0.2
#define WORK_NOISE 0.45
#define WORK_INIT 0.55
#define WORK_PICK 0.15
#define WORK_OUTPUT 0.12
static void work(const fair_ctx *c, const char *phase, double f)
{
    if (c->p->work)
        c->p->work(c->p->progress_ctx, phase, c->w0 + fmin(1.0, f) * (c->w1 - c->w0));
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
    c->s = c->s_t = 0.0;
    if (c->sure) {
        double s_est = 0.0, s_t = 0.0, s;
        if ((rc = mcf__noise_levels(c->X0, c->F, c->nf, c->nv, c->fx, &s_est, &s_t, err)) != MCF_OK)
            return rc;
        s = p->noise_sigma > 0.0 ? p->noise_sigma * hbar : s_est;
        /* the tangential noise: what the tangential reading shows beyond
         * TANGENTIAL_FLOOR mean edges, which clean scans' own irregular
         * triangles read as (0.02-0.12 on the shared scans: noise below
         * it cannot be told from the mesh), and at most the normal
         * noise (scanners' noise is isotropic at most) */
        s_t = fmin(sqrt(fmax(0.0, s_t * s_t - TANGENTIAL_FLOOR * TANGENTIAL_FLOOR * hbar * hbar)), s);
        st->noise = hbar > 0.0 ? s / hbar : 0.0;
        st->noise_tangential = hbar > 0.0 ? s_t / hbar : 0.0;
        /* the creases' smoothing along them moves a vertex by at most
         * CREASE_MAX_MOVE noise levels: more is the shape, not the noise
         * (a coarse mesh's zigzag "chains", car.drc: 0.27 units for noise
         * of 0.016) */
        clamp_moves(c, c->X0, CREASE_MAX_MOVE * s, c->crease);
        /* no noise (or nothing free): nothing to remove */
        if (!(s > 0.0) || c->nfree == 0)
            c->cap = 0;
        c->s = s;
        c->s_t = s_t;
        /* the estimate's uncertainty (S2_REL_SQRT_N); none when the
         * level is given */
        c->s2_rel = p->noise_sigma > 0.0 || c->nfree == 0 ? 0.0
                    : S2_REL_SQRT_N / sqrt((double)c->nfree);
    }
    st->t_target = c->cap;
    return MCF_OK;
}

/* The run's arrays, the probes, the SURE curve and the engine. */
static mcf_status run_init(fair_ctx *c, mcf_error *err)
{
    int nv = c->nv;
    c->ncol = c->sure ? NCOL : 3;
    c->Y = alloc_d(c, 3 * (size_t)nv);
    c->Ybest = alloc_d(c, 3 * (size_t)nv);
    c->Yt = alloc_d(c, 3 * (size_t)nv);
    c->probe = c->sure ? alloc_d(c, NPROBE * (size_t)(c->nfree ? c->nfree : 1)) : NULL;
    if (!c->Y || !c->Ybest || !c->Yt || (c->sure && !c->probe))
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d vertices)", nv);
    memcpy(c->Ybest, c->X0, 3 * sizeof(double) * (size_t)nv);
    memcpy(c->Yt, c->X0, 3 * sizeof(double) * (size_t)nv);
    for (int j = 0; c->sure && j < COMB_J; j++) {
        c->dk[j] = mcf__malloc(3 * (size_t)(c->nfree ? c->nfree : 1), sizeof(float));
        c->bytes += 3 * sizeof(float) * (size_t)c->nfree;
        if (!c->dk[j])
            return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d vertices)", nv);
    }
    if (c->sure) {
        init_probes(c);
        c->st->sure = mcf__malloc((size_t)c->cap + 1, sizeof(double));
        if (!c->st->sure)
            return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory for the SURE curve");
    }
    if (c->cap > 0)
        return c->is_explicit ? explicit_init(c, err) : implicit_init(c, err);
    return MCF_OK;
}

/* Keeps Y - X0 on the free vertices after k steps, with the probes'
 * traces est, as the newest of the last COMB_J iterates (the oldest's
 * buffer reused). */
static void keep_iterate(fair_ctx *c, int k, const double *Y, const double est[NPROBE])
{
    if (c->nk == COMB_J) {
        float *d = c->dk[0];
        memmove(c->dk, c->dk + 1, (COMB_J - 1) * sizeof c->dk[0]);
        memmove(c->kk, c->kk + 1, (COMB_J - 1) * sizeof c->kk[0]);
        memmove(c->trq, c->trq + 1, (COMB_J - 1) * sizeof c->trq[0]);
        c->dk[--c->nk] = d;
    }
    float *d = c->dk[c->nk];
    for (int q = 0; q < c->nfree; q++)
        for (int e = 0; e < 3; e++) {
            size_t i = 3 * (size_t)c->vert[q] + (size_t)e;
            d[3 * (size_t)q + (size_t)e] = (float)(Y[i] - c->X0[i]);
        }
    c->kk[c->nk] = k;
    memcpy(c->trq[c->nk], est, sizeof c->trq[0]);
    c->nk++;
}

/* r_j = n0 . (Y_kj - X0) at free vertex q for the kept iterates. */
static void kept_r(const fair_ctx *c, int q, double *r)
{
    const double *n = c->n0 + 3 * (size_t)c->vert[q];
    for (int j = 0; j < c->nk; j++) {
        const float *d = c->dk[j] + 3 * (size_t)q;
        r[j] = n[0] * d[0] + n[1] * d[1] + n[2] * d[2];
    }
}

/* Solves A x = y for the SPD J x J matrix A (row-major) by Cholesky, A
 * and y overwritten, x into y; 0 when A is not positive definite. */
static int small_spd_solve(double *A, double *y, int J)
{
    for (int j = 0; j < J; j++) {
        for (int k = 0; k < j; k++)
            A[j * J + j] -= A[j * J + k] * A[j * J + k];
        if (!(A[j * J + j] > 0.0))
            return 0;
        A[j * J + j] = sqrt(A[j * J + j]);
        for (int i = j + 1; i < J; i++) {
            for (int k = 0; k < j; k++)
                A[i * J + j] -= A[i * J + k] * A[j * J + k];
            A[i * J + j] /= A[j * J + j];
        }
    }
    for (int i = 0; i < J; i++) {
        for (int k = 0; k < i; k++)
            y[i] -= A[i * J + k] * y[k];
        y[i] /= A[i * J + i];
    }
    for (int i = J - 1; i >= 0; i--) {
        for (int k = i + 1; k < J; k++)
            y[i] -= A[k * J + i] * y[k];
        y[i] /= A[i * J + i];
    }
    return 1;
}

/* Whether the gain of the combination with weights cw stays within
 * [COMB_GAIN_MIN, COMB_GAIN_MAX] on k in [0, 2] (a grid of steps 0.01),
 * g(k) the gain of one step: 1 / (1 + k^2), or Taubin's pair's
 * (1 - 0.5 k)(1 + 0.53 k). */
static int comb_gain_ok(const fair_ctx *c, const double *cw)
{
    for (int t = 0; t <= 200; t++) {
        double k = 0.01 * t, g = c->is_explicit ? (1.0 - 0.5 * k) * (1.0 + 0.53 * k) : 1.0 / (1.0 + k * k);
        double gain = 1.0;
        for (int j = 0; j < c->nk; j++)
            gain += cw[j] * (pow(g, c->kk[j]) - 1.0);
        if (!(gain >= COMB_GAIN_MIN && gain <= COMB_GAIN_MAX))
            return 0;
    }
    return 1;
}

/* SURE's best combination of the kept iterates: with r_j = n0 . (Y_kj -
 * X0) and b_j = tr_j - sum w (the trace of T^kj - I), the displacement
 * sum_j c_j r_j has SURE(c) = sum w (sum_j c_j r_j)^2 - s^2 sum w + 2 s^2
 * (sum w + sum_j c_j b_j), least at G c = -s^2 b, G_jl = sum w r_j r_l
 * (a ridge of 1e-9 of G's mean diagonal keeps iterates that coincide
 * solvable). It replaces c->Ybest when its gain stays within bounds
 * (comb_gain_ok), its SURE plus COMB_PENALTY s^2 per weight is below the
 * best single step's and its gain over the input
 * passes SURE_MIN_GAIN (sure_of, the probes' spread of sum_j c_j tr_j
 * included); st->ncomb reports it taken, st->comb_* the weights found. */
static void combine(fair_ctx *c)
{
    int J = c->nk, n = c->nfree;
    double G[COMB_J * COMB_J] = {0}, cw[COMB_J], est[NPROBE], r[COMB_J], mo[3] = {0, 0, 0};
    double s2 = c->s * c->s, sw = (double)n, gd = 0.0, vtr, z;
    /* combinations between the kept iterates only: a run the cap
     * stopped may have its best step past the last (the box of
     * test_creases_kept at noise 0.1: K* = 200, kept 16-128, error 0.296
     * -> 0.348 of the input's with a combination of them) */
    if (J < 2 || c->kbest == 0 || c->kk[J - 1] < c->kbest)
        return;
    for (int q = 0; q < n; q++) {
        double w = c->w[c->vert[q]];
        kept_r(c, q, r);
        for (int a = 0; a < J; a++)
            for (int b = 0; b < J; b++)
                G[a * J + b] += w * r[a] * r[b];
    }
    for (int j = 0; j < J; j++) {
        gd += G[j * J + j] / J;
        cw[j] = -s2 * (mean_trace(c->trq[j], &vtr) - sw);
    }
    for (int j = 0; j < J; j++)
        G[j * J + j] += 1e-9 * gd;
    if (!(gd > 0.0) || !small_spd_solve(G, cw, J))
        return;
    for (int j = 0; j < J; j++) { /* the weights found, taken or not */
        c->st->comb_steps[j] = c->kk[j];
        c->st->comb_weight[j] = cw[j];
    }
    if (!comb_gain_ok(c, cw))
        return;
    for (int q = 0; q < NPROBE; q++) {
        est[q] = sw; /* the identity's: sum w z^2 = sum w */
        for (int j = 0; j < J; j++)
            est[q] += cw[j] * (c->trq[j][q] - sw);
    }
    /* the gain over the best single step, sum of the free vertices'
     * w (r*^2 - rho^2) and 2 s^2 (tr* - tr): moments of the first (dd),
     * the probes' estimates of the second (est) */
    double dd[2] = {0.0, 0.0};
    for (int q = 0; q < n; q++) {
        size_t i = (size_t)c->vert[q];
        double w = c->w[i], rho = 0.0, d[3];
        kept_r(c, q, r);
        for (int j = 0; j < J; j++)
            rho += cw[j] * r[j];
        mcf__sub3(c->Ybest + 3 * i, c->X0 + 3 * i, d);
        double rs = mcf__dot3(c->n0 + 3 * i, d), t = w * (rs * rs - rho * rho);
        dd[0] += t;
        dd[1] += t * t;
        mo[0] += w * rho * rho;
        mo[1] += w * w * rho * rho;
        mo[2] += w * w * rho * rho * rho * rho;
    }
    double tr = mean_trace(est, &vtr), risk = sure_of(c, 1, c->s, mo, tr, vtr, &z), tr_comb[NPROBE];
    memcpy(tr_comb, est, sizeof est);
    for (int q = 0; q < NPROBE; q++)
        est[q] = c->trbest[q] - est[q];
    double dtr = mean_trace(est, &vtr), gain = c->risk - risk - COMB_PENALTY * J * s2;
    double var = gain_var(c, s2, n, dd[0], dd[1], dtr, vtr);
    if (!(gain > 0.0) || gain * gain < SURE_MIN_GAIN * SURE_MIN_GAIN * var || !(z >= SURE_MIN_GAIN))
        return;
    memcpy(c->Ybest, c->X0, 3 * sizeof(double) * (size_t)c->nv);
    for (int q = 0; q < n; q++)
        for (int j = 0; j < J; j++)
            for (int e = 0; e < 3; e++)
                c->Ybest[3 * (size_t)c->vert[q] + (size_t)e] += cw[j] * c->dk[j][3 * (size_t)q + (size_t)e];
    c->st->ncomb = J;
    /* the result's SURE (its penalty charged) and traces, for the
     * choice between the filters (pick_explicit) */
    c->risk = risk + COMB_PENALTY * J * s2;
    memcpy(c->trbest, tr_comb, sizeof tr_comb);
}

/* The steps, SURE after each (the normal and the tangential part), until
 * K > 2 K* + 10 or the cap: c->Ybest, c->Yt at c->kbest, c->kbest_t. */
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
    for (int k = 1; k <= c->cap; k++) {
        if (hook && hook(hook_ctx, k - 1, NULL))
            return mcf__fail(err, MCF_ECANCELED, "canceled at step %d", k - 1);
        if (c->is_explicit) {
            double t0 = mcf_now();
            mcf__graph_taubin(&c->g, c->fx, c->Z, c->ncol, 1, c->tmp);
            st->time_solve += mcf_now() - t0;
        } else if ((rc = implicit_step(c, err)) != MCF_OK) {
            return rc;
        }
        positions(c, Y);
        if (!c->sure) {
            c->kbest = k;
        } else {
            double mo[6], vtr, zn, zt, est[NPROBE];
            probe_traces(c, est);
            double tr = mean_trace(est, &vtr);
            weighted_r2(c, Y, mo);
            double risk = sure_of(c, 1, s, mo, tr, vtr, &zn);
            /* the tangential part: two directions, the same smoother */
            double risk_t = sure_of(c, 2, s_t, mo + 3, tr, vtr, &zt);
            st->sure[st->nsure++] = risk / sumw / (hbar * hbar);
            /* a step counts only when SURE's gain over the input stands
             * out of its own uncertainty (SURE_MIN_GAIN) */
            if (risk < best && zn >= SURE_MIN_GAIN) {
                best = risk;
                c->kbest = k;
                memcpy(c->trbest, est, sizeof est);
                memcpy(c->Ybest, Y, 3 * sizeof(double) * (size_t)c->nv);
            }
            if (risk_t < best_t && zt >= SURE_MIN_GAIN) {
                best_t = risk_t;
                c->kbest_t = k;
                memcpy(c->Yt, Y, 3 * sizeof(double) * (size_t)c->nv);
            }
            if ((k & (k - 1)) == 0)
                keep_iterate(c, k, Y, est);
        }
        if (hook && hook(hook_ctx, k, c->quiet ? NULL : Y))
            return mcf__fail(err, MCF_ECANCELED, "canceled after step %d", k);
        int kend = c->sure ? 2 * (c->kbest > c->kbest_t ? c->kbest : c->kbest_t) + 11 : c->cap;
        work(c, c->is_explicit ? "passes" : "steps",
             WORK_INIT + (1.0 - WORK_INIT) * k / (kend < c->cap ? kend : c->cap));
        if (c->sure && k > 2 * (c->kbest > c->kbest_t ? c->kbest : c->kbest_t) + 10)
            break;
    }
    if (!c->sure && c->cap > 0)
        memcpy(c->Ybest, Y, 3 * sizeof(double) * (size_t)c->nv);
    c->risk = best;
    return MCF_OK;
}

/* The guard's first positions, into c->Ybest: Y's displacement along
 * the input's normals (what SURE judged) and its part along the surface
 * up to GUARD_TANGENTIAL noise levels. Y's own positions, whose uniform
 * Laplacian slides vertices along long thin triangles, moved car.drc's
 * vertices by up to MAX_MOVE along the surface (noise 0.25 along the
 * normals, seed 1: 1.03x the input's error; 0.96x with this); without any
 * tangential part spot at noise 0.5 (seeds 1-3) kept 11, 14 and 3 more
 * faces against the clean mesh's than the input (4, -6, -17 with Y's;
 * 4, -7, -8 with this). */
static void guard_positions(fair_ctx *c)
{
    double tmax = GUARD_TANGENTIAL * c->s;
    for (int k = 0; k < c->nfree; k++) {
        size_t i = (size_t)c->vert[k];
        const double *n = c->n0 + 3 * i;
        double d[3], t[3];
        mcf__sub3(c->Ybest + 3 * i, c->X0 + 3 * i, d);
        double a = mcf__dot3(n, d);
        for (int e = 0; e < 3; e++)
            t[e] = d[e] - a * n[e];
        double tl = sqrt(mcf__dot3(t, t)), f = tl > tmax ? tmax / tl : 1.0;
        for (int e = 0; e < 3; e++)
            c->Ybest[3 * i + e] = c->X0[3 * i + e] + a * n[e] + f * t[e];
    }
}

/* The output into X: along the normals of the filtered surface, relaxed
 * in its tangent planes, clamped, guarded. */
static mcf_status output(fair_ctx *c, double *X, mcf_error *err)
{
    int nv = c->nv, nf = c->nf, left;
    double s = c->s, s_t = c->s_t;
    mcf_flow_stats *st = c->st;
    mcf_status rc;
    if (c->kbest == 0 && c->kbest_t == 0) {
        /* nothing to remove: the input as it came (crease vertices too) */
        memcpy(X, c->Xin, 3 * sizeof(double) * (size_t)nv);
        return MCF_OK;
    }
    normal_output(c, c->Ybest, X, c->Y);
    if (c->kbest_t > 0 && (rc = tangential_output(c, c->Yt, c->Y, X, err)) != MCF_OK)
        return rc;
    guard_positions(c);
    /* no vertex moves further than MAX_MOVE noise levels (normal, and
     * both tangential parts when the result takes a tangential step)
     * from the input, nor do the guard's positions */
    double rmax = MAX_MOVE * sqrt(s * s + (c->kbest_t > 0 ? 2.0 * s_t * s_t : 0.0));
    if (rmax > 0.0) {
        clamp_moves(c, X, rmax, NULL);
        clamp_moves(c, c->Ybest, rmax, NULL);
    }
    if ((rc = mcf__unfold(X, c->Xin, c->Ybest, c->F, nf, nv, &st->guard_rounds, &st->guard_vertices,
                          &left, err)) != MCF_OK)
        return rc;
    c->bytes += (6 * sizeof(double) + 1) * (size_t)nf + (3 * sizeof(double) + 1) * (size_t)nv;
    return MCF_OK;
}

/* One filter's run on X (3*nv) up to its result along the normals
 * (c->Ybest, c->risk) and its tangential iterate; c->is_explicit, c->quiet
 * set by the caller. */
static mcf_status filter_run(fair_ctx *c, const double *X, const int32_t *F, int nf, int nv,
                             const unsigned char *fixed, const mcf_flow_params *p, double hbar,
                             mcf_flow_stats *st, mcf__step_hook hook, void *hook_ctx, mcf_error *err)
{
    mcf_status rc;
    c->p = p;
    c->nv = nv;
    c->nf = nf;
    c->F = F;
    c->st = st;
    c->hbar = hbar;
    c->X0 = mcf__malloc(3 * (size_t)nv, sizeof(double));
    c->bytes += 3 * sizeof(double) * (size_t)nv;
    if (!c->X0)
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d vertices)", nv);
    memcpy(c->X0, X, 3 * sizeof(double) * (size_t)nv);
    if ((rc = setup(c, fixed, err)) != MCF_OK)
        return rc;
    work(c, "setup", WORK_SETUP);
    if ((rc = plan_amount(c, err)) != MCF_OK)
        return rc;
    work(c, "noise", WORK_NOISE);
    if ((rc = run_init(c, err)) != MCF_OK)
        return rc;
    work(c, c->is_explicit ? "probes" : "factor", WORK_INIT);
    if ((rc = run_steps(c, hook, hook_ctx, err)) == MCF_OK && c->sure)
        combine(c);
    return rc;
}

/* Whether the explicit run e replaces the implicit run i (same input,
 * noise level, weights and probes): SURE's gain of e over i must pass
 * PICK_MIN_GAIN of its standard error, from the sum over the free
 * vertices of w (r_i^2 - r_e^2) (spread of n independent terms), 2 s^2
 * (tr_i - tr_e) (the probes' spread of the difference) and the noise
 * level's uncertainty. */
static int pick_explicit(const fair_ctx *i, const fair_ctx *e)
{
    if (e->kbest == 0 || i->nfree != e->nfree)
        return 0;
    if (i->kbest == 0)
        return 1; /* the implicit filter found nothing to remove */
    double s2 = i->s * i->s, dd[2] = {0.0, 0.0}, est[NPROBE], vtr;
    int n = i->nfree;
    for (int q = 0; q < n; q++) {
        size_t v = (size_t)i->vert[q];
        double a[3], b[3];
        mcf__sub3(i->Ybest + 3 * v, i->X0 + 3 * v, a);
        mcf__sub3(e->Ybest + 3 * v, e->X0 + 3 * v, b);
        double ra = mcf__dot3(i->n0 + 3 * v, a), rb = mcf__dot3(e->n0 + 3 * v, b);
        double t = i->w[v] * (ra * ra - rb * rb);
        dd[0] += t;
        dd[1] += t * t;
    }
    for (int q = 0; q < NPROBE; q++)
        est[q] = i->trbest[q] - e->trbest[q];
    double dtr = mean_trace(est, &vtr), gain = i->risk - e->risk;
    double var = gain_var(i, s2, n, dd[0], dd[1], dtr, vtr);
    return gain > 0.0 && gain * gain >= PICK_MIN_GAIN * PICK_MIN_GAIN * var;
}

/* The explicit run's figures into st when it won (its SURE curve, amount,
 * combination); its curve freed when it lost. */
static void take_stats(mcf_flow_stats *st, mcf_flow_stats *se, int won)
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
    st->filter_explicit = 1;
}

mcf_status mcf__fairing(double *X, const int32_t *F, int nf, int nv, const unsigned char *fixed,
                        const mcf_flow_params *p, double hbar, mcf_flow_stats *st,
                        mcf__step_hook hook, void *hook_ctx, mcf_error *err)
{
    fair_ctx ci, ce, *c = &ci;
    mcf_flow_stats se;
    mcf_status rc;
    memset(&ci, 0, sizeof ci);
    memset(&ce, 0, sizeof ce);
    ci.is_explicit = p->scheme == MCF_FAIRING_EXPLICIT;
    st->filter_explicit = ci.is_explicit;
    /* the shares of work: the default's pick runs the explicit passes
     * after the implicit filter (WORK_PICK of the run), the output last
     * (WORK_OUTPUT) */
    int pick = p->fairing_pick && !ci.is_explicit && p->iterations <= 0;
    ci.w1 = pick ? 1.0 - WORK_OUTPUT - WORK_PICK : 1.0 - WORK_OUTPUT;
    ce.w0 = ci.w1;
    ce.w1 = 1.0 - WORK_OUTPUT;
    rc = filter_run(&ci, X, F, nf, nv, fixed, p, hbar, st, hook, hook_ctx, err);
    size_t peak = ci.bytes + mcf__chol_bytes(ci.chol);
    /* the default request's `fairing` (fairing_pick) with the automatic
     * amount: the explicit passes too, the lower SURE taken
     * (pick_explicit); the factor freed first */
    if (rc == MCF_OK && p->fairing_pick && !ci.is_explicit && ci.sure && ci.cap > 0) {
        mcf__chol_free(ci.chol);
        ci.chol = NULL;
        memset(&se, 0, sizeof se);
        ce.is_explicit = ce.quiet = 1;
        rc = filter_run(&ce, X, F, nf, nv, fixed, p, hbar, &se, hook, hook_ctx, err);
        int won = rc == MCF_OK && pick_explicit(&ci, &ce);
        take_stats(st, &se, won);
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
    if (rc == MCF_OK) {
        st->steps = c->kbest;
        st->tangential_steps = c->kbest_t;
        size_t before = c->bytes;
        rc = output(c, X, err);
        peak += c->bytes - before; /* the guard's arrays */
        c->w0 = 0.0;
        c->w1 = 1.0;
        work(c, "output", 1.0);
    }
    st->peak_bytes = peak;
    fair_free(&ci);
    fair_free(&ce);
    return rc;
}
