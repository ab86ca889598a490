/* SPDX-License-Identifier: MIT */
/*
 * mcf_sort.c - the radix sort behind mesh inspection and the curvature
 * summary where their bucket sorts by vertex cannot serve (no scratch;
 * non-finite curvatures): 64-bit keys (edge keys u << 32 | v, packed face keys, doubles
 * mapped to order-preserving integers), with an optional 32-bit payload.
 *
 * Inspection and the curvature summary sort every edge, every face and
 * every vertex's curvature; with qsort those sorts were 70% of the time of
 * measuring a mesh (which the metrics of every job do twice). LSD radix by
 * bytes is O(n) per pass, stable (so results equal the merge sort's), and
 * skips every byte that is the same for all keys: edge keys of a mesh
 * under 16M vertices need at most 6 of the 8 passes. No allocation here:
 * the caller passes the scratch. mcf__median: the median by selection
 * (the two middle order statistics a sort would put there, in linear
 * time; the noise estimate and the spike repair take medians of every
 * vertex's value: with qsort 9% of the default request's CPU on a 1.74M
 * scan, issue 27); mcf__percentile the same for a percentile (the
 * curvature summary's).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_internal.h"

void mcf__radix_sort_u64(uint64_t *key, uint32_t *val, size_t n, uint64_t *tk,
                         uint32_t *tv)
{
    size_t count[8][256], i;
    uint64_t *src = key, *dst = tk;
    uint32_t *sv = val, *dv = tv;
    int b;

    if (n < 2)
        return;
    memset(count, 0, sizeof count);
    for (i = 0; i < n; i++)
        for (b = 0; b < 8; b++)
            count[b][(key[i] >> (8 * b)) & 0xff]++;
    for (b = 0; b < 8; b++) {
        size_t off[256], sum = 0;
        int d;
        uint64_t *t;
        uint32_t *u;
        /* one digit for every key: this pass would copy them in order */
        if (count[b][(key[0] >> (8 * b)) & 0xff] == n)
            continue;
        for (d = 0; d < 256; d++) {
            off[d] = sum;
            sum += count[b][d];
        }
        for (i = 0; i < n; i++) {
            size_t p = off[(src[i] >> (8 * b)) & 0xff]++;
            dst[p] = src[i];
            if (sv)
                dv[p] = sv[i];
        }
        t = src; src = dst; dst = t;
        u = sv; sv = dv; dv = u;
    }
    if (src != key) {
        memcpy(key, src, n * sizeof *key);
        if (val)
            memcpy(val, sv, n * sizeof *val);
    }
}

uint64_t mcf__double_key(double x)
{
    uint64_t u;
    if (x == 0)
        x = 0; /* -0 sorts as +0, as a comparison would have it */
    memcpy(&u, &x, sizeof u);
    return (u >> 63) ? ~u : u | ((uint64_t)1 << 63);
}

double mcf__key_double(uint64_t u)
{
    double x;
    u = (u >> 63) ? u & ~((uint64_t)1 << 63) : ~u;
    memcpy(&x, &u, sizeof x);
    return x;
}

/* Exchanges v[a] and v[b]. */
static void swap_d(double *v, size_t a, size_t b)
{
    double t = v[a];
    v[a] = v[b];
    v[b] = t;
}

static int cmp_d(const void *x, const void *y)
{
    double a = *(const double *)x, b = *(const double *)y;
    return (a > b) - (a < b);
}

/* Insertion sort of v[lo..hi] (inclusive): the short ranges. */
static void insertion_sort(double *v, size_t lo, size_t hi)
{
    for (size_t a = lo + 1; a <= hi; a++) {
        double x = v[a];
        size_t b = a;
        for (; b > lo && v[b - 1] > x; b--)
            v[b] = v[b - 1];
        v[b] = x;
    }
}

/* Puts the k-th smallest of v[0..n) at v[k], the smaller ones before it
 * and the others after it (k < n). Hoare's selection with the median of
 * three as pivot; past 2 log2(n) + 8 rounds (an adversarial order) the
 * range left is sorted (qsort) instead, so the time stays O(n log n) at worst. */
static void select_kth(double *v, size_t n, size_t k)
{
    size_t lo = 0, hi = n - 1;
    int budget = 8;
    for (size_t m = n; m > 1; m >>= 1)
        budget += 2;
    while (hi - lo > 16) {
        if (budget-- == 0) {
            qsort(v + lo, hi - lo + 1, sizeof *v, cmp_d); /* adversarial order only */
            return;
        }
        size_t mid = lo + (hi - lo) / 2;
        /* the median of three: the smallest at lo and the largest at hi
         * (sentinels for the scans below), the pivot between */
        if (v[mid] < v[lo])
            swap_d(v, mid, lo);
        if (v[hi] < v[lo])
            swap_d(v, hi, lo);
        if (v[hi] < v[mid])
            swap_d(v, hi, mid);
        swap_d(v, mid, lo + 1); /* the pivot at lo + 1 */
        double pv = v[lo + 1];
        size_t i = lo + 1, j = hi;
        for (;;) {
            do
                i++;
            while (v[i] < pv);
            do
                j--;
            while (v[j] > pv);
            if (i >= j)
                break;
            swap_d(v, i, j);
        }
        swap_d(v, lo + 1, j); /* the pivot at j: v[lo..j) <= pv <= v(j..hi] */
        if (j == k)
            return;
        if (k < j)
            hi = j - 1;
        else
            lo = j + 1;
    }
    insertion_sort(v, lo, hi);
}

double mcf__median(double *v, size_t n)
{
    if (n == 0)
        return 0.0;
    size_t h = n / 2;
    select_kth(v, n, h);
    if (n % 2)
        return v[h];
    /* the other middle value: the largest of those before v[h] */
    double a = v[0];
    for (size_t i = 1; i < h; i++)
        if (v[i] > a)
            a = v[i];
    return 0.5 * (a + v[h]);
}

double mcf__percentile(double *v, size_t n, double q)
{
    if (n == 0)
        return 0.0;
    double pos = q * (double)(n - 1), fl = floor(pos);
    size_t lo = (size_t)fl;
    if (lo + 1 >= n)
        lo = n - 1;
    select_kth(v, n, lo);
    if (lo + 1 >= n)
        return v[lo];
    /* the next order statistic: the least of those after v[lo] */
    double b = v[lo + 1];
    for (size_t i = lo + 2; i < n; i++)
        if (v[i] < b)
            b = v[i];
    return v[lo] + (pos - fl) * (b - v[lo]);
}
