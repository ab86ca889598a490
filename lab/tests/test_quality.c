/* SPDX-License-Identifier: MIT */
/*
 * test_quality.c - make quality's own parts (lab/bench/quality_*.c):
 * bilateral normal filtering against an independent numpy implementation
 * (lab/tests/bnf_ref.py, on Debian's /usr/bin/python3), its oracle, and
 * each noise model's definition checked on the repository's small meshes
 * (test_nm.obj: 114 vertices with boundary loops and non-manifold
 * vertices; sphere_cgal.obj: 812 vertices, closed). About a second.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "testlib.h"
#include "api.h"
#include "quality_bnf.h"
#include "quality_geom.h"
#include "quality_noise.h"

static int setup(void **state)
{
    (void)state;
    return tl_mcf_setup("test_quality", "/tmp/test_quality.XXXXXX");
}

static int teardown(void **state)
{
    (void)state;
    return tl_mcf_teardown();
}

static double mean_edge(const mcf_mesh *m)
{
    mcf_mesh_info ci;
    mcf_error e = {0};
    assert_int_equal(mcf_mesh_inspect(m, &ci, &e), MCF_OK);
    return ci.mean_edge;
}

static mcf_mesh *noisy(const mcf_mesh *clean, qn_model k, double rho, int seed, int *outliers)
{
    mcf_error e = {0};
    mcf_mesh *m = qn_make(clean, k, rho, seed, outliers, &e);
    if (!m)
        fail_msg("qn_make %s: %s", qn_name(k), e.msg);
    return m;
}

static void write_raw(const char *path, const mcf_mesh *m)
{
    FILE *f = fopen(path, "wb");
    int32_t n[2] = {mcf_mesh_nvertices(m), mcf_mesh_nfaces(m)};
    assert_non_null(f);
    assert_int_equal(fwrite(n, sizeof n, 1, f), 1);
    assert_int_equal(fwrite(mcf_mesh_positions(m), 3 * sizeof(double), (size_t)n[0], f), (size_t)n[0]);
    assert_int_equal(fwrite(mcf_mesh_faces(m), 3 * sizeof(int32_t), (size_t)n[1], f), (size_t)n[1]);
    assert_int_equal(fclose(f), 0);
}

/* ------------------------------------------------------------ BNF */

/* quality_bnf.c's filter against bnf_ref.py on a noisy mesh, for one
 * parameter set. Tolerance: the two sum the same terms in other orders
 * (rounding ~1e-16 relative per operation), over at most 30 iterations of
 * normalized sums whose weights are smooth in their inputs: 1e-9 of the
 * mean edge leaves many orders of magnitude for that and still catches any
 * difference in the definition (one missing neighbour moves vertices by
 * ~1e-3 h). */
