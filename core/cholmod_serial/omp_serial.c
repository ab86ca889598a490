/*
 * omp_serial.c - serial stand-ins for the three OpenMP entry points that
 * Debian's libcholmod.a calls (GOMP_parallel, omp_get_num_threads,
 * omp_get_thread_num, all from cholmod_super_numeric.o). The Makefile
 * renames CHOLMOD's references to these names (objcopy --redefine-sym)
 * in a private copy of the archive, $(B)/libcholmod_serial.a, and adds
 * this object to it: CHOLMOD runs each parallel region inline, as a team
 * of one, and never reaches libgomp, whose team set-up (allocation, futex
 * calls) cost 45% of a factorization even with OMP_THREAD_LIMIT=1.
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
