/* SPDX-License-Identifier: MIT */
/*
 * mcf_feature.c - the fairing denoiser's feature-aware stage for
 * piecewise-smooth shapes (CAD parts): bilateral normal filtering (Zheng,
 * Fu, Au, Tai 2011) of the face normals, then the vertex update of Sun,
 * Rosin, Martin, Langbein 2007, its range kernel's width and iterations
 * chosen by Stein's unbiased risk estimate with a Monte-Carlo divergence
 * (Ramani, Blu, Unser 2008), and compared by the same estimate with the
 * linear fairing's result (mcf_fairing.c), whose probes it reuses.
 *
 * The filter (mcf__bnf_run): face normals n, centroids c, areas A of the
 * input; nit times
 *     n_i <- normalize(sum_{j in N(i) + i} A_j Ws(|c_i - c_j|) Wr(|n_i - n_j|) n_j),
 * N(i) the faces sharing a vertex with i, Ws and Wr Gaussians of widths
 * sigma_s (the mean distance between the centroids of such faces) and
 * sigma_r; then vit times, on the free vertices,
 *     x_i <- x_i + 1/|F_i| sum_{f at i} n_f <n_f, c_f - x_i>,
 * c_f the current centroids: each face is moved toward the plane through
 * its centroid with the filtered normal. On a flat region this is a
 * Laplacian smoothing of the heights (step 2/3); across a crease the
 * range kernel keeps the two sides' normals apart, so the crease stays.
 *
 * The amount (mcf__feature): for noise of deviation s along the normals,
 * SURE(f) = sum w r^2 - s^2 sum w + 2 s^2 div f, r_i = m_i . (f(y)_i - y_i)
 * along reference normals m, div f = sum w_i d(m_i . f_i)/d(y_i along
 * m_i), estimated by div ~ E_b[sum w_i b_i m_i . (f(y + e b m) - f(y))_i] / e
 * for a Rademacher probe b (one: each probe costs a third of the stage;
 * the variance of its estimate from the bound mcf__feature_div_bound).
 * Two choices the measurements forced
 * (docs/fairing.md): m are the normals of the most smoothing candidate's
 * result, not the noisy mesh's (the filter moves a vertex back along the
 * clean normal and keeps its tangential part, so along the noisy normals
 * its divergence reads the tilt: SURE 0.032 for a true 0.0016 on blade at
 * noise 0.25), and e = 0.3 s, not a tiny step (a narrow range kernel makes
 * the filter switch between nearby outputs; a small step reads only the
 * local slope and SURE comes out low: 0.011 for a true 0.026).
 *
 * Its large buffers (the normals, the pairs, the copies: about 30 MB on a
 * 60k-face mesh) come from mcf__malloc_big (mcf_bigmem.c), on huge pages
 * where the system gives them; the results are the same bits either way.
 *
 * Pure C11; no globals.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_internal.h"

static int imin3(int a, int b, int c)
{
    int m = a < b ? a : b;
    return m < c ? m : c;
}

/* the probe step, in noise levels (above) */
#define FD_STEP 0.3

struct mcf__bnf {
    int nv, nf;
    const int32_t *F;
    int *fptr, *fadj;       /* the faces g > f sharing a vertex with face f:
                               fadj[fptr[f] .. fptr[f+1]); each pair once */
    int *vdeg;              /* faces at each vertex */
    int *vp, *vf;           /* the faces at each vertex, in increasing order:
                               vf[vp[i] .. vp[i+1]) (mcf__vertex_faces) */
    double *ideg;           /* 1 / vdeg (0 where vdeg is 0) */
    double sigma_s;         /* mean distance of neighbouring centroids (input) */
    double *n, *m, *c, *a;  /* 3nf, 3nf, 3nf, nf */
    double *ws;             /* fptr[nf]: the spatial kernel Ws(|c_f - c_g|) of each pair */
    double *wx;             /* nwx: the range kernels of one block's pairs (BNF_BLOCK) */
    int nwx;
    double *t;              /* 3nf: each face's n_f <n_f, c_f> of one vertex iteration */
    double *S;              /* 6nv: the vertex tensors of mcf__bnf_vertices' normals */
    size_t slack;           /* the bytes its huge-page buffers take beyond
                               their sizes (mcf__malloc_big) */
};

/* The faces of one block of the normal iteration: their pairs' range
 * kernels are computed together (mcf__exp_array), about 380 doubles */
enum { BNF_BLOCK = 64 };

void mcf__bnf_free(mcf__bnf *b)
{
    if (!b)
        return;
    free(b->fptr);
    free(b->fadj);
    free(b->vdeg);
    free(b->vp);
    free(b->vf);
    free(b->ideg);
    free(b->n);
    free(b->m);
    free(b->c);
    free(b->a);
    free(b->ws);
    free(b->wx);
    free(b->t);
    free(b->S);
    free(b);
}

/* Normals (unit; zero on a degenerate face), centroids and areas of X's faces. */
static void face_geometry(const mcf__bnf *b, const double *X, double *n, double *c, double *a)
{
    for (int f = 0; f < b->nf; f++) {
        const double *p0 = X + 3 * (size_t)b->F[3 * (size_t)f], *p1 = X + 3 * (size_t)b->F[3 * (size_t)f + 1],
                     *p2 = X + 3 * (size_t)b->F[3 * (size_t)f + 2];
        double e1[3], e2[3], cr[3];
        mcf__sub3(p1, p0, e1);
        mcf__sub3(p2, p0, e2);
        mcf__cross3(e1, e2, cr);
        double l = sqrt(mcf__dot3(cr, cr));
        for (int e = 0; e < 3; e++) {
            n[3 * (size_t)f + e] = l > 0.0 ? cr[e] / l : 0.0;
            if (c)
                c[3 * (size_t)f + e] = (p0[e] + p1[e] + p2[e]) / 3.0;
        }
        if (a)
            a[f] = 0.5 * l;
    }
}

