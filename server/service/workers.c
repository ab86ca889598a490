/* SPDX-License-Identifier: MIT */
/*
 * workers.c - the job service's worker pool: plain pthreads that claim
 * jobs from the store's queue in order, start them, run them (runner.c)
 * and record their outcome (svc_job.c); and the drain's wait. Only workers
 * decode, smooth and encode; no other thread touches a mesh.
 *
 * The cores (svc_config.cores: online CPUs unless --cores) are shared
 * without oversubscribing them: a worker claims a job only while a core
 * is free and holds it for the job's run; once decoded, a job of at least
 * MCF_THREADS_MIN vertices also takes every core no other running job
 * holds, for its flow's threads (svc_admit_cores, svc_admit.c), and
 * gives them all back at its end. So a lone big scan runs on every core, and a job that
 * arrives meanwhile waits queued for a core (its position kept) rather
 * than slowing both; small jobs take one core each, as many at once as
 * there are cores and workers.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "svc_internal.h"
#include "svc_admit.h"

/* The store's claim asks whether the head of the queue fits: its memory
 * estimate beside the running jobs' (svc_admit.c). Reserved when it
 * does; a job this service does not hold (removed meanwhile) fits with
 * nothing (the claim is skipped below). */
typedef struct {
    svc_t *s;
    double held;
    int core;                  /* the core it holds (1) once it fits */
} claim_ctx;

/* A core free and the memory: both reserved (1), else neither (0). */
static int fits(void *arg, const char *id)
{
    claim_ctx *c = arg;
    svc_t *s = c->s;
    svc_job *j;
    double est = 0;

    pthread_mutex_lock(&s->mu);
    if (s->cores_held >= s->cfg.cores) {
        pthread_mutex_unlock(&s->mu);
        return 0;
    }
    s->cores_held++;
    j = svc__find_locked(s, id);
    if (j)
        est = j->mem_estimate;
    pthread_mutex_unlock(&s->mu);
    if (!svc_admit_try(s, est)) {
        pthread_mutex_lock(&s->mu);
        s->cores_held--;
        pthread_mutex_unlock(&s->mu);
        return 0;
    }
    c->held = est;
    c->core = 1;
    return 1;
}

/* A claim's reservations given back (a job not run). */
static void unclaim(claim_ctx *c)
{
    svc_admit_release(c->s, c->held);
    pthread_mutex_lock(&c->s->mu);
    c->s->cores_held -= c->core;
    svc__wake_locked(c->s);
    pthread_mutex_unlock(&c->s->mu);
    c->held = 0;
    c->core = 0;
}

/* A job claimed from a shared queue that cannot be loaded: damaged
 * (EBADMSG: its state.json or request.json does not parse) it is moved
 * to quarantine, logged and counted, never run; gone (ENOENT: its records
 * were removed, evicted or lost in a restart of the store) it is logged.
 * Either way its entry leaves the queue: 1 (the caller acknowledges
 * it). 0 when the store cannot say now: the entry stays pending, and the
 * reaper hands it over again after claim_idle. */
static int unloadable(svc_t *s, const char *id, int e)
{
    svc_store *st = s->store;

    if (e == EBADMSG) {
        st->ops->ack(st, id);          /* before its keys are renamed */
        if (st->ops->quarantine(st, id) == 0)
            srv_logf(SRV_LOG_ERROR, "job %s: taken from the queue, but its "
                     "state.json or request.json does not parse: moved to "
                     "quarantine, not run", id);
        else
            srv_logf(SRV_LOG_ERROR, "job %s: taken from the queue, but its "
                     "state.json or request.json does not parse, and it "
                     "could not be moved to quarantine (%s): not run", id,
                     strerror(errno));
        srv_metrics_quarantined();
    } else if (e == ENOENT) {
        srv_logf(SRV_LOG_ERROR, "job %s: taken from the queue, but its "
                 "records are gone from the store (removed, evicted, or "
                 "lost in a restart of a store without persistence): not "
                 "run", id);
    } else {
        return 0;
    }
    return 1;
}

/* Waits on s->work (s->mu held): until woken, or the store's poll. */
static void wait_work_locked(svc_t *s)
{
    double poll = s->store->ops->poll;
    struct timespec ts;

    if (poll <= 0) {
        pthread_cond_wait(&s->work, &s->mu);
        return;
    }
    clock_gettime(CLOCK_REALTIME, &ts);   /* s->work's clock */
    ts.tv_nsec += (long)(poll * 1e9);
    ts.tv_sec += ts.tv_nsec / 1000000000L;
    ts.tv_nsec %= 1000000000L;
    pthread_cond_timedwait(&s->work, &s->mu, &ts);
}

/* The next job to run: claimed, reserved and started, or NULL when the
 * service stops. A shared store's claim also says 2 (taken over from a
 * replica that stopped: its running state is queued again) and 3 (dead:
 * written failed). Waits (on s->work) while it is draining, the queue is
 * empty or its head does not fit. */