static void bnf_against_numpy(const char *mesh, double rho, const bnf_params *p)
{
    mcf_mesh *clean = tl_load(mesh);
    mcf_mesh *m = noisy(clean, QN_NORMAL, rho, 7, NULL);
    int nv = mcf_mesh_nvertices(m);
    unsigned char *movable = malloc((size_t)nv);
    mcf_error e = {0};
    assert_true(qn_moved(clean, movable, &e) > 0);
    write_raw(tl_in_scratch("bnf_in.bin"), m);
    FILE *f = fopen(tl_in_scratch("bnf_mask.bin"), "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(movable, 1, (size_t)nv, f), (size_t)nv);
    assert_int_equal(fclose(f), 0);
    char script[4096], cwd[2048], cmd[8192], *err = NULL;
    size_t elen;
    const char *td = tl_testdata_dir(); /* tests/data, maybe relative: the children run in the scratch folder */
    assert_non_null(getcwd(cwd, sizeof cwd));
    snprintf(script, sizeof script, "%s%s%.2000s/../../lab/tests/bnf_ref.py", td[0] == '/' ? "" : cwd,
             td[0] == '/' ? "" : "/", td);
    snprintf(cmd, sizeof cmd, "cd '%s' && /usr/bin/python3 '%s' bnf_in.bin bnf_mask.bin %.17g %d %d bnf_out.bin 2>stderr",
             tl_scratch(), script, p->sigma_r, p->normal_iters, p->vertex_iters);
    int st = system(cmd);
    if (st != 0) {
        tl_read_file(tl_in_scratch("stderr"), &err, &elen);
        fail_msg("bnf_ref.py: status %d: %s", st, err ? err : "");
    }

    double *ref;
    size_t len;
    assert_int_equal(tl_read_file(tl_in_scratch("bnf_out.bin"), (char **)&ref, &len), 0);
    assert_int_equal(len, 3 * sizeof(double) * (size_t)nv);
    mcf_mesh *out = mcf_mesh_dup(m, &e);
    assert_int_equal(bnf_filter(out, movable, p), 0);
    const double *X = mcf_mesh_positions(out), *X0 = mcf_mesh_positions(m);
    double h = mean_edge(clean), worst = 0, moved = 0;
    for (int i = 0; i < 3 * nv; i++) {
        worst = fmax(worst, fabs(X[i] - ref[i]));
        moved = fmax(moved, fabs(X[i] - X0[i]));
        if (!movable[i / 3])
            assert_true(X[i] == X0[i]); /* fixed vertices stay to the bit */
    }
    print_message("%s, sigma_r %g, %d/%d iterations: BNF - numpy at most %.2g mean edges\n", mesh, p->sigma_r,
                  p->normal_iters, p->vertex_iters, worst / h);
    if (!(worst <= 1e-9 * h))
        fail_msg("%s: BNF differs from numpy by %g mean edges", mesh, worst / h);
    if (!(moved > 0.01 * h)) /* the filter did something */
        fail_msg("%s: BNF moved at most %g mean edges", mesh, moved / h);
    free(ref);
    free(movable);
    mcf_mesh_free(out);
    mcf_mesh_free(m);
    mcf_mesh_free(clean);
}

static void test_bnf_matches_numpy(void **state)
{
    (void)state;
    bnf_params narrow = {0.3, 3, 5}, wide = {1.0, 8, 20};
    bnf_against_numpy("test_nm.obj", 0.3, &narrow);
    bnf_against_numpy("test_nm.obj", 0.3, &wide);
    bnf_against_numpy("sphere_cgal.obj", 0.25, &narrow);
}

/* The oracle returns the result of its best parameters (the same as
 * bnf_filter's with them), no worse than the grid's first point (always
 * evaluated), and denoises the sphere (Gaussian noise of 0.25 h: BNF at
 * its best leaves well under 0.8 of the input's error). */
static void test_bnf_oracle(void **state)
{
    (void)state;
    mcf_mesh *clean = tl_load("sphere_cgal.obj");
    mcf_mesh *m = noisy(clean, QN_NORMAL, 0.25, 3, NULL);
    int nv = mcf_mesh_nvertices(m);
    unsigned char *movable = malloc((size_t)nv);
    mcf_error e = {0};
    assert_true(qn_moved(clean, movable, &e) > 0);
    bnf_params best, first = {bnf_grid_sigma_r[0], bnf_grid_normal[0], bnf_grid_vertex[0]};
    mcf_mesh *out = NULL;
    assert_int_equal(bnf_oracle(m, clean, movable, &best, &out), 0);
    mcf_mesh *again = mcf_mesh_dup(m, &e), *one = mcf_mesh_dup(m, &e);
    assert_int_equal(bnf_filter(again, movable, &best), 0);
    assert_int_equal(bnf_filter(one, movable, &first), 0);
    assert_memory_equal(mcf_mesh_positions(out), mcf_mesh_positions(again), 3 * sizeof(double) * (size_t)nv);
    mcf_compare_result a, b, c;
    assert_int_equal(mcf_compare(out, clean, &a, &e), MCF_OK);
    assert_int_equal(mcf_compare(one, clean, &b, &e), MCF_OK);
    assert_int_equal(mcf_compare(m, clean, &c, &e), MCF_OK);
    assert_true(a.rms_m <= b.rms_m);
    if (!(a.rms_m < 0.8 * c.rms_m))
        fail_msg("bnf_best leaves %.3f of the input's error", a.rms_m / c.rms_m);
    free(movable);
    mcf_mesh_free(out);
    mcf_mesh_free(again);
    mcf_mesh_free(one);
    mcf_mesh_free(m);
    mcf_mesh_free(clean);
}

/* ------------------------------------------------------------ noise */

static void normals(const mcf_mesh *m, double *N)
{
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m);
    const int32_t *F = mcf_mesh_faces(m);
    memset(N, 0, 3 * sizeof(double) * (size_t)nv);
    for (int f = 0; f < nf; f++) {
        double n[3];
        qg_face_normal(mcf_mesh_positions(m), F + 3 * f, n);
        for (int k = 0; k < 3; k++)
            for (int d = 0; d < 3; d++)
                N[3 * F[3 * f + k] + d] += n[d];
    }
    for (int i = 0; i < nv; i++) {
        double l = sqrt(N[3 * i] * N[3 * i] + N[3 * i + 1] * N[3 * i + 1] + N[3 * i + 2] * N[3 * i + 2]);
        for (int d = 0; d < 3 && l > 0; d++)
            N[3 * i + d] /= l;
    }
}

