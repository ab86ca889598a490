/*
 * api_threads.c - the thread counts of the libraries under libmcf, set once
 * per process by the programs (mcf, mcfd) before any work.
 *
 * CHOLMOD's supernodal factorization opens OpenMP regions with an explicit
 * num_threads(4), which OMP_NUM_THREADS does not cap: on a 2-core machine
 * those regions oversubscribe the cores and the dragon's factorization
 * took 0.84-0.88 s instead of 0.47 s (measured; the regions are small, so
 * 2 threads gain nothing either). OMP_THREAD_LIMIT caps them. libgomp and
 * OpenBLAS read their variables when they are loaded, before main, so
 * setting them means executing the program again, once.
 */
#include <stdlib.h>
#include <unistd.h>

#include "api_internal.h"

void api_bound_library_threads(char **argv, int blas_too)
{
    static const char *const blas[] = {"OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS",
                                       "GOTO_NUM_THREADS", "MKL_NUM_THREADS"};
    int changed = 0;

    if (!getenv("OMP_THREAD_LIMIT")) {
        setenv("OMP_THREAD_LIMIT", "1", 1);
        changed = 1;
    }
    for (size_t i = 0; blas_too && i < sizeof blas / sizeof blas[0]; i++)
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
