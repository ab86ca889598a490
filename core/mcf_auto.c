/*
 * mcf_auto.c - strength=auto: the amount of smoothing chosen from the mesh
 * itself, by estimating its noise and minimizing Stein's unbiased risk
 * estimate (SURE) of the smoothed result.
 *
 * Model: the input is a clean surface plus i.i.d. Gaussian noise of
 * standard deviation s along the vertex normals. The smoother is the
 * run's own linearization: K implicit steps of size t/K with the operator
 * frozen at the input, S_t = ((M + t/K L)^-1 M)^K. For the normal
 * component of the displacement r = n . (S_t Y - Y), per vertex,
 *     SURE(t) = |r|^2 - n s^2 + 2 s^2 tr(S_t)
 * is an unbiased estimate of the squared error against the clean surface
 * (Stein 1981), so its minimizer is an estimate of the best time. The
 * trace comes from Hutchinson's estimator with three Rademacher probes
 * (relative error about sqrt(2/n): 0.5% at 100k vertices).
 *
 * The noise level s is the hard part: the residual after a small
 * smoothing underestimates it 1.5-2.3x (the smoothing removes part of the
 * noise, the surface's own detail adds to it). Here s is measured by a
 * second-order high-pass that cancels a smooth surface to second order,
 * e_i = d_i - avg_j d_j with d_i = n_i . (Y_i - avg_j Y_j) over the
 * 1-ring (the uniform graph Laplacian, mcf_graph.c), whose response to
 * noise depends on the valences and shapes around each vertex; it is
 * calibrated on the same mesh by the response to unit Gaussian noise along
 * the normals (s = MAD(e_Y) / MAD(e_noise)), and the median absolute
 * deviation ignores the features (creases, ears) where the surface itself
 * does not cancel. The normals n are those of 10 uniform Taubin passes of
 * Y, not Y's own: a noisy normal tilts with the noise and the projection
 * then misses part of it (0.36-0.39 read for 0.5). Both medians run over
 * the free vertices of degree >= 3 only: fixed and boundary vertices
 * carry no noise, and counting them read 0.5 as 0.23 on a scan with many
 * holes.
 *
 * Cost: one pattern, one noise calibration, then per candidate time one
 * factorization and K six-column solves (15 candidates). Pure C11 and
 * CHOLMOD, no globals; its own cholmod_common.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cholmod.h>

#include "mcf_internal.h"

typedef struct {
    int nv;
    mcf__pattern pat;
    double *N;          /* 3*nv unit vertex normals of X */
    cholmod_common cm;
    int cm_started;
    cholmod_sparse *A;
    cholmod_factor *L;
    cholmod_dense *B, *Y, *Yw, *Ew;
    double *lval;       /* nnz: L's upper values at X */
    double *mass;       /* nv */
} auto_ctx;

static void auto_free(auto_ctx *a)
{
    free(a->N);
    free(a->lval);
    free(a->mass);
    mcf__pattern_free(&a->pat);
    if (a->cm_started) {
        cholmod_free_factor(&a->L, &a->cm);
        cholmod_free_sparse(&a->A, &a->cm);
        cholmod_free_dense(&a->B, &a->cm);
        cholmod_free_dense(&a->Y, &a->cm);
        cholmod_free_dense(&a->Yw, &a->cm);
        cholmod_free_dense(&a->Ew, &a->cm);
        cholmod_finish(&a->cm);
    }
}

/* The second-order high-pass along the unit normals N (3*nv) of positions
 * P (3*nv) into e (nv): d_i = n_i . (P_i - avg_j P_j) over the 1-ring,
 * e_i = d_i - avg_j d_j. d (nv) and tmp (3*nv) are scratch. */
static void high_pass(const mcf__graph *g, const double *N, const double *P, double *e,
                      double *d, double *tmp)
{
    mcf__graph_average(g, P, 3, tmp);
    for (int i = 0; i < g->n; i++) {
        double r[3];
        mcf__sub3(P + 3 * (size_t)i, tmp + 3 * (size_t)i, r);
        d[i] = mcf__dot3(N + 3 * (size_t)i, r);
    }
    mcf__graph_average(g, d, 1, tmp);
    for (int i = 0; i < g->n; i++)
        e[i] = d[i] - tmp[i];
}

static int cmp_double(const void *x, const void *y)
{
    double a = *(const double *)x, b = *(const double *)y;
    return (a > b) - (a < b);
}