mcf__bnf *mcf__bnf_new(const double *X, const int32_t *F, int nf, int nv, mcf_error *err)
{
    mcf__bnf *b = mcf__calloc(1, sizeof *b);
    int *vp = NULL, *vf = NULL, *mark = NULL;
    if (!b)
        goto oom;
    b->nv = nv;
    b->nf = nf;
    b->F = F;
    vp = b->vp = mcf__calloc((size_t)nv + 2, sizeof(int));
    vf = b->vf = mcf__malloc(3 * (size_t)nf + 1, sizeof(int));
    mark = mcf__malloc((size_t)nf + 1, sizeof(int));
    b->fptr = mcf__malloc((size_t)nf + 1, sizeof(int));
    b->vdeg = mcf__calloc((size_t)nv + 1, sizeof(int));
    b->ideg = mcf__malloc((size_t)nv + 1, sizeof(double));
    b->n = mcf__malloc_big(3 * (size_t)nf + 1, sizeof(double));
    b->m = mcf__malloc_big(3 * (size_t)nf + 1, sizeof(double));
    b->c = mcf__malloc_big(3 * (size_t)nf + 1, sizeof(double));
    b->a = mcf__malloc((size_t)nf + 1, sizeof(double));
    b->t = mcf__malloc_big(3 * (size_t)nf + 1, sizeof(double));
    b->S = mcf__malloc_big(6 * (size_t)nv + 1, sizeof(double));
    if (!vp || !vf || !mark || !b->fptr || !b->vdeg || !b->ideg || !b->n || !b->m || !b->c || !b->a || !b->t || !b->S)
        goto oom;
    b->slack = 4 * mcf__big_slack(3 * (size_t)nf + 1, sizeof(double)) + mcf__big_slack(6 * (size_t)nv + 1, sizeof(double));
    /* the faces at each vertex, then each face's neighbours, deduplicated */
    mcf__vertex_faces(F, nf, nv, vp, vf);
    for (int i = 0; i < nv; i++) {
        b->vdeg[i] = vp[i + 1] - vp[i];
        b->ideg[i] = b->vdeg[i] > 0 ? 1.0 / b->vdeg[i] : 0.0;
    }
    for (int pass = 0; pass < 2; pass++) {
        size_t q = 0;
        for (int f = 0; f < nf; f++)
            mark[f] = -1;
        for (int f = 0; f < nf; f++) {
            b->fptr[f] = (int)q;
            mark[f] = f;
            for (int k = 0; k < 3; k++) {
                int v = F[3 * (size_t)f + k];
                for (int t = vp[v]; t < vp[v + 1]; t++)
                    if (vf[t] > f && mark[vf[t]] != f) {
                        mark[vf[t]] = f;
                        if (pass)
                            b->fadj[q] = vf[t];
                        q++;
                    }
            }
        }
        if (q > (size_t)INT32_MAX) {
            free(mark);
            mcf__bnf_free(b);
            mcf__fail(err, MCF_ELIMIT, "feature filter: %d faces have too many neighbours", nf);
            return NULL;
        }
        b->fptr[nf] = (int)q;
        if (!pass && (!(b->fadj = mcf__malloc_big(q + 1, sizeof(int))) || !(b->ws = mcf__malloc_big(q + 1, sizeof(double)))))
            goto oom;
        if (!pass)
            b->slack += mcf__big_slack(q + 1, sizeof(int)) + mcf__big_slack(q + 1, sizeof(double));
    }
    int most = 0;
    for (int f0 = 0; f0 < nf; f0 += BNF_BLOCK) {
        int f1 = f0 + BNF_BLOCK < nf ? f0 + BNF_BLOCK : nf;
        if (b->fptr[f1] - b->fptr[f0] > most)
            most = b->fptr[f1] - b->fptr[f0];
    }
    b->nwx = most;
    if (!(b->wx = mcf__malloc((size_t)most + 1, sizeof(double))))
        goto oom;
    free(mark);
    /* sigma_s: the mean distance between neighbouring centroids */
    face_geometry(b, X, b->n, b->c, b->a);
    double sum = 0.0;
    size_t np = (size_t)b->fptr[nf];
    for (int f = 0; f < nf; f++)
        for (int t = b->fptr[f]; t < b->fptr[f + 1]; t++) {
            double d[3];
            mcf__sub3(b->c + 3 * (size_t)f, b->c + 3 * (size_t)b->fadj[t], d);
            sum += sqrt(mcf__dot3(d, d));
        }
    b->sigma_s = np ? sum / (double)np : 0.0;
    return b;
oom: /* vp and vf are b's */
    free(mark);
    mcf__bnf_free(b);
    mcf__fail(err, MCF_ENOMEM, "feature filter: out of memory (%d faces)", nf);
    return NULL;
}

size_t mcf__bnf_bytes(const mcf__bnf *b)
{
    size_t np = b ? (size_t)b->fptr[b->nf] : 0;
    return b ? np * (sizeof(int) + sizeof(double)) + (size_t)b->nf * (13 * sizeof(double) + 4 * sizeof(int)) +
                   (size_t)b->nv * (7 * sizeof(double) + 2 * sizeof(int)) + (size_t)b->nwx * sizeof(double) + b->slack
             : 0;
}

void mcf__bnf_start(mcf__bnf *b, const double *X)
{
    double is2 = b->sigma_s > 0.0 ? 1.0 / (2.0 * b->sigma_s * b->sigma_s) : 0.0;
    face_geometry(b, X, b->n, b->c, b->a);
    /* the spatial kernel of each pair, the same every iteration */
    for (int f = 0; f < b->nf; f++)
        for (int t = b->fptr[f]; t < b->fptr[f + 1]; t++) {
            double d[3];
            mcf__sub3(b->c + 3 * (size_t)f, b->c + 3 * (size_t)b->fadj[t], d);
            b->ws[t] = exp(-mcf__dot3(d, d) * is2);
        }
}

const double *mcf__bnf_normals(mcf__bnf *b, double sigma_r, int nit)
{
    double ir2 = 1.0 / (2.0 * sigma_r * sigma_r);
    /* Measured on couplingdown_sub2.obj (59,424 faces, 6 pairs a face;
     * 2026-11-29, a harness timing 60 iterations): 91 ns a face and
     * iteration with libm's exp one pair at a time and the sums kept in
     * memory, 53 ns with the block's exps in lanes, the face's own sum in
     * registers and one division a face.
     * Each iteration's sums start at m = A n (the normalization below
     * writes the next one's) */
    for (int f = 0; nit > 0 && f < b->nf; f++)
        for (int e = 0; e < 3; e++)
            b->m[3 * (size_t)f + e] = b->a[f] * b->n[3 * (size_t)f + e];
    for (int it = 0; it < nit; it++) {
        /* the sums into m: each pair's kernel Ws Wr (symmetric) once, on
         * both of its faces, each weighted by the other's area */
        for (int f0 = 0; f0 < b->nf; f0 += BNF_BLOCK) {
            int f1 = f0 + BNF_BLOCK < b->nf ? f0 + BNF_BLOCK : b->nf, p0 = b->fptr[f0];
            double *wr = b->wx;
            /* the block's range kernels: their exponents, then their
             * exps at once (mcf__exp_array: 4 lanes) */
            for (int f = f0; f < f1; f++)
                for (int t = b->fptr[f]; t < b->fptr[f + 1]; t++) {
                    double d[3];
                    mcf__sub3(b->n + 3 * (size_t)f, b->n + 3 * (size_t)b->fadj[t], d);
                    wr[t - p0] = -mcf__dot3(d, d) * ir2;
                }
            mcf__exp_array(b->wx, (size_t)(b->fptr[f1] - p0));
            for (int f = f0; f < f1; f++) {
                const double *nf_ = b->n + 3 * (size_t)f;
                double *sf = b->m + 3 * (size_t)f, af = b->a[f];
                double s0 = sf[0], s1 = sf[1], s2 = sf[2], n0 = nf_[0], n1 = nf_[1], n2 = nf_[2];
                for (int t = b->fptr[f]; t < b->fptr[f + 1]; t++) {
                    size_t g = (size_t)b->fadj[t];
                    const double *ng = b->n + 3 * g;
                    double *sg = b->m + 3 * g;
                    double wt = b->ws[t] * wr[t - p0], wf = wt * b->a[g], wg = wt * af;
                    s0 += wf * ng[0];
                    s1 += wf * ng[1];
                    s2 += wf * ng[2];
                    sg[0] += wg * n0;
                    sg[1] += wg * n1;
                    sg[2] += wg * n2;
                }
                sf[0] = s0;
                sf[1] = s1;
                sf[2] = s2;
            }
        }
        /* normalized into m, and the next iteration's start A n into n
         * (the two swap below) */
        int last = it == nit - 1;
        for (int f = 0; f < b->nf; f++) {
            double *sf = b->m + 3 * (size_t)f, *nf_ = b->n + 3 * (size_t)f, l = sqrt(mcf__dot3(sf, sf)),
                   il = l > 0.0 ? 1.0 / l : 0.0, af = b->a[f];
            for (int e = 0; e < 3; e++) {
                sf[e] = l > 0.0 ? sf[e] * il : nf_[e];
                if (!last)
                    nf_[e] = af * sf[e];
            }
        }
        double *t = b->n;
        b->n = b->m;
        b->m = t;
    }
    return b->n;
}

