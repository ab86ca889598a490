/* SPDX-License-Identifier: MIT */
/*
 * test_core_fairing.c - the fairing filters (core/mcf_fairing.c), the
 * default of a request that names no scheme:
 *  - both variants agree with their equations, written out here with
 *    dense linear algebra on a 100-vertex height field with a fixed
 *    boundary (steps, normal-only output, fold guard, the SURE curve);
 *  - on real scans with injected noise the default request's error is at
 *    most 0.75x that of Taubin's lambda|mu filter at its best pass count
 *    (chosen knowing the clean mesh) on the median case, never above the
 *    input's, and adds no folds: the repository's meshes here, the large
 *    scans under MESHES.
 * Errors are mcf_compare's area-weighted RMS against the clean mesh.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_internal.h" /* mcf__mix64: the run's probes, replayed */
#include "testlib.h"

/* ------------------------------------------------ dense reference */

enum { G = 10, NV = G * G, NF = 2 * (G - 1) * (G - 1) };

/* A 10 x 10 height field over [0, 1]^2, z = 0.2 sin(3x) cos(2y) plus a
 * deterministic bump per vertex (noise of about a tenth of an edge). */
static mcf_mesh *height_field(void)
{
    double X[3 * NV];
    int32_t F[3 * NF];
    int f = 0;
    for (int j = 0; j < G; j++)
        for (int i = 0; i < G; i++) {
            double x = i / (G - 1.0), y = j / (G - 1.0);
            double b = sin(12.9898 * i + 78.233 * j) * 43758.5453;
            b -= floor(b);
            X[3 * (j * G + i)] = x;
            X[3 * (j * G + i) + 1] = y;
            X[3 * (j * G + i) + 2] = 0.2 * sin(3 * x) * cos(2 * y) + 0.02 * (b - 0.5);
        }
    for (int j = 0; j + 1 < G; j++)
        for (int i = 0; i + 1 < G; i++) {
            int a = j * G + i, b = a + 1, c = a + G, d = c + 1;
            int32_t t[6] = {a, b, d, a, d, c};
            memcpy(F + 3 * f, t, sizeof t);
            f += 2;
        }
    mcf_mesh *m = mcf_mesh_new(NV, X, NF, F, NULL);
    assert_non_null(m);
    return m;
}

/* Solves the SPD system A x = b (n x n, row-major, A destroyed) by
 * Cholesky; b becomes x. */
static void dense_solve(double *A, double *b, int n)
{
    for (int j = 0; j < n; j++) {
        double s = A[j * n + j];
        for (int k = 0; k < j; k++)
            s -= A[j * n + k] * A[j * n + k];
        assert_true(s > 0.0);
        A[j * n + j] = sqrt(s);
        for (int i = j + 1; i < n; i++) {
            double t = A[i * n + j];
            for (int k = 0; k < j; k++)
                t -= A[i * n + k] * A[j * n + k];
            A[i * n + j] = t / A[j * n + j];
        }
    }
    for (int i = 0; i < n; i++) {
        for (int k = 0; k < i; k++)
            b[i] -= A[i * n + k] * b[k];
        b[i] /= A[i * n + i];
    }
    for (int i = n - 1; i >= 0; i--) {
        for (int k = i + 1; k < n; k++)
            b[i] -= A[k * n + i] * b[k];
        b[i] /= A[i * n + i];
    }
}

/* The graph of the height field: adjacency (weight 1 per edge), degrees,
 * boundary (fixed) vertices. */
typedef struct {
    double A[NV * NV], D[NV];
    int fixed[NV], free_idx[NV], nfree, vert[NV];
} graph;

static void make_graph(const int32_t *F, graph *g)
{
    memset(g, 0, sizeof *g);
    for (int f = 0; f < NF; f++)
        for (int k = 0; k < 3; k++) {
            int a = F[3 * f + k], b = F[3 * f + (k + 1) % 3];
            g->A[a * NV + b] = g->A[b * NV + a] = 1.0;
        }
    for (int i = 0; i < NV; i++) {
        for (int j = 0; j < NV; j++)
            g->D[i] += g->A[i * NV + j];
        int x = i % G, y = i / G;
        g->fixed[i] = x == 0 || y == 0 || x == G - 1 || y == G - 1;
        g->free_idx[i] = g->fixed[i] ? -1 : g->nfree;
        if (!g->fixed[i])
            g->vert[g->nfree++] = i;
    }
}

static void normals(const double *X, const int32_t *F, double *N, int unit)
{
    memset(N, 0, sizeof(double) * 3 * NV);
    for (int f = 0; f < NF; f++) {
        const double *a = X + 3 * F[3 * f], *b = X + 3 * F[3 * f + 1], *c = X + 3 * F[3 * f + 2];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
        for (int k = 0; k < 3; k++)
            for (int d = 0; d < 3; d++)
                N[3 * F[3 * f + k] + d] += n[d];
    }
    for (int i = 0; unit && i < NV; i++) {
        double l = sqrt(N[3 * i] * N[3 * i] + N[3 * i + 1] * N[3 * i + 1] + N[3 * i + 2] * N[3 * i + 2]);
        for (int d = 0; d < 3; d++)
            N[3 * i + d] /= l;
    }
}

static void face_n(const double *X, const int32_t *t, double *n)
{
    const double *a = X + 3 * t[0], *b = X + 3 * t[1], *c = X + 3 * t[2];
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    n[0] = u[1] * v[2] - u[2] * v[1];
    n[1] = u[2] * v[0] - u[0] * v[2];
    n[2] = u[0] * v[1] - u[1] * v[0];
}

/* The guard (docs/fairing.md): while X has faces folded against X0, their
 * vertices that X moved take Y's positions (2 rounds), then halve their
 * displacement from X0 (6 rounds), then take X0's (at most 64 rounds in
 * all). */
static void reference_guard(const double *X0, const double *Y, const int32_t *F, int nf, int nv, double *X)
{
    unsigned char *bad = malloc((size_t)nf), *mark = malloc((size_t)nv);
    assert_non_null(bad);
    assert_non_null(mark);
    for (int round = 0; round < 64 && tl_folds_against(X, X0, F, nf, nv, bad) > 0; round++) {
        memset(mark, 0, (size_t)nv);
        for (int f = 0; f < nf; f++)
            if (bad[f])
                for (int k = 0; k < 3; k++)
                    mark[F[3 * f + k]] = 1;
        for (int v = 0; v < nv; v++) {
            double *x = X + 3 * v;
            const double *x0 = X0 + 3 * v;
            if (!mark[v] || !memcmp(x, x0, 3 * sizeof(double)))
                continue;
            for (int d = 0; d < 3; d++)
                x[d] = round < 2 ? Y[3 * v + d] : round < 8 ? x0[d] + 0.5 * (x[d] - x0[d]) : x0[d];
        }
    }
    free(bad);
    free(mark);
}

/* The output of the equations from the filtered positions Y:
 * X = X0 + n <n, Y - X0> with n the area-weighted normals of Y, then the
 * guard. */
static void reference_output(const graph *g, const double *X0, const double *Y, const int32_t *F, double *X)
{
    double N[3 * NV];
    normals(Y, F, N, 1);
    for (int i = 0; i < NV; i++) {
        double a = 0.0;
        for (int d = 0; d < 3; d++)
            a += N[3 * i + d] * (Y[3 * i + d] - X0[3 * i + d]);
        for (int d = 0; d < 3; d++)
            X[3 * i + d] = X0[3 * i + d] + (g->fixed[i] ? 0.0 : a * N[3 * i + d]);
    }
    reference_guard(X0, Y, F, NF, NV, X);
}

/* T (nfree x nfree): one implicit step's linear part S^-1 D_F (S = D_F +
 * L_FF D_F^-1 L_FF) and its constant c (nfree x 3: -S^-1 L_FF D_F^-1
 * L_FB X0_B); explicit: one Taubin pass's (I + mu U)(I + lambda U) on the
 * free rows, U = D^-1 A - I, and its constant. */
static void step_operator(const graph *g, const double *X0, int is_explicit, double *T, double *c)
{
    int n = g->nfree;
    double *S = calloc((size_t)n * n, sizeof *S), *col = calloc((size_t)n, sizeof *col);
    assert_non_null(S);
    assert_non_null(col);
    if (is_explicit) {
        /* apply the pass to unit vectors (the linear part, fixed rows 0)
         * and to X0 with zero free rows (the constant) */
        for (int q = 0; q <= n; q++) {
            double x[NV * 3];
            memset(x, 0, sizeof x);
            if (q < n)
                x[3 * g->vert[q]] = 1.0;
            else
                for (int i = 0; i < NV; i++)
                    for (int d = 0; d < 3; d++)
                        x[3 * i + d] = g->fixed[i] ? X0[3 * i + d] : 0.0;
            for (int h = 0; h < 2; h++) {
                double co = h ? -0.53 : 0.5, y[NV * 3];
                for (int i = 0; i < NV; i++)
                    for (int d = 0; d < 3; d++) {
                        double avg = 0.0;
                        for (int j = 0; j < NV; j++)
                            avg += g->A[i * NV + j] * x[3 * j + d];
                        avg /= g->D[i];
                        y[3 * i + d] = g->fixed[i] ? x[3 * i + d] : x[3 * i + d] + co * (avg - x[3 * i + d]);
                    }
                memcpy(x, y, sizeof x);
            }
            for (int k = 0; k < n; k++) {
                if (q < n)
                    T[k * n + q] = x[3 * g->vert[k]];
                else
                    for (int d = 0; d < 3; d++)
                        c[3 * k + d] = x[3 * g->vert[k] + d];
            }
        }
        free(S);
        free(col);
        return;
    }
    /* L_FF D_F^-1 L_FF: L = D - A */
    for (int a = 0; a < n; a++)
        for (int b = 0; b < n; b++) {
            double s = 0.0;
            for (int k = 0; k < n; k++) {
                int i = g->vert[a], j = g->vert[b], v = g->vert[k];
                double lik = (i == v ? g->D[i] : 0.0) - g->A[i * NV + v];
                double lkj = (v == j ? g->D[v] : 0.0) - g->A[v * NV + j];
                s += lik * lkj / g->D[v];
            }
            S[a * n + b] = s + (a == b ? g->D[g->vert[a]] : 0.0);
        }
    double *Sc = malloc(sizeof(double) * (size_t)n * n);
    assert_non_null(Sc);
    for (int q = 0; q < n; q++) { /* T e_q = S^-1 D e_q */
        memcpy(Sc, S, sizeof(double) * (size_t)n * n);
        memset(col, 0, sizeof(double) * (size_t)n);
        col[q] = g->D[g->vert[q]];
        dense_solve(Sc, col, n);
        for (int k = 0; k < n; k++)
            T[k * n + q] = col[k];
    }
    for (int d = 0; d < 3; d++) { /* c = -S^-1 L_FF D_F^-1 L_FB X0_B */
        double *lb = calloc((size_t)n, sizeof *lb);
        assert_non_null(lb);
        for (int k = 0; k < n; k++) /* (L_FB X0_B)_k / D_k */
            for (int j = 0; j < NV; j++)
                if (g->fixed[j])
                    lb[k] -= g->A[g->vert[k] * NV + j] * X0[3 * j + d] / g->D[g->vert[k]];
        for (int a = 0; a < n; a++) {
            double s = 0.0;
            for (int k = 0; k < n; k++) {
                int i = g->vert[a], v = g->vert[k];
                s += ((i == v ? g->D[i] : 0.0) - g->A[i * NV + v]) * lb[k];
            }
            col[a] = -s;
        }
        memcpy(Sc, S, sizeof(double) * (size_t)n * n);
        dense_solve(Sc, col, n);
        for (int k = 0; k < n; k++)
            c[3 * k + d] = col[k];
        free(lb);
    }
    free(Sc);
    free(S);
    free(col);
}

