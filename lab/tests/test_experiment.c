/* SPDX-License-Identifier: MIT */
/*
 * test_experiment.c - the lab's flow studies end to end: runs
 * $MCF_BUILD/lab/mcflab (default build/lab/mcflab) on small icospheres (and the 812-vertex
 * sphere_cgal.obj) and reads back the CSV files: rows, columns, the fitted
 * orders of desbrun2 and euler, euler's stability limit against
 * 2/lambda_max, the U shape of the dt sweep, the sphere law, usage
 * errors, and the plots (PNG and SVG when gnuplot is on the PATH; a
 * warning and CSV files only when it is not).
 *
 * Every study here runs on 162 to 812 vertices: the binary takes a few
 * seconds.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "testlib.h"
#include "api.h"

static int have_gnuplot;

/* A successful run, or the failure with its stderr. */
static void expect_ok(tl_run_result *r)
{
    if (r->status != 0)
        fail_msg("mcflab: status %d: %s", r->status, r->err);
    tl_run_free(r);
}

/* ------------------------------------------------------------------ CSV */

#define MAX_COLS 40
#define MAX_ROWS 400

typedef struct {
    char *buf;
    int ncols, nrows;
    char *head[MAX_COLS];
    char *cell[MAX_ROWS][MAX_COLS];
} csv;

/* Reads scratch/name; every row must have as many fields as the header. */
static void csv_load(csv *c, const char *name)
{
    const char *path = tl_in_scratch(name);
    size_t len;
    memset(c, 0, sizeof *c);
    if (tl_read_file(path, &c->buf, &len) != 0)
        fail_msg("cannot read %s", path);
    char *line = c->buf, *next;
    for (int row = -1; line && *line; row++, line = next) {
        next = strchr(line, '\n');
        if (next)
            *next++ = '\0';
        char **dst = row < 0 ? c->head : c->cell[row];
        int k = 0;
        if (row >= MAX_ROWS)
            fail_msg("%s: more than %d rows", name, MAX_ROWS);
        for (char *f = line;; k++) {
            char *comma = strchr(f, ',');
            if (k >= MAX_COLS)
                fail_msg("%s: more than %d columns", name, MAX_COLS);
            if (comma)
                *comma = '\0';
            dst[k] = f;
            if (!comma)
                break;
            f = comma + 1;
        }
        if (row < 0)
            c->ncols = k + 1;
        else if (k + 1 != c->ncols)
            fail_msg("%s: row %d has %d fields, the header %d", name, row + 1, k + 1, c->ncols);
        else
            c->nrows = row + 1;
    }
}

static int csv_col(const csv *c, const char *name)
{
    for (int k = 0; k < c->ncols; k++)
        if (!strcmp(c->head[k], name))
            return k;
    fail_msg("no column '%s'", name);
    return -1;
}

static const char *csv_get(const csv *c, int row, const char *name)
{
    return c->cell[row][csv_col(c, name)];
}

static double csv_num(const csv *c, int row, const char *name)
{
    return strtod(csv_get(c, row, name), NULL);
}

/* The row whose column `scheme` is s (-1 if none). */
static int csv_find(const csv *c, const char *s)
{
    for (int i = 0; i < c->nrows; i++)
        if (!strcmp(csv_get(c, i, "scheme"), s))
            return i;
    return -1;
}

static int csv_count(const csv *c, const char *s)
{
    int n = 0;
    for (int i = 0; i < c->nrows; i++)
        n += !strcmp(csv_get(c, i, "scheme"), s);
    return n;
}

static void csv_free(csv *c)
{
    free(c->buf);
}

/* ---------------------------------------------------------------- files */

static int exists(const char *name)
{
    struct stat sb;
    return stat(tl_in_scratch(name), &sb) == 0 && sb.st_size > 0;
}

/* PNG and SVG both there (and real) when gnuplot is, both absent when not. */
static void expect_plot(const char *base)
{
    char png[256], svg[256], *buf;
    const char *path;
    size_t len;
    snprintf(png, sizeof png, "%s.png", base);
    snprintf(svg, sizeof svg, "%s.svg", base);
    if (!have_gnuplot) {
        assert_false(exists(png));
        assert_false(exists(svg));
        return;
    }
    path = tl_in_scratch(png);
    if (tl_read_file(path, &buf, &len) != 0)
        fail_msg("no plot %s", path);
    assert_true(len > 1000 && !memcmp(buf, "\x89PNG", 4));
    free(buf);
    path = tl_in_scratch(svg);
    if (tl_read_file(path, &buf, &len) != 0)
        fail_msg("no plot %s", path);
    assert_non_null(strstr(buf, "<svg"));
    free(buf);
}