void mcf__bnf_tensors(const mcf__bnf *b, const double *n, double *S)
{
    for (int i = 0; i < b->nv; i++) {
        double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0, s4 = 0.0, s5 = 0.0;
        for (int t = b->vp[i]; t < b->vp[i + 1]; t++) {
            const double *nn = n + 3 * (size_t)b->vf[t];
            s0 += nn[0] * nn[0];
            s1 += nn[0] * nn[1];
            s2 += nn[0] * nn[2];
            s3 += nn[1] * nn[1];
            s4 += nn[1] * nn[2];
            s5 += nn[2] * nn[2];
        }
        double *si = S + 6 * (size_t)i;
        si[0] = s0;
        si[1] = s1;
        si[2] = s2;
        si[3] = s3;
        si[4] = s4;
        si[5] = s5;
    }
}

void mcf__bnf_vertices_s(mcf__bnf *b, const double *n, const double *S, const unsigned char *fixed, int vit, double *Y)
{
    /* x_i + 1/|F_i| sum_f n_f <n_f, c_f - x_i>
     *   = x_i + 1/|F_i| (sum_f n_f <n_f, c_f> - S_i x_i),
     * S_i = sum_f n_f n_f' (fixed with the normals): each face's
     * n_f <n_f, c_f> written, then every vertex gathers its faces'. The
     * same update as the faces' scatter into the corners (the sums in
     * another order: 1e-15 of the coordinates apart), in 5.2-5.4 ns a
     * face and iteration against 7.3-7.6 (couplingdown_sub2.obj, 59,424
     * faces, 30 iterations; 2026-11-29, lab/results/quality/issue31-cpu5) */
    const int32_t *F = b->F;
    for (int it = 0; it < vit; it++) {
        for (int f = 0; f < b->nf; f++) {
            const int32_t *tri = F + 3 * (size_t)f;
            const double *nn = n + 3 * (size_t)f, *y0 = Y + 3 * (size_t)tri[0], *y1 = Y + 3 * (size_t)tri[1],
                         *y2 = Y + 3 * (size_t)tri[2];
            double h = (nn[0] * (y0[0] + y1[0] + y2[0]) + nn[1] * (y0[1] + y1[1] + y2[1]) +
                        nn[2] * (y0[2] + y1[2] + y2[2])) *
                       (1.0 / 3.0);
            double *tf = b->t + 3 * (size_t)f;
            tf[0] = h * nn[0];
            tf[1] = h * nn[1];
            tf[2] = h * nn[2];
        }
        for (int i = 0; i < b->nv; i++) {
            if ((fixed && fixed[i]) || b->vdeg[i] == 0)
                continue;
            double a0 = 0.0, a1 = 0.0, a2 = 0.0;
            for (int t = b->vp[i]; t < b->vp[i + 1]; t++) {
                const double *tf = b->t + 3 * (size_t)b->vf[t];
                a0 += tf[0];
                a1 += tf[1];
                a2 += tf[2];
            }
            double *y = Y + 3 * (size_t)i, x0 = y[0], x1 = y[1], x2 = y[2], id = b->ideg[i];
            const double *si = S + 6 * (size_t)i;
            y[0] = x0 + (a0 - (si[0] * x0 + si[1] * x1 + si[2] * x2)) * id;
            y[1] = x1 + (a1 - (si[1] * x0 + si[3] * x1 + si[4] * x2)) * id;
            y[2] = x2 + (a2 - (si[2] * x0 + si[4] * x1 + si[5] * x2)) * id;
        }
    }
}

void mcf__bnf_vertices(mcf__bnf *b, const double *n, const unsigned char *fixed, int vit, double *Y)
{
    mcf__bnf_tensors(b, n, b->S);
    mcf__bnf_vertices_s(b, n, b->S, fixed, vit, Y);
}

void mcf__bnf_run(mcf__bnf *b, const double *X, const unsigned char *fixed, double sigma_r, int nit, int vit,
                  double *Y)
{
    mcf__bnf_start(b, X);
    const double *n = mcf__bnf_normals(b, sigma_r, nit);
    memcpy(Y, X, 3 * sizeof(double) * (size_t)b->nv);
    mcf__bnf_vertices(b, n, fixed, vit, Y);
}

/* ------------------------------------------------------------ the choice */

/* The candidates: range widths (on |n_i - n_j|, unit normals) x normal
 * iterations (the results after each of NIT, one run per width) x vertex
 * iterations (after each of VIT, one run per normal count): 18. Measured
 * on the three shared CAD parts at noise 0.1-0.5 h along the normals, the
 * true risk known from the clean mesh (a lab diagnostic, 2026-11-28): the
 * least lay at sigma_r 0.35-1.0, 5-30 normal and 5-40 vertex iterations
 * (blade.obj: 0.7-1.0, 20-30, 20-40; car.drc: 0.35-0.7, 5-30, 5;
 * couplingdown_sub2.obj: 0.35, 10-20, 5). A middle width (0.6) was never
 * SURE's pick in make quality's CAD cases (normal noise, seed 1) nor on
 * the box of test_feature_box, and cost a third of the stage. */