/* Y after K steps of (T, c) from X0. */
static void reference_steps(const graph *g, const double *T, const double *c, const double *X0, int K,
                            double *Y)
{
    int n = g->nfree;
    memcpy(Y, X0, sizeof(double) * 3 * NV);
    for (int k = 0; k < K; k++) {
        double y[3 * NV];
        memcpy(y, Y, sizeof y);
        for (int a = 0; a < n; a++)
            for (int d = 0; d < 3; d++) {
                double s = c[3 * a + d];
                for (int b = 0; b < n; b++)
                    s += T[a * n + b] * y[3 * g->vert[b] + d];
                Y[3 * g->vert[a] + d] = s;
            }
    }
}

/* Runs variant var (0 implicit, 1 explicit) on m: K steps, or (K 0) the
 * automatic amount for noise sigma mean edges. */
static void run_variant(mcf_mesh *m, int var, int K, double sigma, mcf_flow_stats *st)
{
    mcf_flow_params p;
    mcf_error err = {0};
    mcf_flow_params_init(&p);
    p.scheme = var ? MCF_FAIRING_EXPLICIT : MCF_FAIRING;
    p.iterations = K;
    p.noise_sigma = sigma;
    if (mcf_flow_run(m, &p, st, &err) != MCF_OK)
        fail_msg("%s: %s", var ? "fairing_explicit" : "fairing", err.msg);
}

/* Both variants at a fixed step count against the equations: the same
 * positions to 1e-10 of the field's extent (dense Cholesky against
 * CHOLMOD, and the run's normalization to unit area and back: rounding at
 * 1e-15 relative, times a system whose condition number is below 100 and
 * a few steps; 1e-10 leaves five orders for it). */
static void test_equations_fixed_steps(void **state)
{
    static graph g;
    (void)state;
    for (int var = 0; var < 2; var++) {
        int K = var ? 12 : 4;
        mcf_mesh *m = height_field();
        const int32_t *F = mcf_mesh_faces(m);
        double X0[3 * NV], Y[3 * NV], Xref[3 * NV];
        memcpy(X0, mcf_mesh_positions(m), sizeof X0);
        make_graph(F, &g);
        int n = g.nfree;
        double *T = malloc(sizeof(double) * (size_t)n * n), *c = malloc(sizeof(double) * 3 * (size_t)n);
        assert_non_null(T);
        assert_non_null(c);
        step_operator(&g, X0, var, T, c);
        reference_steps(&g, T, c, X0, K, Y);
        reference_output(&g, X0, Y, F, Xref);

        mcf_flow_stats st;
        run_variant(m, var, K, 0.0, &st);
        const double *Xc = mcf_mesh_positions(m);
        double worst = 0.0, moved = 0.0;
        for (int q = 0; q < 3 * NV; q++) {
            worst = fmax(worst, fabs(Xc[q] - Xref[q]));
            moved = fmax(moved, fabs(Xref[q] - X0[q]));
        }
        print_message("%s, %d steps: largest difference from the equations %.2e (largest move %.3f)\n",
                      var ? "fairing_explicit" : "fairing", K, worst, moved);
        assert_true(worst <= 1e-10);
        assert_true(moved > 1e-3); /* the filter did something */
        assert_int_equal(st.steps, K);
        assert_int_equal(st.factorizations, var ? 0 : 1);
        mcf_flow_stats_free(&st);
        free(T);
        free(c);
        mcf_mesh_free(m);
    }
}

enum { MAXK = 2100, NPROBE = 6 };

/* The run's Hutchinson estimate of tr(W T^K) replayed: its six
 * Rademacher probes (mcf_fairing.c's init_probes: the sign of
 * mcf__mix64(q 0x9e3779b97f4a7c15 + k + 1) for probe q at free vertex k),
 * through R^K = D^1/2 T^K D^-1/2 for the implicit variant (its probes run
 * in y = D^1/2 x), T^K for the explicit one. */
static double probe_trace(const graph *g, const double *TK, const double *w, int is_explicit)
{
    int n = g->nfree;
    double tr = 0.0;
    for (int q = 0; q < NPROBE; q++)
        for (int a = 0; a < n; a++) {
            double za = (mcf__mix64((uint64_t)q * 0x9e3779b97f4a7c15ULL + (uint64_t)a + 1) >> 63) ? 1.0 : -1.0;
            double t = 0.0;
            for (int b = 0; b < n; b++) {
                double zb = (mcf__mix64((uint64_t)q * 0x9e3779b97f4a7c15ULL + (uint64_t)b + 1) >> 63) ? 1.0 : -1.0;
                t += (is_explicit ? 1.0 : sqrt(g->D[g->vert[a]] / g->D[g->vert[b]])) * TK[a * n + b] * zb;
            }
            tr += w[g->vert[a]] * za * t / NPROBE;
        }
    return tr;
}

/* The combination against its equations: the steps kept are the last
 * MCF_FAIRING_COMB powers of two up to the last step; the weights solve
 * G c = -s^2 b, G_jl = sum w r_j r_l, b_j = tr_j - sum w, tr_j the run's
 * probe estimate of tr(W T^kj) (trk, replayed). The run keeps the
 * displacements in single precision (relative rounding 6e-8) and adds a
 * ridge of 1e-9 of G's mean diagonal: G's entries within 2e-7 of |G|'s
 * row, so the weights within |G^-1| (2e-7 |G| |c| + 1e-9 mean diag |c|)
 * (measured: 2e-5 of a bound of 5e-3 and up). */
static void check_combination(const graph *g, const double *T, const double *c, const double *X0,
                              const double *N0, const double *w, double s, const mcf_flow_stats *st,
                              const double *trk, const char *name)
{
    enum { J = MCF_FAIRING_COMB };
    int n = g->nfree, last = st->nsure - 1, top = 1;
    /* the weights the run found, whether it took them or not (on this
     * field it does not: its bound on the combination's gain, the noise
     * being no Gaussian along the normals) */
    assert_true(st->ncomb == 0 || st->ncomb == J);
    assert_true(st->comb_steps[0] > 0);
    while (2 * top <= last)
        top *= 2;
    static double r[J][NV], Y[3 * NV];
    double Gm[J * J], Gi[J * J], b[J], gd = 0.0;
    for (int j = 0; j < J; j++) {
        assert_int_equal(st->comb_steps[j], top >> (J - 1 - j));
        reference_steps(g, T, c, X0, st->comb_steps[j], Y);
        for (int a = 0; a < n; a++) {
            int i = g->vert[a];
            r[j][a] = 0.0;
            for (int d = 0; d < 3; d++)
                r[j][a] += N0[3 * i + d] * (Y[3 * i + d] - X0[3 * i + d]);
        }
        b[j] = trk[st->comb_steps[j]] - n;
    }
    for (int j = 0; j < J; j++) {
        for (int l = 0; l < J; l++) {
            Gm[j * J + l] = 0.0;
            for (int a = 0; a < n; a++)
                Gm[j * J + l] += w[g->vert[a]] * r[j][a] * r[l][a];
        }
        gd += Gm[j * J + j] / J;
    }
    for (int l = 0; l < J; l++) { /* G^-1 by columns */
        double A[J * J], e[J] = {0};
        memcpy(A, Gm, sizeof A);
        e[l] = 1.0;
        dense_solve(A, e, J);
        for (int j = 0; j < J; j++)
            Gi[j * J + l] = e[j];
    }
    /* the gain of the weights on the spectrum [0, 2]: a combination taken
     * stays within [-0.5, 1.1] (mcf_fairing.c's COMB_GAIN_MIN, _MAX) */
    double gmin = INFINITY, gmax = -INFINITY;
    for (int t = 0; t <= 2000; t++) {
        double k = 0.001 * t, g1 = strcmp(name, "fairing") ? (1.0 - 0.5 * k) * (1.0 + 0.53 * k) : 1.0 / (1.0 + k * k);
        double gain = 1.0;
        for (int j = 0; j < J; j++)
            gain += st->comb_weight[j] * (pow(g1, st->comb_steps[j]) - 1.0);
        gmin = fmin(gmin, gain);
        gmax = fmax(gmax, gain);
    }
    print_message("%s: the combination's gain %.3f .. %.3f\n", name, gmin, gmax);
    if (st->ncomb)
        assert_true(gmin >= -0.5 - 1e-3 && gmax <= 1.1 + 1e-3);
    for (int j = 0; j < J; j++) {
        double ref = 0.0, tol = 0.0;
        for (int l = 0; l < J; l++) {
            ref -= s * s * Gi[j * J + l] * b[l];
            double dg = 1e-9 * gd * fabs(st->comb_weight[l]);
            for (int m = 0; m < J; m++)
                dg += 2e-7 * fabs(Gm[l * J + m]) * fabs(st->comb_weight[m]);
            tol += fabs(Gi[j * J + l]) * dg;
        }
        print_message("%s: combination weight of %d steps %.6f, equations %.6f (tolerance %.1e)%s\n", name,
                      st->comb_steps[j], st->comb_weight[j], ref, tol, st->ncomb ? "" : ", not taken");
        if (!(fabs(st->comb_weight[j] - ref) <= tol))
            fail_msg("%s: weight of %d steps %.8f, equations %.8f", name, st->comb_steps[j], st->comb_weight[j], ref);
    }
}

/* The automatic amount against SURE written out: with the noise level
 * given (noise_sigma), the curve st.sure[K] equals sum w r^2 - s^2 sum w +
 * 2 s^2 tr(W T^K), r along the input's normals, w the barycentric areas
 * over their mean, up to the trace's Hutchinson estimate from six
 * Rademacher probes: within 5 of its standard deviations, computed here
 * from the dense matrix (Var z'Bz = 2 (|B_s|_F^2 - sum B_ii^2) for B_s the
 * symmetric part; the implicit variant carries its probes through
 * D^1/2 T D^-1/2, which has the same diagonal). The result is the
 * curve's minimizer, and the run stopped at the first power of two past
 * K* + 5 or the cap. */