/* No gnuplot script is left behind unless --keep-scripts. */
static void expect_no_scripts(void)
{
    char cmd[128];
    snprintf(cmd, sizeof cmd, "ls -a %s | grep -q '^\\.mcf-plot-'", tl_scratch());
    assert_int_not_equal(system(cmd), 0);
}

/* ---------------------------------------------------------------- tests */

/* The MATH.md protocol on the 162-vertex icosphere, T = 0.01 in 32, 64,
 * 128 steps against desbrun2 at 2048. */
static void test_order(void **state)
{
    (void)state;
    tl_run_result r = tl_run("order", "--sphere", "2", "--steps", "32,64,128", "--ref-scheme", "desbrun2",
                       "--schemes", "euler,desbrun2,cmcf", "--name", "ord", "--out", ".", "--quiet", NULL);
    expect_ok(&r);
    csv c;
    csv_load(&c, "ord-order.csv");
    assert_int_equal(c.nrows, 9);
    for (int i = 0; i < c.nrows; i++) {
        assert_string_equal(csv_get(&c, i, "status"), "OK");
        assert_true(csv_num(&c, i, "error") > 0);
        tl_assert_near(csv_num(&c, i, "T"), 0.01, 1e-15, "T");
    }
    csv_free(&c);
    csv_load(&c, "ord-order-summary.csv");
    assert_int_equal(c.nrows, 3);
    /* measured 1.001 and 2.002; the reference (dt/16) biases a slope by
     * a few hundredths at most: 0.1 and 0.15 are generous */
    int e = csv_find(&c, "euler"), d = csv_find(&c, "desbrun2"), m = csv_find(&c, "cmcf");
    assert_true(e >= 0 && d >= 0 && m >= 0);
    tl_assert_near(csv_num(&c, e, "fitted_slope"), 1.0, 0.1, "euler slope");
    tl_assert_near(csv_num(&c, d, "fitted_slope"), 2.0, 0.15, "desbrun2 slope");
    assert_int_equal((int)csv_num(&c, d, "points"), 3);
    /* cmcf integrates its own flow: measured against its own fine run, it
     * is first order (measured 1.03), not stuck at its distance to MCF */
    assert_string_equal(csv_get(&c, m, "reference"), "cmcf");
    tl_assert_near(csv_num(&c, m, "fitted_slope"), 1.0, 0.15, "cmcf slope");
    assert_int_equal((int)csv_num(&c, m, "reference_steps"), 2048);
    csv_free(&c);
    expect_plot("ord-order");
    expect_no_scripts();
}

/* euler's largest acceptable dt in 10 steps on the 642-vertex icosphere
 * lies between 1/lambda_max and 2.6/lambda_max. Theory says 2, but ten
 * steps show the instability only once |1 - z|^10 has grown the top
 * mode's share of the noise into a folded face: measured 2.47 (1.47^10
 * ~ 47); at 2.6, 1.6^10 ~ 110 would fold it for certain. (The flow no
 * longer refuses a stable step that flips slivers, which used to end
 * these runs at 2.14.) neumann2's theory is half of euler's. */
