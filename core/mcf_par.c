/* SPDX-License-Identifier: MIT */
/*
 * mcf_par.c - a loop over [0, n) split between threads: the passes' and
 * the graph averages' work on big scans (issue 27).
 *
 * The caller names the thread count (mcf_flow_params.threads: the CLI
 * gives its cores, the daemon the cores no other job holds); there is no
 * pool and no global: each call starts nthreads - 1 POSIX threads on
 * contiguous ranges, runs the first range itself and joins them, which
 * costs tens of microseconds against the milliseconds a pass over a
 * large mesh takes (callers run it only above MCF_PAR_MIN items). A thread
 * that cannot be started leaves its range to the caller, so the call
 * never fails. Each range writes only its own items, so the results are
 * those of one thread bit for bit. The threads' CPU (CLOCK_THREAD_CPUTIME_ID,
 * read by each at its end) is added to the caller's counter after the
 * join, so a caller that budgets CPU by its own thread's clock can count
 * them too (mcfd's per-job budget, issue 28).
 */
#define _POSIX_C_SOURCE 200809L
#include <pthread.h>
#include <time.h>

#include "mcf_internal.h"

enum { MAX_THREADS = 64 };

typedef struct {
    mcf__par_fn fn;
    void *ctx;
    size_t lo, hi;
    double cpu_s;              /* the thread's CPU seconds, at its end */
} par_range;

static void *run_range(void *arg)
{
    par_range *r = arg;
    r->fn(r->ctx, r->lo, r->hi);
    return NULL;
}

/* A started thread's range, then its whole CPU time (its clock starts
 * with it). */
static void *run_thread(void *arg)
{
    par_range *r = arg;
    struct timespec ts;

    run_range(r);
    if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts) == 0)
        r->cpu_s = (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
    return NULL;
}

void mcf__par_for(int nthreads, double *cpu_s, size_t n, mcf__par_fn fn, void *ctx)
{
    par_range r[MAX_THREADS];
    pthread_t tid[MAX_THREADS];
    int started[MAX_THREADS];
    size_t t, nt;

    if (nthreads > MAX_THREADS)
        nthreads = MAX_THREADS;
    nt = nthreads > 1 && n >= MCF_PAR_MIN ? (size_t)nthreads : 1;
    for (t = 0; t < nt; t++) {
        r[t].fn = fn;
        r[t].ctx = ctx;
        r[t].lo = n * t / nt;
        r[t].hi = n * (t + 1) / nt;
        r[t].cpu_s = 0.0;
    }
    for (t = 1; t < nt; t++)
        started[t] = pthread_create(&tid[t], NULL, run_thread, &r[t]) == 0;
    run_range(&r[0]);
    for (t = 1; t < nt; t++) {
        if (started[t])
            pthread_join(tid[t], NULL);
        else
            run_range(&r[t]); /* on the caller's clock */
        if (cpu_s)
            *cpu_s += r[t].cpu_s;
    }
}
