/* SPDX-License-Identifier: MIT */
/*
 * test_core_cholesky.c - the implicit schemes' solver (core/mcf_cholesky.c:
 * CHOLMOD's supernodal factor of the pre-permuted lower triangle, our own
 * supernodal solve of three or more columns) against independent
 * references: a dense
 * Cholesky written here (small systems), CHOLMOD's own cholmod_factorize +
 * cholmod_solve2 on the upper triangle (the route it replaced), the
 * residual through the pattern's matrix-vector product, a matrix that is
 * not positive definite, and the serial stand-ins of OpenMP from several
 * threads at once (mcfd's workers factor concurrently).
 */
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cholmod.h>

#include "testlib.h"
#include "mcf_internal.h"

/* The system of one desbrun step, A = M + h L, on a noisy icosphere or a
 * test mesh: pattern, values, and a 3-column right-hand side. */
typedef struct {
    mcf_mesh *m;
    mcf__pattern pat;
    double *val, *B;
    int n;
} sys;

static void sys_make(sys *s, mcf_mesh *m, double h)
{
    memset(s, 0, sizeof *s);
    s->m = m;
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m);
    const double *X = mcf_mesh_positions(m);
    const int32_t *F = mcf_mesh_faces(m);
    s->n = nv;
    assert_int_equal(mcf__pattern_build(F, nf, nv, 1, &s->pat, NULL), MCF_OK);
    double *w = calloc(3 * (size_t)nf, sizeof *w), *area = calloc((size_t)nf, sizeof *area);
    double *mass = calloc((size_t)nv, sizeof *mass);
    s->val = calloc((size_t)s->pat.nnz, sizeof *s->val);
    s->B = calloc(3 * (size_t)nv, sizeof *s->B);
    assert_true(w && area && mass && s->val && s->B);
    mcf__cot_weights(X, F, nf, MCF_LAPLACIAN_COTAN, 1e-3 * mcf__mean_edge(X, F, nf), w, area);
    mcf__mass(X, F, nf, nv, MCF_MASS_BARYCENTRIC, area, mass);
    mcf__pattern_fill_L(&s->pat, F, nf, w, s->val);
    for (int t = 0; t < s->pat.nnz; t++)
        s->val[t] *= h;
    for (int j = 0; j < nv; j++) {
        /* a vertex no face uses has no mass: an identity row, as the flow's */
        s->val[s->pat.diag[j]] += mass[j] > 0.0 ? mass[j] : 1.0;
        for (int d = 0; d < 3; d++)
            s->B[3 * j + d] = mass[j] * X[3 * j + d] + 0.1 * sin(7.0 * j + d);
    }
    free(w);
    free(area);
    free(mass);
}

static void sys_free(sys *s)
{
    mcf__pattern_free(&s->pat);
    free(s->val);
    free(s->B);
    mcf_mesh_free(s->m);
}

static mcf__chol *factor_ncol(const sys *s, int ncol)
{
    mcf_error e = {0};
    mcf__chol *ch = mcf__chol_new(&s->pat, ncol, &e);
    assert_non_null(ch);
    assert_int_equal(mcf__chol_analyze(ch, &e), MCF_OK);
    assert_int_equal(mcf__chol_analyze(ch, &e), MCF_OK); /* once: a no-op */
    assert_int_equal(mcf__chol_factorize(ch, s->val, &e), MCF_OK);
    return ch;
}

static mcf__chol *factor(const sys *s)
{
    return factor_ncol(s, 3);
}

/* max |a - b| / max |b| over 3n values */
static double rel_max(const double *a, const double *b, int n)
{
    double num = 0.0, den = 0.0;
    for (size_t i = 0; i < 3 * (size_t)n; i++) {
        num = fmax(num, fabs(a[i] - b[i]));
        den = fmax(den, fabs(b[i]));
    }
    return num / den;
}

/* Y = A X (n x 3) for the symmetric matrix whose upper triangle the
 * pattern stores (CSC): the test's own product, independent of the
 * factor. */
