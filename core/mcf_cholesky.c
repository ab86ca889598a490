/* SPDX-License-Identifier: MIT */
/*
 * mcf_cholesky.c - core's SPD solver (the implicit schemes, the automatic
 * amount, the fairing filter): a supernodal Cholesky factorization
 * (CHOLMOD) of a job's SPD matrix, analysed once, refactored as often as
 * the caller needs, and solved for all its columns at once.
 *
 * What it does differently from cholmod_factorize + cholmod_solve2, each
 * measured on the 435k-vertex dragon (lab/README.md, Benchmarks):
 *  - The symbolic analysis (ordering, supernodes) runs once per job on the
 *    job's pattern, as before. From it, the lower triangle of P A P' is laid
 *    out once (S, natural order) with a map from each entry of the job's
 *    upper triangle to its place in S. A refactorization scatters the values
 *    through the map and calls cholmod_super_numeric on S directly:
 *    cholmod_factorize would allocate and fill a permuted transpose of A at
 *    every step (about 25 ms and fresh pages each time).
 *  - The solve of up to four columns runs over the supernodal factor
 *    itself with the columns (x, y, z, a probe) interleaved: one pass
 *    forward, one back, no BLAS call per supernode (99.7% of the dragon's
 *    50k supernodes have 16 columns or fewer, where a call costs more than
 *    its flops), no column-major copies of the right-hand side. More
 *    columns (the fairing filter's nine) go to CHOLMOD's own supernodal
 *    solve on the same factor, where the BLAS calls pay (measured on
 *    armadillo's fairing: this kernel with three vectors a row took 37% of
 *    the run's CPU, CHOLMOD's 31%).
 *  - Both run with subnormal numbers flushed to zero (x86: MXCSR's FTZ and
 *    DAZ, on the calling thread only, restored after). At strength 0.33
 *    in 10 steps a step is tiny (dt ~ 0.01 h^2), the off-diagonal entries are
 *    ~1e-2 of the diagonal and the fill of the factor decays geometrically
 *    along the elimination tree, far below 1e-308: every multiply with a
 *    subnormal operand is a microcode assist of ~100 cycles. It took the
 *    dragon's desbrun2 request at strength 0.33 from 12.3 to 7.2 s of CPU
 *    (lab/README.md, Benchmarks), with the same bytes out: a value below 2.2e-308 next to a diagonal of
 *    order 1e-6 or more is 300 orders of magnitude under the rounding.
 * The factor is CHOLMOD's (the serial build, see the Makefile), so its
 * values and their rounding are those of cholmod_factorize, but for
 * subnormal values, which are 0 here.
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cholmod.h>

#include "mcf_internal.h"

#if defined(__x86_64__) || defined(__SSE2__)
#include <xmmintrin.h>
#define FTZ_DAZ 0x8040u /* MXCSR flush-to-zero (bit 15), denormals-are-zero (bit 6) */
static unsigned subnormals_off(void)
{
    unsigned old = _mm_getcsr();
    _mm_setcsr(old | FTZ_DAZ);
    return old;
}
static void subnormals_restore(unsigned old)
{
    _mm_setcsr(old);
}
#else
/* elsewhere the arithmetic is the same, only slower on tiny steps */
static unsigned subnormals_off(void)
{
    return 0;
}
static void subnormals_restore(unsigned old)
{
    (void)old;
}
#endif

/* One row of the three right-hand sides, padded to four doubles (x, y,
 * z, unused) so that a row is one vector: two SSE2 operations in a generic
 * x86-64 build, one AVX operation in the AVX2 clone. Lane-wise arithmetic,
 * no fused multiply-add (ISO C mode contracts nothing), so both clones give
 * the same bits. */
typedef double v4d __attribute__((vector_size(32)));

