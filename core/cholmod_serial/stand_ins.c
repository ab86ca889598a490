/* SPDX-License-Identifier: MIT */
/*
 * stand_ins.c - what the private copy of CHOLMOD calls instead of libgomp
 * and of SuiteSparse's clock. The Makefile renames these references in
 * Debian's libcholmod.a (objcopy --redefine-sym) to the functions below,
 * in a copy of the archive, $(B)/libcholmod_serial.a, and adds this object
 * to it.
 *
 * OpenMP: the three entry points cholmod_super_numeric.o calls
 * (GOMP_parallel, omp_get_num_threads, omp_get_thread_num). CHOLMOD runs
 * each parallel region inline, as a team of one, and never reaches
 * libgomp, whose team set-up (allocation, futex calls) for each of the
 * ~150,000 regions of a dragon factorization cost 45% of it even with
 * OMP_THREAD_LIMIT=1.
 *
 * SuiteSparse_time: cholmod_super_numeric.o reads the clock around every
 * BLAS call it makes (four per supernode) for timing statistics in
 * cholmod_common (CHOLMOD_CPU_GEMM_TIME and the like) that mcf never
 * reads: 5% of a factorization of the armadillo. It reads 0 here, so those
 * statistics stay 0.
 *
 * Thread safety: no state at all. A region runs on the thread that opens
 * it, so the workers of mcfd, each factoring its own matrix, run their
 * regions at once without sharing anything. What the stand-ins promise is
 * what a team of one is in OpenMP: the outlined function runs once, sees
 * one thread, its own number 0, and so takes every iteration of each
 * statically scheduled loop (the only kind CHOLMOD 3.0.14 opens: it
 * calls no other libgomp entry point, which the Makefile checks).
 */
void mcf__omp_parallel(void (*fn)(void *), void *data, unsigned num_threads, unsigned flags);
int mcf__omp_get_num_threads(void);
int mcf__omp_get_thread_num(void);
double mcf__suitesparse_time(void);

void mcf__omp_parallel(void (*fn)(void *), void *data, unsigned num_threads, unsigned flags)
{
    (void)num_threads;
    (void)flags;
    fn(data);
}

int mcf__omp_get_num_threads(void)
{
    return 1;
}

int mcf__omp_get_thread_num(void)
{
    return 0;
}

double mcf__suitesparse_time(void)
{
    return 0.0;
}