static void test_stability(void **state)
{
    (void)state;
    tl_run_result r = tl_run("stability", "--sphere", "3", "--schemes", "euler,neumann2,desbrun",
                       "--dt-max", "100/lambda", "--name", "stab", "--out", ".", "--quiet", NULL);
    expect_ok(&r);
    csv c;
    csv_load(&c, "stab-stability.csv");
    assert_int_equal(c.nrows, 3);
    int e = csv_find(&c, "euler"), n = csv_find(&c, "neumann2"), d = csv_find(&c, "desbrun");
    assert_true(e >= 0 && n >= 0 && d >= 0);
    double lam = csv_num(&c, e, "lambda_max");
    assert_true(lam > 0);
    double z = csv_num(&c, e, "measured_dt_lambda");
    print_message("euler: largest acceptable dt = %.3f / lambda_max (theory 2)\n", z);
    assert_true(z >= 1.0 && z <= 2.6);
    tl_assert_near(csv_num(&c, e, "measured_dt") * lam, z, 1e-5 * z, "dt * lambda");
    assert_string_equal(csv_get(&c, e, "theory"), "2/lambda_max");
    assert_string_equal(csv_get(&c, n, "theory"), "1/lambda_max");
    assert_string_equal(csv_get(&c, d, "theory"), "unconditional");
    assert_int_equal((int)csv_num(&c, e, "censored"), 0);
    /* the bracket is closed: the first failing dt is within 2^(1/64) */
    double ff = csv_num(&c, e, "first_failing_dt_lambda");
    /* 1e-5: the CSV prints 6 significant digits */
    assert_true(ff > z && ff <= z * pow(2.0, 1.0 / 64) * (1 + 1e-5));
    assert_true(csv_num(&c, n, "measured_dt_lambda") < z);
    /* desbrun: the top of the range (100/lambda, 10 steps past the
     * sphere's extinction at 0.25) is a point, but no failure */
    assert_true(csv_num(&c, d, "measured_dt_lambda") > 2.2);
    csv_free(&c);
    csv_load(&c, "stab-stability-runs.csv");
    assert_true(c.nrows >= 3 + 2 * 6);
    for (int i = 0; i < c.nrows; i++) {
        int ok = (int)csv_num(&c, i, "acceptable");
        assert_true(ok == (csv_get(&c, i, "reason")[0] == '\0'));
    }
    csv_free(&c);
    expect_plot("stab-stability");
}

/* The article's design on the 162-vertex icosphere: every dt, 10 steps;
 * the error is U-shaped in the total time. */
static void test_dt_sweep(void **state)
{
    (void)state;
    tl_run_result r = tl_run("dt-sweep", "--sphere", "2", "--schemes", "euler,desbrun2,taubin", "--dt-min",
                       "0.1/lambda", "--dt-max", "100/lambda", "--per-decade", "2", "--name", "sw", "--out", ".",
                       "--quiet", NULL);
    expect_ok(&r);
    csv c;
    csv_load(&c, "sw-dt-sweep.csv");
    /* 0.1 .. 100 at 2 per decade: 7 values, taubin once */
    assert_int_equal(csv_count(&c, "euler"), 7);
    assert_int_equal(csv_count(&c, "desbrun2"), 7);
    assert_int_equal(csv_count(&c, "taubin"), 1);
    assert_int_equal(c.nrows, 15);
    int euler_fail_above = 0;
    for (int i = 0; i < c.nrows; i++) {
        const char *s = csv_get(&c, i, "scheme"), *st = csv_get(&c, i, "status");
        double z = csv_num(&c, i, "dt_lambda");
        if (!strcmp(s, "taubin"))
            continue;
        assert_int_equal((int)csv_num(&c, i, "iterations"), 10);
        if (z < 1.0) /* well inside every bound */
            assert_string_equal(st, "OK");
        if (!strcmp(s, "euler") && z > 3.0)
            euler_fail_above += strcmp(st, "OK") != 0;
        if (!strcmp(st, "OK")) {
            assert_int_equal((int)csv_num(&c, i, "steps"), 10);
            tl_assert_near(csv_num(&c, i, "t_final"), 10 * csv_num(&c, i, "dt"), 1e-12, "t = 10 dt");
            assert_true(csv_num(&c, i, "rms_rel") > 0 && csv_num(&c, i, "frobenius") > 0);
            /* MCF shrinks: area and volume go down */
            assert_true(csv_num(&c, i, "area_drift") < 0 && csv_num(&c, i, "volume_drift") < 0);
        }
    }
    /* euler at 3.2/lambda and beyond (4 values) is refused by the flow */
    assert_int_equal(euler_fail_above, 4);
    csv_free(&c);

    csv_load(&c, "sw-dt-sweep-summary.csv");
    assert_int_equal(c.nrows, 3);
    int d = csv_find(&c, "desbrun2");
    double best = csv_num(&c, d, "best_rms_rel"), noisy = csv_num(&c, d, "noisy_rms_rel");
    assert_true(best < noisy);
    tl_assert_near(csv_num(&c, d, "best_time"), 10 * csv_num(&c, d, "best_dt"), 1e-12, "best time");
    /* U shape: the best dt is inside the range, not at its end */
    double lam = csv_num(&c, d, "lambda_max");
    assert_true(csv_num(&c, d, "best_dt") * lam < 99);
    assert_true(isfinite(csv_num(&c, d, "rising_slope")) && csv_num(&c, d, "rising_slope") > 0);
    assert_int_equal((int)csv_num(&c, d, "failed_runs"), 0);
    csv_free(&c);
    expect_plot("sw-dt-sweep-error");
    expect_plot("sw-dt-sweep-runtime");
}