struct mcf__chol {
    int n;
    int ncol;           /* the most columns of a solve */
    const mcf__pattern *pat;
    cholmod_common cm;
    cholmod_factor *L;
    cholmod_sparse *S;  /* tril(P A P'), stype -1, natural order */
    int *smap;          /* pat->nnz: entry of A's upper triangle -> S->x */
    v4d *y;             /* n: the permuted right-hand side / solution */
    v4d *buf;           /* maxesize: the solve's rows below a supernode */
    cholmod_dense *B, *X, *Yw, *Ew; /* more than 4 columns: CHOLMOD's solve */
    size_t bytes;       /* smap, y and buf */
    int analysed;
};

mcf__chol *mcf__chol_new(const mcf__pattern *pat, int ncol, mcf_error *err)
{
    mcf__chol *ch = mcf__calloc(1, sizeof *ch);
    if (!ch) {
        mcf__fail(err, MCF_ENOMEM, "solver: out of memory");
        return NULL;
    }
    ch->n = pat->n;
    ch->ncol = ncol;
    ch->pat = pat;
    cholmod_start(&ch->cm);
    ch->cm.error_handler = NULL;
    ch->cm.print = 0;
    /* Always supernodal (CHOLMOD's default picks simplicial below 40 flops
     * per entry of L, i.e. on small meshes only, where either takes
     * microseconds): one code path, the one the scans take. Ordering:
     * CHOLMOD's default, AMD, with METIS tried as well when AMD's fill is
     * high (flops/lnz >= 500 and lnz/nnz(A) >= 5). Forcing METIS saves
     * flops but not time on scanned meshes (the dragon: 2.6 s of analysis
     * for 1.6 GFlop per factorization against AMD's 0.5 s and 2.2 GFlop);
     * on icosphere-7, whose AMD fill is poor, the default tries METIS. */
    ch->cm.supernodal = CHOLMOD_SUPERNODAL;
    return ch;
}

void mcf__chol_free(mcf__chol *ch)
{
    if (!ch)
        return;
    cholmod_free_factor(&ch->L, &ch->cm);
    cholmod_free_sparse(&ch->S, &ch->cm);
    cholmod_free_dense(&ch->B, &ch->cm);
    cholmod_free_dense(&ch->X, &ch->cm);
    cholmod_free_dense(&ch->Yw, &ch->cm);
    cholmod_free_dense(&ch->Ew, &ch->cm);
    cholmod_finish(&ch->cm);
    free(ch->smap);
    free(ch->y);
    free(ch->buf);
    free(ch);
}

size_t mcf__chol_bytes(const mcf__chol *ch)
{
    return ch ? ch->bytes + ch->cm.memory_usage : 0;
}

const mcf__pattern *mcf__chol_pattern(const mcf__chol *ch)
{
    return ch->pat;
}

void mcf__chol_size(const mcf__chol *ch, double *nnz, double *flops)
{
    *nnz = ch ? ch->cm.lnz : 0.0;
    *flops = ch ? ch->cm.fl : 0.0;
}

static mcf_status chol_status(mcf__chol *ch, const char *what, mcf_error *err)
{
    int s = ch->cm.status;
    if (s == CHOLMOD_OUT_OF_MEMORY)
        return mcf__fail(err, MCF_ENOMEM, "%s: out of memory", what);
    if (s == CHOLMOD_TOO_LARGE)
        return mcf__fail(err, MCF_ELIMIT, "%s: the factor of this mesh is too large for CHOLMOD's integers", what);
    return mcf__fail(err, MCF_ENUMERIC, "%s failed (status %d)", what, s);
}