static void pattern_matvec(const mcf__pattern *p, const double *val,
                           const double *X, double *Y)
{
    memset(Y, 0, sizeof(double) * 3 * (size_t)p->n);
    for (int j = 0; j < p->n; j++) {
        const double *xj = X + 3 * (size_t)j;
        double y0 = 0.0, y1 = 0.0, y2 = 0.0;
        for (int t = p->colptr[j]; t < p->colptr[j + 1]; t++) {
            int i = p->rowind[t];
            double a = val[t];
            const double *xi = X + 3 * (size_t)i;
            y0 += a * xi[0]; y1 += a * xi[1]; y2 += a * xi[2];
            if (i != j) {
                double *yi = Y + 3 * (size_t)i;
                yi[0] += a * xj[0]; yi[1] += a * xj[1]; yi[2] += a * xj[2];
            }
        }
        Y[3 * (size_t)j] += y0; Y[3 * (size_t)j + 1] += y1; Y[3 * (size_t)j + 2] += y2;
    }
}

/* ||A X - B||_max / ||B||_max through the pattern (no factor involved) */
static double residual(const sys *s, const double *X)
{
    double *AX = calloc(3 * (size_t)s->n, sizeof *AX);
    assert_non_null(AX);
    pattern_matvec(&s->pat, s->val, X, AX);
    double r = rel_max(AX, s->B, s->n);
    free(AX);
    return r;
}

/* Against a dense Cholesky of the same matrix, written out here. The
 * condition number of M + h L on these meshes is below 1e4 (h = 1e-2 on a
 * unit sphere: 1 + h lambda_max / m_min), so two double-precision solves
 * agree to about 1e4 * 1e-16; 1e-11 leaves room, a wrong entry, sign or
 * permutation shows up at 1e-3 and above. */
static void test_dense_reference(void **state)
{
    (void)state;
    mcf_mesh *m = mcf_mesh_new_icosphere(2, 1.0, NULL);
    assert_non_null(m);
    assert_int_equal(mcf_mesh_add_noise(m, 0.2, 3, NULL), MCF_OK);
    sys s;
    sys_make(&s, m, 1e-2);
    int n = s.n;
    double *D = calloc((size_t)n * n, sizeof *D), *Xd = malloc(3 * sizeof(double) * n);
    double *b = malloc(sizeof(double) * n), *X = malloc(3 * sizeof(double) * n);
    assert_true(D && Xd && b && X);
    for (int j = 0; j < n; j++)
        for (int t = s.pat.colptr[j]; t < s.pat.colptr[j + 1]; t++) {
            int i = s.pat.rowind[t];
            D[(size_t)i * n + j] = D[(size_t)j * n + i] = s.val[t];
        }
    /* dense lower Cholesky, row-major, then two triangular solves per column */
    for (int j = 0; j < n; j++) {
        double d = D[(size_t)j * n + j];
        for (int k = 0; k < j; k++)
            d -= D[(size_t)j * n + k] * D[(size_t)j * n + k];
        assert_true(d > 0.0);
        d = sqrt(d);
        D[(size_t)j * n + j] = d;
        for (int i = j + 1; i < n; i++) {
            double v = D[(size_t)i * n + j];
            for (int k = 0; k < j; k++)
                v -= D[(size_t)i * n + k] * D[(size_t)j * n + k];
            D[(size_t)i * n + j] = v / d;
        }
    }
    for (int c = 0; c < 3; c++) {
        for (int i = 0; i < n; i++) {
            double v = s.B[3 * i + c];
            for (int k = 0; k < i; k++)
                v -= D[(size_t)i * n + k] * b[k];
            b[i] = v / D[(size_t)i * n + i];
        }
        for (int i = n - 1; i >= 0; i--) {
            double v = b[i];
            for (int k = i + 1; k < n; k++)
                v -= D[(size_t)k * n + i] * b[k];
            b[i] = v / D[(size_t)i * n + i];
        }
        for (int i = 0; i < n; i++)
            Xd[3 * i + c] = b[i];
    }
    mcf__chol *ch = factor_ncol(&s, 9);
    mcf__chol_solve3(ch, s.B, X);
    /* the solver flushes subnormals only while it runs: the caller's
     * thread gets its own floating-point state back */
    volatile double tiny = 1e-300;
    assert_true(tiny * 1e-10 > 0.0);
    double r = rel_max(X, Xd, n);
    printf("    dense reference (%d unknowns): max difference %.1e of the solution\n", n, r);
    assert_true(r <= 1e-11);
    /* in place (B and X the same array) */
    memcpy(X, s.B, 3 * sizeof(double) * n);
    mcf__chol_solve3(ch, X, X);
    assert_true(rel_max(X, Xd, n) <= 1e-11);
    /* more columns at once: nine column-major (the fairing filter's
     * layout), six row-major, four column-major (the automatic amount's):
     * column c is (1 + c) B_(c mod 3), so its solution is (1 + c)
     * Xd_(c mod 3); the same 1e-11 */
    const int ncols[3] = {9, 6, 4};
    for (int t = 0; t < 3; t++) {
        int ncol = ncols[t];
        size_t rs = t == 1 ? (size_t)ncol : 1, cs = t == 1 ? 1 : (size_t)n;
        double *C = malloc(sizeof(double) * 9 * n);
        assert_non_null(C);
        for (int c = 0; c < ncol; c++)
            for (int i = 0; i < n; i++)
                C[rs * i + cs * c] = (1.0 + c) * s.B[3 * i + c % 3];
        assert_int_equal(mcf__chol_solve(ch, ncol, C, rs, cs, C, NULL), MCF_OK);
        for (int c = 0; c < ncol; c++)
            for (int i = 0; i < n; i++) {
                double want = Xd[3 * i + c % 3], got = C[rs * i + cs * c] / (1.0 + c);
                assert_true(fabs(got - want) <= 1e-11 * (1.0 + fabs(want)));
            }
        free(C);
    }
    mcf__chol_free(ch);
    free(D); free(Xd); free(b); free(X);
    sys_free(&s);
}