static const double SIGMA_R[] = {0.35, 1.0};
static const int NIT[] = {5, 12, 30};
static const int VIT[] = {5, 12, 30};
enum { NSIG = sizeof SIGMA_R / sizeof SIGMA_R[0], NNIT = sizeof NIT / sizeof NIT[0],
       NVIT = sizeof VIT / sizeof VIT[0], NCAND = NSIG * NNIT * NVIT, NPROBE_F = 1 };
/* the pilot, the candidate whose result gives the reference normals m:
 * the widest kernel, these iterations (normal iterations within NIT's
 * range) */
enum { PILOT_NIT = 15, PILOT_VIT = 20 };
/* the noise level read from the residuals (below): within [1/S_RANGE,
 * S_RANGE] of the frame's reading */
#define S_RANGE 2.0

/* SURE's terms of one result Y against the frame: sum_F w r^2 and the
 * per-vertex r_i along m into r (nfree, may be NULL). */
static double residuals(const mcf__feature_frame *fr, const double *w, const double *Y, const double *X0,
                        const double *m, double *r)
{
    double sum = 0.0;
    for (int k = 0; k < fr->nfree; k++) {
        size_t i = (size_t)fr->vert[k];
        double d[3];
        mcf__sub3(Y + 3 * i, X0 + 3 * i, d);
        double rk = mcf__dot3(m + 3 * i, d);
        if (r)
            r[k] = rk;
        sum += w[i] * rk * rk;
    }
    return sum;
}

/* The variance of a difference of two SUREs over the same vertices: the
 * spread of the per-vertex terms w (ra^2 - rb^2) (n independent terms),
 * the probes' spread of the two divergences' difference (vdiv, times
 * 4 s^4), and the noise level's relative error on s^2 (times the
 * divergences' difference ddiv, 2 s^2 ddiv s2_rel). */
static double diff_var(const mcf__feature_frame *fr, double s, const double *ra, const double *rb, double ddiv,
                       double vdiv)
{
    double s2 = s * s, sd = 0.0, sd2 = 0.0;
    int n = fr->nfree;
    for (int k = 0; k < n; k++) {
        double w = fr->w[fr->vert[k]], t = w * ((ra ? ra[k] * ra[k] : 0.0) - (rb ? rb[k] * rb[k] : 0.0));
        sd += t;
        sd2 += t * t;
    }
    double spread = n > 1 ? fmax(0.0, sd2 - sd * sd / n) * n / (n - 1.0) : 0.0;
    double ds = 2.0 * ddiv * s2 * fr->s2_rel;
    return spread + 4.0 * s2 * s2 * vdiv + ds * ds;
}

double mcf__feature_div(const mcf__feature_frame *fr, const double *w, const double *m, const double *Y,
                        const double *Yz, const double *z, double eps)
{
    double div = 0.0;
    for (int k = 0; k < fr->nfree; k++) {
        size_t i = (size_t)fr->vert[k];
        double d[3];
        mcf__sub3(Yz + 3 * i, Y + 3 * i, d);
        div += w[i] * z[k] * mcf__dot3(m + 3 * i, d);
    }
    return div / eps;
}

/* One probe's estimate of tr(J' W J) = E |W^1/2 J z|^2: sum_k w_i (m_i .
 * (Yz_i - Y_i))^2 / eps^2 (the same finite difference as the divergence). */
static double jtj(const mcf__feature_frame *fr, const double *w, const double *m, const double *Y, const double *Yz,
                  double eps)
{
    double sum = 0.0;
    for (int k = 0; k < fr->nfree; k++) {
        size_t i = (size_t)fr->vert[k];
        double d[3];
        mcf__sub3(Yz + 3 * i, Y + 3 * i, d);
        double a = mcf__dot3(m + 3 * i, d);
        sum += w[i] * a * a;
    }
    return sum / (eps * eps);
}

double mcf__feature_div_bound(const mcf__feature_frame *fr, const double *w, const double *m, const double *Y,
                              const double *Yz, double eps)
{
    double sum = 0.0;
    for (int k = 0; k < fr->nfree; k++) {
        size_t i = (size_t)fr->vert[k];
        double d[3];
        mcf__sub3(Yz + 3 * i, Y + 3 * i, d);
        double a = w[i] * mcf__dot3(m + 3 * i, d);
        sum += a * a;
    }
    return 2.0 * sum / (eps * eps);
}

/* mean and variance of the mean of q estimates */
static double mean_var(const double *e, int q, double *var)
{
    double m = 0.0, v = 0.0;
    for (int j = 0; j < q; j++)
        m += e[j] / q;
    for (int j = 0; j < q; j++)
        v += (e[j] - m) * (e[j] - m);
    *var = q > 1 ? v / ((q - 1.0) * q) : 0.0;
    return m;
}

/* The weights of the candidates' SURE: the barycentric areas of the most
 * smoothing candidate's result Y (into ap, nv) over their mean on the
 * frame's vertices (into wp, nv, zeroed by the caller).
 * The noisy mesh's areas grow with the noise at each vertex, so sum w r^2
 * comes out high for a result that removes the noise (blade, noise 0.25,
 * clean normals: SURE 0.0157 for a true 0.0020 with them, 0.0022 for
 * 0.0027 with these), and most for the candidate that removes the most. */
static void pilot_weights(const mcf__feature_frame *fr, const double *Y, const int32_t *F, int nf, int nv,
                          double *wp, double *ap)
{
    double sum = 0.0;
    for (int f = 0; f < nf; f++) {
        const int32_t *t = F + 3 * (size_t)f;
        double e1[3], e2[3], cr[3];
        mcf__sub3(Y + 3 * (size_t)t[1], Y + 3 * (size_t)t[0], e1);
        mcf__sub3(Y + 3 * (size_t)t[2], Y + 3 * (size_t)t[0], e2);
        mcf__cross3(e1, e2, cr);
        double a = sqrt(mcf__dot3(cr, cr)) / 6.0;
        for (int k = 0; k < 3; k++)
            wp[t[k]] += a;
    }
    memcpy(ap, wp, sizeof(double) * (size_t)nv);
    for (int k = 0; k < fr->nfree; k++)
        sum += wp[fr->vert[k]];
    for (int k = 0; k < fr->nfree; k++)
        wp[fr->vert[k]] = sum > 0.0 ? wp[fr->vert[k]] * fr->nfree / sum : 1.0;
}

/* One candidate's sums: with the pilot's weights (the choice: residual,
 * divergence, tr J'WJ) and with the frame's (the comparison: residual,
 * divergence and its variance). */
typedef struct {
    double sr2, div, jj;
    double sr2_f, div_f, vdiv_f;
    double rms;               /* the widest kernel's: the residual's RMS over
                                 every vertex the filter moves */
} cand_sums;