mcf_status mcf__chol_analyze(mcf__chol *ch, mcf_error *err)
{
    const mcf__pattern *pat = ch->pat;
    int n = ch->n, nnz = pat->nnz;
    /* A's upper triangle as CHOLMOD sees it: a view of the pattern */
    cholmod_sparse A = {0};
    A.nrow = A.ncol = (size_t)n;
    A.nzmax = (size_t)nnz;
    A.p = pat->colptr;
    A.i = pat->rowind;
    A.stype = 1;
    A.itype = CHOLMOD_INT;
    A.xtype = CHOLMOD_PATTERN;
    A.dtype = CHOLMOD_DOUBLE;
    A.sorted = 1;
    A.packed = 1;
    if (ch->analysed)
        return MCF_OK; /* analysed already (another user of the solver) */
    if (!(ch->L = cholmod_analyze(&A, &ch->cm)))
        return chol_status(ch, "cholmod_analyze", err);
    if (!ch->L->is_super)
        return mcf__fail(err, MCF_ENUMERIC, "cholmod_analyze: no supernodal factor");

    /* S = tril(P A P'): entry (i, j), i <= j, of A goes to row
     * max(pinv i, pinv j) of column min(pinv i, pinv j) */
    const int *perm = ch->L->Perm;
    int *pinv = mcf__malloc((size_t)n, sizeof(int));
    ch->smap = mcf__malloc((size_t)nnz, sizeof(int));
    ch->y = aligned_alloc(sizeof(v4d), sizeof(v4d) * ((size_t)n + 1));
    ch->buf = aligned_alloc(sizeof(v4d), sizeof(v4d) * ((size_t)ch->L->maxesize + 1));
    ch->S = cholmod_allocate_sparse((size_t)n, (size_t)n, (size_t)nnz, 0, 1, -1, CHOLMOD_REAL, &ch->cm);
    if (!pinv || !ch->smap || !ch->y || !ch->buf || !ch->S) {
        free(pinv);
        return mcf__fail(err, MCF_ENOMEM, "solver: out of memory (%d unknowns)", n);
    }
    ch->bytes = sizeof(int) * (size_t)nnz + sizeof(v4d) * ((size_t)n + ch->L->maxesize + 2);
    for (int k = 0; k < n; k++)
        pinv[perm[k]] = k;
    int *sp = ch->S->p, *si = ch->S->i;
    memset(sp, 0, sizeof(int) * ((size_t)n + 1));
    for (int j = 0; j < n; j++)
        for (int t = pat->colptr[j]; t < pat->colptr[j + 1]; t++) {
            int a = pinv[pat->rowind[t]], b = pinv[j];
            sp[(a < b ? a : b) + 1]++;
        }
    for (int k = 0; k < n; k++)
        sp[k + 1] += sp[k];
    int *next = mcf__malloc((size_t)n, sizeof(int)); /* next free slot of each column */
    if (!next) {
        free(pinv);
        return mcf__fail(err, MCF_ENOMEM, "solver: out of memory (%d unknowns)", n);
    }
    memcpy(next, sp, sizeof(int) * (size_t)n);
    for (int j = 0; j < n; j++)
        for (int t = pat->colptr[j]; t < pat->colptr[j + 1]; t++) {
            int a = pinv[pat->rowind[t]], b = pinv[j];
            int col = a < b ? a : b, row = a < b ? b : a;
            int slot = next[col]++;
            si[slot] = row;
            ch->smap[t] = slot;
        }
    free(next);
    free(pinv);
    ch->analysed = 1;
    return MCF_OK;
}

mcf_status mcf__chol_factorize(mcf__chol *ch, const double *val, mcf_error *err)
{
    double *sx = ch->S->x, zero[2] = {0.0, 0.0};
    const int *smap = ch->smap;
    for (int t = 0; t < ch->pat->nnz; t++)
        sx[smap[t]] = val[t];
    unsigned fpu = subnormals_off();
    int ok = cholmod_super_numeric(ch->S, NULL, zero, ch->L, &ch->cm);
    subnormals_restore(fpu);
    /* By Common->status, not by the return value (which is FALSE for every
     * error and TRUE for a matrix that is not positive definite) */
    if (ch->cm.status == CHOLMOD_NOT_POSDEF)
        return mcf__fail(err, MCF_ENOTPOSDEF,
                         "system matrix not positive definite at column %d (degenerate or inverted geometry)",
                         (int)ch->L->minor);
    if (!ok || ch->cm.status < CHOLMOD_OK)
        return chol_status(ch, "cholmod_super_numeric", err);
    return MCF_OK;
}