/* Against cholmod_factorize + cholmod_solve2 on the upper triangle (the
 * route mcf_cholesky.c replaced), on a scan with boundary, degenerate
 * faces and unreferenced vertices (bunny.drc: 35k vertices). Same
 * ordering, same supernodal kernel: the solutions differ only by the
 * summation order of the solves, a few ulps times the condition number
 * (1e-12 leaves 1e3 of room over what this case shows); the residual
 * through the pattern is independent of both factorizations. */
static void test_cholmod_reference(void **state)
{
    (void)state;
    mcf_mesh *m = tl_load("bunny.drc");
    assert_non_null(m);
    sys s;
    /* normalized to about unit area by h: bunny.drc's area is ~5.7e-2 */
    sys_make(&s, m, 1e-5);
    int n = s.n;
    double *X = malloc(3 * sizeof(double) * n);
    assert_non_null(X);
    mcf__chol *ch = factor(&s);
    mcf__chol_solve3(ch, s.B, X);

    cholmod_common cm;
    cholmod_start(&cm);
    cm.supernodal = CHOLMOD_SUPERNODAL;
    cholmod_sparse *A = cholmod_allocate_sparse((size_t)n, (size_t)n, (size_t)s.pat.nnz, 1, 1, 1,
                                                CHOLMOD_REAL, &cm);
    cholmod_dense *Bd = cholmod_allocate_dense((size_t)n, 3, (size_t)n, CHOLMOD_REAL, &cm);
    assert_true(A && Bd);
    memcpy(A->p, s.pat.colptr, sizeof(int) * (n + 1));
    memcpy(A->i, s.pat.rowind, sizeof(int) * s.pat.nnz);
    memcpy(A->x, s.val, sizeof(double) * s.pat.nnz);
    for (int i = 0; i < n; i++)
        for (int d = 0; d < 3; d++)
            ((double *)Bd->x)[i + (size_t)d * n] = s.B[3 * i + d];
    cholmod_factor *L = cholmod_analyze(A, &cm);
    assert_non_null(L);
    assert_true(cholmod_factorize(A, L, &cm) && cm.status == CHOLMOD_OK);
    cholmod_dense *Xc = cholmod_solve(CHOLMOD_A, L, Bd, &cm);
    assert_non_null(Xc);
    double *Xr = malloc(3 * sizeof(double) * n);
    assert_non_null(Xr);
    for (int i = 0; i < n; i++)
        for (int d = 0; d < 3; d++)
            Xr[3 * i + d] = ((double *)Xc->x)[i + (size_t)d * n];
    double r = rel_max(X, Xr, n), res = residual(&s, X), res_ref = residual(&s, Xr);
    printf("    bunny.drc (%d unknowns): against cholmod_solve %.1e, residual %.1e (cholmod's %.1e)\n",
           n, r, res, res_ref);
    assert_true(r <= 1e-12);
    assert_true(res <= 1e-12);
    cholmod_free_dense(&Xc, &cm);
    cholmod_free_dense(&Bd, &cm);
    cholmod_free_sparse(&A, &cm);
    cholmod_free_factor(&L, &cm);
    cholmod_finish(&cm);
    mcf__chol_free(ch);
    free(X);
    free(Xr);
    sys_free(&s);
}

