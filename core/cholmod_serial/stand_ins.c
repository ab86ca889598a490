/* SPDX-License-Identifier: MIT */
/*
 * stand_ins.c - what the private copy of CHOLMOD calls instead of libgomp
 * and of SuiteSparse's clock. The Makefile renames these references in
 * Debian's libcholmod.a (objcopy --redefine-sym) to the functions below,
 * in a copy of the archive, $(B)/libcholmod_serial.a, and adds this object
 * to it.
 *
 * OpenMP: the three entry points cholmod_super_numeric.o calls
 * (GOMP_parallel, omp_get_num_threads, omp_get_thread_num). CHOLMOD runs
 * each parallel region inline, as a team of one, and never reaches
 * libgomp, whose team set-up (allocation, futex calls) for each of the
 * ~150,000 regions of a dragon factorization cost 45% of it even with
 * OMP_THREAD_LIMIT=1.
 *
 * SuiteSparse_time: cholmod_super_numeric.o reads the clock around every
 * BLAS call it makes (four per supernode) for timing statistics in
 * cholmod_common (CHOLMOD_CPU_GEMM_TIME and the like) that mcf never
 * reads: 5% of a factorization of the armadillo. It reads 0 here, so those
 * statistics stay 0.
 *
 * dpotrf_ and dtrsm_ (the supernode's own factor and its rows below):
 * renamed to mcf__dpotrf and mcf__dtrsm, which run the small calls as
 * plain column-major loops (the shapes cholmod_super_numeric uses: lower,
 * right side, transposed) and hand everything else to the BLAS. Most
 * supernodes of a scan are tiny (the armadillo: 5,006 of 8.6 columns),
 * where OpenBLAS's dpotrf (an unblocked dpotf2 of one dgemv and one dscal
 * per column) and dtrsm (packing, then its kernel) spend more on calls
 * and copies than on flops: the armadillo's numeric factorization 12.1 ->
 * 10.6 ms (minimum of 30, interleaved; lab/bench/README.md). The update
 * calls (dsyrk, dgemm) stay OpenBLAS's: as loops they were not faster. The
 * loops round differently from OpenBLAS (another order of the same
 * operations); the AVX2 clone does each element's operations in the
 * generic one's order (no fused multiply-add).
 *
 * Thread safety: no state at all. A region runs on the thread that opens
 * it, so the workers of mcfd, each factoring its own matrix, run their
 * regions at once without sharing anything. What the stand-ins promise is
 * what a team of one is in OpenMP: the outlined function runs once, sees
 * one thread, its own number 0, and so takes every iteration of each
 * statically scheduled loop (the only kind CHOLMOD 3.0.14 opens: it
 * calls no other libgomp entry point, which the Makefile checks).
 */
void mcf__omp_parallel(void (*fn)(void *), void *data, unsigned num_threads, unsigned flags);
int mcf__omp_get_num_threads(void);
int mcf__omp_get_thread_num(void);
double mcf__suitesparse_time(void);

void mcf__omp_parallel(void (*fn)(void *), void *data, unsigned num_threads, unsigned flags)
{
    (void)num_threads;
    (void)flags;
    fn(data);
}

int mcf__omp_get_num_threads(void)
{
    return 1;
}

int mcf__omp_get_thread_num(void)
{
    return 0;
}

double mcf__suitesparse_time(void)
{
    return 0.0;
}

/* ------------------------------------------------ small dpotrf, dtrsm */

#include <math.h>
#include <stddef.h>

void dtrsm_(const char *side, const char *uplo, const char *ta, const char *diag, const int *m, const int *n,
            const double *alpha, const double *a, const int *lda, double *b, const int *ldb);
void dpotrf_(const char *uplo, const int *n, double *a, const int *lda, int *info);
void mcf__dtrsm(const char *side, const char *uplo, const char *ta, const char *diag, const int *m, const int *n,
                const double *alpha, const double *a, const int *lda, double *b, const int *ldb);
void mcf__dpotrf(const char *uplo, const int *n, double *a, const int *lda, int *info);