/* Y (n rows, permuted) = L^-T L^-1 Y with the supernodal factor:
 * supernode s holds columns super[s] .. super[s+1]-1, its rows
 * ls[pi[s] ..] (the first nscol are its own columns, in order) and the
 * values column-major at lx[px[s]] with leading dimension nsrow. The rows
 * below the diagonal block are reached through ls once per supernode: in
 * buf (at least L->maxesize rows), where the columns' updates accumulate
 * (forward) or which holds their gathered values (back), so the inner
 * loops run over contiguous memory. */
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
static inline void solve_body(const cholmod_factor *L, v4d *y, v4d *buf)
{
    const int *super = L->super, *pi = L->pi, *px = L->px, *ls = L->s;
    const double *lx = L->x;
    int nsuper = (int)L->nsuper;
    const v4d zero = {0.0, 0.0, 0.0, 0.0};
    for (int s = 0; s < nsuper; s++) {
        int k1 = super[s], nscol = super[s + 1] - k1, nsrow = pi[s + 1] - pi[s];
        int nrect = nsrow - nscol;
        const int *rows = ls + pi[s] + nscol;
        v4d *yk = y + k1;
        for (int ii = 0; ii < nrect; ii++)
            buf[ii] = zero;
        for (int jj = 0; jj < nscol; jj++) {
            const double *col = lx + px[s] + (size_t)jj * nsrow, *lr = col + nscol;
            v4d a = yk[jj] / col[jj];
            yk[jj] = a;
            for (int ii = jj + 1; ii < nscol; ii++)
                yk[ii] -= col[ii] * a;
            for (int ii = 0; ii < nrect; ii++)
                buf[ii] += lr[ii] * a;
        }
        for (int ii = 0; ii < nrect; ii++)
            y[rows[ii]] -= buf[ii];
    }
    for (int s = nsuper - 1; s >= 0; s--) {
        int k1 = super[s], nscol = super[s + 1] - k1, nsrow = pi[s + 1] - pi[s];
        int nrect = nsrow - nscol;
        const int *rows = ls + pi[s] + nscol;
        v4d *yk = y + k1;
        for (int ii = 0; ii < nrect; ii++)
            buf[ii] = y[rows[ii]];
        for (int jj = nscol - 1; jj >= 0; jj--) {
            const double *col = lx + px[s] + (size_t)jj * nsrow, *lr = col + nscol;
            v4d a = yk[jj];
            for (int ii = jj + 1; ii < nscol; ii++)
                a -= col[ii] * yk[ii];
            /* the long dot product in four chains: one chain waits an
             * add's latency per row */
            v4d s0 = zero, s1 = zero, s2 = zero, s3 = zero;
            int ii = 0;
            for (; ii + 4 <= nrect; ii += 4) {
                s0 += lr[ii] * buf[ii];
                s1 += lr[ii + 1] * buf[ii + 1];
                s2 += lr[ii + 2] * buf[ii + 2];
                s3 += lr[ii + 3] * buf[ii + 3];
            }
            for (; ii < nrect; ii++)
                s0 += lr[ii] * buf[ii];
            yk[jj] = (a - ((s0 + s1) + (s2 + s3))) / col[jj];
        }
    }
}

static void solve_generic(const cholmod_factor *L, v4d *y, v4d *buf)
{
    solve_body(L, y, buf);
}

#if defined(__x86_64__) && defined(__GNUC__)
#define SOLVE_AVX2 1
__attribute__((target("avx2")))
static void solve_avx2(const cholmod_factor *L, v4d *y, v4d *buf)
{
    solve_body(L, y, buf);
}
#endif

