/* SPDX-License-Identifier: MIT */
/*
 * svc_admit.c - admission of the job service's jobs to memory and cores.
 * Memory: each job carries an estimate of its
 * peak memory (api_estimate_memory, made from what its input declares);
 * one larger than --max-job-memory is refused at submission, and a worker
 * starts the job at the head of the queue only while the estimates of the
 * running jobs plus its own fit in --max-memory (the others wait in the
 * queue, in order). After decoding, the job's estimate is made again from
 * the real counts (polygons split, STL welded) and its reservation grown,
 * waiting for running jobs to finish when it does not fit; a job alone
 * always runs, so a grow can never deadlock. The estimate counts the
 * steps too (their log and progress events: step_bytes).
 *
 * Uploads in flight (both doors) hold reservations in the same budget,
 * of the bytes they buffer (svc_admit_more): a job waits while they fill
 * it, and an upload that does not fit is refused (EBUSY).
 *
 * So the daemon's memory stays within its resting size plus --max-memory
 * as far as the estimates hold (their margin: api_estimate.c; the tested
 * figure: README, reliability). One budget per service, under a mutex of
 * its own, taken last (svc_internal.h's lock order). The estimates:
 * api/api_estimate.c.
 *
 * Cores: a worker claims a job only while one of --cores is free
 * (workers.c); once decoded, a job of MCF_THREADS_MIN vertices or more
 * takes every core no other running job holds for its flow's threads
 * (svc_admit_cores, under the service's mutex: s->cores_held).
 */
#include <math.h>
#include <pthread.h>
#include <time.h>

#include "svc_admit.h"
#include "svc_internal.h"

void svc_admit_init(svc_t *s)
{
    svc_admit_budget *a = &s->admit;
    pthread_mutex_init(&a->mu, NULL);
    pthread_cond_init(&a->freed, NULL);
    a->used = 0;
    a->holders = 0;
}

void svc_admit_destroy(svc_t *s)
{
    pthread_mutex_destroy(&s->admit.mu);
    pthread_cond_destroy(&s->admit.freed);
}

/* What a run's steps hold while it runs: the core's step log (56 B a
 * step) and the events' offsets (8 B, in an array that doubles), and the
 * progress events (an ndjson line of about 110 B each, in a buffer that
 * doubles, SVC_EVENTS_MAX at most). 100,000 steps: 31 MB. */
static double step_bytes(const api_params *p, const api_limits *lim)
{
    double n = api_params_steps(p, lim, NULL), ev;
    if (n > lim->max_iterations) /* time / dt: refused at submission */
        n = lim->max_iterations;
    ev = 240.0 * n;
    if (ev > 2.0 * (double)SVC_EVENTS_MAX)
        ev = 2.0 * (double)SVC_EVENTS_MAX;
    return 72.0 * n + ev;
}

double svc_admit_estimate(const void *input, size_t input_len,
                          size_t target_len, const api_params *p,
                          const api_limits *lim)
{
    api_mem_estimate e;
    api_estimate_memory(input, input_len, p, &e);
    return e.job_bytes + step_bytes(p, lim) +
           (target_len ? 3.0 * (double)target_len + 48.0 * (double)e.vertices
                       : 0);
}

double svc_admit_estimate_counts(int nv, int nf, size_t input_len,
                                 size_t target_len, const api_params *p,
                                 const api_limits *lim)
{
    return api_estimate_job_bytes(nv, nf, input_len, p) + step_bytes(p, lim) +
           (target_len ? 3.0 * (double)target_len + 48.0 * nv : 0);
}

int svc_admit_refuse(const svc_config *cfg, double estimate, svc_error *e)
{
    mcf_error err;
    if (!(estimate > (double)cfg->max_job_memory))
        return 0;
    mcf_error_set(&err, MCF_ELIMIT, "the job's estimated peak memory, %.0f "
                  "MiB, exceeds --max-job-memory %.0f MiB: refused",
                  estimate / 1048576.0,
                  (double)cfg->max_job_memory / 1048576.0);
    svc_error_from_mcf(e, MCF_ELIMIT, API_JOB_RUN, NULL, &err);
    return 1;
}

int svc_admit_try(svc_t *s, double estimate)
{
    svc_admit_budget *a = &s->admit;
    int ok;
    pthread_mutex_lock(&a->mu);
    ok = a->holders == 0 || a->used + estimate <= (double)s->cfg.max_memory;
    if (ok) {
        a->used += estimate;
        a->holders++;
    }
    pthread_mutex_unlock(&a->mu);
    return ok;
}

int svc_admit_more(svc_t *s, double *held, double more)
{
    svc_admit_budget *a = &s->admit;
    int ok;
    pthread_mutex_lock(&a->mu);
    ok = a->holders == (*held > 0 ? 1 : 0) ||
         a->used + more <= (double)s->cfg.max_memory;
    if (ok) {
        if (*held == 0)
            a->holders++;
        a->used += more;
        *held += more;
    }
    pthread_mutex_unlock(&a->mu);
    return ok;
}

int svc_admit_grow(svc_t *s, double *held, double estimate,
                   const mcf_cancel_flag *cancel)
{
    svc_admit_budget *a = &s->admit;
    int rc = 0;
    if (!(estimate > *held))
        return 0;
    pthread_mutex_lock(&a->mu);
    for (;;) {
        double others = a->used - *held;
        struct timespec ts;
        if (a->holders == 1 || others + estimate <= (double)s->cfg.max_memory) {
            a->used += estimate - *held;
            *held = estimate;
            break;
        }
        if (cancel && atomic_load_explicit(cancel, memory_order_acquire)) {
            rc = -1;
            break;
        }
        clock_gettime(CLOCK_REALTIME, &ts); /* pthread_cond_timedwait's clock */
        ts.tv_nsec += 100 * 1000 * 1000;
        if (ts.tv_nsec >= 1000000000L) {
            ts.tv_sec++;
            ts.tv_nsec -= 1000000000L;
        }
        pthread_cond_timedwait(&a->freed, &a->mu, &ts);
    }
    pthread_mutex_unlock(&a->mu);
    return rc;
}

void svc_admit_release(svc_t *s, double held)
{
    svc_admit_budget *a = &s->admit;
    pthread_mutex_lock(&a->mu);
    a->used -= held;
    if (--a->holders <= 0) {
        a->holders = 0;
        a->used = 0;
    }
    pthread_cond_broadcast(&a->freed);
    pthread_mutex_unlock(&a->mu);
}

int svc_admit_cores(svc_job *j, int nv)
{
    svc_t *s = j->svc;
    int n;

    pthread_mutex_lock(&s->mu);
    if (nv >= MCF_THREADS_MIN && s->cores_held < s->cfg.cores) {
        j->cores += s->cfg.cores - s->cores_held;
        s->cores_held = s->cfg.cores;
    }
    n = j->cores;
    pthread_mutex_unlock(&s->mu);
    return n;
}
