/* SPDX-License-Identifier: MIT */
/*
 * test_core_laplacian.c - the operators against trivially correct
 * references: symmetry, zero row sums and PSD of L on noisy and degenerate
 * meshes, and one desbrun step of the CHOLMOD solver against a dense
 * Cholesky solve of the same system (SQLite's reference-model test). The
 * explicit step's fused face pass (mcf__weights_mass_LX, SIMD in blocks of
 * four faces) against the separate passes mcf__cot_weights, mcf__mass and
 * mcf__apply_L, and against itself one face at a time (the scalar path).
 */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"
#include "mcf_internal.h"

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

/* ------------------------------------------- the fused explicit pass */

#define EPS DBL_EPSILON /* 2^-52, twice the unit roundoff */

/* The fused pass of faces F[0 .. nf-1] against the separate passes, with
 * and without stored weights, and (when one_by_one) against itself called
 * on one face at a time, which takes the scalar path. */
static void check_fused(const double *X, const int32_t *F, int nf, int nv,
                        mcf_laplacian lap, int one_by_one)
{
    double delta = MCF_MOLLIFY * mcf__mean_edge(X, F, nf);
    double *wr = malloc(3 * sizeof(double) * nf), *ar = malloc(sizeof(double) * nf);
    double *mr = malloc(sizeof(double) * nv), *Yr = malloc(3 * sizeof(double) * nv);
    double *w = malloc(3 * sizeof(double) * nf), *area = malloc(sizeof(double) * nf);
    double *mass = malloc(sizeof(double) * nv), *Y = malloc(3 * sizeof(double) * nv);
    double *m2 = malloc(sizeof(double) * nv), *Y2 = malloc(3 * sizeof(double) * nv);
    double *tolm = calloc((size_t)nv, sizeof(double)), *tolY = calloc((size_t)nv, sizeof(double));
    double *magY = calloc((size_t)nv, sizeof(double));
    int *corners = calloc((size_t)nv, sizeof(int));
    assert_true(wr && ar && mr && Yr && w && area && mass && Y && m2 && Y2 && tolm && tolY && magY && corners);

    mcf__cot_weights(X, F, nf, lap, delta, wr, ar);
    mcf__mass(X, F, nf, nv, MCF_MASS_BARYCENTRIC, ar, mr);
    mcf__apply_L(F, nf, nv, wr, X, Yr);
    double total = mcf__weights_mass_LX(X, F, nf, nv, lap, delta, w, area, mass, Y);
    double total2 = mcf__weights_mass_LX(X, F, nf, nv, lap, delta, NULL, NULL, m2, Y2);
    /* the same function doing the same operations, only not storing w and
     * area: equal bit for bit */
    assert_true(total == total2);
    assert_memory_equal(mass, m2, sizeof(double) * nv);
    assert_memory_equal(Y, Y2, 3 * sizeof(double) * nv);

    double asum = 0.0, tola = 0.0;
    for (int f = 0; f < nf; f++) {
        const int32_t *t = F + 3 * f;
        double e[3][3], len = 0.0, Q = 0.0, ne = 0.0, wsum = 0.0;
        for (int k = 0; k < 3; k++) {
            mcf__sub3(X + 3 * t[(k + 2) % 3], X + 3 * t[(k + 1) % 3], e[k]);
            len = sqrt(mcf__dot3(e[k], e[k])) + delta; /* mollified length bound */
            Q += len * len;
            for (int d = 0; d < 3; d++)
                ne = fmax(ne, fabs(e[k][d]));
            wsum += fabs(wr[3 * f + k]);
        }
        /* Area: the same formula both ways; 4 eps Q covers another
         * evaluation order of the cross product, whose terms are <= Q. */
        double ta = 4 * EPS * Q;
        tl_assert_near(area[f], ar[f], ta, "fused area");
        /* Weights: <e_i, e_j> / (4A) (or Heron's lengths over 8A): errors of
         * a few eps in the dot product (terms <= Q) and in A (relative to
         * Q / 2A, the cross product's cancellation) give 16 eps (1 + |w|)
         * Q / 2A. */
        double tw = 0.0;
        for (int k = 0; k < 3; k++) {
            double tk = 16 * EPS * (1 + fabs(wr[3 * f + k])) * Q / (2 * ar[f]);
            tl_assert_near(w[3 * f + k], wr[3 * f + k], tk, "fused weight");
            tw = fmax(tw, tk);
        }
        asum += ar[f];
        tola += ta;
        for (int k = 0; k < 3; k++) {
            int v = t[k];
            corners[v]++;
            tolm[v] += ta / 3 + EPS * ar[f];
            /* Y_v sums +-w_k e_k over the faces at v: terms <= |w| |e| */
            magY[v] += wsum * ne;
            tolY[v] += 3 * tw * ne; /* from weights differing within tw */
        }
    }
    /* the total area: a sum of nf areas in another grouping */
    tl_assert_near(total, asum, tola + nf * EPS * asum, "fused total area");
    for (int v = 0; v < nv; v++) {
        /* mass: the same area/3 terms, summed in the same face order, and
         * the summation error of corners[v] terms */
        tl_assert_near(mass[v], mr[v], tolm[v] + corners[v] * EPS * mr[v], "fused mass");
        /* L X: the combined per-vertex form (w2 (p0-p1) + w1 (p0-p2) ...)
         * and apply_L's per-edge form add the same products in another
         * order: at most 2 per corner, so (2 corners + 1) eps of the summed
         * magnitudes */
        for (int d = 0; d < 3; d++)
            tl_assert_near(Y[3 * v + d], Yr[3 * v + d],
                           (2 * corners[v] + 1) * EPS * magY[v] + tolY[v], "fused L X");
    }

#if !defined(__FP_FAST_FMA)
    /* One face at a time runs the scalar path; summed per vertex in face
     * order, it gives the blocked (SIMD) path's results exactly: both do
     * the same IEEE operations in the same order, and without FMA in the
     * target nothing can be contracted. Faces with a repeated vertex add
     * twice to it within one call, which sums in another grouping. */
    if (one_by_one) {
        double *Ys = calloc(3 * (size_t)nv, sizeof(double)), *ms = calloc((size_t)nv, sizeof(double));
        double *Yf = malloc(3 * sizeof(double) * nv), *mf = malloc(sizeof(double) * nv);
        double ts = 0.0, wf[3], af;
        assert_true(Ys && ms && Yf && mf);
        for (int f = 0; f < nf; f++) {
            const int32_t *t = F + 3 * f;
            assert_true(t[0] != t[1] && t[1] != t[2] && t[2] != t[0]);
            ts += mcf__weights_mass_LX(X, t, 1, nv, lap, delta, wf, &af, mf, Yf);
            assert_memory_equal(wf, w + 3 * f, sizeof wf);
            assert_true(af == area[f]);
            for (int k = 0; k < 3; k++) {
                for (int d = 0; d < 3; d++)
                    Ys[3 * t[k] + d] += Yf[3 * t[k] + d];
                ms[t[k]] += mf[t[k]];
            }
        }
        assert_true(ts == total);
        assert_memory_equal(ms, mass, sizeof(double) * nv);
        assert_memory_equal(Ys, Y, 3 * sizeof(double) * nv);
        free(Ys); free(ms); free(Yf); free(mf);
    }
#else
    (void)one_by_one;
#endif
    free(wr); free(ar); free(mr); free(Yr); free(w); free(area); free(mass); free(Y);
    free(m2); free(Y2); free(tolm); free(tolY); free(magY); free(corners);
}