/* Median of |v_i| over the free vertices with a 1-ring of at least 3 (the
 * others, on slivers and boundaries' tips, say little; fixed vertices
 * carry no noise); work (nv) is scratch. */
static double mad(const mcf__graph *g, const unsigned char *fixed, const double *v,
                  double *work)
{
    size_t k = 0;
    for (int i = 0; i < g->n; i++)
        if (g->ptr[i + 1] - g->ptr[i] >= 3 && !(fixed && fixed[i]))
            work[k++] = fabs(v[i]);
    if (k == 0)
        return 0.0;
    qsort(work, k, sizeof *work, cmp_double);
    return k % 2 ? work[k / 2] : 0.5 * (work[k / 2 - 1] + work[k / 2]);
}

/* The tangential second-order high-pass of P (3*nv) into e (nv): the
 * length of the tangential part (normals N) of (I - Avg)^2 P; tmp and t2
 * are 3*nv scratch. */
static void tangential_high_pass(const mcf__graph *g, const double *N, const double *P, double *e,
                                 double *tmp, double *t2)
{
    size_t n3 = 3 * (size_t)g->n;
    mcf__graph_average(g, P, 3, tmp);
    for (size_t q = 0; q < n3; q++)
        tmp[q] = P[q] - tmp[q];
    mcf__graph_average(g, tmp, 3, t2);
    for (int i = 0; i < g->n; i++) {
        double r[3];
        const double *n = N + 3 * (size_t)i;
        mcf__sub3(tmp + 3 * (size_t)i, t2 + 3 * (size_t)i, r);
        double a = mcf__dot3(n, r);
        for (int c = 0; c < 3; c++)
            r[c] -= a * n[c];
        e[i] = sqrt(mcf__dot3(r, r));
    }
}

mcf_status mcf__noise_level(const double *X, const int32_t *F, int nf, int nv,
                            const unsigned char *fixed, double *sigma, mcf_error *err)
{
    return mcf__noise_levels(X, F, nf, nv, fixed, sigma, NULL, err);
}

mcf_status mcf__noise_levels(const double *X, const int32_t *F, int nf, int nv,
                             const unsigned char *fixed, double *sigma, double *sigma_t,
                             mcf_error *err)
{
    mcf__graph g;
    mcf_status rc = mcf__graph_build(F, nf, nv, &g, err);
    if (rc != MCF_OK)
        return rc;
    double *N = mcf__malloc(3 * (size_t)nv, sizeof(double));
    double *P = mcf__malloc(3 * (size_t)nv, sizeof(double));
    double *tmp = mcf__malloc(3 * (size_t)nv, sizeof(double));
    double *e = mcf__malloc((size_t)nv, sizeof(double));
    double *d = mcf__malloc((size_t)nv, sizeof(double));
    if (!N || !P || !tmp || !e || !d) {
        rc = mcf__fail(err, MCF_ENOMEM, "noise estimate: out of memory (%d vertices)", nv);
        goto done;
    }
    /* the normals of the surface without its noise: those of the noisy
     * mesh itself tilt with the noise, and the high-pass along them then
     * misses a part of it (0.36-0.39 read for 0.5 mean edges) */
    memcpy(P, X, 3 * sizeof(double) * (size_t)nv);
    mcf__graph_taubin(&g, fixed, P, 3, 10, tmp);
    mcf__vertex_normals(P, F, nf, nv, N);
    high_pass(&g, N, X, e, d, tmp);
    double mad_y = mad(&g, fixed, e, P);
    /* the response to unit Gaussian noise along the same normals on the
     * free vertices (mcf_mesh_add_noise's generator: reproducible) */
    mcf__gauss_fill(0x5eed5eedULL, d, (size_t)nv);
    for (int i = 0; i < nv; i++)
        for (int c = 0; c < 3; c++)
            P[3 * (size_t)i + c] = fixed && fixed[i] ? 0.0 : d[i] * N[3 * (size_t)i + c];
    high_pass(&g, N, P, e, d, tmp);
    double mad_n = mad(&g, fixed, e, P);
    *sigma = mad_n > 0.0 ? mad_y / mad_n : 0.0;
    if (sigma_t) {
        /* the same for the tangential part, calibrated by unit Gaussian
         * noise in the tangent planes (two independent components) */
        double *t2 = mcf__malloc(3 * (size_t)nv, sizeof(double));
        if (!t2) {
            rc = mcf__fail(err, MCF_ENOMEM, "noise estimate: out of memory (%d vertices)", nv);
            goto done;
        }
        tangential_high_pass(&g, N, X, e, tmp, t2);
        double mt_y = mad(&g, fixed, e, d);
        mcf__gauss_fill(0x7a5eed5eULL, P, 3 * (size_t)nv);
        for (int i = 0; i < nv; i++) {
            double *z = P + 3 * (size_t)i, a = mcf__dot3(z, N + 3 * (size_t)i);
            for (int c = 0; c < 3; c++)
                z[c] = fixed && fixed[i] ? 0.0 : z[c] - a * N[3 * (size_t)i + c];
        }
        tangential_high_pass(&g, N, P, e, tmp, t2);
        double mt_n = mad(&g, fixed, e, d);
        *sigma_t = mt_n > 0.0 ? mt_y / mt_n : 0.0;
        free(t2);
    }
done:
    free(N);
    free(P);
    free(tmp);
    free(e);
    free(d);
    mcf__graph_free(&g);
    return rc;
}

