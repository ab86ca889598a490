/* SPDX-License-Identifier: MIT */
/*
 * mcf_bigmem.c - large scratch buffers on transparent huge pages where
 * the system gives them: the feature stage's normals, pairs and copies
 * (mcf_feature.c), tens of MB touched a page at a time.
 *
 * A buffer of at least MCF_BIG_MIN bytes is allocated 2 MiB-aligned, its
 * size rounded up to 2 MiB, and advised MADV_HUGEPAGE (Linux; a system
 * with transparent huge pages set to "madvise" or "always" then maps it
 * in 2 MiB pages). Elsewhere, or below the size, it is malloc's. Free it
 * with free(). The contents are malloc's: uninitialized.
 *
 * Why: on the team's machine (a virtual machine, Linux 6.18, THP
 * "madvise") each 4 KiB page's first touch traps to the host, about 10 us;
 * page faults were 9% of the feature stage's samples and 14% of the
 * default request's (perf, couplingdown_sub2.obj normal 0.25 h,
 * 2026-11-29), and the gathers over the pairs miss the TLB.
 */
#define _DEFAULT_SOURCE
#include <stdint.h>
#include <stdlib.h>
#if defined(__linux__)
#include <sys/mman.h>
#endif

#include "mcf_internal.h"

enum { HUGE_PAGE = 2 << 20 };

#if defined(__linux__) && defined(MADV_HUGEPAGE)
/* n * size bytes go on huge pages: from MCF_BIG_MIN on, and when the
 * rounding cannot overflow */
static int is_big(size_t n, size_t size)
{
    return n > 0 && size > 0 && n <= SIZE_MAX / size && n * size >= MCF_BIG_MIN && n * size <= SIZE_MAX - HUGE_PAGE;
}

/* n * size rounded up to whole huge pages */
static size_t big_size(size_t n, size_t size)
{
    return (n * size + HUGE_PAGE - 1) / HUGE_PAGE * HUGE_PAGE;
}
#endif

size_t mcf__big_slack(size_t n, size_t size)
{
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    if (is_big(n, size))
        return big_size(n, size) - n * size;
#endif
    (void)n;
    (void)size;
    return 0;
}

void *mcf__malloc_big(size_t n, size_t size)
{
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    if (is_big(n, size)) {
        size_t r = big_size(n, size);
        void *p = aligned_alloc(HUGE_PAGE, r);
        if (p) {
            (void)madvise(p, r, MADV_HUGEPAGE); /* advice: refused, the pages stay 4 KiB */
            return p;
        }
    }
#endif
    return mcf__malloc(n, size);
}