/* The area-weighted RMS over the vertices the filter moves (not fixed, on
 * a face) of n_i . (Y_i - X_i), n the reference normals, a the pilot's
 * barycentric areas: the residual's deviation, creases and all. */
static double moving_residual(const mcf__bnf *b, const unsigned char *fixed, const double *X, const double *Y,
                              const double *n, const double *a)
{
    double sum = 0.0, sa = 0.0;
    for (int i = 0; i < b->nv; i++)
        if (!(fixed && fixed[i]) && b->vdeg[i] > 0) {
            double d[3];
            mcf__sub3(Y + 3 * (size_t)i, X + 3 * (size_t)i, d);
            double r = mcf__dot3(n + 3 * (size_t)i, d);
            sum += a[i] * r * r;
            sa += a[i];
        }
    return sa > 0.0 ? sqrt(sum / sa) : 0.0;
}

/* The noise level the candidates' residuals say: the least over the
 * widest range kernel's candidates k of rms_k / sqrt(1 - (2 div_k -
 * tr J_k'WJ_k) / sum w) (E sum w r^2 = |bias|^2 + s^2 (tr W - 2 tr WJ +
 * tr J'WJ) for noise of deviation s: the bias only adds, so the least is
 * the nearest; the widest kernel's filter is the nearest to linear, where
 * the finite differences read J'WJ, while a narrow one's switching makes
 * them read more than sum w), within [s0 / S_RANGE, s0 S_RANGE] of the
 * frame's reading s0. Two corrections measured (2026-11-28, make
 * quality's noise along the normals, seed 1, the level along m known from
 * the clean mesh): tr J'WJ taken at most tr WJ (a smoother's Jacobian has
 * its eigenvalues in [0, 1]; the many-iteration candidates' finite
 * differences read up to 6x more, 2,344 for a divergence of 379 on
 * blade.obj at 0.5 h, and the least over the candidates came out 10%
 * low: 0.561 for 0.622, so SURE took 5 + 30 iterations, 0.134 of s^2 per
 * vertex where 12 + 30 gave 0.044); and the geometric mean of the least
 * and the most of the candidates' readings, not the least (the least is
 * the candidate whose finite differences over-read most, the most the
 * one with the most bias: blade.obj 0.5 h 0.575 and 0.657 for 0.622).
 * With it the default's error over the input's went 0.534 -> 0.323 on
 * blade.obj at 0.5 h and stayed within 0.001 on the four other CAD cases
 * the stage runs on (blade 0.25, couplingdown_sub2 0.1/0.25/0.5); the
 * most of them (0.459 on couplingdown_sub2 at 0.5 h, 0.504 now) took
 * blade 0.25 to 0.292 (0.233 now). The residual over every moving vertex (weighted by
 * the pilot's areas), not SURE's sum over the frame's: the frame leaves
 * out the creases, which on a noisy mesh are where the noise is large
 * (blade.obj at 0.5 h: 29% of the vertices; the sum read 0.32 h where
 * this reads 0.38 h of the noisy mesh's mean edge, which is longer than
 * the clean one's). The linear fairing's reading (mcf__noise_levels)
 * is low on meshes of graded density: blade.obj 0.28 h, and with it SURE
 * took a candidate of 0.90 of the input's error (0.23 at this reading). */
static double noise_from_residuals(const cand_sums *cs, double sumw, double s0)
{
    double lo = INFINITY, hi = 0.0;
    for (int k = (NSIG - 1) * NNIT * NVIT; k < NCAND; k++) {
        double dof = 1.0 - (2.0 * cs[k].div - fmin(cs[k].jj, cs[k].div)) / sumw;
        double v = cs[k].rms / sqrt(fmax(dof, 0.25));
        lo = fmin(lo, v);
        hi = fmax(hi, v);
    }
    return fmin(fmax(sqrt(lo * hi), s0 / S_RANGE), s0 * S_RANGE);
}

/* Residuals beyond which a vertex leaves the comparison with the linear
 * fairing (below), in noise levels. */
#define OUTLIER_R 4.0

/* The comparison of the chosen candidate with the linear fairing's result
 * (feature_run) without the vertices where either result's residual is
 * beyond OUTLIER_R s: their residual terms (rb, rl: nfree) zeroed and
 * taken off both risks (*risk, *risk_lin); returns their count.
 * SURE's residual term is unbiased only for Gaussian noise: at a spike
 * of height E the spike stage (mcf_spikes.c) left, a result that pulls
 * the vertex back by a E is charged a^2 E^2, though most of that is the
 * spike's own height, which SURE's -s^2 does not take off; the range
 * kernel keeps a spike (a normal far from its neighbours' weighs
 * little), so SURE ranked the stage ahead because it kept the spikes
 * (blade.obj, 1% outliers on 0.5 h, seed 1: 33 vertices with a residual
 * over 3 s carried 0.110 of the linear result's sum against 0.027 of the
 * stage's, more than the whole gain of 0.053; the stage taken at 0.517
 * of the input's error where the linear result is 0.336). A residual of
 * pure Gaussian noise passes OUTLIER_R s with probability 6e-5 (a
 * smoother's I - J has its eigenvalues in [0, 1], so a residual's noise
 * part has deviation <= s), so the cut drops the spikes and the vertices
 * where a result's bias is many s, on which the comparison then judges
 * neither. Their divergences stay in both sums: each vertex's diagonal
 * term is in [0, w], so 2 s^2 w at most per vertex dropped, an eighth of
 * the (4 s)^2 w of residual each drops. */
static int drop_outliers(const mcf__feature_frame *fr, double s, double *rb, double *rl, double *risk,
                         double *risk_lin)
{
    double cut = OUTLIER_R * s;
    int n = 0;
    for (int k = 0; k < fr->nfree; k++)
        if (fabs(rb[k]) > cut || fabs(rl[k]) > cut) {
            double w = fr->w[fr->vert[k]];
            *risk -= w * rb[k] * rb[k];
            *risk_lin -= w * rl[k] * rl[k];
            rb[k] = rl[k] = 0.0;
            n++;
        }
    return n;
}

/* A candidate's SURE (the choice's: the pilot's weights) at the noise
 * level's square s2. */
static double cand_risk(const cand_sums *c, double sumw, double s2)
{
    return c->sr2 - s2 * sumw + 2.0 * s2 * c->div;
}

/* The candidate of least SURE at noise level s (the first of equals). */
static int least_sure(const cand_sums *cs, double sumw, double s)
{
    double lo = INFINITY, s2 = s * s;
    int k = 0;
    for (int j = 0; j < NCAND; j++) {
        double risk = cand_risk(&cs[j], sumw, s2);
        if (risk < lo) {
            lo = risk;
            k = j;
        }
    }
    return k;
}