static void test_equations_sure(void **state)
{
    static graph g;
    (void)state;
    for (int var = 0; var < 2; var++) {
        mcf_mesh *m = height_field();
        const int32_t *F = mcf_mesh_faces(m);
        double X0[3 * NV], N0[3 * NV], w[NV];
        memcpy(X0, mcf_mesh_positions(m), sizeof X0);
        make_graph(F, &g);
        int n = g.nfree;
        mcf_mesh_info info;
        assert_int_equal(mcf_mesh_inspect(m, &info, NULL), MCF_OK);
        double h = info.mean_edge, sigma = 0.15, s = sigma * h;
        normals(X0, F, N0, 1);
        /* barycentric areas: |n_f| / 6 per corner, over their free mean */
        double sumw = 0.0;
        memset(w, 0, sizeof w);
        for (int f = 0; f < NF; f++) {
            double a[3];
            face_n(X0, F + 3 * f, a);
            for (int k = 0; k < 3; k++)
                w[F[3 * f + k]] += sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]) / 6.0;
        }
        for (int i = 0; i < NV; i++)
            sumw += g.fixed[i] ? 0.0 : w[i];
        for (int i = 0; i < NV; i++)
            w[i] = g.fixed[i] ? 0.0 : w[i] * n / sumw;
        double *T = malloc(sizeof(double) * (size_t)n * n), *c = malloc(sizeof(double) * 3 * (size_t)n);
        double *TK = malloc(sizeof(double) * (size_t)n * n), *tmp = malloc(sizeof(double) * (size_t)n * n);
        assert_non_null(T);
        assert_non_null(c);
        assert_non_null(TK);
        assert_non_null(tmp);
        step_operator(&g, X0, var, T, c);

        mcf_flow_stats st;
        run_variant(m, var, 0, sigma, &st);
        assert_non_null(st.sure);
        assert_true(st.nsure >= 2);
        /* identity to start: T^0 */
        for (int a = 0; a < n; a++)
            for (int b = 0; b < n; b++)
                TK[a * n + b] = a == b;
        int kmin = 0;
        static double trk[MAXK];
        for (int K = 0; K < st.nsure; K++) {
            if (K > 0) { /* TK = T TK */
                for (int a = 0; a < n; a++)
                    for (int b = 0; b < n; b++) {
                        double t = 0.0;
                        for (int q = 0; q < n; q++)
                            t += T[a * n + q] * TK[q * n + b];
                        tmp[a * n + b] = t;
                    }
                memcpy(TK, tmp, sizeof(double) * (size_t)n * n);
            }
            double Y[3 * NV];
            reference_steps(&g, T, c, X0, K, Y);
            double r2 = 0.0, tr = 0.0, fro = 0.0, dia = 0.0;
            for (int a = 0; a < n; a++) {
                int i = g.vert[a];
                double r = 0.0;
                for (int d = 0; d < 3; d++)
                    r += N0[3 * i + d] * (Y[3 * i + d] - X0[3 * i + d]);
                r2 += w[i] * r * r;
                tr += w[i] * TK[a * n + a];
                /* B = W R^K, R^K = D^1/2 T^K D^-1/2 for the implicit probes */
                for (int b = 0; b < n; b++) {
                    double sc = var ? 1.0 : sqrt(g.D[i] / g.D[g.vert[b]]);
                    double bab = w[i] * TK[a * n + b] * sc;
                    double sc2 = var ? 1.0 : sqrt(g.D[g.vert[b]] / g.D[i]);
                    double bba = w[g.vert[b]] * TK[b * n + a] * sc2;
                    fro += 0.25 * (bab + bba) * (bab + bba);
                }
                dia += (w[i] * TK[a * n + a]) * (w[i] * TK[a * n + a]);
            }
            double sd = sqrt(2.0 * (fro - dia) / 6.0);
            if (K < MAXK)
                trk[K] = probe_trace(&g, TK, w, var);
            double ref = (r2 - s * s * n + 2.0 * s * s * tr) / n / (h * h);
            double tol = 5.0 * 2.0 * s * s * sd / n / (h * h) + 1e-9;
            if (!(fabs(st.sure[K] - ref) <= tol))
                fail_msg("%s: SURE(%d) %.6f, equations %.6f (tolerance %.2e)", var ? "fairing_explicit" : "fairing", K,
                         st.sure[K], ref, tol);
            if (st.sure[K] < st.sure[kmin])
                kmin = K;
        }
        /* the implicit steps solve the three coordinates only, one
         * 3-column solve a step: the probes' traces come from Lanczos
         * quadrature (mcf_fairing_trace.c), which the combination's
         * weights check against the probes replayed (check_combination) */
        if (!var)
            assert_int_equal(st.solves, st.nsure - 1);
        print_message("%s: SURE over %d step counts agrees, minimum at %d (%d tangential)\n",
                      var ? "fairing_explicit" : "fairing", st.nsure, st.steps, st.tangential_steps);
        assert_int_equal(st.steps, kmin);
        int kmax = st.steps > st.tangential_steps ? st.steps : st.tangential_steps;
        int kstop = 1; /* the first power of two past kmax + 5 */
        while (kstop <= kmax + 5)
            kstop *= 2;
        assert_true(st.nsure - 1 == kstop ||
                    st.nsure - 1 == (var ? MCF_FAIRING_MAX_PASSES : MCF_FAIRING_MAX_STEPS));
        tl_assert_near(st.noise, sigma, 1e-12, "the noise level the amount used");
        /* the run's s: sigma of its own mean edge (working units, unit
         * area), back in the input's units */
        double s_run = sigma * st.mean_edge * sqrt(st.area0);
        check_combination(&g, T, c, X0, N0, w, s_run, &st, trk, var ? "fairing_explicit" : "fairing");
        mcf_flow_stats_free(&st);
        free(T);
        free(c);
        free(TK);
        free(tmp);
        mcf_mesh_free(m);
    }
}

/* ------------------------------------------------ against Taubin */

static double rms(const mcf_mesh *m, const mcf_mesh *clean)
{
    mcf_compare_result r;
    assert_int_equal(mcf_compare(m, clean, &r, NULL), MCF_OK);
    return r.rms_m;
}

/* Taubin's oracle: the product's scheme=taubin with the Laplacian lap
 * (lambda 0.5, mu -0.53; uniform: Open3D's filter_smooth_taubin's
 * weights; cotan: the product's default, bench_quality's taubin_best),
 * one pass at a time, the best error over the pass counts (stopping 20
 * passes past the best once 5% worse). */
static double taubin_oracle(const mcf_mesh *noisy, const mcf_mesh *clean, mcf_laplacian lap, int *passes)
{
    mcf_mesh *x = mcf_mesh_dup(noisy, NULL);
    mcf_flow_params p;
    mcf_error err = {0};
    double best = rms(x, clean);
    int kbest = 0;
    assert_non_null(x);
    mcf_flow_params_init(&p);
    p.scheme = MCF_TAUBIN;
    p.laplacian = lap;
    p.iterations = 1;
    for (int k = 1; k <= 500; k++) {
        if (mcf_flow_run(x, &p, NULL, &err) != MCF_OK)
            fail_msg("taubin: %s", err.msg);
        double e = rms(x, clean);
        if (e < best) {
            best = e;
            kbest = k;
        }
        if (k > 2 * kbest + 20 && e > 1.05 * best)
            break;
    }
    mcf_mesh_free(x);
    *passes = kbest;
    return best;
}

/* test_default_beats_cotan_taubin's bound on the median ratio: measured
 * 0.794 before the combination of iterates (tree 9b45e5f: knot1 0.68-0.74)
 * and 0.739 with it (knot1 0.61-0.62; the sorted ratios' middle pair is
 * sphere_cgal's 0.628 and bunny_npm_closed's 0.851); halfway. The runs
 * are deterministic (seeded noise and probes): the margin, 0.02 either
 * side, is for a change elsewhere, not for chance. */
#define COTAN_BOUND 0.76
static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* One case of the default request against Taubin's oracle: clean with
 * noise rho mean edges along the normals (seed), the oracle with the
 * Laplacian lap, the default request's run (its stats into st: the
 * caller frees them); the errors of the input, the oracle and the
 * result. */
typedef struct {
    double in, tb, e;
    int passes;
    mcf_scheme scheme;
} default_case;

/* A copy of clean with noise rho along the normals (seed) and the default
 * request's parameters for it (api_params_init, then api_params_finish
 * with nothing set) into *ap. */
static mcf_mesh *noisy_default(const mcf_mesh *clean, double rho, int seed, api_params *ap)
{
    mcf_mesh *m = mcf_mesh_dup(clean, NULL);
    mcf_error err = {0};
    assert_non_null(m);
    api_params_init(ap);
    assert_int_equal(mcf_flow_add_noise(m, &ap->flow, rho, (uint64_t)seed, &err), MCF_OK);
    assert_int_equal(api_params_finish(ap, mcf_mesh_nvertices(m), NULL, &err), MCF_OK);
    return m;
}

static void run_default_case(const mcf_mesh *clean, double rho, int seed, mcf_laplacian lap, mcf_flow_stats *st,
                             default_case *r)
{
    api_params ap;
    mcf_mesh *m = noisy_default(clean, rho, seed, &ap);
    mcf_error err = {0};
    r->in = rms(m, clean);
    r->tb = taubin_oracle(m, clean, lap, &r->passes);
    if (mcf_flow_run(m, &ap.flow, st, &err) != MCF_OK)
        fail_msg("the default request: %s", err.msg);
    r->e = rms(m, clean);
    r->scheme = ap.flow.scheme;
    api_params_free(&ap);
    mcf_mesh_free(m);
}

/* The default request (api_params_init, api_params_finish with nothing
 * set: the fairing filter) on each mesh x noise 0.1, 0.25, 0.5 mean edges
 * along the normals (seed 1): the median of its error over Taubin's
 * oracle at most 0.75 (the bound), every case below the input's
 * error and with no more faces lying backwards than the input
 * (flow.folded_faces, the FOLDS warning's count: the guard at work). */