/* Solves (M + h L) Y = M B, K times in place on the 6 columns of a->B's
 * data (column-major, nv x 6: the positions, then the three probes; one
 * 6-column solve costs less than two of 3). */
static mcf_status apply_smoother(auto_ctx *a, int K, mcf_error *err)
{
    int n = a->nv;
    for (int k = 0; k < K; k++) {
        double *b = a->B->x;
        for (int c = 0; c < 6; c++)
            for (int i = 0; i < n; i++)
                b[(size_t)c * n + i] *= a->mass[i];
        if (!cholmod_solve2(CHOLMOD_A, a->L, a->B, NULL, &a->Y, NULL, &a->Yw, &a->Ew, &a->cm))
            return mcf__fail(err, MCF_ENUMERIC, "strength=auto: cholmod_solve failed (status %d)", a->cm.status);
        memcpy(a->B->x, a->Y->x, sizeof(double) * 6 * (size_t)n);
    }
    return MCF_OK;
}

mcf_status mcf__auto_time(const double *X, const int32_t *F, int nf, int nv,
                          const unsigned char *fixed, mcf_laplacian lap, mcf_mass mk,
                          double hbar, int K, double *t_best, double *sigma,
                          mcf_error *err)
{
    /* candidate times in units of h^2: strength 0.1 to 1.5 */
    static const double C[] = {0.01, 0.02, 0.035, 0.05, 0.07, 0.1, 0.14, 0.2,
                               0.28, 0.4, 0.56, 0.8, 1.1, 1.6, 2.25};
    enum { NC = sizeof C / sizeof C[0] };
    double risk[NC];
    auto_ctx a;
    mcf_status rc = MCF_OK;
    double *w = NULL, *area = NULL, *yn = NULL, *probe = NULL;
    memset(&a, 0, sizeof a);
    a.nv = nv;
    if ((rc = mcf__pattern_build(F, nf, nv, 1, &a.pat, err)) != MCF_OK)
        return rc;
    a.N = mcf__malloc(3 * (size_t)nv, sizeof(double));
    a.lval = mcf__malloc((size_t)a.pat.nnz, sizeof(double));
    a.mass = mcf__malloc((size_t)nv, sizeof(double));
    w = mcf__malloc(3 * (size_t)nf, sizeof(double));
    area = mcf__malloc((size_t)nf, sizeof(double));
    yn = mcf__malloc((size_t)nv, sizeof(double));
    probe = mcf__malloc(3 * (size_t)nv, sizeof(double));
    if (!a.N || !a.lval || !a.mass || !w || !area || !yn || !probe) {
        rc = mcf__fail(err, MCF_ENOMEM, "strength=auto: out of memory (%d vertices)", nv);
        goto done;
    }
    mcf__vertex_normals(X, F, nf, nv, a.N);
    double s;
    if ((rc = mcf__noise_level(X, F, nf, nv, fixed, &s, err)) != MCF_OK)
        goto done;
    *sigma = s;

    /* the operators at X */
    mcf__cot_weights(X, F, nf, lap, MCF_MOLLIFY * hbar, w, area);
    mcf__mass(X, F, nf, nv, mk, area, a.mass);
    mcf__pattern_fill_L(&a.pat, F, nf, w, a.lval);
    for (int i = 0; i < nv; i++)
        if (!(a.mass[i] > 0.0))
            a.mass[i] = 1e-300; /* unreferenced: decoupled, S = identity there */

    cholmod_start(&a.cm);
    a.cm_started = 1;
    a.cm.error_handler = NULL;
    a.cm.print = 0;
    a.A = cholmod_allocate_sparse((size_t)nv, (size_t)nv, (size_t)a.pat.nnz, 1, 1, 1, CHOLMOD_REAL, &a.cm);
    a.B = cholmod_allocate_dense((size_t)nv, 6, (size_t)nv, CHOLMOD_REAL, &a.cm);
    if (!a.A || !a.B) {
        rc = mcf__fail(err, MCF_ENOMEM, "strength=auto: CHOLMOD allocation failed");
        goto done;
    }
    memcpy(a.A->p, a.pat.colptr, sizeof(int) * ((size_t)nv + 1));
    memcpy(a.A->i, a.pat.rowind, sizeof(int) * (size_t)a.pat.nnz);
    /* Rademacher probes, deterministic */
    for (size_t i = 0; i < 3 * (size_t)nv; i++)
        probe[i] = (mcf__mix64(i + 0x9e3779b97f4a7c15ULL) >> 63) ? 1.0 : -1.0;
    for (int i = 0; i < nv; i++)
        yn[i] = mcf__dot3(a.N + 3 * (size_t)i, X + 3 * (size_t)i);

    for (int k = 0; k < NC; k++) {
        double t = C[k] * hbar * hbar, h = t / K, *ax = a.A->x;
        for (int q = 0; q < a.pat.nnz; q++)
            ax[q] = h * a.lval[q];
        for (int j = 0; j < nv; j++)
            ax[a.pat.diag[j]] += a.mass[j];
        if (!a.L && !(a.L = cholmod_analyze(a.A, &a.cm))) {
            rc = mcf__fail(err, a.cm.status == CHOLMOD_OUT_OF_MEMORY ? MCF_ENOMEM : MCF_ENUMERIC,
                           "strength=auto: cholmod_analyze failed (status %d)", a.cm.status);
            goto done;
        }
        if (!cholmod_factorize(a.A, a.L, &a.cm) || a.cm.status != CHOLMOD_OK) {
            rc = mcf__fail(err, a.cm.status == CHOLMOD_OUT_OF_MEMORY ? MCF_ENOMEM : MCF_ENUMERIC,
                           "strength=auto: factorization failed (status %d)", a.cm.status);
            goto done;
        }
        /* the positions (columns 0-2) and the probes (3-5) through S_t */
        double *b = a.B->x, r2 = 0.0, tr = 0.0;
        for (int c = 0; c < 3; c++)
            for (int i = 0; i < nv; i++) {
                b[(size_t)c * nv + i] = X[3 * (size_t)i + c];
                b[(size_t)(c + 3) * nv + i] = probe[3 * (size_t)i + c];
            }
        if ((rc = apply_smoother(&a, K, err)) != MCF_OK)
            goto done;
        b = a.B->x;
        /* |r|^2: the normal component of the displacement */
        for (int i = 0; i < nv; i++) {
            double ri = 0.0;
            for (int c = 0; c < 3; c++)
                ri += a.N[3 * (size_t)i + c] * b[(size_t)c * nv + i];
            ri -= yn[i];
            r2 += ri * ri;
        }
        /* tr(S_t): three probes */
        for (int c = 0; c < 3; c++)
            for (int i = 0; i < nv; i++)
                tr += probe[3 * (size_t)i + c] * b[(size_t)(c + 3) * nv + i];
        tr /= 3.0;
        risk[k] = r2 - nv * s * s + 2.0 * s * s * tr;
    }
    /* the grid's minimum, refined by the parabola through it and its
     * neighbours in log t */
    int kb = 0;
    for (int k = 1; k < NC; k++)
        if (risk[k] < risk[kb])
            kb = k;
    double lt = log(C[kb]);
    if (kb > 0 && kb < NC - 1) {
        double x0 = log(C[kb - 1]), x1 = lt, x2 = log(C[kb + 1]);
        double y0 = risk[kb - 1], y1 = risk[kb], y2 = risk[kb + 1];
        double den = (x0 - x1) * (x0 - x2) * (x1 - x2);
        double A2 = (x2 * (y1 - y0) + x1 * (y0 - y2) + x0 * (y2 - y1)) / den;
        double B2 = (x2 * x2 * (y0 - y1) + x1 * x1 * (y2 - y0) + x0 * x0 * (y1 - y2)) / den;
        if (A2 > 0.0) {
            double xv = -B2 / (2.0 * A2);
            if (xv > x0 && xv < x2)
                lt = xv;
        }
    }
    *t_best = exp(lt) * hbar * hbar;
done:
    free(w);
    free(area);
    free(yn);
    free(probe);
    auto_free(&a);
    return rc;
}