/* Displacement of vertex i, its length and its component off the unit
 * vector u (|d x u|). */
static double off_axis(const double *d, const double *u)
{
    double c[3] = {d[1] * u[2] - d[2] * u[1], d[2] * u[0] - d[0] * u[2], d[0] * u[1] - d[1] * u[0]};
    return sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
}

/* Every model: fixed vertices stay to the bit, the same seed gives the
 * same bytes, and each model's own law (the file comment of
 * quality_noise.c). Statistical bounds: with n >= 700 moved vertices on
 * sphere_cgal the sample standard deviation of n Gaussian draws is within
 * 10% of sigma by more than 5 standard errors (1/sqrt(2n) < 2.7%). */
static void test_noise_models(void **state)
{
    (void)state;
    static const char *const meshes[2] = {"test_nm.obj", "sphere_cgal.obj"};
    for (int mi = 0; mi < 2; mi++) {
        mcf_mesh *clean = tl_load(meshes[mi]);
        int nv = mcf_mesh_nvertices(clean);
        const double *C = mcf_mesh_positions(clean);
        double h = mean_edge(clean), rho = 0.25, sigma = rho * h;
        unsigned char *moved = malloc((size_t)nv);
        double *N = malloc(3 * sizeof(double) * (size_t)nv);
        mcf_error e = {0};
        int nmoved = qn_moved(clean, moved, &e);
        assert_true(nmoved > 0 && nmoved <= nv);
        if (mi == 0)
            assert_true(nmoved < nv); /* test_nm has a boundary */
        normals(clean, N);
        mcf_mesh *nrm = noisy(clean, QN_NORMAL, rho, 5, NULL);
        for (int k = 0; k < QN_COUNT; k++) {
            int outliers = -1;
            mcf_mesh *a = noisy(clean, (qn_model)k, rho, 5, &outliers), *b = noisy(clean, (qn_model)k, rho, 5, NULL);
            const double *X = mcf_mesh_positions(a);
            assert_memory_equal(X, mcf_mesh_positions(b), 3 * sizeof(double) * (size_t)nv);
            assert_int_equal(outliers == 0, k != QN_OUT);
            for (int i = 0; i < nv; i++)
                /* == not memcmp: iso, as issue 16 wrote it, adds 0.0 to them (-0 becomes +0) */
                if (!moved[i] && (X[3 * i] != C[3 * i] || X[3 * i + 1] != C[3 * i + 1] || X[3 * i + 2] != C[3 * i + 2]))
                    fail_msg("%s: %s moved fixed vertex %d by %g", meshes[mi], qn_name((qn_model)k), i,
                             fabs(X[3 * i] - C[3 * i]) + fabs(X[3 * i + 1] - C[3 * i + 1]) + fabs(X[3 * i + 2] - C[3 * i + 2]));
            double ss = 0, ssd = 0, u[3] = {0, 0, 0};
            int changed = 0, odd = 0;
            for (int i = 0; i < nv; i++) {
                if (!moved[i])
                    continue;
                double d[3] = {X[3 * i] - C[3 * i], X[3 * i + 1] - C[3 * i + 1], X[3 * i + 2] - C[3 * i + 2]};
                double l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                changed += l > 0;
                ss += l * l;
                ssd += d[0] * d[0];
                if (k == QN_CORR && off_axis(d, N + 3 * i) > 1e-12 * h)
                    odd++;
                if (k == QN_VIEW) {
                    if (u[0] == 0 && u[1] == 0 && u[2] == 0 && l > 0)
                        for (int c = 0; c < 3; c++)
                            u[c] = d[c] / l;
                    else if (off_axis(d, u) > 1e-9 * h)
                        odd++;
                }
                if (k == QN_QUANT)
                    for (int c = 0; c < 3; c++) {
                        /* on one grid of step sigma: differences from the first moved vertex are whole steps */
                        int first = 0;
                        while (!moved[first])
                            first++;
                        double q = (X[3 * i + c] - X[3 * first + c]) / sigma;
                        odd += fabs(q - floor(q + 0.5)) > 1e-6 || fabs(d[c]) > 0.5 * sigma * (1 + 1e-9);
                    }
            }
            double rms = sqrt(ss / nmoved);
            switch ((qn_model)k) {
            case QN_NORMAL:
                assert_memory_equal(X, mcf_mesh_positions(nrm), 3 * sizeof(double) * (size_t)nv);
                break;
            case QN_ISO:
                if (mi == 1)
                    tl_assert_near(sqrt(ssd / nmoved) / sigma, 1.0, 0.1, "iso: x sigma / (rho h)");
                break;
            case QN_VIEW:
                assert_int_equal(odd, 0);
                if (mi == 1)
                    tl_assert_near(rms / sigma, 1.0, 0.1, "view: RMS / (rho h)");
                break;
            case QN_CORR:
                assert_int_equal(odd, 0);
                tl_assert_near(rms / sigma, 1.0, 1e-12, "corr: RMS / (rho h), rescaled exactly");
                break;
            case QN_OUT: {
                /* `normal` plus K spikes of 3-5 h along the normal */
                const double *Y = mcf_mesh_positions(nrm);
                int spikes = 0, want = (int)floor(0.01 * nmoved + 0.5);
                for (int i = 0; i < nv; i++) {
                    double d[3] = {X[3 * i] - Y[3 * i], X[3 * i + 1] - Y[3 * i + 1], X[3 * i + 2] - Y[3 * i + 2]};
                    double l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                    if (l == 0)
                        continue;
                    spikes++;
                    assert_true(moved[i]);
                    assert_true(l >= 3 * h * (1 - 1e-12) && l <= 5 * h * (1 + 1e-12));
                    assert_true(off_axis(d, N + 3 * i) <= 1e-9 * h);
                }
                assert_int_equal(spikes, want < 1 ? 1 : want);
                assert_int_equal(outliers, spikes);
                break;
            }
            case QN_QUANT:
                assert_int_equal(odd, 0);
                assert_true(changed > nmoved / 2);
                break;
            case QN_CLEAN:
                assert_memory_equal(X, C, 3 * sizeof(double) * (size_t)nv);
                break;
            default:
                break;
            }
            mcf_mesh_free(a);
            mcf_mesh_free(b);
        }
        /* corr is correlated over neighbours, normal is not: the mean
         * product of the amplitudes along the normals across an edge over
         * their mean square (~0.9 after 9 averagings; ~0 for independent
         * draws, within 0.15 at sphere_cgal's 2,430 edges) */
        if (mi == 1) {
            mcf_mesh *cr = noisy(clean, QN_CORR, rho, 5, NULL);
            const mcf_mesh *two[2] = {nrm, cr};
            double corr[2];
            for (int t = 0; t < 2; t++) {
                const double *X = mcf_mesh_positions(two[t]);
                const int32_t *F = mcf_mesh_faces(clean);
                double *z = malloc(sizeof(double) * (size_t)nv), num = 0, den = 0;
                for (int i = 0; i < nv; i++)
                    z[i] = (X[3 * i] - C[3 * i]) * N[3 * i] + (X[3 * i + 1] - C[3 * i + 1]) * N[3 * i + 1] +
                           (X[3 * i + 2] - C[3 * i + 2]) * N[3 * i + 2];
                for (int f = 0; f < mcf_mesh_nfaces(clean); f++)
                    for (int c = 0; c < 3; c++) {
                        int a = F[3 * f + c], b = F[3 * f + (c + 1) % 3];
                        num += z[a] * z[b];
                        den += 0.5 * (z[a] * z[a] + z[b] * z[b]);
                    }
                corr[t] = num / den;
                free(z);
            }
            if (!(corr[1] > 0.7 && fabs(corr[0]) < 0.15))
                fail_msg("neighbour correlation: corr %.3f, normal %.3f", corr[1], corr[0]);
            mcf_mesh_free(cr);
        }
        /* the direction of `view` comes from the seed */
        mcf_mesh *v1 = noisy(clean, QN_VIEW, rho, 1, NULL), *v2 = noisy(clean, QN_VIEW, rho, 2, NULL);
        assert_memory_not_equal(mcf_mesh_positions(v1), mcf_mesh_positions(v2), 3 * sizeof(double) * (size_t)nv);
        mcf_mesh_free(v1);
        mcf_mesh_free(v2);
        /* bad levels: a precise error, no mesh */
        assert_null(qn_make(clean, QN_QUANT, 0.0, 1, NULL, &e));
        assert_int_equal(e.status, MCF_EINVAL);
        assert_null(qn_make(clean, QN_NORMAL, -1.0, 1, NULL, &e));
        assert_null(qn_make(clean, QN_VIEW, NAN, 1, NULL, &e));
        assert_int_equal(qn_parse("view"), QN_VIEW);
        assert_int_equal(qn_parse("gauss"), -1);
        mcf_mesh_free(nrm);
        free(moved);
        free(N);
        mcf_mesh_free(clean);
    }
}

