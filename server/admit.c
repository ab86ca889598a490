/*
 * admit.c - memory admission of jobs: each job carries an estimate of its
 * peak memory (api_estimate_memory, made from what its input declares);
 * one larger than --max-job-memory is refused at submission, and a worker
 * starts the job at the head of the queue only while the estimates of the
 * running jobs plus its own fit in --max-memory (the others wait in the
 * queue, in order). After decoding, the job's estimate is made again from
 * the real counts (polygons split, STL welded) and its reservation grown,
 * waiting for running jobs to finish when it does not fit; a job alone
 * always runs, so a grow can never deadlock.
 *
 * So the daemon's memory stays within its resting size plus --max-memory
 * as far as the estimates hold (their margin: api_estimate.c; the tested
 * figure: README, reliability). One mutex of its own, taken inside the
 * job lock when the worker pops the queue, never the other way round.
 */
#include <math.h>

#include "admit.h"

static struct {
    pthread_mutex_t mu;
    pthread_cond_t freed;
    double used;               /* sum of the running jobs' reservations */
    int holders;               /* jobs holding one */
} A = {PTHREAD_MUTEX_INITIALIZER, PTHREAD_COND_INITIALIZER, 0, 0};

int srv_admit_refuse(const srv_config *cfg, double estimate, srv_problem *p)
{
    if (!(estimate > (double)cfg->max_job_memory))
        return 0;
    srv_problem_set(p, 422, "ELIMIT", "the job's estimated peak memory, "
                    "%.0f MiB, exceeds --max-job-memory %.0f MiB: refused",
                    estimate / 1048576.0,
                    (double)cfg->max_job_memory / 1048576.0);
    return 1;
}

int srv_admit_try(const srv_config *cfg, double estimate)
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

int srv_admit_grow(const srv_config *cfg, double *held, double estimate,
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

void srv_admit_release(double held)
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

double srv_admit_used(void)
{
    double u;
    pthread_mutex_lock(&A.mu);
    u = A.used;
    pthread_mutex_unlock(&A.mu);
    return u;
}