/* All face counts mod 4 (the SIMD block) and mod 8: nf, nf-1, ..., nf-7. */
static void check_fused_prefixes(const double *X, const int32_t *F, int nf, int nv,
                                 int one_by_one)
{
    for (int cut = 0; cut < 8; cut++)
        for (int lap = 0; lap < 2; lap++)
            check_fused(X, F, nf - cut, nv, lap ? MCF_LAPLACIAN_UNIFORM : MCF_LAPLACIAN_COTAN,
                        one_by_one);
}

static void test_fused_icosphere(void **state)
{
    (void)state;
    mcf_mesh *m = test_mesh(3, 0); /* noisy, 1280 faces */
    check_fused_prefixes(mcf_mesh_positions(m), mcf_mesh_faces(m), mcf_mesh_nfaces(m),
                         mcf_mesh_nvertices(m), 1);
    mcf_mesh_free(m);
}

/* A bumpy 8 x 8 grid whose face list mixes, inside blocks of four, ordinary
 * triangles with mollified ones: zero-length edges (a copy of a vertex),
 * collinear corners, needles (a corner 1e-9 off the opposite side) and,
 * when repeated is set, a face with a repeated vertex. */
static void test_fused_degenerate(void **state)
{
    (void)state;
    enum { N = 8, NG = N * N };
    double X[3 * (NG + 2)];
    int32_t F[3 * (2 * (N - 1) * (N - 1) + 8)];
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) {
            double *p = X + 3 * (i * N + j);
            p[0] = i; p[1] = j; p[2] = 0.3 * sin(1.3 * i) * cos(0.7 * j);
        }
    memcpy(X + 3 * NG, X + 3 * (2 * N + 3), 3 * sizeof(double)); /* copy of a vertex */
    double *needle = X + 3 * (NG + 1); /* just off the side 0 - N */
    for (int d = 0; d < 3; d++)
        needle[d] = 0.5 * (X[d] + X[3 * N + d]);
    needle[1] += 1e-9;
    for (int repeated = 0; repeated < 2; repeated++) {
        const int32_t special[][3] = {
            {2 * N + 3, NG, 3 * N + 4},          /* zero-length edge */
            {0, 1, 2},                           /* collinear */
            {0, N, NG + 1},                      /* needle */
            {NG, 2 * N + 3, 2 * N + 4},          /* zero-length edge */
            {repeated ? 5 : 6, 5, 7},            /* repeated vertex, or 3 collinear */
        };
        int nf = 0, ns = 0, at[5];
        for (int i = 0; i + 1 < N; i++)
            for (int j = 0; j + 1 < N; j++) {
                int a = i * N + j, b = a + N, c = a + N + 1, d = a + 1;
                int32_t tri[2][3] = {{a, b, c}, {a, c, d}};
                for (int h = 0; h < 2; h++) {
                    memcpy(F + 3 * nf++, tri[h], sizeof tri[h]);
                    /* special faces at 1, 6, 11, 16, 21: lanes 1, 2,
                     * 3, 0, 1 of the blocks of four 0, 1, 2, 4, 5 */
                    if (nf % 5 == 1 && ns < 5) {
                        at[ns] = nf;
                        memcpy(F + 3 * nf++, special[ns++], sizeof special[0]);
                    }
                }
            }
        assert_int_equal(ns, 5);
        /* make sure the mixing is there: the special faces are mollified
         * (area > twice the true one, which is 0 or ~1e-9) and the
         * ordinary faces of their blocks are not (true area, up to
         * rounding: 1e-12 relative) */
        double delta = MCF_MOLLIFY * mcf__mean_edge(X, F, nf);
        double *w = malloc(3 * sizeof(double) * nf), *area = malloc(sizeof(double) * nf);
        assert_true(w && area);
        mcf__cot_weights(X, F, nf, MCF_LAPLACIAN_COTAN, delta, w, area);
        int mollified = 0, plain = 0;
        for (int f = 0; f < nf; f++) {
            const int32_t *t = F + 3 * f;
            double e1[3], e2[3], n[3];
            mcf__sub3(X + 3 * t[0], X + 3 * t[2], e1);
            mcf__sub3(X + 3 * t[1], X + 3 * t[0], e2);
            mcf__cross3(e2, e1, n);
            double true_area = 0.5 * sqrt(mcf__dot3(n, n));
            int special_here = 0, special_block = 0;
            for (int k = 0; k < 5; k++) {
                special_here |= f == at[k];
                special_block |= f / 4 == at[k] / 4;
            }
            if (special_here) {
                assert_true(area[f] > 2 * true_area);
                mollified++;
            } else if (special_block) {
                tl_assert_near(area[f], true_area, 1e-12 * true_area, "ordinary face area");
                plain++;
            }
        }
        assert_int_equal(mollified, 5);
        assert_int_equal(plain, 15); /* three per block */
        free(w);
        free(area);
        check_fused_prefixes(X, F, nf, NG + 2, !repeated);
    }
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
        cmocka_unit_test(test_fused_icosphere),
        cmocka_unit_test(test_fused_degenerate),
    };
    return cmocka_run_group_tests_name("core_laplacian", tests, NULL, NULL);
}