static void default_against_taubin(const char *const *names, int nmesh)
{
    static const double rho[3] = {0.1, 0.25, 0.5};
    double ratio[64];
    int nr = 0;
    for (int q = 0; q < nmesh; q++)
        tl_need_mesh(names[q]);
    for (int q = 0; q < nmesh; q++) {
        mcf_mesh *clean = tl_load(names[q]);
        for (int k = 0; k < 3; k++) {
            mcf_flow_stats st;
            default_case r;
            run_default_case(clean, rho[k], 1, MCF_LAPLACIAN_UNIFORM, &st, &r);
            ratio[nr++] = r.e / r.tb;
            print_message("%-20s rho %.2f: %s K=%d, noise %.3f, error/input %.3f, /Taubin(%d passes) %.3f, "
                          "guard %d rounds, folds %d\n",
                          names[q], rho[k], mcf_scheme_get(r.scheme)->name, st.steps, st.noise, r.e / r.in,
                          r.passes, r.e / r.tb, st.guard_rounds, st.folded_faces);
            assert_true(r.scheme == MCF_FAIRING || r.scheme == MCF_FAIRING_EXPLICIT);
            if (!(r.e < r.in))
                fail_msg("%s rho %.2f: error %.4g not below the input's %.4g", names[q], rho[k], r.e, r.in);
            assert_int_equal(st.folded_faces, 0);
            mcf_flow_stats_free(&st);
        }
        mcf_mesh_free(clean);
    }
    qsort(ratio, (size_t)nr, sizeof *ratio, cmp_double);
    double med = nr % 2 ? ratio[nr / 2] : 0.5 * (ratio[nr / 2 - 1] + ratio[nr / 2]);
    print_message("median error / Taubin's oracle over %d cases: %.3f (worst %.3f)\n", nr, med, ratio[nr - 1]);
    assert_true(med <= 0.75);
}

/* The repository's meshes: closed coarse scan, genus 1, sphere, and the
 * 35k-vertex Stanford bunny with its holes (fixed boundary). Measured
 * before this test was written: median 0.71, worst 0.84 (bunny_npm at
 * 0.5). */
static void test_default_beats_taubin(void **state)
{
    tl_long("the default against Taubin's oracle");
    static const char *const names[] = {"bunny_npm_closed.obj", "knot1.obj", "sphere_cgal.obj", "bunny.drc"};
    (void)state;
    default_against_taubin(names, 4);
}

/* Against the product's own cotan Taubin at its best pass count (what
 * bench_quality's taubin_best and the bar measure), at noise 0.25
 * mean edges along the normals, seeds 1-3, on the repository's meshes:
 * the median ratio at most COTAN_BOUND (about 12 s, most of it the
 * oracle's single passes on bunny.drc). */
static void test_default_beats_cotan_taubin(void **state)
{
    tl_long("the default against cotan Taubin's oracle");
    static const char *const names[] = {"bunny_npm_closed.obj", "knot1.obj", "sphere_cgal.obj", "bunny.drc"};
    double ratio[12];
    int nr = 0;
    (void)state;
    for (int q = 0; q < 4; q++) {
        mcf_mesh *clean = tl_load(names[q]);
        for (int seed = 1; seed <= 3; seed++) {
            mcf_flow_stats st;
            default_case r;
            run_default_case(clean, 0.25, seed, MCF_LAPLACIAN_COTAN, &st, &r);
            ratio[nr++] = r.e / r.tb;
            print_message("%-20s seed %d: K=%d, combination of %d, error/input %.3f, /cotan Taubin(%d passes) %.3f\n",
                          names[q], seed, st.steps, st.ncomb, r.e / r.in, r.passes, r.e / r.tb);
            mcf_flow_stats_free(&st);
        }
        mcf_mesh_free(clean);
    }
    qsort(ratio, (size_t)nr, sizeof *ratio, cmp_double);
    double med = 0.5 * (ratio[nr / 2 - 1] + ratio[nr / 2]);
    print_message("median error / cotan Taubin's oracle over %d cases at noise 0.25: %.3f (worst %.3f)\n", nr, med,
                  ratio[nr - 1]);
    assert_true(med <= COTAN_BOUND);
}

/* The large scans (MESHES). */
static void test_default_beats_taubin_scans(void **state)
{
    static const char *const names[] = {"spot.obj", "fertility.obj", "stanford-bunny.obj", "armadillo.obj"};
    (void)state;
    default_against_taubin(names, 4);
}

/* The fold guard against the input (docs/fairing.md): the default
 * request on each mesh x noise rho along the normals (seed 1) has its
 * error below the input's, folds no face (flow.folded_faces, checked
 * against tl_folds_against: 0), and has at most 0.1% of the faces (the
 * `folds` warning's threshold) more facing against the clean mesh's same
 * face than the input had (mcf_compare's inverted_faces). That last count
 * needs the clean mesh, which the guard does not have: a face lying
 * backwards in the input may be the noise's fold or the clean model's own
 * folded sliver, and unfolding the first kind unfolds some of the second
 * (snowden, seed 1, 0.1: 723 -> 703 of 109,259 faces; 737 before the
 * moves were bounded, 0.013% over; the earlier guard took it to 1,331). */
static void guard_keeps_orientation(const char *const *names, int nmesh, const double *rho, int nrho)
{
    for (int q = 0; q < nmesh; q++)
        tl_need_mesh(names[q]);
    for (int q = 0; q < nmesh; q++) {
        mcf_mesh *clean = tl_load(names[q]);
        for (int k = 0; k < nrho; k++) {
            api_params ap;
            mcf_mesh *m = noisy_default(clean, rho[k], 1, &ap);
            mcf_flow_stats st;
            mcf_compare_result c0, c1;
            mcf_error err = {0};
            mcf_mesh *in = mcf_mesh_dup(m, NULL);
            assert_int_equal(mcf_compare(m, clean, &c0, NULL), MCF_OK);
            if (mcf_flow_run(m, &ap.flow, &st, &err) != MCF_OK)
                fail_msg("%s: %s", names[q], err.msg);
            assert_int_equal(mcf_compare(m, clean, &c1, NULL), MCF_OK);
            int folds = tl_folds_against(mcf_mesh_positions(m), mcf_mesh_positions(in), mcf_mesh_faces(m),
                                         mcf_mesh_nfaces(m), mcf_mesh_nvertices(m), NULL);
            print_message("%-20s rho %.2f: error/input %.3f, faces against the clean mesh's %d -> %d, "
                          "guard %d rounds (%d moves), folds %d\n",
                          names[q], rho[k], c1.rms_m / c0.rms_m, c0.inverted_faces, c1.inverted_faces,
                          st.guard_rounds, st.guard_vertices, folds);
            assert_true(c1.rms_m < c0.rms_m);
            assert_true(c1.inverted_faces <= c0.inverted_faces + mcf_mesh_nfaces(m) / 1000);
            /* No fold, counted the same by core (st.folded_faces) and by
             * the test. dragon_vrip_res2 at noise 0.1 had one on the AMD
             * EPYC machine: face 178664 and its twin 178667 (the same
             * sliver with the opposite orientation, a two-sided fin),
             * turned against the input; their neighbourhood's summed
             * normal is 0 but for rounding, whose sign the guard (working
             * units) and the count (input units) read differently. A sum
             * within rounding of perpendicular now counts as lying
             * backwards in both (mcf_folds.c). */
            assert_int_equal(folds, 0);
            assert_int_equal(st.folded_faces, folds);
            mcf_flow_stats_free(&st);
            api_params_free(&ap);
            mcf_mesh_free(in);
            mcf_mesh_free(m);
        }
        mcf_mesh_free(clean);
    }
}

/* The decimated scans (MESHES), whose clean models have 1,837 and 1,902
 * faces lying backwards in their own neighbourhood: the earlier guard
 * unfolded them and took faces facing against the clean mesh's from 696
 * to 1,331 (snowden) and 396 to 935 (dragon_vrip_res2) at 0.1. */
static void test_guard_scans(void **state)
{
    static const char *const names[] = {"snowden.obj", "dragon_vrip_res2.obj"};
    static const double rho[] = {0.1, 0.25};
    (void)state;
    guard_keeps_orientation(names, 2, rho, 2);
}

/* A closed box 2 x 1 x 1, each side a grid of squares of side 1/n split
 * in two triangles, the edges shared: a CAD part with 12 creases of 90
 * degrees and 8 corners. */
static mcf_mesh *box_mesh(int n)
{
    static const double dims[3] = {2.0, 1.0, 1.0};
    int cap = 6 * (2 * n + 1) * (2 * n + 1), nv = 0, nf = 0;
    double *X = malloc(sizeof(double) * 3 * (size_t)cap);
    int32_t *F = malloc(sizeof(int32_t) * 3 * 2 * (size_t)cap);
    int *ids = malloc(sizeof(int) * (size_t)(2 * n + 1) * (size_t)(2 * n + 1));
    assert_non_null(X);
    assert_non_null(F);
    assert_non_null(ids);
    for (int axis = 0; axis < 3; axis++)
        for (int side = 0; side < 2; side++) {
            int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
            int nu = (int)(n * dims[a1] + 0.5), nw = (int)(n * dims[a2] + 0.5);
            for (int i = 0; i <= nu; i++)
                for (int j = 0; j <= nw; j++) {
                    double p[3];
                    p[axis] = side * dims[axis];
                    p[a1] = dims[a1] * i / nu;
                    p[a2] = dims[a2] * j / nw;
                    int id = -1;
                    for (int q = 0; q < nv && id < 0; q++) /* shared edges */
                        if (fabs(X[3 * q] - p[0]) + fabs(X[3 * q + 1] - p[1]) + fabs(X[3 * q + 2] - p[2]) < 1e-12)
                            id = q;
                    if (id < 0) {
                        memcpy(X + 3 * nv, p, sizeof p);
                        id = nv++;
                    }
                    ids[i * (nw + 1) + j] = id;
                }
            for (int i = 0; i < nu; i++)
                for (int j = 0; j < nw; j++) {
                    int a = ids[i * (nw + 1) + j], b = ids[(i + 1) * (nw + 1) + j];
                    int c = ids[(i + 1) * (nw + 1) + j + 1], d = ids[i * (nw + 1) + j + 1];
                    /* outward: (a1, a2, axis) is right-handed */
                    int32_t t[6] = {a, b, c, a, c, d};
                    if (side == 0) {
                        t[1] = c; t[2] = b; t[4] = d; t[5] = c;
                    }
                    memcpy(F + 3 * nf, t, sizeof t);
                    nf += 2;
                }
        }
    mcf_mesh *m = mcf_mesh_new(nv, X, nf, F, NULL);
    assert_non_null(m);
    free(X);
    free(F);
    free(ids);
    return m;
}

/* A clean box on its own grid (box_mesh(8): every coordinate a multiple
 * of 1/8, the step 0.88 of the mean edge) is a design, not a quantized
 * scan (mcf_lattice.c, LATTICE_MAX_STEP): the default request reads no
 * noise (its high-pass is zero but at the corners: 6e-17 h, the
 * coordinates' rounding, under NOISE_FLOOR), runs no step and returns it
 * bit for bit. Read as a grid it had read 0.25 h of noise and
 * run 81 steps (a 4 x 2 x 2 box of unit squares, 2026-11-29). */
