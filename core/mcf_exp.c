/* SPDX-License-Identifier: MIT */
/*
 * mcf_exp.c - exp over an array, four lanes at a time where the CPU has
 * AVX2: the feature stage's range kernel (mcf_feature.c) takes one exp a
 * pair of neighbouring faces and normal iteration, 43 million on
 * couplingdown_sub2.obj's 59,424 faces, where libm's scalar exp was 25%
 * of the default request's CPU (perf, 2026-11-29).
 *
 * exp(x) = 2^k exp(r), k = x / ln 2 rounded to nearest (the 1.5 2^52
 * trick), r = x - k ln 2 in two parts (fdlibm's ln2_hi, whose trailing
 * zeros make k ln2_hi exact for |k| < 2^20, and ln2_lo), |r| <= ln 2 / 2;
 * exp(r) by its Taylor polynomial to r^13 in Horner's form: the first
 * term left out, r^14 / 14! < 4e-18 for |r| <= 0.347, is 1/50 of an ulp;
 * 2^k put into the exponent's bits. The AVX2 lanes make the scalar
 * loop's operations in its order, with no fused multiply-add (C11 does
 * not contract a * b + c), so both give the same bits on any machine.
 * Measured against libm (tests/test_core_exp.c): within 1 ulp over
 * [-708, 709] (the test allows 2).
 *
 * Pure C11; no globals.
 */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "mcf_internal.h"

/* the domain: below X_LO 2^k leaves the normal range (the result is
 * exp(X_LO), 3.3e-308, for any x below it), above X_HI exp overflows */
#define X_LO -708.0
#define X_HI 709.0

static const double LOG2E = 1.4426950408889634074;
static const double LN2_HI = 6.93147180369123816490e-01; /* 0x3fe62e42fee00000 */
static const double LN2_LO = 1.90821492927058770002e-10; /* 0x3dea39ef35793c76 */
static const double ROUNDER = 6755399441055744.0;        /* 1.5 2^52 */
/* 1 / j!, j = 13 .. 2 (the polynomial's highest first; 1 and 1 after) */
static const double INVFACT[12] = {1.0 / 6227020800.0, 1.0 / 479001600.0, 1.0 / 39916800.0, 1.0 / 3628800.0,
                                   1.0 / 362880.0,     1.0 / 40320.0,     1.0 / 5040.0,     1.0 / 720.0,
                                   1.0 / 120.0,        1.0 / 24.0,        1.0 / 6.0,        1.0 / 2.0};

static double exp1(double x)
{
    x = x >= X_LO ? x : X_LO; /* a NaN too, as the AVX2 lanes' max */
    x = x <= X_HI ? x : X_HI;
    double t = x * LOG2E + ROUNDER, k = t - ROUNDER;
    double r = (x - k * LN2_HI) - k * LN2_LO, p = INVFACT[0];
    for (int j = 1; j < 12; j++)
        p = p * r + INVFACT[j];
    p = p * r + 1.0;
    p = p * r + 1.0;
    int64_t bits = ((int64_t)k + 1023) << 52;
    double s;
    memcpy(&s, &bits, sizeof s);
    return p * s;
}

#if defined(__GNUC__) && defined(__x86_64__)
#define EXP_AVX2 1
#include <immintrin.h>

/* 2^k from t = k + 1.5 2^52: t's low bits hold k + 2^51, exactly */
__attribute__((target("avx2"), always_inline)) static inline __m256d scale(__m256d t, __m256d rnd, __m256i bias)
{
    __m256i k = _mm256_sub_epi64(_mm256_castpd_si256(t), _mm256_castpd_si256(rnd));
    return _mm256_castsi256_pd(_mm256_slli_epi64(_mm256_add_epi64(k, bias), 52));
}

__attribute__((target("avx2"))) static void exp_avx2(double *x, size_t n)
{
    const __m256d lo = _mm256_set1_pd(X_LO), hi = _mm256_set1_pd(X_HI), l2e = _mm256_set1_pd(LOG2E);
    const __m256d rnd = _mm256_set1_pd(ROUNDER), ln2h = _mm256_set1_pd(LN2_HI), ln2l = _mm256_set1_pd(LN2_LO);
    const __m256d one = _mm256_set1_pd(1.0);
    const __m256i bias = _mm256_set1_epi64x(1023);
    /* two vectors at a time: the polynomial is a chain of 28 dependent
     * operations, which one vector leaves waiting on their latency */
    size_t i = 0;
    for (; i + 8 <= n; i += 8) {
        __m256d v[2], t[2], r[2], p[2];
        for (int h = 0; h < 2; h++) {
            v[h] = _mm256_min_pd(_mm256_max_pd(_mm256_loadu_pd(x + i + 4 * h), lo), hi);
            t[h] = _mm256_add_pd(_mm256_mul_pd(v[h], l2e), rnd);
            __m256d k = _mm256_sub_pd(t[h], rnd);
            r[h] = _mm256_sub_pd(_mm256_sub_pd(v[h], _mm256_mul_pd(k, ln2h)), _mm256_mul_pd(k, ln2l));
            p[h] = _mm256_set1_pd(INVFACT[0]);
        }
        for (int j = 1; j < 12; j++) {
            __m256d c = _mm256_set1_pd(INVFACT[j]);
            p[0] = _mm256_add_pd(_mm256_mul_pd(p[0], r[0]), c);
            p[1] = _mm256_add_pd(_mm256_mul_pd(p[1], r[1]), c);
        }
        for (int h = 0; h < 2; h++) {
            p[h] = _mm256_add_pd(_mm256_mul_pd(p[h], r[h]), one);
            p[h] = _mm256_add_pd(_mm256_mul_pd(p[h], r[h]), one);
            _mm256_storeu_pd(x + i + 4 * h, _mm256_mul_pd(p[h], scale(t[h], rnd, bias)));
        }
    }
    for (; i + 4 <= n; i += 4) {
        /* max/min as the scalar clamps (a NaN gives lo: max takes its
         * second operand when one is a NaN) */
        __m256d v = _mm256_min_pd(_mm256_max_pd(_mm256_loadu_pd(x + i), lo), hi);
        __m256d t = _mm256_add_pd(_mm256_mul_pd(v, l2e), rnd), k = _mm256_sub_pd(t, rnd);
        __m256d r = _mm256_sub_pd(_mm256_sub_pd(v, _mm256_mul_pd(k, ln2h)), _mm256_mul_pd(k, ln2l));
        __m256d p = _mm256_set1_pd(INVFACT[0]);
        for (int j = 1; j < 12; j++)
            p = _mm256_add_pd(_mm256_mul_pd(p, r), _mm256_set1_pd(INVFACT[j]));
        p = _mm256_add_pd(_mm256_mul_pd(p, r), one);
        p = _mm256_add_pd(_mm256_mul_pd(p, r), one);
        _mm256_storeu_pd(x + i, _mm256_mul_pd(p, scale(t, rnd, bias)));
    }
}
#endif

void mcf__exp_array(double *x, size_t n)
{
    size_t i = 0;
#if defined(EXP_AVX2)
    if (__builtin_cpu_supports("avx2")) {
        exp_avx2(x, n);
        i = n / 4 * 4;
    }
#endif
    for (; i < n; i++)
        x[i] = exp1(x[i]);
}

double mcf__exp_scalar(double x)
{
    return exp1(x);
}
