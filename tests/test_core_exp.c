/* SPDX-License-Identifier: MIT */
/*
 * test_core_exp.c - exp over an array (core/mcf_exp.c), which the feature
 * stage's range kernel takes:
 *  - against libm's exp (the independent reference) in ulps of libm's
 *    value over the whole domain and densely where the stage uses it;
 *  - the array's lanes (AVX2 where the CPU has it, 8 and 4 at a time, and
 *    the scalar tail) give the scalar function's bits at every length and
 *    offset;
 *  - the clamps at the domain's ends and a NaN.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_internal.h"
#include "testlib.h"

/* |a - b| in units of b's last place */
static double ulps(double a, double b)
{
    return fabs(a - b) / (nextafter(b, INFINITY) - b);
}

/* a deterministic uniform draw in [0, 1) (xorshift64*) */
static double draw(uint64_t *s)
{
    *s ^= *s >> 12;
    *s ^= *s << 25;
    *s ^= *s >> 27;
    return (double)((*s * 2685821657736338717ULL) >> 11) * 0x1.0p-53;
}

/* Within 2 ulp of libm over [-708, 709] (200,000 draws, then the range
 * the feature stage uses, [-17, 0], at 100,000 more, and the points where
 * the reduction's k changes, x = (j + 1/2) ln 2, from both sides). The
 * polynomial's own error is 1/50 ulp (mcf_exp.c); the rest is the
 * rounding of its 14 Horner steps and the reduction, about 1 ulp; libm's
 * exp is within 1 ulp of the true value; so 2 ulp between them.
 * Measured: 1.000 ulp at most (2026-11-29). */
static void test_exp_against_libm(void **state)
{
    enum { NX = 300000 };
    double *x = malloc(sizeof(double) * NX), worst = 0.0, at = 0.0;
    uint64_t s = 88172645463325252ULL;
    (void)state;
    assert_non_null(x);
    for (int i = 0; i < NX; i++)
        x[i] = i < 200000 ? -708.0 + 1417.0 * draw(&s) : -17.0 * draw(&s);
    double *y = malloc(sizeof(double) * NX);
    assert_non_null(y);
    memcpy(y, x, sizeof(double) * NX);
    mcf__exp_array(y, NX);
    for (int i = 0; i < NX; i++) {
        double u = ulps(y[i], exp(x[i]));
        if (u > worst) {
            worst = u;
            at = x[i];
        }
    }
    for (int j = -1020; j <= 1020; j++)
        for (int side = -1; side <= 1; side += 2) {
            double v = (j + 0.5) * 0.69314718055994530942 + side * 1e-12 * (abs(j) + 1);
            if (v < -708.0 || v > 709.0)
                continue;
            double u = ulps(mcf__exp_scalar(v), exp(v));
            if (u > worst) {
                worst = u;
                at = v;
            }
        }
    print_message("exp: worst %.3f ulp against libm, at x = %.17g\n", worst, at);
    assert_true(worst <= 2.0);
    assert_true(mcf__exp_scalar(0.0) == 1.0);
    free(x);
    free(y);
}

/* Every length 0..40 at offsets 0..3 of a buffer: the lanes and the
 * scalar tail give mcf__exp_scalar's bits, and nothing past the length
 * is written. */
static void test_exp_lanes_match_scalar(void **state)
{
    double in[48], out[48];
    uint64_t s = 12345;
    (void)state;
    for (int i = 0; i < 48; i++)
        in[i] = -20.0 * draw(&s) + (i % 7 == 0 ? 3.0 : 0.0);
    for (int off = 0; off < 4; off++)
        for (int n = 0; n + off <= 44; n++) {
            memcpy(out, in, sizeof in);
            mcf__exp_array(out + off, (size_t)n);
            for (int i = 0; i < 48; i++) {
                double want = i >= off && i < off + n ? mcf__exp_scalar(in[i]) : in[i];
                assert_memory_equal(&out[i], &want, sizeof(double));
            }
        }
}

/* Below -708 (and a NaN) the result is exp(-708), above 709 exp(709):
 * finite and normal, never a subnormal's garbage exponent. */
static void test_exp_clamps(void **state)
{
    double v[8] = {-708.0, -709.0, -1e300, -INFINITY, NAN, 709.0, 710.0, INFINITY};
    (void)state;
    mcf__exp_array(v, 8);
    double lo = mcf__exp_scalar(-708.0), hi = mcf__exp_scalar(709.0);
    assert_true(ulps(lo, exp(-708.0)) <= 2.0);
    assert_true(ulps(hi, exp(709.0)) <= 2.0);
    for (int i = 0; i < 5; i++)
        assert_true(v[i] == lo);
    for (int i = 5; i < 8; i++)
        assert_true(v[i] == hi);
    assert_true(mcf__exp_scalar(NAN) == lo);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_exp_against_libm),
        cmocka_unit_test(test_exp_lanes_match_scalar),
        cmocka_unit_test(test_exp_clamps),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