/* A fixed final time instead of 10 steps; on a mesh file, normalized to
 * unit area (so a scaled copy gives the same figures). */
static void test_fixed_time_file(void **state)
{
    (void)state;
    tl_run_result r = tl_run("dt-sweep", "--mesh", tl_sphere(), "--schemes", "desbrun,desbrun2", "--time",
                       "1e-4", "--dt-min", "1e-6", "--dt-max", "5e-5", "--per-decade", "1", "--out", ".",
                       "--no-plots", "--quiet", NULL);
    expect_ok(&r);
    csv c;
    csv_load(&c, "sphere_cgal-dt-sweep.csv");
    assert_int_equal(c.nrows, 6);
    for (int i = 0; i < c.nrows; i++) {
        assert_string_equal(csv_get(&c, i, "mesh"), "sphere_cgal");
        assert_string_equal(csv_get(&c, i, "status"), "OK");
        tl_assert_near(csv_num(&c, i, "t_final"), 1e-4, 1e-15, "fixed time");
        assert_int_equal((int)csv_num(&c, i, "iterations"), 0);
        /* 1e-6 and 1e-5 from the grid, then the end of the range, 5e-5 */
        int steps = (int)csv_num(&c, i, "steps");
        assert_true(steps == 100 || steps == 10 || steps == 2);
    }
    /* --no-plots: none */
    assert_false(exists("sphere_cgal-dt-sweep-error.png"));

    /* the same mesh 100 times larger and moved: the same dt means the
     * same flow after normalization, so the same errors */
    mcf_mesh *m = tl_load("sphere_cgal.obj");
    double *X = mcf_mesh_positions_mut(m);
    for (int i = 0; i < 3 * mcf_mesh_nvertices(m); i++)
        X[i] = 100 * X[i] + 7;
    api_buf b;
    api_buf_init(&b, 1u << 26);
    assert_int_equal(api_obj_encode(m, &b, NULL), MCF_OK);
    FILE *f = fopen(tl_in_scratch("big.obj"), "w");
    assert_non_null(f);
    assert_int_equal(fwrite(b.data, 1, b.len, f), b.len);
    assert_int_equal(fclose(f), 0);
    api_buf_free(&b);
    mcf_mesh_free(m);
    r = tl_run("dt-sweep", "--mesh", "big.obj", "--schemes", "desbrun,desbrun2", "--time", "1e-4",
            "--dt-min", "1e-6", "--dt-max", "5e-5", "--per-decade", "1", "--out", ".", "--no-plots", "--quiet", NULL);
    expect_ok(&r);
    csv big;
    csv_load(&big, "big-dt-sweep.csv");
    assert_int_equal(big.nrows, c.nrows);
    for (int i = 0; i < c.nrows; i++) {
        double a = csv_num(&c, i, "rms_rel"), z = csv_num(&big, i, "rms_rel");
        /* rounding of x*100+7 only: 1e-6 relative is far above it */
        tl_assert_near(z, a, 1e-6 * a, "rms_rel of the scaled copy");
        tl_assert_near(csv_num(&big, i, "dt"), csv_num(&c, i, "dt"), 1e-15, "dt");
    }
    csv_free(&big);
    csv_free(&c);
}

