/*
 * test_core_laplacian.c - the operators against trivially correct
 * references: symmetry, zero row sums and PSD of L on noisy and degenerate
 * meshes, and one desbrun step of the CHOLMOD solver against a dense
 * Cholesky solve of the same system (SQLite's reference-model test).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"

/* Dense n x n from the public CSR operator. */
static double *dense_L(const mcf_operator *op)
{
    int n = op->n;
    double *A = calloc((size_t)n * n, sizeof *A);
    assert_non_null(A);
    for (int i = 0; i < n; i++)
        for (int t = op->rowptr[i]; t < op->rowptr[i + 1]; t++)
            A[(size_t)i * n + op->col[t]] += op->val[t];
    return A;
}

/* In-place dense Cholesky (lower); returns 0 if not positive definite. */
static int cholesky(double *A, int n)
{
    for (int j = 0; j < n; j++) {
        double d = A[(size_t)j * n + j];
        for (int k = 0; k < j; k++)
            d -= A[(size_t)j * n + k] * A[(size_t)j * n + k];
        if (!(d > 0.0))
            return 0;
        d = sqrt(d);
        A[(size_t)j * n + j] = d;
        for (int i = j + 1; i < n; i++) {
            double s = A[(size_t)i * n + j];
            for (int k = 0; k < j; k++)
                s -= A[(size_t)i * n + k] * A[(size_t)j * n + k];
            A[(size_t)i * n + j] = s / d;
        }
    }
    return 1;
}

static void chol_solve(const double *Lc, int n, double *b)
{
    for (int i = 0; i < n; i++) {
        double s = b[i];
        for (int k = 0; k < i; k++)
            s -= Lc[(size_t)i * n + k] * b[k];
        b[i] = s / Lc[(size_t)i * n + i];
    }
    for (int i = n - 1; i >= 0; i--) {
        double s = b[i];
        for (int k = i + 1; k < n; k++)
            s -= Lc[(size_t)k * n + i] * b[k];
        b[i] = s / Lc[(size_t)i * n + i];
    }
}

/* A noisy icosphere plus, optionally, degenerate triangles: vertex 1 is
 * moved onto vertex 0, which gives zero-area faces and a zero-length edge. */
static mcf_mesh *test_mesh(int level, int degenerate)
{
    mcf_mesh *m = mcf_mesh_new_icosphere(level, 1.0, NULL);
    assert_non_null(m);
    assert_int_equal(mcf_mesh_add_noise(m, 0.2, 7, NULL), MCF_OK);
    if (degenerate) {
        double *X = mcf_mesh_positions_mut(m);
        memcpy(X + 3, X, 3 * sizeof(double));
    }
    return m;
}

static void check_L_properties(int degenerate, mcf_laplacian lap)
{
    mcf_mesh *m = test_mesh(2, degenerate);
    mcf_operator op = {0};
    assert_int_equal(mcf_operator_build(m, lap, MCF_MASS_BARYCENTRIC, &op, NULL), MCF_OK);
    int n = op.n;
    double *A = dense_L(&op), maxabs = 0.0;
    for (size_t i = 0; i < (size_t)n * n; i++) {
        assert_true(isfinite(A[i]));
        if (fabs(A[i]) > maxabs)
            maxabs = fabs(A[i]);
    }
    for (int i = 0; i < n; i++) {
        double row = 0.0;
        assert_true(op.mass[i] > 0.0);
        for (int j = 0; j < n; j++) {
            row += A[(size_t)i * n + j];
            /* symmetric to the last bit: both halves come from one value */
            assert_true(A[(size_t)i * n + j] == A[(size_t)j * n + i]);
        }
        /* row sums vanish up to summation rounding: 64 eps * max entry */
        tl_assert_near(row, 0.0, 64 * 2.2e-16 * maxabs * n, "row sum of L");
    }
    /* PSD: L + tau I has a Cholesky factor for tau = 1e-10 * max entry
     * (L is singular: constants are in its kernel, so tau > 0 is needed;
     * a negative eigenvalue larger than tau would make this fail). */
    for (int i = 0; i < n; i++)
        A[(size_t)i * n + i] += 1e-10 * maxabs;
    assert_true(cholesky(A, n));
    free(A);
    mcf_operator_free(&op);
    mcf_mesh_free(m);
}

