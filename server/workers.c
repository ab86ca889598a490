/*
 * workers.c - the job service's worker pool: plain pthreads that take
 * jobs off the queue in order and run them (runner.c); the waits of a
 * drain (svc_wait_idle) and the checkpoint of running jobs for a restart.
 * Only workers decode, smooth and encode; no other thread touches a mesh.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "svc_internal.h"

static void *worker_main(void *arg)
{
    (void)arg;
    svc__lock();
    for (;;) {
        svc_job *j;
        while (!svc__S.stopping && (svc__S.draining || !svc__S.qhead))
            pthread_cond_wait(&svc__S.work, &svc__S.mu);
        if (svc__S.stopping)
            break;
        j = svc__queue_pop();
        j->refs++;
        j->status = SVC_JOB_RUNNING;
        j->started = srv_wall();
        svc__S.busy++;
        svc__notify(j, SVC_NOTIFY_STATE);
        svc__unlock();
        svc__run_job(j);
        svc__lock();
        svc__S.busy--;
        svc__unref_locked(j);
        pthread_cond_broadcast(&svc__S.idle);
    }
    svc__unlock();
    return NULL;
}

int svc__workers_start(char *msg, size_t msgsize)
{
    int i, n = svc__S.cfg.workers;

    svc__S.threads = calloc((size_t)n, sizeof *svc__S.threads);
    if (!svc__S.threads) {
        snprintf(msg, msgsize, "out of memory");
        return -1;
    }
    for (i = 0; i < n; i++) {
        if (pthread_create(&svc__S.threads[i], NULL, worker_main, NULL) != 0) {
            snprintf(msg, msgsize, "cannot start worker %d: %s", i,
                     strerror(errno));
            svc__lock();
            svc__S.stopping = 1;
            pthread_cond_broadcast(&svc__S.work);
            svc__unlock();
            while (i-- > 0)
                pthread_join(svc__S.threads[i], NULL);
            return -1;
        }
        svc__lock();
        svc__S.nthreads = i + 1;
        svc__unlock();
    }
    return 0;
}

void svc__workers_stop(void)
{
    int i;

    svc__lock();
    svc__S.stopping = 1;
    pthread_cond_broadcast(&svc__S.work);
    svc__unlock();
    for (i = 0; i < svc__S.nthreads; i++)
        pthread_join(svc__S.threads[i], NULL);
    free(svc__S.threads);
    svc__S.threads = NULL;
    svc__S.nthreads = 0;
}

int svc_wait_idle(double timeout)
{
    struct timespec ts;
    double end = srv_mono() + timeout;
    int idle;

    svc__lock();
    while (svc__S.busy > 0) {
        double now = srv_mono(); /* idle waits on CLOCK_MONOTONIC */
        if (now >= end)
            break;
        ts.tv_sec = (time_t)end;
        ts.tv_nsec = (long)((end - (double)ts.tv_sec) * 1e9);
        pthread_cond_timedwait(&svc__S.idle, &svc__S.mu, &ts);
    }
    idle = svc__S.busy == 0;
    svc__unlock();
    return idle;
}

void svc_checkpoint_running(void)
{
    int b;
    svc_job *j;

    svc__lock();
    for (b = 0; b < SVC_NBUCKETS; b++)
        for (j = svc__S.buckets[b]; j; j = j->hnext)
            /* A job its user (or its hung-up client) canceled stays
             * canceled: it is not put back in the queue. */
            if (j->status == SVC_JOB_RUNNING &&
                !(j->cancel && (j->cancel_reason == SVC_CANCEL_USER ||
                                j->cancel_reason == SVC_CANCEL_CLIENT))) {
                j->cancel = 1;
                j->cancel_reason = SVC_CANCEL_SHUTDOWN;
            }
    svc__unlock();
}