static svc_job *next_job(svc_t *s, double *held)
{
    char id[SVC_ID_LEN + 1];
    claim_ctx c = {s, 0, 0};
    unsigned seen;
    svc_job *j;
    int stop, rc, got, done;

    for (;;) {
        pthread_mutex_lock(&s->mu);
        while (!s->stopping && s->draining)
            pthread_cond_wait(&s->work, &s->mu);
        seen = s->wakes;
        stop = s->stopping;
        pthread_mutex_unlock(&s->mu);
        if (stop)
            return NULL;
        c.held = 0;
        c.core = 0;
        got = s->store->ops->claim(s->store, fits, &c, id);
        if (got == 3) {        /* dead-lettered: failed, not run */
            unclaim(&c);
            if ((j = svc_job_get(s, id)))
                svc__dead(j);
            svc_job_unref(j);
            continue;
        }
        if (got == 1 || got == 2) {
            done = 1;
            if (!(j = svc_job_get(s, id)))
                done = unloadable(s, id, errno);
            if (j && got == 2) {   /* taken over: queued again */
                srv_logf(SRV_LOG_INFO, "job %s: taken over from a replica "
                         "that stopped heartbeating", id);
                pthread_mutex_lock(&s->mu);
                svc__retaken_locked(j);
                pthread_mutex_unlock(&s->mu);
            }
            rc = j ? svc__start(j) : -1;
            if (rc == 0) {
                pthread_mutex_lock(&s->mu);
                j->cores = c.core;
                pthread_mutex_unlock(&s->mu);
                svc_job_unref(j); /* svc__start took the worker's */
                *held = c.held;
                return j;
            }
            /* no longer queued (canceled, removed): done with; its cancel
             * being written, or a drain: back at the head, to run should
             * the cancel fail, or after the restart */
            unclaim(&c);
            if (rc < 0 && done)
                s->store->ops->ack(s->store, id);
            else if (rc >= 0)
                s->store->ops->push(s->store, id, 1);
            svc_job_unref(j);
            if (rc < 0)
                continue;
        }
        /* nothing claimable (or the head waits for its cancel): sleep
         * until something changes (a submit, a cancel, a job's or
         * upload's memory freed, drain, stop), or, for a queue other
         * replicas fill, until the next poll */
        pthread_mutex_lock(&s->mu);
        if (!s->stopping && s->wakes == seen)
            wait_work_locked(s);
        pthread_mutex_unlock(&s->mu);
    }
}

static void *worker_main(void *arg)
{
    svc_t *s = arg;
    svc_outcome o;
    svc_job *j;
    double held;

    while ((j = next_job(s, &held)) != NULL) {
        pthread_mutex_lock(&s->mu);
        j->mem_held = held;
        pthread_mutex_unlock(&s->mu);
        svc__run(j, &o);
        svc__finish(j, &o);
        free(o.result);
        free(o.metrics);
        free(o.fields);
        svc_admit_release(s, j->mem_held); /* its memory is free */
        pthread_mutex_lock(&s->mu);
        s->busy--;
        s->cores_held -= j->cores;   /* its cores are free */
        j->cores = 0;
        svc__wake_locked(s);
        pthread_cond_broadcast(&s->idle);
        svc__unref_locked(j);
        pthread_mutex_unlock(&s->mu);
    }
    return NULL;
}

int svc__workers_start(svc_t *s, char *msg, size_t msgsize)
{
    int i, n = s->cfg.workers;

    s->threads = calloc((size_t)n, sizeof *s->threads);
    if (!s->threads) {
        snprintf(msg, msgsize, "out of memory");
        return -1;
    }
    for (i = 0; i < n; i++) {
        if (pthread_create(&s->threads[i], NULL, worker_main, s) != 0) {
            snprintf(msg, msgsize, "cannot start worker %d: %s", i,
                     strerror(errno));
            return -1; /* svc_stop joins the ones started */
        }
        pthread_mutex_lock(&s->mu);
        s->nthreads = i + 1;
        pthread_mutex_unlock(&s->mu);
    }
    return 0;
}

void svc__workers_stop(svc_t *s)
{
    int i;

    pthread_mutex_lock(&s->mu);
    s->stopping = 1;
    svc__wake_locked(s);
    pthread_mutex_unlock(&s->mu);
    for (i = 0; i < s->nthreads; i++)
        pthread_join(s->threads[i], NULL);
    free(s->threads);
    s->threads = NULL;
    s->nthreads = 0;
}

int svc_wait_idle(svc_t *s, double timeout)
{
    struct timespec ts;
    double end = srv_mono() + timeout;
    int idle;

    pthread_mutex_lock(&s->mu);
    while (s->busy > 0) {
        double now = srv_mono(); /* idle waits on CLOCK_MONOTONIC */
        if (now >= end)
            break;
        ts.tv_sec = (time_t)end;
        ts.tv_nsec = (long)((end - (double)ts.tv_sec) * 1e9);
        pthread_cond_timedwait(&s->idle, &s->mu, &ts);
    }
    idle = s->busy == 0;
    pthread_mutex_unlock(&s->mu);
    return idle;
}