static void test_L_cotan(void **state)
{
    (void)state;
    check_L_properties(0, MCF_LAPLACIAN_COTAN);
}

static void test_L_cotan_degenerate(void **state)
{
    (void)state;
    check_L_properties(1, MCF_LAPLACIAN_COTAN);
}

static void test_L_uniform(void **state)
{
    (void)state;
    check_L_properties(0, MCF_LAPLACIAN_UNIFORM);
}

/* Cotan of the icosahedron: every angle is 60 degrees, so each edge
 * weight is -(cot 60 + cot 60)/2 = -1/sqrt(3) and the diagonal 5/sqrt(3). */
static void test_L_exact_values(void **state)
{
    (void)state;
    mcf_mesh *m = mcf_mesh_new_icosphere(0, 1.0, NULL);
    mcf_operator op = {0};
    assert_int_equal(mcf_operator_build(m, MCF_LAPLACIAN_COTAN, MCF_MASS_BARYCENTRIC, &op, NULL), MCF_OK);
    for (int i = 0; i < op.n; i++)
        for (int t = op.rowptr[i]; t < op.rowptr[i + 1]; t++)
            tl_assert_near(op.val[t], op.col[t] == i ? 5.0 / sqrt(3.0) : -1.0 / sqrt(3.0), 1e-14,
                           "icosahedron cotan entry");
    mcf_operator_free(&op);
    mcf_mesh_free(m);
}

/* One desbrun step equals the dense solve of (M + dt L) X+ = M X. */
static void check_dense_step(mcf_mesh *m, int fixed_boundary)
{
    int n = mcf_mesh_nvertices(m);
    const double dt = 0.05;
    mcf_operator op = {0};
    assert_int_equal(mcf_operator_build(m, MCF_LAPLACIAN_COTAN, MCF_MASS_BARYCENTRIC, &op, NULL), MCF_OK);
    double *A = dense_L(&op);
    double *X0 = malloc(3 * sizeof(double) * n), *Y = malloc(sizeof(double) * n);
    memcpy(X0, mcf_mesh_positions(m), 3 * sizeof(double) * n);
    mcf_mesh_info info;
    assert_int_equal(mcf_mesh_inspect(m, &info, NULL), MCF_OK);

    /* boundary vertices: endpoints of edges with one face, found densely */
    int *fixed = calloc((size_t)n, sizeof *fixed);
    if (fixed_boundary) {
        const int32_t *F = mcf_mesh_faces(m);
        int nf = mcf_mesh_nfaces(m);
        for (int f = 0; f < nf; f++)
            for (int k = 0; k < 3; k++) {
                int a = F[3 * f + k], b = F[3 * f + (k + 1) % 3], cnt = 0;
                for (int g = 0; g < nf; g++)
                    for (int l = 0; l < 3; l++) {
                        int c = F[3 * g + l], d = F[3 * g + (l + 1) % 3];
                        cnt += (c == a && d == b) || (c == b && d == a);
                    }
                if (cnt == 1)
                    fixed[a] = fixed[b] = 1;
            }
    }
    for (int i = 0; i < n; i++) /* unreferenced vertices stay where they are */
        if (!(op.mass[i] > 0.0))
            fixed[i] = 1;
    for (size_t i = 0; i < (size_t)n * n; i++)
        A[i] *= dt;
    for (int i = 0; i < n; i++)
        A[(size_t)i * n + i] += op.mass[i];
    /* Dirichlet: identity rows/columns, couplings to the right-hand side */
    double *Afull = malloc(sizeof(double) * n * n);
    memcpy(Afull, A, sizeof(double) * n * n);
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++)
            if ((fixed[i] || fixed[j]) && i != j)
                A[(size_t)i * n + j] = 0.0;
            else if (fixed[i] && i == j)
                A[(size_t)i * n + j] = 1.0;
    assert_true(cholesky(A, n));

    mcf_flow_params p;
    mcf_flow_params_init(&p);
    p.scheme = MCF_DESBRUN;
    p.dt = dt;
    p.iterations = 1;
    p.normalize = 0;
    p.boundary = fixed_boundary ? MCF_BOUNDARY_FIXED : MCF_BOUNDARY_FREE;
    mcf_error err = {0};
    assert_int_equal(mcf_flow_run(m, &p, NULL, &err), MCF_OK);
    const double *X1 = mcf_mesh_positions(m);
    double num = 0.0, den = 0.0;
    for (int d = 0; d < 3; d++) {
        for (int i = 0; i < n; i++) {
            if (fixed[i]) {
                Y[i] = X0[3 * i + d];
                continue;
            }
            Y[i] = op.mass[i] * X0[3 * i + d];
            for (int j = 0; j < n; j++)
                if (fixed[j])
                    Y[i] -= Afull[(size_t)i * n + j] * X0[3 * j + d];
        }
        chol_solve(A, n, Y);
        for (int i = 0; i < n; i++) {
            num += (X1[3 * i + d] - Y[i]) * (X1[3 * i + d] - Y[i]);
            den += Y[i] * Y[i];
        }
    }
    /* 1e-12 relative: both are backward-stable Cholesky solves of a
     * well-conditioned SPD system (cond ~ 1 + dt lambda_max ~ 1e2). */
    assert_true(sqrt(num / den) < 1e-12);
    free(A); free(Afull); free(X0); free(Y); free(fixed);
    mcf_operator_free(&op);
}