/* Below these flops the loops: measured on the armadillo's matrix, dtrsm
 * 2k / 20k / 100k / everything: 11.96 / 11.51 / 11.09 / 11.52 ms with
 * dpotrf to the BLAS, dpotrf 1k / 100k: 12.38 / 12.09 (12.4 all BLAS) */
#define SMALL_TRSM 20000.0
#define SMALL_POTRF 100000.0

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC optimize("O3") /* the row loops vectorized */
#endif
#if defined(__GNUC__)
#define BODY __attribute__((always_inline)) static inline
#else
#define BODY static inline
#endif

/* B (m x n, leading dimension lb) = B A'^-1, A lower n x n (la) */
BODY void trsm_rlt(int M, int N, const double *a, int la, double *b, int lb)
{
    for (int j = 0; j < N; j++) {
        double *bj = b + (size_t)j * lb;
        for (int p = 0; p < j; p++) {
            double ajp = a[j + (size_t)p * la];
            const double *bp = b + (size_t)p * lb;
            for (int i = 0; i < M; i++)
                bj[i] -= bp[i] * ajp;
        }
        double d = a[j + (size_t)j * la];
        for (int i = 0; i < M; i++)
            bj[i] /= d;
    }
}

/* lower Cholesky of A (n x n, la) in place; the first column that is not
 * positive (1-based, as LAPACK's info), else 0 */
BODY int potrf_l(int N, double *a, int la)
{
    for (int j = 0; j < N; j++) {
        double *aj = a + (size_t)j * la;
        for (int p = 0; p < j; p++) {
            const double *ap = a + (size_t)p * la;
            double ajp = ap[j];
            for (int i = j; i < N; i++)
                aj[i] -= ap[i] * ajp;
        }
        double d = aj[j];
        if (!(d > 0.0))
            return j + 1;
        d = sqrt(d);
        aj[j] = d;
        for (int i = j + 1; i < N; i++)
            aj[i] /= d;
    }
    return 0;
}

static void trsm_generic(int M, int N, const double *a, int la, double *b, int lb)
{
    trsm_rlt(M, N, a, la, b, lb);
}

static int potrf_generic(int N, double *a, int la)
{
    return potrf_l(N, a, la);
}

#if defined(__x86_64__) && defined(__GNUC__)
#define SMALL_AVX2 1
__attribute__((target("avx2"))) static void trsm_avx2(int M, int N, const double *a, int la, double *b, int lb)
{
    trsm_rlt(M, N, a, la, b, lb);
}

__attribute__((target("avx2"))) static int potrf_avx2(int N, double *a, int la)
{
    return potrf_l(N, a, la);
}
#endif

static int is(const char *c, char up)
{
    return *c == up || *c == up + ('a' - 'A');
}

void mcf__dtrsm(const char *side, const char *uplo, const char *ta, const char *diag, const int *m, const int *n,
                const double *alpha, const double *a, const int *lda, double *b, const int *ldb)
{
    if (!is(side, 'R') || !is(uplo, 'L') || !(is(ta, 'T') || is(ta, 'C')) || !is(diag, 'N') || *alpha != 1.0 ||
        0.5 * *m * (double)*n * *n > SMALL_TRSM) {
        dtrsm_(side, uplo, ta, diag, m, n, alpha, a, lda, b, ldb);
        return;
    }
#if defined(SMALL_AVX2)
    if (__builtin_cpu_supports("avx2")) {
        trsm_avx2(*m, *n, a, *lda, b, *ldb);
        return;
    }
#endif
    trsm_generic(*m, *n, a, *lda, b, *ldb);
}

void mcf__dpotrf(const char *uplo, const int *n, double *a, const int *lda, int *info)
{
    if (!is(uplo, 'L') || *n * (double)*n * *n / 3.0 > SMALL_POTRF) {
        dpotrf_(uplo, n, a, lda, info);
        return;
    }
#if defined(SMALL_AVX2)
    if (__builtin_cpu_supports("avx2")) {
        *info = potrf_avx2(*n, a, *lda);
        return;
    }
#endif
    *info = potrf_generic(*n, a, *lda);
}