/* A matrix that is not positive definite is ENOTPOSDEF with its column;
 * the next factorization of a good matrix on the same solver works. */
static void test_not_posdef_then_recover(void **state)
{
    (void)state;
    mcf_mesh *m = mcf_mesh_new_icosphere(3, 1.0, NULL);
    assert_non_null(m);
    sys s;
    sys_make(&s, m, 1e-2);
    mcf_error e = {0};
    mcf__chol *ch = mcf__chol_new(&s.pat, 3, &e);
    assert_non_null(ch);
    assert_int_equal(mcf__chol_analyze(ch, &e), MCF_OK);
    double *bad = malloc(sizeof(double) * s.pat.nnz), *X = malloc(3 * sizeof(double) * s.n);
    assert_true(bad && X);
    memcpy(bad, s.val, sizeof(double) * s.pat.nnz);
    bad[s.pat.diag[17]] = -1.0;
    assert_int_equal(mcf__chol_factorize(ch, bad, &e), MCF_ENOTPOSDEF);
    assert_non_null(strstr(e.msg, "not positive definite at column"));
    assert_int_equal(mcf__chol_factorize(ch, s.val, &e), MCF_OK);
    mcf__chol_solve3(ch, s.B, X);
    assert_true(residual(&s, X) <= 1e-12);
    mcf__chol_free(ch);
    free(bad);
    free(X);
    sys_free(&s);
}

/* Four threads factor and solve their own systems at once, as mcfd's
 * workers do, through the serial stand-ins of OpenMP (no shared state):
 * every result equals the one computed alone, to the bit. */
typedef struct {
    const sys *s;
    const double *expect;
    int ok;
} worker_arg;

static void *worker(void *p)
{
    worker_arg *a = p;
    double *X = malloc(3 * sizeof(double) * a->s->n);
    a->ok = X != NULL;
    for (int rep = 0; rep < 3 && a->ok; rep++) {
        mcf_error e = {0};
        mcf__chol *ch = mcf__chol_new(&a->s->pat, 3, &e);
        a->ok = ch && mcf__chol_analyze(ch, &e) == MCF_OK &&
                mcf__chol_factorize(ch, a->s->val, &e) == MCF_OK;
        if (a->ok) {
            mcf__chol_solve3(ch, a->s->B, X);
            a->ok = memcmp(X, a->expect, 3 * sizeof(double) * a->s->n) == 0;
        }
        mcf__chol_free(ch);
    }
    free(X);
    return NULL;
}

static void test_concurrent_workers(void **state)
{
    (void)state;
    sys s[2];
    mcf_mesh *m0 = mcf_mesh_new_icosphere(4, 1.0, NULL), *m1 = tl_load("knot1.obj");
    assert_true(m0 && m1);
    sys_make(&s[0], m0, 1e-2);
    sys_make(&s[1], m1, 1e-3);
    double *expect[2];
    for (int k = 0; k < 2; k++) {
        expect[k] = malloc(3 * sizeof(double) * s[k].n);
        assert_non_null(expect[k]);
        mcf__chol *ch = factor(&s[k]);
        mcf__chol_solve3(ch, s[k].B, expect[k]);
        mcf__chol_free(ch);
    }
    pthread_t th[4];
    worker_arg arg[4];
    for (int i = 0; i < 4; i++) {
        arg[i] = (worker_arg){&s[i % 2], expect[i % 2], 0};
        assert_int_equal(pthread_create(&th[i], NULL, worker, &arg[i]), 0);
    }
    for (int i = 0; i < 4; i++) {
        pthread_join(th[i], NULL);
        assert_true(arg[i].ok);
    }
    for (int k = 0; k < 2; k++) {
        free(expect[k]);
        sys_free(&s[k]);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_dense_reference),
        cmocka_unit_test(test_cholmod_reference),
        cmocka_unit_test(test_not_posdef_then_recover),
        cmocka_unit_test(test_concurrent_workers),
    };
    return cmocka_run_group_tests_name("core_cholesky", tests, NULL, NULL);
}