/* The shrinking sphere: R(t) from the volume against sqrt(R0^2 - 4t). */
static void test_sphere(void **state)
{
    (void)state;
    tl_run_result r = tl_run("sphere", "--sphere", "2", "--time", "0.1", "--steps", "50", "--schemes",
                       "desbrun2,euler,linear", "--name", "sph", "--out", ".", "--quiet", NULL);
    expect_ok(&r);
    csv c;
    csv_load(&c, "sph-sphere-summary.csv");
    assert_int_equal(c.nrows, 3);
    int d = csv_find(&c, "desbrun2"), e = csv_find(&c, "euler"), l = csv_find(&c, "linear");
    assert_int_equal((int)csv_num(&c, d, "steps"), 50);
    /* explicit: half its bound at the final radius, so more steps */
    assert_true(csv_num(&c, e, "steps") > 1 && csv_num(&c, e, "dt_lambda0") < 1.0);
    /* 162 vertices: the discrete sphere shrinks ~0.8% off the law at
     * t = 0.1 (spatial error, measured 0.78%); 3% bounds it */
    assert_true(csv_num(&c, d, "r_rel_error") < 0.03);
    assert_true(csv_num(&c, e, "r_rel_error") < 0.03);
    tl_assert_near(csv_num(&c, d, "r_exact"), sqrt(pow(csv_num(&c, d, "r0"), 2) - 0.4), 1e-9, "exact radius");
    /* linear heat flow is not MCF: R0 exp(-2t/R0^2) ~ 0.82 instead of 0.77 */
    assert_true(csv_num(&c, l, "r_rel_error") > 0.03);
    csv_free(&c);
    csv_load(&c, "sph-sphere.csv");
    int rows = csv_count(&c, "desbrun2");
    assert_true(rows >= 2 && rows <= 121);
    double prev = INFINITY;
    for (int i = 0; i < c.nrows; i++)
        if (!strcmp(csv_get(&c, i, "scheme"), "desbrun2")) {
            double rv = csv_num(&c, i, "r_volume");
            assert_true(rv < prev); /* strictly shrinking */
            prev = rv;
        }
    csv_free(&c);
    expect_plot("sph-sphere-radius");
    expect_plot("sph-sphere-volume");
    expect_plot("sph-sphere-error");
}

/* Without gnuplot on the PATH: CSV files, no plots, one warning, exit 0. */
static void test_no_gnuplot(void **state)
{
    (void)state;
    tl_run_result r = tl_run_env("/nonexistent", "order", "--sphere", "1", "--steps", "8,16", "--schemes",
                           "desbrun", "--ref-factor", "4", "--name", "nogp", "--out", ".", "--quiet", NULL);
    assert_int_equal(r.status, 0);
    assert_non_null(strstr(r.err, "gnuplot not found"));
    tl_run_free(&r);
    assert_true(exists("nogp-order.csv"));
    assert_false(exists("nogp-order.png"));
    assert_false(exists("nogp-order.svg"));
    expect_no_scripts();
}

static void test_usage(void **state)
{
    (void)state;
    tl_run_result r = tl_run(NULL);
    tl_expect_error(&r, 2, "missing study");
    r = tl_run("sweep", "--out", ".", NULL);
    tl_expect_error(&r, 2, "unknown study");
    r = tl_run("order", "--sphere", "1", NULL);
    tl_expect_error(&r, 2, "--out");
    r = tl_run("order", "--sphere", "1", "--schemes", "taubin", "--out", ".", NULL);
    tl_expect_error(&r, 2, "taubin");
    r = tl_run("order", "--sphere", "1", "--mesh", tl_sphere(), "--out", ".", NULL);
    tl_expect_error(&r, 2, "exclude");
    r = tl_run("dt-sweep", "--schemes", "euler,nosuch", "--out", ".", NULL);
    tl_expect_error(&r, 2, "nosuch");
    r = tl_run("dt-sweep", "--dt-min", "1e-3/lambdas", "--out", ".", NULL);
    tl_expect_error(&r, 2, "--dt-min");
    r = tl_run("order", "--steps", "64,32", "--out", ".", NULL);
    tl_expect_error(&r, 2, "--steps");
    r = tl_run("sphere", "--time", "0.3", "--out", ".", NULL);
    tl_expect_error(&r, 2, "extinction");
    r = tl_run("dt-sweep", "--mesh", "no-such-file.obj", "--out", ".", NULL);
    tl_expect_error(&r, 1, "no-such-file.obj");
}

static int setup(void **state)
{
    (void)state;
    if (tl_prog_setup("test_experiment", "/tmp/mcf-experiment-XXXXXX", "lab/mcflab") != 0)
        return -1;
    /* the same lookup the tool does (execlp on the PATH) */
    have_gnuplot = system("command -v gnuplot >/dev/null 2>&1") == 0;
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    return tl_mcf_teardown();
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_order),         cmocka_unit_test(test_stability),
        cmocka_unit_test(test_dt_sweep),      cmocka_unit_test(test_fixed_time_file),
        cmocka_unit_test(test_sphere),        cmocka_unit_test(test_no_gnuplot),
        cmocka_unit_test(test_usage),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