static void test_clean_box_on_grid(void **state)
{
    mcf_mesh *m = box_mesh(8), *m0 = mcf_mesh_dup(m, NULL);
    api_params ap;
    mcf_flow_stats st;
    mcf_error err = {0};
    (void)state;
    assert_non_null(m0);
    api_params_init(&ap);
    assert_int_equal(api_params_finish(&ap, mcf_mesh_nvertices(m), NULL, &err), MCF_OK);
    assert_int_equal(mcf_flow_run(m, &ap.flow, &st, &err), MCF_OK);
    print_message("clean box on its grid: noise read %.3g, K=%d\n", st.noise, st.steps);
    /* the rounding's 6e-17 h is under NOISE_FLOOR: no noise, no step
     * (it ran 447 steps that moved nothing) */
    assert_true(st.noise == 0.0);
    assert_int_equal(st.steps, 0);
    assert_memory_equal(mcf_mesh_positions(m), mcf_mesh_positions(m0),
                        3 * sizeof(double) * (size_t)mcf_mesh_nvertices(m));
    mcf_flow_stats_free(&st);
    api_params_free(&ap);
    mcf_mesh_free(m);
    mcf_mesh_free(m0);
}

/* Sharp features: on the box with noise along the normals the default
 * request keeps the creases (it finds them: crease_vertices > 0) and its
 * error is at most 0.75x Taubin's oracle at 0.1 and 0.25 (measured 0.38
 * and 0.69 here; without the crease step the filter rounded the edges:
 * 1.12 and 0.95 on another draw of the same noise). At 0.5 the smoothed
 * surface no longer shows every crease (measured 0.91): below the input's
 * error is all that is asserted there. */
static void test_creases_kept(void **state)
{
    static const double rho[3] = {0.1, 0.25, 0.5};
    mcf_mesh *clean = box_mesh(16);
    mcf_mesh_info info;
    (void)state;
    assert_int_equal(mcf_mesh_inspect(clean, &info, NULL), MCF_OK);
    assert_int_equal(info.closed, 1);
    assert_int_equal(info.manifold, 1);
    for (int k = 0; k < 3; k++) {
        mcf_flow_stats st;
        default_case r;
        run_default_case(clean, rho[k], 2, MCF_LAPLACIAN_UNIFORM, &st, &r);
        print_message("box rho %.2f: %d crease vertices, K=%d, error/input %.3f, /Taubin(%d passes) %.3f, folds %d\n",
                      rho[k], st.crease_vertices, st.steps, r.e / r.in, r.passes, r.e / r.tb, st.folded_faces);
        assert_true(st.crease_vertices > 0);
        assert_true(r.e < r.in);
        if (k < 2)
            assert_true(r.e <= 0.75 * r.tb);
        assert_int_equal(st.folded_faces, 0);
        mcf_flow_stats_free(&st);
    }
    mcf_mesh_free(clean);
}

/* The box of test_creases_kept with noise along the normals, seed, run
 * by scheme (fairing_pick: the default request's pick; noise_sigma: the
 * level told, 0: read); its error into *e, the stats into st. */
static void run_box(const mcf_mesh *clean, double rho, int seed, mcf_scheme scheme, int pick, double noise_sigma,
                    mcf_flow_stats *st, double *e)
{
    mcf_flow_params p;
    mcf_error err = {0};
    mcf_mesh *m = mcf_mesh_dup(clean, NULL);
    assert_non_null(m);
    mcf_flow_params_init(&p);
    p.scheme = scheme;
    p.fairing_pick = pick;
    p.noise_sigma = noise_sigma;
    assert_int_equal(mcf_flow_add_noise(m, &p, rho, (uint64_t)seed, &err), MCF_OK);
    if (mcf_flow_run(m, &p, st, &err) != MCF_OK)
        fail_msg("%s: %s", mcf_scheme_get(scheme)->name, err.msg);
    *e = rms(m, clean);
    mcf_mesh_free(m);
}

/* The feature-aware stage (bilateral normal filtering and a vertex
 * update, its parameters by SURE) on the box of test_creases_kept with
 * noise along the normals, seeds 1-2, against the linear fairing (the
 * named `fairing`: creases held, no feature stage):
 * - by name (`fairing_feature`) it is taken (flow.feature) and its error
 *   is at most margin[k] of the linear one's: 0.75 at noise 0.1, 1.0 at
 *   0.25 (measured 0.63, 0.64 and 0.60, 0.96 before the noise re-reading;
 *   printed below);
 * - the default request runs it on the box at 12 subdivisions (its
 *   creases 13% of the vertices pass the gate, FEATURE_CREASE_SHARE 10%;
 *   at 16, 9.8% do not) and its error is at most the linear one's on the
 *   same input (SURE takes the better of the two; a 2% margin for SURE's
 *   own error);
 * - told a noise level 0.6 of the true one (noise_sigma), the stage reads
 *   the level from its residuals (flow.feature_noise) within 25% of the
 *   true one (mean edges; the noisy box's mean edge is within 2% of the
 *   clean one's at these levels; measured in the print). */
static void test_feature_box(void **state)
{
    tl_long("the feature stage on a noisy box");
    static const double rho[2] = {0.1, 0.25}, margin[2] = {0.75, 1.0};
    mcf_mesh *clean = box_mesh(16), *clean12 = box_mesh(12);
    (void)state;
    for (int k = 0; k < 2; k++)
        for (int seed = 1; seed <= 2; seed++) {
            mcf_flow_stats sl, sf, sd, sh, sl12;
            double el, ef, ed, eh, el12;
            run_box(clean, rho[k], seed, MCF_FAIRING, 0, 0.0, &sl, &el);
            run_box(clean, rho[k], seed, MCF_FAIRING_FEATURE, 0, 0.0, &sf, &ef);
            run_box(clean12, rho[k], seed, MCF_FAIRING, 0, 0.0, &sl12, &el12);
            run_box(clean12, rho[k], seed, MCF_FAIRING, 1, 0.0, &sd, &ed);
            run_box(clean, rho[k], seed, MCF_FAIRING_FEATURE, 0, 0.6 * rho[k], &sh, &eh);
            print_message("box rho %.2f seed %d: error / linear fairing's: fairing_feature %.3f (%s; sigma_r %.2f, "
                          "%d + %d iterations, noise read %.3f); box 12: default %.3f (feature %s); told %.3f: read %.3f\n",
                          rho[k], seed, ef / el, sf.feature ? "taken" : "not taken", sf.feature_sigma_r,
                          sf.feature_normal_iters, sf.feature_vertex_iters, sf.feature_noise, ed / el12,
                          sd.feature_ran ? (sd.feature ? "taken" : "not taken") : "not run", 0.6 * rho[k],
                          sh.feature_noise);
            assert_int_equal(sf.feature_ran, 1);
            assert_int_equal(sf.feature, 1);
            assert_true(ef <= margin[k] * el);
            assert_int_equal(sf.folded_faces, 0);
            assert_int_equal(sd.feature_ran, 1);
            assert_true(ed <= 1.02 * el12);
            assert_true(fabs(sh.feature_noise - rho[k]) <= 0.25 * rho[k]);
            mcf_flow_stats_free(&sl);
            mcf_flow_stats_free(&sf);
            mcf_flow_stats_free(&sd);
            mcf_flow_stats_free(&sh);
            mcf_flow_stats_free(&sl12);
        }
    mcf_mesh_free(clean);
    mcf_mesh_free(clean12);
}

/* The default request on a mesh with creases the feature stage's gate
 * opens on runs the stage first, against the linear result with its
 * creases held, and makes the run with none held only when the stage is
 * not taken (mcf_fairing.c; FEATURE_HELD_GAIN standard errors). One case:
 * clean with noise rho along the normals (seed); where the default takes
 * the stage, its z is at least 5, the creases it found are still
 * reported (crease_vertices: the run with none held, which zeroes it when
 * taken, was not made) and its output is the named `fairing_feature`'s to
 * the bit, a second path to the same stage (no linear steps, compared
 * with the input; the same creases, weights, noise reading and probes, so
 * the same pick); where not, the stage's z is below 5. Returns whether
 * the stage was taken. */
static int feature_first_case(const char *name, const mcf_mesh *clean, double rho, int seed)
{
    api_params ap;
    mcf_error err = {0};
    mcf_flow_stats sd, sf;
    mcf_mesh *m = noisy_default(clean, rho, seed, &ap), *f = mcf_mesh_dup(m, NULL);
    assert_non_null(f);
    double in = rms(m, clean);
    if (mcf_flow_run(m, &ap.flow, &sd, &err) != MCF_OK)
        fail_msg("the default request: %s", err.msg);
    mcf_flow_params pf = ap.flow;
    pf.scheme = MCF_FAIRING_FEATURE;
    pf.fairing_pick = 0;
    if (mcf_flow_run(f, &pf, &sf, &err) != MCF_OK)
        fail_msg("fairing_feature: %s", err.msg);
    const double *X = mcf_mesh_positions(m), *Y = mcf_mesh_positions(f);
    double d = 0.0;
    for (int i = 0; i < 3 * mcf_mesh_nvertices(m); i++)
        d = fmax(d, fabs(X[i] - Y[i]));
    print_message("%s rho %.2f seed %d: stage %s (z %.2f), %d crease vertices, error / input %.3f, "
                  "largest difference from fairing_feature %.3g\n",
                  name, rho, seed, sd.feature ? "taken" : "not taken", sd.feature_z, sd.crease_vertices,
                  rms(m, clean) / in, d);
    int taken = sd.feature;
    assert_int_equal(sd.feature_ran, 1);
    if (taken) {
        assert_true(sd.feature_z >= 5.0);
        assert_true(sd.crease_vertices > 0);
        assert_int_equal(sf.feature, 1);
        assert_true(d == 0.0);
    } else {
        assert_true(sd.feature_z < 5.0);
    }
    mcf_flow_stats_free(&sd);
    mcf_flow_stats_free(&sf);
    api_params_free(&ap);
    mcf_mesh_free(m);
    mcf_mesh_free(f);
    return taken;
}

/* The box of test_feature_box at 12 subdivisions (13% of its vertices
 * on creases), noise 0.1 and 0.25: its flat sides are the linear
 * fairing's with the creases held, the stage is not taken (measured z
 * -7.75 and -4.98); couplingdown_sub2.obj (29,696 vertices, 22-31% on
 * creases) at noise 0.1, seed 1: taken (measured z 24.71; 4 s of CPU, 15 s
 * under ASan+UBSan). At 0.25 h the stage is taken at z 5.72 where, before
 * it came first, the run with none held replaced the held one
 * (crease_vertices 0; lab/results/quality/issue31-cpu). */
static void test_feature_before_uncreased(void **state)
{
    mcf_mesh *box = box_mesh(12);
    (void)state;
    assert_int_equal(feature_first_case("box 12", box, 0.1, 1), 0);
    assert_int_equal(feature_first_case("box 12", box, 0.25, 2), 0);
    mcf_mesh_free(box);
    tl_need_mesh("couplingdown_sub2.obj");
    mcf_mesh *cd = tl_load("couplingdown_sub2.obj");
    assert_int_equal(feature_first_case("couplingdown_sub2", cd, 0.1, 1), 1);
    mcf_mesh_free(cd);
}