static mcf_status feature_run(const double *X, const int32_t *F, int nf, int nv, const unsigned char *fixed,
                              const mcf__feature_frame *fr, double *Yout, mcf__feature_pick *pick, mcf_error *err)
{
    int nfree = fr->nfree, nin = 1 + NPROBE_F;
    double s = fr->s, eps = FD_STEP * s, sumw = 0.0;
    size_t n3 = 3 * (size_t)nv, nf3 = 3 * (size_t)nf;
    mcf_status rc = MCF_OK;
    memset(pick, 0, sizeof *pick);
    mcf__bnf *b = mcf__bnf_new(X, F, nf, nv, err);
    double *m = mcf__malloc_big(n3 + 1, sizeof(double)), *Xp = mcf__malloc_big((size_t)nin * n3 + 1, sizeof(double));
    double *Yp = mcf__malloc_big((size_t)nin * n3 + 1, sizeof(double));
    /* Sq: the probes' vertex tensors of one normal count's normals
     * (mcf__bnf_tensors), made once for its three vertex counts; X's in
     * b's own (sq below) */
    double *Sq = mcf__malloc_big((size_t)(nin - 1) * 6 * nv + 1, sizeof(double));
    /* Nk: each normal count's normals of each input, then (Nw) the widest
     * kernel's on X, kept for the result */
    double *Nk = mcf__malloc_big((size_t)NNIT * (nin + 1) * nf3 + 1, sizeof(double)), *Nw = Nk + (size_t)NNIT * nin * nf3;
    double *rbest = mcf__malloc((size_t)nfree + 1, sizeof(double)), *rlin = mcf__malloc((size_t)nfree + 1, sizeof(double));
    double *wp = mcf__calloc((size_t)nv + 1, sizeof(double)), *ap = mcf__malloc((size_t)nv + 1, sizeof(double));
    cand_sums *cs = mcf__malloc(NCAND, sizeof *cs);
    if (!b) {
        rc = err ? err->status : MCF_ENOMEM;
        goto done;
    }
    if (!m || !Xp || !Yp || !Sq || !Nk || !rbest || !rlin || !wp || !ap || !cs) {
        rc = mcf__fail(err, MCF_ENOMEM, "feature filter: out of memory (%d vertices)", nv);
        goto done;
    }
    pick->bytes = mcf__bnf_bytes(b) +
                  sizeof(double) * ((size_t)nin * 2 * n3 + (size_t)(nin - 1) * 6 * nv + (size_t)(nin + 1) * NNIT * nf3 + n3 +
                                    2 * (size_t)nv + 2 * (size_t)nfree) +
                  NCAND * sizeof *cs + mcf__big_slack(n3 + 1, sizeof(double)) +
                  2 * mcf__big_slack((size_t)nin * n3 + 1, sizeof(double)) +
                  mcf__big_slack((size_t)(nin - 1) * 6 * nv + 1, sizeof(double)) +
                  mcf__big_slack((size_t)NNIT * (nin + 1) * nf3 + 1, sizeof(double));
    for (int k = 0; k < nfree; k++)
        sumw += fr->w[fr->vert[k]];
    if (!(s > 0.0) || nfree == 0 || fr->nprobe < NPROBE_F)
        goto done;
    /* the reference normals m: those of a strongly smoothing candidate's
     * result (the widest range kernel, PILOT_NIT + PILOT_VIT iterations),
     * its normals read on the way to the widest kernel's candidates' on X
     * (into Nw and their slots of Nk; the pilot's in a slot the probes
     * fill later) */
    double *pilot_n = Nk + ((size_t)(NNIT - 1) * nin + 1) * nf3;
    mcf__bnf_start(b, X);
    for (int ni = 0, done = 0; ni < NNIT; ni++) {
        if (done < PILOT_NIT && PILOT_NIT <= NIT[ni]) {
            memcpy(pilot_n, mcf__bnf_normals(b, SIGMA_R[NSIG - 1], PILOT_NIT - done), nf3 * sizeof(double));
            done = PILOT_NIT;
        }
        memcpy(Nw + (size_t)ni * nf3, mcf__bnf_normals(b, SIGMA_R[NSIG - 1], NIT[ni] - done), nf3 * sizeof(double));
        memcpy(Nk + (size_t)ni * nin * nf3, Nw + (size_t)ni * nf3, nf3 * sizeof(double));
        done = NIT[ni];
    }
    memcpy(Yp, X, n3 * sizeof(double));
    mcf__bnf_vertices(b, pilot_n, fixed, PILOT_VIT, Yp);
    mcf__vertex_normals(Yp, F, nf, nv, m);
    pilot_weights(fr, Yp, F, nf, nv, wp, ap);
    /* the inputs: X, and X + eps z_q m for the probes z_q */
    for (int q = 0; q < nin; q++) {
        double *x = Xp + (size_t)q * n3;
        memcpy(x, X, n3 * sizeof(double));
        if (q > 0)
            for (int k = 0; k < nfree; k++) {
                size_t i = (size_t)fr->vert[k];
                double z = fr->probe[(size_t)(q - 1) * nfree + k];
                for (int e = 0; e < 3; e++)
                    x[3 * i + e] += eps * z * m[3 * i + e];
            }
    }
    /* every candidate's sums, the results read on the way; the widest
     * kernel first (its normals on X are in Nk), the narrowest last (its
     * normals on X stay in Nk for the result). The noise level is read
     * from the widest kernel's (noise_from_residuals), so the other
     * widths' SUREs are known as their candidates come: the least one's
     * result on X is kept in Yout (kb), not run again below */
    double sf = s, lo = INFINITY;
    int kb = -1;
    for (int si = NSIG - 1; si >= 0; si--) {
        for (int q = si == NSIG - 1; q < nin; q++) {
            mcf__bnf_start(b, Xp + (size_t)q * n3);
            for (int ni = 0; ni < NNIT; ni++)
                memcpy(Nk + ((size_t)ni * nin + q) * nf3,
                       mcf__bnf_normals(b, SIGMA_R[si], NIT[ni] - (ni ? NIT[ni - 1] : 0)), nf3 * sizeof(double));
        }
        for (int ni = 0; ni < NNIT; ni++) {
            memcpy(Yp, Xp, (size_t)nin * n3 * sizeof(double));
            double *sq[1 + NPROBE_F];
            for (int q = 0; q < nin; q++) {
                sq[q] = q ? Sq + (size_t)(q - 1) * 6 * nv : b->S;
                mcf__bnf_tensors(b, Nk + ((size_t)ni * nin + q) * nf3, sq[q]);
            }
            for (int vi = 0; vi < NVIT; vi++) {
                int j = (si * NNIT + ni) * NVIT + vi;
                cand_sums *c = &cs[j];
                double div[NPROBE_F], divf[NPROBE_F], jj[NPROBE_F], v;
                for (int q = 0; q < nin; q++)
                    mcf__bnf_vertices_s(b, Nk + ((size_t)ni * nin + q) * nf3, sq[q], fixed,
                                        VIT[vi] - (vi ? VIT[vi - 1] : 0), Yp + (size_t)q * n3);
                c->sr2 = residuals(fr, wp, Yp, X, m, NULL);
                c->sr2_f = residuals(fr, fr->w, Yp, X, m, NULL);
                for (int q = 1; q < nin; q++) {
                    const double *z = fr->probe + (size_t)(q - 1) * nfree, *Yq = Yp + (size_t)q * n3;
                    div[q - 1] = mcf__feature_div(fr, wp, m, Yp, Yq, z, eps);
                    divf[q - 1] = mcf__feature_div(fr, fr->w, m, Yp, Yq, z, eps);
                    jj[q - 1] = jtj(fr, wp, m, Yp, Yq, eps);
                }
                c->div = mean_var(div, NPROBE_F, &v);
                c->jj = mean_var(jj, NPROBE_F, &v);
                c->div_f = mean_var(divf, NPROBE_F, &c->vdiv_f);
                if (NPROBE_F == 1) /* no spread to read: the bound */
                    c->vdiv_f = mcf__feature_div_bound(fr, fr->w, m, Yp, Yp + n3, eps);
                c->rms = si == NSIG - 1 ? moving_residual(b, fixed, X, Yp, m, ap) : 0.0;
                double risk = si < NSIG - 1 ? cand_risk(c, sumw, sf * sf) : INFINITY;
                if (risk < lo || (risk == lo && j < kb)) {
                    lo = risk;
                    kb = j;
                    memcpy(Yout, Yp, n3 * sizeof(double));
                }
            }
        }
        if (si == NSIG - 1 && !fr->s_known)
            sf = noise_from_residuals(cs, sumw, s);
    }
    /* the noise level and the candidate of least SURE at it */
    double s2 = sf * sf;
    int k = least_sure(cs, sumw, sf);
    pick->s = sf;
    pick->sigma_r = SIGMA_R[k / (NNIT * NVIT)];
    pick->normal_iters = NIT[(k / NVIT) % NNIT];
    pick->vertex_iters = VIT[k % NVIT];
    pick->div = cs[k].div_f;
    pick->vdiv = cs[k].vdiv_f;
    pick->risk = cs[k].sr2_f - s2 * sumw + 2.0 * s2 * cs[k].div_f;
    /* the result: another width's is in Yout already (kb: the same
     * iterations from X, the same bits); the widest kernel's normals on X
     * are in Nw */
    int ks = k / (NNIT * NVIT), kn = (k / NVIT) % NNIT;
    if (k != kb) {
        memcpy(Yout, X, n3 * sizeof(double));
        if (ks == NSIG - 1)
            mcf__bnf_vertices(b, Nw + (size_t)kn * nf3, fixed, pick->vertex_iters, Yout);
        else
            mcf__bnf_run(b, X, fixed, pick->sigma_r, pick->normal_iters, pick->vertex_iters, Yout);
    }
    residuals(fr, fr->w, Yout, X, m, rbest);
    /* against the linear fairing's result (or the input): its SURE along
     * the same normals m, its trace from the same probes, at the same
     * noise level */
    double trl, vtrl, rs2 = s > 0.0 ? s2 / (s * s) : 1.0;
    if (fr->Ylin) {
        double sl = residuals(fr, fr->w, fr->Ylin, fr->X0, m, rlin);
        trl = mean_var(fr->trlin, fr->nprobe, &vtrl);
        pick->risk_lin = sl - s2 * sumw + 2.0 * s2 * trl + fr->lin_penalty * rs2;
        pick->outliers = drop_outliers(fr, sf, rbest, rlin, &pick->risk, &pick->risk_lin);
    } else {
        trl = sumw;
        vtrl = 0.0;
        pick->risk_lin = s2 * sumw;
    }
    double gain = pick->risk_lin - pick->risk;
    double var = diff_var(fr, sf, fr->Ylin ? rlin : NULL, rbest, trl - pick->div, vtrl + pick->vdiv);
    pick->z = var > 0.0 ? gain / sqrt(var) : (gain > 0.0 ? INFINITY : 0.0);
    pick->won = gain > 0.0 && pick->z >= fr->min_z;
    pick->risk /= sumw;
    pick->risk_lin /= sumw;
done:
    mcf__bnf_free(b);
    free(m);
    free(Xp);
    free(Yp);
    free(Sq);
    free(Nk);
    free(rbest);
    free(rlin);
    free(wp);
    free(ap);
    free(cs);
    return rc;
}