/* Flips: the count of faces whose normal points against the clean mesh's
 * (dot < 0): 0 on the clean mesh itself, every face on its mirror image
 * (x -> -x reverses every orientation). */
static void test_flips(void **state)
{
    (void)state;
    mcf_mesh *clean = tl_load("sphere_cgal.obj");
    mcf_error e = {0};
    mcf_mesh *mirror = mcf_mesh_dup(clean, &e);
    double *X = mcf_mesh_positions_mut(mirror);
    for (int i = 0; i < mcf_mesh_nvertices(mirror); i++)
        X[3 * i] = -X[3 * i];
    assert_int_equal(qg_flips(clean, clean), 0);
    int want = 0;
    const int32_t *F = mcf_mesh_faces(clean);
    for (int f = 0; f < mcf_mesh_nfaces(clean); f++) {
        double n[3];
        qg_face_normal(mcf_mesh_positions(clean), F + 3 * f, n);
        /* the mirrored face's normal: (nx, -ny, -nz) (a reflection
         * reverses the orientation), so the dot is nx^2 - ny^2 - nz^2 */
        want += n[0] * n[0] - n[1] * n[1] - n[2] * n[2] < 0;
    }
    assert_int_equal(qg_flips(mirror, clean), want);
    assert_true(want > 0 && want < mcf_mesh_nfaces(clean));
    mcf_mesh_free(mirror);
    mcf_mesh_free(clean);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_bnf_matches_numpy),
        cmocka_unit_test(test_bnf_oracle),
        cmocka_unit_test(test_noise_models),
        cmocka_unit_test(test_flips),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