/* The smoothing along the creases (mcf__creases_smooth), whose Jacobian's
 * diagonal is the divergence SURE takes at a held crease vertex
 * (mcf_fairing.c, crease_divergence), against a dense computation: on the
 * clean box of test_creases_kept (its 12 edges found, 252 vertices, and
 * left where they are: a straight chain has nothing to smooth), a vertex
 * of the edge y = z = 0 (33 vertices, x = 0 .. 2) moved by 1e-6 across it
 * answers on that edge as the column of (T_mu T_lambda)^3, T_c = I + c (A
 * - I) with A the average of the two chain neighbours and the corners
 * held, and nowhere else. Tolerance 1e-6: the move tilts the chain's
 * tangent, whose part is dropped, by O(1e-6), a second-order change.
 * Inside the edge (16 edges from either corner, 6 reached by 3 passes)
 * the diagonal is the endless chain's, the mean of ((1 - k/2)(1 + 0.53
 * k))^3 over its spectrum k = 1 - cos t: 0.48204 (numpy, 1e5 points), the
 * figure docs/fairing.md gives. */
static void test_crease_smoothing(void **state)
{
    enum { NP = 33 };
    mcf_mesh *box = box_mesh(16);
    int nv = mcf_mesh_nvertices(box), nf = mcf_mesh_nfaces(box), path[NP], np = 0;
    const double *X0 = mcf_mesh_positions(box);
    const int32_t *F = mcf_mesh_faces(box);
    mcf__graph g;
    mcf_error err = {0};
    (void)state;
    assert_int_equal(mcf__graph_build(F, nf, nv, &g, &err), MCF_OK);
    double *X = malloc(sizeof(double) * 3 * (size_t)nv), *Xp = malloc(sizeof(double) * 3 * (size_t)nv);
    unsigned char *fixed = calloc((size_t)nv, 1), *crease = calloc((size_t)nv, 1);
    unsigned char *chains = calloc((size_t)g.ptr[nv] + 1, 1);
    double *M = malloc(sizeof(double) * NP * NP), *T = malloc(sizeof(double) * NP * NP);
    assert_true(X && Xp && fixed && crease && chains && M && T);
    memcpy(X, X0, sizeof(double) * 3 * (size_t)nv);
    assert_int_equal(mcf__creases(&g, F, nf, nv, fixed, X, crease, chains, NULL), 252);
    for (int i = 0; i < 3 * nv; i++)
        assert_true(fabs(X[i] - X0[i]) <= 1e-15);
    for (int x = 0; x <= 32; x++) /* the edge's vertices by x */
        for (int i = 0; i < nv; i++)
            if (fabs(X0[3 * i] - x / 16.0) < 1e-12 && fabs(X0[3 * i + 1]) < 1e-12 && fabs(X0[3 * i + 2]) < 1e-12)
                path[np++] = i;
    assert_int_equal(np, NP);
    /* M = (T_mu T_lambda)^3 on the path, its ends held */
    for (int i = 0; i < NP * NP; i++)
        M[i] = i % (NP + 1) == 0;
    for (int pass = 0; pass < 6; pass++) {
        double c = pass % 2 ? MCF_TAUBIN_MU : MCF_TAUBIN_LAMBDA;
        memcpy(T, M, sizeof(double) * NP * NP);
        for (int a = 1; a < NP - 1; a++)
            for (int b = 0; b < NP; b++)
                M[a * NP + b] = T[a * NP + b] + c * (0.5 * (T[(a - 1) * NP + b] + T[(a + 1) * NP + b]) - T[a * NP + b]);
    }
    const double u[3] = {0.0, sqrt(0.5), sqrt(0.5)}, delta = 1e-6;
    const int ks[3] = {1, 3, 16};
    for (int q = 0; q < 3; q++) {
        int k = ks[q];
        memcpy(Xp, X, sizeof(double) * 3 * (size_t)nv);
        for (int e = 0; e < 3; e++)
            Xp[3 * path[k] + e] += delta * u[e];
        assert_int_equal(mcf__creases_smooth(&g, nv, fixed, chains, Xp), 0);
        double worst = 0.0, off = 0.0;
        for (int i = 0; i < nv; i++) {
            double d[3] = {Xp[3 * i] - X[3 * i], Xp[3 * i + 1] - X[3 * i + 1], Xp[3 * i + 2] - X[3 * i + 2]};
            int on = -1;
            for (int j = 0; j < NP; j++)
                if (path[j] == i)
                    on = j;
            double resp = (d[0] * u[0] + d[1] * u[1] + d[2] * u[2]) / delta;
            if (on >= 0)
                worst = fmax(worst, fabs(resp - M[on * NP + k]));
            else
                off = fmax(off, sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) / delta);
        }
        print_message("chain vertex %d: diagonal %.5f (dense), largest difference on the chain %.2e, off it %.2e\n",
                      k, M[k * NP + k], worst, off);
        assert_true(worst <= 1e-6);
        assert_true(off == 0.0);
    }
    assert_true(fabs(M[16 * NP + 16] - 0.48204) <= 1e-4);
    mcf__graph_free(&g);
    free(X);
    free(Xp);
    free(fixed);
    free(crease);
    free(chains);
    free(M);
    free(T);
    mcf_mesh_free(box);
}

/* The default request on mesh clean with noise rho along the normals,
 * seed; held: its crease stage as before (fairing_robust off: creases
 * held, no second look; no spike stage either, which Gaussian noise
 * gives nothing to do). Its error into *e, the stats into st. */
static void run_creases(const mcf_mesh *clean, double rho, int seed, int held, mcf_flow_stats *st, double *e)
{
    api_params ap;
    mcf_mesh *m = noisy_default(clean, rho, seed, &ap);
    mcf_error err = {0};
    if (held)
        ap.flow.fairing_robust = 0;
    if (mcf_flow_run(m, &ap.flow, st, &err) != MCF_OK)
        fail_msg("the default request: %s", err.msg);
    *e = rms(m, clean);
    api_params_free(&ap);
    mcf_mesh_free(m);
}

/* The default request's second look at the creases (docs/fairing.md,
 * "Creases"): the filter again with none held, taken when SURE says so,
 * judged here against the clean mesh (the truth SURE cannot see), each
 * case against the same input with the creases held as before:
 * - bunny_npm_closed.obj, an organic scan whose ears' ridges pass the
 *   crease test (70-84 crease vertices of 1,839), at noise 0.25 and 0.5:
 *   no crease held, and the error at most 0.96 of the held one's
 *   (measured 0.92-0.93 with make quality's draw; printed below);
 * - the box of test_creases_kept (16 subdivisions: the gate of the
 *   feature stage not passed), whose creases are its shape, at noise 0.1
 *   and 0.25: creases held, the error at most 1.02 of the held one's
 *   (SURE's own error; the same result when the second look is not
 *   taken). About 1 s. */
static void test_creases_by_sure(void **state)
{
    static const double rho[2] = {0.25, 0.5}, rbox[2] = {0.1, 0.25};
    mcf_mesh *bunny = tl_load("bunny_npm_closed.obj"), *box = box_mesh(16);
    (void)state;
    for (int k = 0; k < 2; k++)
        for (int shape = 0; shape < 2; shape++) {
            mcf_flow_stats sa, sb;
            double ea, eb;
            const mcf_mesh *clean = shape ? box : bunny;
            double r = shape ? rbox[k] : rho[k];
            run_creases(clean, r, 1, 0, &sa, &ea);
            run_creases(clean, r, 1, 1, &sb, &eb);
            print_message("%s rho %.2f: crease vertices held %d (before %d), error / before %.3f\n",
                          shape ? "box" : "bunny_npm_closed", r, sa.crease_vertices, sb.crease_vertices, ea / eb);
            assert_true(sb.crease_vertices > 0);
            if (shape) {
                assert_true(sa.crease_vertices > 0);
                assert_true(ea <= 1.02 * eb);
            } else {
                assert_int_equal(sa.crease_vertices, 0);
                assert_true(ea <= 0.96 * eb);
            }
            assert_int_equal(sa.folded_faces, 0);
            mcf_flow_stats_free(&sa);
            mcf_flow_stats_free(&sb);
        }
    mcf_mesh_free(bunny);
    mcf_mesh_free(box);
}

/* A folded sheet: n x n vertices over [-1, 1]^2, z = |x| (two planes
 * meeting at 90 degrees along x = 0, a crease of n vertices) plus a gentle
 * wave, each square split along one diagonal; its border fixed (the
 * default). */
static mcf_mesh *folded_sheet(int n)
{
    double *X = malloc(sizeof(double) * 3 * (size_t)n * (size_t)n);
    int32_t *F = malloc(sizeof(int32_t) * 6 * (size_t)(n - 1) * (size_t)(n - 1));
    assert_non_null(X);
    assert_non_null(F);
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            double x = -1.0 + 2.0 * i / (n - 1), y = -1.0 + 2.0 * j / (n - 1), *p = X + 3 * (i * n + j);
            p[0] = x;
            p[1] = y;
            p[2] = fabs(x) + 0.05 * sin(3.0 * y) * cos(2.0 * x);
        }
    for (int i = 0, f = 0; i + 1 < n; i++)
        for (int j = 0; j + 1 < n; j++, f += 2) {
            int32_t a = i * n + j, b = (i + 1) * n + j, c = (i + 1) * n + j + 1, d = i * n + j + 1;
            int32_t t[6] = {a, b, c, a, c, d};
            memcpy(F + 3 * f, t, sizeof t);
        }
    mcf_mesh *m = mcf_mesh_new(n * n, X, 2 * (n - 1) * (n - 1), F, NULL);
    assert_non_null(m);
    free(X);
    free(F);
    return m;
}

/* The default request's passes (fairing_explicit, as api_params_finish
 * picks above 150,000 vertices) on clean + noise rho (seed 1), the second
 * look judged near the creases and, as a reference, on the whole mesh
 * (fairing_look_whole): the same choice, then the same output to the bit,
 * and the first judged as look says (crease_look_near: 1 on the submesh,
 * 2 near a sample of the chains, 0 on the whole mesh after all). 1 when
 * the creases were held. */
static int look_near_agrees_as(const mcf_mesh *clean, const char *name, double rho, int look)
{
    mcf_flow_stats st[2];
    mcf_mesh *out[2];
    for (int whole = 0; whole < 2; whole++) {
        api_params ap;
        mcf_error err = {0};
        out[whole] = noisy_default(clean, rho, 1, &ap);
        ap.flow.scheme = MCF_FAIRING_EXPLICIT;
        ap.flow.fairing_pick = 0;
        ap.flow.fairing_look_whole = whole;
        if (mcf_flow_run(out[whole], &ap.flow, &st[whole], &err) != MCF_OK)
            fail_msg("the default request's passes: %s", err.msg);
        api_params_free(&ap);
    }
    print_message("%s rho %.2f: crease vertices held %d near, %d whole; error %.4f\n", name, rho,
                  st[0].crease_vertices, st[1].crease_vertices, rms(out[0], clean));
    assert_int_equal(st[0].crease_look_near, look);
    assert_int_equal(st[1].crease_look_near, 0);
    assert_int_equal(st[0].crease_vertices, st[1].crease_vertices);
    assert_memory_equal(mcf_mesh_positions(out[0]), mcf_mesh_positions(out[1]),
                        3 * sizeof(double) * (size_t)mcf_mesh_nvertices(clean));
    int held = st[0].crease_vertices > 0;
    for (int w = 0; w < 2; w++) {
        mcf_flow_stats_free(&st[w]);
        mcf_mesh_free(out[w]);
    }
    return held;
}

