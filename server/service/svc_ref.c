/* SPDX-License-Identifier: MIT */
/*
 * svc_ref.c - a job's references and subscriptions in the job service:
 * the job's allocation and its reference count (the last unref frees it),
 * its status names, and the subscribers a change of it is told about
 * (svc__notify, called under the service lock by svc_job.c, which alone
 * changes a job's status). Every list and count here is guarded by the
 * service lock (svc_t.mu).
 */
#include <stdio.h>
#include <stdlib.h>

#include "svc_internal.h"

/* ------------------------------------------------------------ references */

static const char *const status_names[] = {"queued", "running", "succeeded",
                                           "failed", "canceled"};

const char *svc_job_status_name(svc_job_status s)
{
    return (unsigned)s < 5 ? status_names[s] : "unknown";
}

int svc_job_status_terminal(svc_job_status s)
{
    return s == SVC_JOB_SUCCEEDED || s == SVC_JOB_FAILED ||
           s == SVC_JOB_CANCELED;
}

svc_job *svc__job_new(svc_t *s)
{
    svc_job *j = calloc(1, sizeof *j);
    if (!j)
        return NULL;
    j->svc = s;
    j->refs = 1;
    j->status = SVC_JOB_QUEUED;
    api_params_init(&j->params);
    api_buf_init(&j->events, SVC_EVENTS_MAX);
    snprintf(j->scheme, sizeof j->scheme, "unknown");
    snprintf(j->ev_after, sizeof j->ev_after, "0");
    return j;
}

void svc__job_free(svc_job *j)
{
    api_params_free(&j->params);
    free(j->params_json);
    free(j->params_given);
    free(j->result);
    api_buf_free(&j->events);
    free(j->event_end);
    free(j);
}

void svc__unref_locked(svc_job *j)
{
    if (--j->refs == 0)
        svc__job_free(j);
}

void svc_job_unref(svc_job *j)
{
    svc_t *s;
    if (!j)
        return;
    s = j->svc;
    pthread_mutex_lock(&s->mu);
    svc__unref_locked(j);
    pthread_mutex_unlock(&s->mu);
}

svc_job *svc_job_ref(svc_job *j)
{
    pthread_mutex_lock(&j->svc->mu);
    j->refs++;
    pthread_mutex_unlock(&j->svc->mu);
    return j;
}

const char *svc_job_id(const svc_job *j)
{
    return j->id;
}

/* ----------------------------------------------------------- subscriptions */

void svc__notify(svc_job *j, unsigned what)
{
    svc_sub *sb;
    for (sb = j->subs; sb; sb = sb->next)
        if (sb->flags & what)
            sb->fn(sb->ctx, what);
}

int svc_subscribe(svc_job *j, unsigned flags, svc_notify_fn fn, void *ctx,
                  svc_sub **sub)
{
    svc_sub *sb = calloc(1, sizeof *sb);

    *sub = NULL;
    if (!sb)
        return -1;
    sb->job = j;
    sb->flags = flags | SVC_NOTIFY_STATE;
    sb->fn = fn;
    sb->ctx = ctx;
    pthread_mutex_lock(&j->svc->mu);
    sb->next = j->subs;
    if (j->subs)
        j->subs->prev = sb;
    j->subs = sb;
    pthread_mutex_unlock(&j->svc->mu);
    *sub = sb;
    return 0;
}

void svc_unsubscribe(svc_sub *sb)
{
    svc_t *s;
    if (!sb)
        return;
    s = sb->job->svc;
    pthread_mutex_lock(&s->mu);
    if (sb->prev)
        sb->prev->next = sb->next;
    else
        sb->job->subs = sb->next;
    if (sb->next)
        sb->next->prev = sb->prev;
    pthread_mutex_unlock(&s->mu);
    free(sb);
}

int svc_followers(const svc_job *j)
{
    const svc_sub *sb;
    int n = 0;

    pthread_mutex_lock(&j->svc->mu);
    for (sb = j->subs; sb; sb = sb->next)
        n += (sb->flags & SVC_NOTIFY_PROGRESS) != 0;
    pthread_mutex_unlock(&j->svc->mu);
    return n;
}
