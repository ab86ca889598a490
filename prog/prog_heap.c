/* SPDX-License-Identifier: MIT */
/*
 * prog_heap.c - the heap of the programs (mcf, mcfd) on transparent huge
 * pages, set once per process before any work: glibc's tunable
 * glibc.malloc.hugetlb=1 makes malloc ask madvise(MADV_HUGEPAGE) for every
 * piece of heap of 2 MiB or more it takes (the main heap, and each block
 * it maps on its own: a daemon worker's arrays, which live in the worker
 * thread's arena and are mapped anew for each block over 64 MiB), so a big
 * scan's arrays fault in 2 MiB at a time instead of 4 KiB and its gathers
 * miss the TLB less. The 1.74M scan's default request through mcf: 300,211
 * faults -> 1,874, 0.79x the CPU, the same output (lab/bench/README.md,
 * 2026-11-29). The programs' own, not the libraries': glibc reads its
 * tunables when the process starts, so setting one means executing the
 * program again (prog_reexec, once; prog_bound_blas_threads's execution
 * serves both when it happens).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "prog.h"

int prog_heap_huge_pages(void)
{
#ifdef __GLIBC__
    const char *t = getenv("GLIBC_TUNABLES");
    char buf[1024];
    if (t && strstr(t, "glibc.malloc.hugetlb"))
        return 0;
    if (snprintf(buf, sizeof buf, "%s%sglibc.malloc.hugetlb=1", t ? t : "", t && *t ? ":" : "") >= (int)sizeof buf)
        return 0;
    return setenv("GLIBC_TUNABLES", buf, 1) == 0;
#else
    return 0;
#endif
}

void prog_reexec(char **argv)
{
    execv("/proc/self/exe", argv);
    /* no /proc: carry on as the process is */
}