static void test_desbrun_dense_closed(void **state)
{
    (void)state;
    mcf_mesh *m = test_mesh(1, 0); /* 42 vertices */
    check_dense_step(m, 0);
    mcf_mesh_free(m);
}

/* An open patch: the upper cap of a noisy icosphere with fixed boundary. */
static void test_desbrun_dense_open(void **state)
{
    (void)state;
    mcf_mesh *s = test_mesh(1, 0);
    const double *X = mcf_mesh_positions(s);
    const int32_t *F = mcf_mesh_faces(s);
    int nf = mcf_mesh_nfaces(s), nv = mcf_mesh_nvertices(s), k = 0;
    int32_t *G = malloc(sizeof(int32_t) * 3 * nf);
    for (int f = 0; f < nf; f++) {
        double z = X[3 * F[3 * f] + 2] + X[3 * F[3 * f + 1] + 2] + X[3 * F[3 * f + 2] + 2];
        if (z > -0.5) {
            memcpy(G + 3 * k, F + 3 * f, 3 * sizeof(int32_t));
            k++;
        }
    }
    mcf_mesh *m = mcf_mesh_new(nv, X, k, G, NULL);
    assert_non_null(m);
    mcf_mesh_info info;
    assert_int_equal(mcf_mesh_inspect(m, &info, NULL), MCF_OK);
    assert_true(info.boundary_edges > 0);
    check_dense_step(m, 1);
    mcf_mesh_free(m);
    mcf_mesh_free(s);
    free(G);
}

/* lambda_max of the icosahedron (unit circumradius) against the dense
 * spectrum bound: the power iteration's value is a Rayleigh quotient, so
 * it lies below the true largest eigenvalue and near it. */
static void test_lambda_max(void **state)
{
    (void)state;
    mcf_mesh *m = test_mesh(1, 0);
    double lam = 0.0;
    assert_int_equal(mcf_lambda_max(m, MCF_LAPLACIAN_COTAN, MCF_MASS_BARYCENTRIC, &lam, NULL), MCF_OK);
    mcf_operator op = {0};
    assert_int_equal(mcf_operator_build(m, MCF_LAPLACIAN_COTAN, MCF_MASS_BARYCENTRIC, &op, NULL), MCF_OK);
    /* Gershgorin on M^-1/2 L M^-1/2: an upper bound of the true value */
    double gers = 0.0;
    for (int i = 0; i < op.n; i++) {
        double r = 0.0;
        for (int t = op.rowptr[i]; t < op.rowptr[i + 1]; t++)
            r += fabs(op.val[t]) / sqrt(op.mass[i] * op.mass[op.col[t]]);
        if (r > gers)
            gers = r;
    }
    assert_true(lam > 0.0 && lam <= gers * (1 + 1e-12));
    mcf_operator_free(&op);
    mcf_mesh_free(m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_L_cotan),
        cmocka_unit_test(test_L_cotan_degenerate),
        cmocka_unit_test(test_L_uniform),
        cmocka_unit_test(test_L_exact_values),
        cmocka_unit_test(test_desbrun_dense_closed),
        cmocka_unit_test(test_desbrun_dense_open),
        cmocka_unit_test(test_lambda_max),
    };
    return cmocka_run_group_tests_name("core_laplacian", tests, NULL, NULL);
}
