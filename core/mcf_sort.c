/* SPDX-License-Identifier: MIT */
/*
 * mcf_sort.c - the radix sort behind mesh inspection and the curvature
 * summary: 64-bit keys (edge keys u << 32 | v, packed face keys, doubles
 * mapped to order-preserving integers), with an optional 32-bit payload.
 *
 * Inspection and the curvature summary sort every edge, every face and
 * every vertex's curvature; with qsort those sorts were 70% of the time of
 * measuring a mesh (which the metrics of every job do twice). LSD radix by
 * bytes is O(n) per pass, stable (so results equal the merge sort's), and
 * skips every byte that is the same for all keys: edge keys of a mesh
 * under 16M vertices need at most 6 of the 8 passes. No allocation here:
 * the caller passes the scratch.
 */
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