/* ------------------------------------------------------------ locality */

/* A vertex order in which neighbours lie close (breadth-first over the
 * faces, each component from its least vertex): new[i] the new index of
 * vertex i; and the faces sorted by their first vertex in it: fo[k] the
 * face at position k. The filter's sums gather and scatter over the
 * faces sharing a vertex; in a mesh's own order those lie anywhere
 * (couplingdown_sub2.obj, a subdivided mesh: vertices of one face a
 * median 11,763 indices apart), and perf showed the stage waiting on
 * those loads (the two instructions reading a neighbour's normal and
 * adding into it took 54% of mcf__bnf_normals' samples). */
static int locality_order(const int32_t *F, int nf, int nv, int *neu, int *fo)
{
    int *vp = mcf__calloc((size_t)nv + 2, sizeof(int)), *vf = mcf__malloc(3 * (size_t)nf + 1, sizeof(int));
    int *queue = mcf__malloc((size_t)nv + 1, sizeof(int)), *key = mcf__calloc((size_t)nv + 2, sizeof(int));
    if (!vp || !vf || !queue || !key) {
        free(vp);
        free(vf);
        free(queue);
        free(key);
        return -1;
    }
    mcf__vertex_faces(F, nf, nv, vp, vf);
    for (int i = 0; i < nv; i++)
        neu[i] = -1;
    int n = 0;
    for (int r = 0; r < nv; r++) {
        if (neu[r] >= 0)
            continue;
        int head = n;
        neu[r] = n;
        queue[n++] = r;
        while (head < n) {
            int v = queue[head++];
            for (int t = vp[v]; t < vp[v + 1]; t++)
                for (int k = 0; k < 3; k++) {
                    int u = F[3 * (size_t)vf[t] + k];
                    if (neu[u] < 0) {
                        neu[u] = n;
                        queue[n++] = u;
                    }
                }
        }
    }
    /* the faces by the least new index of their corners (counting sort) */
    for (int f = 0; f < nf; f++) {
        const int32_t *t = F + 3 * (size_t)f;
        key[imin3(neu[t[0]], neu[t[1]], neu[t[2]]) + 1]++;
    }
    for (int i = 0; i < nv; i++)
        key[i + 1] += key[i];
    for (int f = 0; f < nf; f++) {
        const int32_t *t = F + 3 * (size_t)f;
        fo[key[imin3(neu[t[0]], neu[t[1]], neu[t[2]])]++] = f;
    }
    free(vp);
    free(vf);
    free(queue);
    free(key);
    return 0;
}