static int look_near_agrees(const mcf_mesh *clean, const char *name, double rho)
{
    return look_near_agrees_as(clean, name, rho, 1);
}

/* m with every triangle split in four at its edges' midpoints
 * (lab/bench/scale_mesh.py's split: the corners first, then one vertex
 * per edge in the order the faces meet them). */
static mcf_mesh *split4(const mcf_mesh *m)
{
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m), cap = 1;
    const double *X = mcf_mesh_positions(m);
    const int32_t *F = mcf_mesh_faces(m);
    while (cap < 8 * nf)
        cap *= 2;
    int64_t *key = malloc(sizeof(int64_t) * (size_t)cap);
    int32_t *mid = malloc(sizeof(int32_t) * (size_t)cap), *F2 = malloc(sizeof(int32_t) * 12 * (size_t)nf);
    double *X2 = malloc(sizeof(double) * 3 * ((size_t)nv + 3 * (size_t)nf));
    assert_true(key && mid && F2 && X2);
    for (int k = 0; k < cap; k++)
        key[k] = -1;
    memcpy(X2, X, sizeof(double) * 3 * (size_t)nv);
    int n = nv;
    for (int f = 0; f < nf; f++) {
        int32_t v[3] = {F[3 * f], F[3 * f + 1], F[3 * f + 2]}, e[3];
        for (int k = 0; k < 3; k++) {
            int a = v[k], b = v[(k + 1) % 3];
            int64_t kk = a < b ? (int64_t)a * nv + b : (int64_t)b * nv + a;
            size_t h = (size_t)(mcf__mix64((uint64_t)kk) & (uint64_t)(cap - 1));
            while (key[h] >= 0 && key[h] != kk)
                h = (h + 1) & (size_t)(cap - 1);
            if (key[h] < 0) {
                key[h] = kk;
                mid[h] = n;
                for (int d = 0; d < 3; d++)
                    X2[3 * (size_t)n + d] = 0.5 * (X[3 * a + d] + X[3 * b + d]);
                n++;
            }
            e[k] = mid[h];
        }
        int32_t t[12] = {v[0], e[0], e[2], e[0], v[1], e[1], e[2], e[1], v[2], e[0], e[1], e[2]};
        memcpy(F2 + 12 * (size_t)f, t, sizeof t);
    }
    mcf_mesh *out = mcf_mesh_new(n, X2, 4 * nf, F2, NULL);
    assert_non_null(out);
    free(key);
    free(mid);
    free(F2);
    free(X2);
    return out;
}

/* The 7M scan's construction (lab/bench/scale_mesh.py: a scan split
 * twice, every triangle into 16 coplanar ones, so that the curvature sits
 * on the original edges, which read as creases) on an icosphere of level
 * `level` whose radii are jittered by +-1 of its mean edge (seed 5). */
static mcf_mesh *jittered_split_sphere(int level)
{
    mcf_error err = {0};
    mcf_mesh_info info;
    mcf_mesh *ico = mcf_mesh_new_icosphere(level, 1.0, &err);
    assert_non_null(ico);
    assert_int_equal(mcf_mesh_inspect(ico, &info, NULL), MCF_OK);
    int nv = mcf_mesh_nvertices(ico);
    double *X = mcf_mesh_positions_mut(ico);
    uint64_t r = 5;
    for (int i = 0; i < nv; i++) {
        double f = 1.0 + info.mean_edge * (2.0 * tl_uniform01(&r) - 1.0);
        for (int d = 0; d < 3; d++)
            X[3 * i + d] *= f;
    }
    mcf_mesh *s1 = split4(ico), *s2 = split4(s1);
    mcf_mesh_free(ico);
    mcf_mesh_free(s1);
    return s2;
}

/* Where the crease vertices' submesh is most of the mesh, the choice is
 * judged near a sample of their chains (crease_look_near 2) when the
 * sample's z is past SUB_SAMPLE_Z (mcf_fairing_sub.c), with the whole
 * mesh's choice and output to the bit: level 5 (163,842 vertices, 3,905
 * crease vertices, their submesh 48% of the mesh) at 0.1 mean edges, held
 * (measured: z -13.6 on the sample). Else the whole mesh judges
 * (crease_look_near 0): level 4 (40,962 vertices) at 0.5, where the whole
 * mesh takes none held and the sample reads z -2.5, the other side (a
 * threshold under 2.5 would hold them). About 4 s of CPU. */
static void test_look_near_sample(void **state)
{
    mcf_mesh *big = jittered_split_sphere(5), *small = jittered_split_sphere(4);
    (void)state;
    assert_int_equal(mcf_mesh_nvertices(big), 163842);
    assert_int_equal(mcf_mesh_nvertices(small), 40962);
    assert_true(look_near_agrees_as(big, "jittered icosphere 5 split twice", 0.1, 2));
    assert_false(look_near_agrees_as(small, "jittered icosphere 4 split twice", 0.5, 0));
    mcf_mesh_free(big);
    mcf_mesh_free(small);
}

/* The passes judge holding the creases or not on the submesh near them
 * (mcf_fairing_sub.c) and run the winner's alone: on the folded sheet
 * (14,641 vertices, the crease its shape, 121 vertices) at noise 0.1 and
 * 0.25 mean edges, held (measured: all 121 at both, and 62 at 0.5), as
 * judged on the whole mesh, with the same output. About 1.5 s. */
static void test_look_near_creases(void **state)
{
    mcf_mesh *sheet = folded_sheet(121);
    (void)state;
    assert_true(look_near_agrees(sheet, "sheet", 0.1));
    assert_true(look_near_agrees(sheet, "sheet", 0.25));
    mcf_mesh_free(sheet);
}

/* The same on fertility.obj (4,494 vertices), whose sharpest ridges pass
 * the crease test, at 0.1, 0.25 and 0.5 mean edges: both choices made
 * (this draw: none held at 0.1 and 0.25, 15 crease vertices held at 0.5;
 * numpy's draw of tests/noisy.py the other way round, with SURE's z near
 * and whole 0.12 / 0.27, -0.21 / -0.16, 1.09 / 0.99). About 0.5 s. */
static void test_look_near_creases_scan(void **state)
{
    static const double rho[3] = {0.1, 0.25, 0.5};
    tl_need_mesh("fertility.obj");
    mcf_mesh *fert = tl_load("fertility.obj");
    int held = 0;
    (void)state;
    for (int k = 0; k < 3; k++)
        held += look_near_agrees(fert, "fertility", rho[k]);
    assert_true(held > 0 && held < 3);
    mcf_mesh_free(fert);
}

/* ------------------------------------------- never worse than sent */

#define PI_D 3.14159265358979323846

/* A coarse genus-1 mesh (the unseen set had one of 250 vertices):
 * a torus of radii 1 and r, 25 x 10 vertices; jittered: at jittered
 * angles, each quad split along a diagonal drawn at random (fixed seed):
 * uneven triangles, few vertices per turn; else at even angles, each quad
 * split along the same diagonal (/work/check/e2e.py's). */
static mcf_mesh *coarse_torus(double rt, int jittered)
{
    enum { NU = 25, NW = 10 };
    double X[3 * NU * NW], u[NU];
    int32_t F[6 * NU * NW];
    uint64_t r = 7;
    for (int i = 0; i < NU; i++)
        u[i] = 2.0 * PI_D * (i + (jittered ? 0.8 * (tl_uniform01(&r) - 0.5) : 0.0)) / NU;
    for (int i = 0; i < NU; i++)
        for (int j = 0; j < NW; j++) {
            double v = 2.0 * PI_D * (j + (jittered ? 0.8 * (tl_uniform01(&r) - 0.5) : 0.0)) / NW,
                   *x = X + 3 * (i * NW + j);
            x[0] = (1.0 + rt * cos(v)) * cos(u[i]);
            x[1] = (1.0 + rt * cos(v)) * sin(u[i]);
            x[2] = rt * sin(v);
        }
    for (int i = 0; i < NU; i++)
        for (int j = 0; j < NW; j++) {
            int32_t a = i * NW + j, b = ((i + 1) % NU) * NW + j, c = ((i + 1) % NU) * NW + (j + 1) % NW,
                    d = i * NW + (j + 1) % NW, *t = F + 6 * (i * NW + j);
            int32_t q1[6] = {a, b, c, a, c, d}, q2[6] = {a, b, d, b, c, d};
            memcpy(t, !jittered || tl_uniform01(&r) < 0.5 ? q1 : q2, sizeof q1);
        }
    mcf_mesh *m = mcf_mesh_new(NU * NW, X, 2 * NU * NW, F, NULL);
    assert_non_null(m);
    return m;
}

/* Noise of rho mean edges: along the normals (mcf_flow_add_noise, the
 * default parameters), or isotropic (each coordinate, on the vertices
 * that the normal noise moves: the run's free ones). */
static mcf_mesh *noisy_copy(const mcf_mesh *clean, const api_params *ap, int iso, double rho, int seed)
{
    mcf_mesh *m = mcf_mesh_dup(clean, NULL);
    mcf_mesh_info info;
    assert_non_null(m);
    assert_int_equal(mcf_flow_add_noise(m, &ap->flow, rho, (uint64_t)seed, NULL), MCF_OK);
    if (!iso)
        return m;
    assert_int_equal(mcf_mesh_inspect(clean, &info, NULL), MCF_OK);
    int nv = mcf_mesh_nvertices(m);
    double *X = malloc(3 * sizeof(double) * (size_t)nv);
    const double *N = mcf_mesh_positions(m), *C = mcf_mesh_positions(clean);
    uint64_t r = 1000003u * (uint64_t)seed + (uint64_t)(rho * 1e6);
    assert_non_null(X);
    for (int i = 0; i < nv; i++) {
        int moved = memcmp(N + 3 * i, C + 3 * i, 3 * sizeof(double)) != 0;
        for (int d = 0; d < 3; d++)
            X[3 * i + d] = C[3 * i + d] + (moved ? rho * info.mean_edge * tl_gauss01(&r) : 0.0);
    }
    mcf_mesh *out = mcf_mesh_new(nv, X, mcf_mesh_nfaces(clean), mcf_mesh_faces(clean), NULL);
    assert_non_null(out);
    free(X);
    mcf_mesh_free(m);
    return out;
}

