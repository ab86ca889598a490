/* SPDX-License-Identifier: MIT */
/*
 * prog_threads.c - the thread count of the BLAS under libmcf, set once per
 * process by the programs (mcf, mcfd) before any work. The programs' own,
 * not the libraries': it re-executes the process.
 *
 * The policy: one BLAS thread per job. The daemon's workers are its
 * parallelism (one per core), and a factorization of a scanned surface is
 * ~50,000 small supernodes (8.7 columns on average on the dragon) where a
 * second OpenBLAS thread finds nothing to share: measured on a dragon
 * step, 2 threads cost 1.34x the CPU time of one and 1.49x the wall time
 * on the machine as it was (load 6 on 2 cores), 1.39x and 4.79x beside two
 * more busy processes (bench_core --threads, bench/README.md). So both
 * programs set it to 1 unless the environment says otherwise
 * (OPENBLAS_NUM_THREADS, or the others below). CHOLMOD opens no threads
 * (the Makefile links a copy without OpenMP). OpenBLAS reads its variables
 * when it is loaded, before main, so setting them means executing the
 * program again, once.
 */
#include <stdlib.h>
#include <unistd.h>

#include "prog.h"

void prog_bound_blas_threads(char **argv)
{
    static const char *const blas[] = {"OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS",
                                       "GOTO_NUM_THREADS", "MKL_NUM_THREADS"};
    int changed = 0;

    for (size_t i = 0; i < sizeof blas / sizeof blas[0]; i++)
        if (!getenv(blas[i])) {
            setenv(blas[i], "1", 1);
            changed = 1;
        }
    if (changed && !getenv("MCF_REEXECED")) {
        setenv("MCF_REEXECED", "1", 1);
        execv("/proc/self/exe", argv);
        /* no /proc: carry on with the libraries' defaults */
    }
}
