/*
 * svc_admit.c - memory admission of the job service's jobs: each job carries an estimate of its
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
 * figure: README, reliability). One mutex of its own, taken inside the
 * service lock when a worker pops the queue (workers.c), never the other
 * way round. The estimates: api/api_estimate.c.
 */
#include <math.h>
#include <pthread.h>
#include <time.h>

#include "svc_admit.h"
#include "svc_internal.h"

static struct {
    pthread_mutex_t mu;
    pthread_cond_t freed;
    double used;               /* sum of the running jobs' reservations */
    int holders;               /* jobs and uploads holding one */
} A = {PTHREAD_MUTEX_INITIALIZER, PTHREAD_COND_INITIALIZER, 0, 0};

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
    svc_error_from_mcf(e, MCF_ELIMIT, SVC_STAGE_RUN, NULL, &err);
    return 1;
}

int svc_admit_try(const svc_config *cfg, double estimate)
{
    int ok;
    pthread_mutex_lock(&A.mu);
    ok = A.holders == 0 || A.used + estimate <= (double)cfg->max_memory;
    if (ok) {
        A.used += estimate;
        A.holders++;
    }
    pthread_mutex_unlock(&A.mu);
    return ok;
}

int svc_admit_more(const svc_config *cfg, double *held, double more)
{
    int ok;
    pthread_mutex_lock(&A.mu);
    ok = A.holders == (*held > 0 ? 1 : 0) || A.used + more <= (double)cfg->max_memory;
    if (ok) {
        if (*held == 0)
            A.holders++;
        A.used += more;
        *held += more;
    }
    pthread_mutex_unlock(&A.mu);
    return ok;
}

int svc_admit_grow(const svc_config *cfg, double *held, double estimate,
                   const mcf_cancel_flag *cancel)
{
    int rc = 0;
    if (!(estimate > *held))
        return 0;
    pthread_mutex_lock(&A.mu);
    for (;;) {
        double others = A.used - *held;
        struct timespec ts;
        if (A.holders == 1 || others + estimate <= (double)cfg->max_memory) {
            A.used += estimate - *held;
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
        pthread_cond_timedwait(&A.freed, &A.mu, &ts);
    }
    pthread_mutex_unlock(&A.mu);
    return rc;
}

void svc_admit_release(double held)
{
    pthread_mutex_lock(&A.mu);
    A.used -= held;
    if (--A.holders <= 0) {
        A.holders = 0;
        A.used = 0;
    }
    pthread_cond_broadcast(&A.freed);
    pthread_mutex_unlock(&A.mu);
}