/* The default request never returns a mesh further from the clean one
 * than it was sent (issue 16): car.drc (a coarse CAD mesh of 920 vertices,
 * many open pieces, long thin triangles; in the repository) and the
 * coarse torus, noise along the normals and isotropic of 0.1, 0.25 and
 * 0.5 mean edges, seeds 1-3. Before the SURE gain's test, the guard's
 * projected positions and the bounds of docs/fairing.md, car.drc came back
 * with up to 1.31x the input's error (normal 0.1, seed 1) and 7 of these
 * 18 car cases above 1; the torus never was. */
static void test_never_worse(void **state)
{
    static const double rho[3] = {0.1, 0.25, 0.5};
    (void)state;
    tl_need_mesh("car.drc");
    for (int q = 0; q < 2; q++) {
        mcf_mesh *clean = q ? coarse_torus(0.4, 1) : tl_load("car.drc");
        double worst = 0.0;
        for (int iso = 0; iso < 2; iso++)
            for (int k = 0; k < 3; k++)
                for (int seed = 1; seed <= 3; seed++) {
                    api_params ap;
                    mcf_flow_stats st;
                    mcf_error err = {0};
                    api_params_init(&ap);
                    mcf_mesh *m = noisy_copy(clean, &ap, iso, rho[k], seed);
                    double in = rms(m, clean);
                    assert_int_equal(api_params_finish(&ap, mcf_mesh_nvertices(m), NULL, &err), MCF_OK);
                    if (mcf_flow_run(m, &ap.flow, &st, &err) != MCF_OK)
                        fail_msg("%s: %s", q ? "torus" : "car.drc", err.msg);
                    double e = rms(m, clean);
                    worst = fmax(worst, e / in);
                    /* 1e-9: the round trip through the run's working
                     * units (mcf_flow_run scales and shifts the mesh) of
                     * a mesh returned as it came */
                    if (!(e <= in * (1.0 + 1e-9)))
                        fail_msg("%s, %s noise %.2f, seed %d: error %.5g above the input's %.5g (%.3fx, K=%d)",
                                 q ? "torus" : "car.drc", iso ? "isotropic" : "normal", rho[k], seed, e, in,
                                 e / in, st.steps);
                    mcf_flow_stats_free(&st);
                    api_params_free(&ap);
                    mcf_mesh_free(m);
                }
        print_message("%s: worst error / input %.3f over 18 cases\n", q ? "coarse torus" : "car.drc", worst);
        mcf_mesh_free(clean);
    }
}

/* Coarse tori (250 vertices: the even one of /work/check/e2e.py, radii
 * 1 and 0.35, and test_never_worse's jittered one) at noise 0.1 and 0.25
 * mean edges along the normals, seeds 1-3: the default request's error
 * at most COARSE_BOUND times the uniform Taubin oracle's (the filter a
 * pipeline engineer has for free). Before the default chose between the
 * implicit steps and the explicit passes by SURE the implicit filter
 * alone was up to ~1.5x the oracle on the even torus (its gain
 * 1 / (1 + k^2)^K damps the coarse cross-section's own low mode,
 * k ~ 0.2). 1.1: the oracle knows the clean mesh and picks its pass count
 * per case, the default does not (SURE's choice of K scatters a few
 * percent about its own oracle on a 250-vertex mesh); the runs are
 * deterministic, the margin is not for chance. */
#define COARSE_BOUND 1.1
static void test_coarse_torus_taubin(void **state)
{
    static const double rho[2] = {0.1, 0.25};
    (void)state;
    double worst = 0.0;
    for (int q = 0; q < 2; q++) {
    mcf_mesh *clean = q ? coarse_torus(0.4, 1) : coarse_torus(0.35, 0);
    for (int k = 0; k < 2; k++)
        for (int seed = 1; seed <= 3; seed++) {
            mcf_flow_stats st;
            default_case r;
            run_default_case(clean, rho[k], seed, MCF_LAPLACIAN_UNIFORM, &st, &r);
            print_message("%s torus %.2f seed %d: noise %.3f, K=%d, explicit %d, error/input %.3f, /uniform Taubin(%d) %.3f\n",
                          q ? "jittered" : "even", rho[k], seed, st.noise, st.steps, st.filter_explicit, r.e / r.in, r.passes, r.e / r.tb);
            worst = fmax(worst, r.e / r.tb);
            mcf_flow_stats_free(&st);
        }
    mcf_mesh_free(clean);
    }
    print_message("coarse tori: worst error / uniform Taubin's oracle %.3f over 12 cases\n", worst);
    assert_true(worst <= COARSE_BOUND);
}

/* The even coarse torus of test_coarse_torus_taubin, noise along the
 * normals, seed: run by scheme with fairing_pick as given and the default
 * request's robust stages; the noisy input's error into *in, the
 * result's into *e, the positions into X (3 nv). */
static void run_torus(const mcf_mesh *clean, double rho, int seed, mcf_scheme scheme, int pick, mcf_flow_stats *st,
                      double *in, double *e, double *X)
{
    mcf_flow_params p;
    mcf_error err = {0};
    mcf_mesh *m = mcf_mesh_dup(clean, NULL);
    assert_non_null(m);
    mcf_flow_params_init(&p);
    p.scheme = scheme;
    p.fairing_pick = pick;
    p.fairing_robust = 1;
    assert_int_equal(mcf_flow_add_noise(m, &p, rho, (uint64_t)seed, &err), MCF_OK);
    *in = rms(m, clean);
    if (mcf_flow_run(m, &p, st, &err) != MCF_OK)
        fail_msg("%s: %s", mcf_scheme_get(scheme)->name, err.msg);
    *e = rms(m, clean);
    memcpy(X, mcf_mesh_positions(m), 3 * sizeof(double) * (size_t)mcf_mesh_nvertices(m));
    mcf_mesh_free(m);
}

/* The default's pick between the filters (issue 27) against each filter
 * run alone with the same robust stages (fairing_pick off), on the even
 * coarse torus (the passes win there: docs/fairing.md) and the level-3
 * icosphere (642 vertices: the implicit steps win) at noise 0.1 and 0.25
 * along the normals, seeds 1-3; both outcomes must occur. Where the
 * pick keeps the implicit steps, the implicit filter alone measures the
 * lower error and the pick's output is its bit for bit (the passes' run
 * reads nothing the implicit result depends on); where it takes the
 * passes, the passes alone measure the lower error and the pick's is
 * within 2% of theirs (the pick keeps the implicit run's tangential step,
 * the passes alone their own; on normal noise neither takes one: measured
 * equal to 4 digits, 2026-11-28). Measured: torus pick 0.31-0.47 of the
 * input's error, the implicit filter 0.47-0.74; icosphere 0.22-0.29,
 * the passes 0.32-0.47. */
static void test_pick_is_the_better(void **state)
{
    static const double rho[2] = {0.1, 0.25};
    (void)state;
    int took = 0, kept = 0;
    for (int q = 0; q < 2; q++) {
    mcf_mesh *clean = q ? mcf_mesh_new_icosphere(3, 1.0, NULL) : coarse_torus(0.35, 0);
    assert_non_null(clean);
    size_t n3 = 3 * (size_t)mcf_mesh_nvertices(clean);
    double *X = malloc(3 * n3 * sizeof(double)), *Xi = X + n3, *Xe = Xi + n3;
    assert_non_null(X);
    for (int k = 0; k < 2; k++)
        for (int seed = 1; seed <= 3; seed++) {
            mcf_flow_stats st, si, se;
            double in, e, ei, ee;
            run_torus(clean, rho[k], seed, MCF_FAIRING, 1, &st, &in, &e, X);
            run_torus(clean, rho[k], seed, MCF_FAIRING, 0, &si, &in, &ei, Xi);
            run_torus(clean, rho[k], seed, MCF_FAIRING_EXPLICIT, 0, &se, &in, &ee, Xe);
            print_message("%s %.2f seed %d: pick explicit %d, error/input pick %.4f, implicit %.4f, passes %.4f\n",
                          q ? "icosphere" : "torus", rho[k], seed, st.filter_explicit, e / in, ei / in, ee / in);
            if (!st.filter_explicit) {
                kept++;
                assert_true(ei < ee);
                assert_memory_equal(X, Xi, n3 * sizeof(double));
            } else {
                took++;
                assert_true(ee < ei);
                assert_true(e <= 1.02 * ee);
            }
            mcf_flow_stats_free(&st);
            mcf_flow_stats_free(&si);
            mcf_flow_stats_free(&se);
        }
    free(X);
    mcf_mesh_free(clean);
    }
    assert_true(took >= 1 && kept >= 1);
}

/* What the filters refuse: time, dt, adaptive (they are no flows). */
static void test_refusals(void **state)
{
    mcf_mesh *m = height_field();
    mcf_flow_params p;
    mcf_error err = {0};
    (void)state;
    for (int var = 0; var < 2; var++) {
        mcf_flow_params_init(&p);
        p.scheme = var ? MCF_FAIRING_EXPLICIT : MCF_FAIRING;
        p.time = 1e-3;
        assert_int_equal(mcf_flow_run(m, &p, NULL, &err), MCF_EINVAL);
        assert_non_null(strstr(err.msg, "is a filter"));
        p.time = 0;
        p.dt = 1e-4;
        assert_int_equal(mcf_flow_run(m, &p, NULL, &err), MCF_EINVAL);
        p.dt = 0;
        p.noise_sigma = -1;
        assert_int_equal(mcf_flow_run(m, &p, NULL, &err), MCF_EINVAL);
    }
    mcf_mesh_free(m);
}

int main(void)
{
    /* MCF_TEST_FILTER=test_feature_box (a cmocka pattern) runs a subset. */
    if (getenv("MCF_TEST_FILTER") && *getenv("MCF_TEST_FILTER"))
        cmocka_set_test_filter(getenv("MCF_TEST_FILTER"));
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_equations_fixed_steps),
        cmocka_unit_test(test_equations_sure),
        cmocka_unit_test(test_refusals),
        cmocka_unit_test(test_creases_kept),
        cmocka_unit_test(test_crease_smoothing),
        cmocka_unit_test(test_creases_by_sure),
        cmocka_unit_test(test_look_near_creases),
        cmocka_unit_test(test_look_near_creases_scan),
        cmocka_unit_test(test_look_near_sample),
        cmocka_unit_test(test_feature_box),
        cmocka_unit_test(test_clean_box_on_grid),
        cmocka_unit_test(test_feature_before_uncreased),
        cmocka_unit_test(test_default_beats_taubin),
        cmocka_unit_test(test_default_beats_cotan_taubin),
        cmocka_unit_test(test_default_beats_taubin_scans),
        cmocka_unit_test(test_guard_scans),
        cmocka_unit_test(test_never_worse),
        cmocka_unit_test(test_coarse_torus_taubin),
        cmocka_unit_test(test_pick_is_the_better),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