/* Up to four columns: our kernel, one vector per row. More: CHOLMOD's
 * supernodal solve on the same factor, whose BLAS calls pay with many
 * columns (the fairing filter's nine on armadillo: our kernel with three
 * vectors per row took 37% of the run's CPU against 31% for CHOLMOD's). */
mcf_status mcf__chol_solve(mcf__chol *ch, int ncol, const double *B, size_t rs, size_t cs, double *X,
                           mcf_error *err)
{
    int n = ch->n;
    if (ncol > 4) {
        /* column-major B is read in place, else copied to ch->B */
        int cm = rs == 1 && cs == (size_t)n;
        if (!cm && !ch->B &&
            !(ch->B = cholmod_allocate_dense((size_t)n, (size_t)ch->ncol, (size_t)n, CHOLMOD_REAL, &ch->cm)))
            return chol_status(ch, "solver", err);
        cholmod_dense Bv = {0};
        Bv.nrow = Bv.d = (size_t)n;
        Bv.ncol = (size_t)ncol;
        Bv.nzmax = (size_t)ncol * (size_t)n;
        Bv.xtype = CHOLMOD_REAL;
        Bv.dtype = CHOLMOD_DOUBLE;
        if (cm) {
            Bv.x = (double *)(uintptr_t)B; /* CHOLMOD's dense is not const; only read */
        } else {
            double *bx = Bv.x = ch->B->x;
            for (int c = 0; c < ncol; c++)
                for (int k = 0; k < n; k++)
                    bx[(size_t)c * n + k] = B[rs * k + cs * c];
        }
        unsigned fpu = subnormals_off();
        int ok = cholmod_solve2(CHOLMOD_A, ch->L, &Bv, NULL, &ch->X, NULL, &ch->Yw, &ch->Ew, &ch->cm);
        subnormals_restore(fpu);
        if (!ok) /* only its workspace, allocated on the first call */
            return chol_status(ch, "cholmod_solve2", err);
        const double *xx = ch->X->x;
        if (cm)
            memcpy(X, xx, sizeof(double) * (size_t)ncol * (size_t)n);
        else
            for (int c = 0; c < ncol; c++)
                for (int k = 0; k < n; k++)
                    X[rs * k + cs * c] = xx[(size_t)c * n + k];
        return MCF_OK;
    }
    const int *perm = ch->L->Perm;
    v4d *y = ch->y;
    if (ncol == 3 && rs == 3 && cs == 1) { /* the flow's: the loads unrolled */
        for (int k = 0; k < n; k++) {
            const double *b = B + 3 * (size_t)perm[k];
            y[k] = (v4d){b[0], b[1], b[2], 0.0};
        }
    } else {
        for (int k = 0; k < n; k++) {
            const double *b = B + rs * (size_t)perm[k];
            v4d v = {0.0, 0.0, 0.0, 0.0};
            for (int c = 0; c < ncol; c++)
                v[c] = b[cs * c];
            y[k] = v;
        }
    }
    unsigned fpu = subnormals_off();
#if defined(SOLVE_AVX2)
    if (__builtin_cpu_supports("avx2"))
        solve_avx2(ch->L, y, ch->buf);
    else
#endif
        solve_generic(ch->L, y, ch->buf);
    subnormals_restore(fpu);
    if (ncol == 3 && rs == 3 && cs == 1) {
        for (int k = 0; k < n; k++) {
            double *x = X + 3 * (size_t)perm[k];
            x[0] = y[k][0];
            x[1] = y[k][1];
            x[2] = y[k][2];
        }
    } else {
        for (int k = 0; k < n; k++) {
            double *x = X + rs * (size_t)perm[k];
            for (int c = 0; c < ncol; c++)
                x[cs * c] = y[k][c];
        }
    }
    return MCF_OK;
}

void mcf__chol_solve3(mcf__chol *ch, const double *B, double *X)
{
    mcf__chol_solve(ch, 3, B, 3, 1, X, NULL);
}