mcf_status mcf__feature(const double *X, const int32_t *F, int nf, int nv, const unsigned char *fixed,
                        const mcf__feature_frame *fr, double *Yout, mcf__feature_pick *pick, mcf_error *err)
{
    /* the stage on the mesh renumbered for locality (locality_order):
     * the same sums in other orders */
    size_t n3 = 3 * (size_t)nv;
    int *neu = mcf__malloc((size_t)nv + 1, sizeof(int)), *fo = mcf__malloc((size_t)nf + 1, sizeof(int));
    int *vert = mcf__malloc((size_t)fr->nfree + 1, sizeof(int));
    int32_t *Fp = mcf__malloc(3 * (size_t)nf + 1, sizeof(int32_t));
    unsigned char *fx = fixed ? mcf__malloc((size_t)nv + 1, 1) : NULL;
    double *Xp = mcf__malloc_big(n3 + 1, sizeof(double)), *Yp = mcf__malloc_big(n3 + 1, sizeof(double));
    double *w = mcf__malloc((size_t)nv + 1, sizeof(double));
    double *Yl = fr->Ylin ? mcf__malloc_big(2 * n3 + 1, sizeof(double)) : NULL;
    mcf_status rc;
    if (!neu || !fo || !vert || !Fp || (fixed && !fx) || !Xp || !Yp || !w || (fr->Ylin && !Yl) ||
        locality_order(F, nf, nv, neu, fo) != 0) {
        rc = mcf__fail(err, MCF_ENOMEM, "feature filter: out of memory (%d vertices)", nv);
        memset(pick, 0, sizeof *pick);
        goto done;
    }
    mcf__feature_frame fp = *fr;
    for (int f = 0; f < nf; f++)
        for (int k = 0; k < 3; k++)
            Fp[3 * (size_t)f + k] = neu[F[3 * (size_t)fo[f] + k]];
    for (int i = 0; i < nv; i++) {
        size_t j = (size_t)neu[i];
        memcpy(Xp + 3 * j, X + 3 * (size_t)i, 3 * sizeof(double));
        memcpy(Yp + 3 * j, Yout + 3 * (size_t)i, 3 * sizeof(double)); /* untouched when nothing to filter */
        w[j] = fr->w[i];
        if (fx)
            fx[j] = fixed[i];
        if (Yl) {
            memcpy(Yl + 3 * j, fr->Ylin + 3 * (size_t)i, 3 * sizeof(double));
            memcpy(Yl + n3 + 3 * j, fr->X0 + 3 * (size_t)i, 3 * sizeof(double));
        }
    }
    for (int k = 0; k < fr->nfree; k++)
        vert[k] = neu[fr->vert[k]];
    fp.vert = vert;
    fp.w = w;
    fp.Ylin = Yl;
    fp.X0 = Yl ? Yl + n3 : NULL;
    rc = feature_run(Xp, Fp, nf, nv, fx, &fp, Yp, pick, err);
    if (rc == MCF_OK) {
        for (int i = 0; i < nv; i++)
            memcpy(Yout + 3 * (size_t)i, Yp + 3 * (size_t)neu[i], 3 * sizeof(double));
        pick->bytes += sizeof(int) * (2 * (size_t)nv + (size_t)nf + (size_t)fr->nfree + 3 * (size_t)nf) + (size_t)nv +
                       sizeof(double) * (3 * n3 + (size_t)nv) + 2 * mcf__big_slack(n3 + 1, sizeof(double)) +
                       (Yl ? mcf__big_slack(2 * n3 + 1, sizeof(double)) : 0);
    }
done:
    free(neu);
    free(fo);
    free(vert);
    free(Fp);
    free(fx);
    free(Xp);
    free(Yp);
    free(w);
    free(Yl);
    return rc;
}

mcf_status mcf__feature_output(const double *Xin, const double *fn_orig, const double *Y, const int32_t *F, int nf,
                               int nv, const unsigned char *fixed, double rmax, const double *grid, int *flips,
                               int *turned, double *X,
                               int *rounds, int *moves, mcf_error *err)
{
    double *N = mcf__malloc(3 * (size_t)nv + 1, sizeof(double)), *G = mcf__malloc(3 * (size_t)nv + 1, sizeof(double));
    int left;
    if (!N || !G) {
        free(N);
        free(G);
        return mcf__fail(err, MCF_ENOMEM, "feature filter: out of memory (%d vertices)", nv);
    }
    mcf__vertex_normals(Y, F, nf, nv, N);
    memcpy(X, Xin, 3 * sizeof(double) * (size_t)nv);
    memcpy(G, Y, 3 * sizeof(double) * (size_t)nv);
    for (int i = 0; i < nv; i++) {
        if (fixed && fixed[i])
            continue;
        double d[3], *x = X + 3 * (size_t)i;
        const double *n = N + 3 * (size_t)i, *x0 = Xin + 3 * (size_t)i;
        mcf__sub3(Y + 3 * (size_t)i, x0, d);
        double a = mcf__dot3(n, d);
        for (int e = 0; e < 3; e++)
            x[e] += a * n[e];
        /* moves beyond rmax taken back as the linear fairing's are
         * (mcf_fairing.c, MAX_MOVE): to rmax - (l - rmax) / 2, none
         * from 3 rmax on; on X and on the guard's positions G */
        for (int t = 0; t < 2; t++) {
            double *p = t ? G + 3 * (size_t)i : x;
            mcf__sub3(p, x0, d);
            double l = sqrt(mcf__dot3(d, d));
            if (rmax > 0.0 && l > rmax)
                for (int e = 0; e < 3; e++)
                    p[e] = x0[e] + d[e] * (fmax(0.0, rmax - (l - rmax) / 2.0) / l);
        }
    }
    if (grid) {
        mcf__lattice_clip(X, Xin, nv, fixed, grid);
        mcf__lattice_clip(G, Xin, nv, fixed, grid);
    }
    /* the faces the input had without area, turned against Y's normal
     * field, taken back as the linear fairing's output does (mcf_flips.c) */
    int flip_moves;
    mcf_status rc = flips ? mcf__flips_repair(X, Xin, N, F, nf, nv, grid != NULL, flips, &flip_moves, err) : MCF_OK;
    /* the faces turned against the output's smoothed normal field
     * (mcf_turned.c), as the linear fairing's output does */
    if (rc == MCF_OK && turned)
        rc = mcf__turned_repair(X, Xin, F, nf, nv, turned, err);
    if (rc == MCF_OK)
        rc = mcf__unfold(X, Xin, fn_orig, G, F, nf, nv, rounds, moves, &left, err);
    free(N);
    free(G);
    return rc;
}
