/* SPDX-License-Identifier: MIT */
/*
 * svc_shared.c - the job service on a store that several replicas share
 * (store.h, "A store shared by replicas"): a job this replica does not
 * run is the store's, so a reader loads it (a job another replica
 * accepted) or refreshes it (one another replica runs or finished) from
 * its state.json; the sweep refreshes the unfinished ones, follows the
 * progress lines of those running elsewhere (so SSE and WatchJob on any
 * replica follow every run) and passes a cancel asked on another replica
 * to the runs of this one. The status changes themselves are svc_job.c's.
 * Every store call is made without the service lock.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "svc_internal.h"

/* The job's state.json, parsed: 0, or -1 (errno; ENOENT: the job is
 * gone from the store). */
static int read_state(svc_t *s, const char *id, svc_state_rec *r)
{
    svc_store *st = s->store;
    char *text = NULL, *shown = NULL;
    size_t len;
    cJSON *o;
    int rc = -1;

    if (st->ops->get(st, id, "state.json", &text, &len) != 0)
        return -1;
    if ((o = cJSON_Parse(text)) && svc__state_parse(o, r, &shown) == 0)
        rc = 0;
    else
        errno = EIO;
    snprintf(r->id, sizeof r->id, "%s", id);
    free(shown);
    cJSON_Delete(o);
    free(text);
    return rc;
}

/* Applies r to j (a reference held); a job that ends here takes its
 * events from the store at once, so that a follower never sees it ended
 * without them. */
static void apply(svc_t *s, svc_job *j, const svc_state_rec *r)
{
    int n = 0, ended;
    size_t bytes = 0;

    pthread_mutex_lock(&s->mu);
    ended = svc_job_status_terminal(r->status) &&
            !svc_job_status_terminal(j->status) && !j->run_here;
    pthread_mutex_unlock(&s->mu);
    if (ended && !svc__events_stored(s->store, j->id, &n, &bytes))
        n = 0, bytes = 0;
    pthread_mutex_lock(&s->mu);
    svc__remote_state(j, r, n, bytes);
    pthread_mutex_unlock(&s->mu);
}

/* A job of the store the table does not hold: loaded and inserted (or
 * the one another thread inserted meanwhile). A reference, or NULL and
 * errno (ENOENT: the store has no such job; EAGAIN: it cannot say now). */
static svc_job *load_new(svc_t *s, const char *id)
{
    svc_job *n = NULL, *j;
    svc_state_rec r;

    int rc = strlen(id) == SVC_ID_LEN ? svc__load(s, id, &n, &r) : 1;

    if (rc != 0) {
        int e = rc == -1 ? errno : ENOENT;  /* -2: not a job's record */
        if (n)
            svc__job_free(n);
        errno = e;
        return NULL;
    }
    pthread_mutex_lock(&s->mu);
    if (!(j = svc__find_locked(s, id))) {
        j = n;
        n = NULL;
        j->status = SVC_JOB_QUEUED;    /* counted, then r applied */
        svc__table_insert(s, j);
        s->queued++;
    }
    j->refs++;
    pthread_mutex_unlock(&s->mu);
    if (n)
        svc__job_free(n);
    apply(s, j, &r);
    return j;
}

/* j, a job of the table this replica does not run, as the store has it
 * now; out of the table when the store no longer holds it (deleted or
 * expired on another replica). 0, or -1 when it is gone. */
static int refresh(svc_t *s, svc_job *j)
{
    svc_state_rec r;

    if (read_state(s, j->id, &r) == 0) {
        apply(s, j, &r);
        return 0;
    }
    if (errno != ENOENT)
        return 0;              /* the store is down: the last state known */
    pthread_mutex_lock(&s->mu);
    if (j->in_table && !j->run_here)
        svc__table_remove(s, j);
    pthread_mutex_unlock(&s->mu);
    return -1;
}

svc_job *svc__shared_get(svc_t *s, const char *id)
{
    svc_job *j;
    int local;

    pthread_mutex_lock(&s->mu);
    j = svc__find_locked(s, id);
    if (j)
        j->refs++;
    /* the jobs this replica runs are its own; a finished one changes no
     * more (but a deletion elsewhere is seen at its next read) */
    local = j && j->run_here;
    pthread_mutex_unlock(&s->mu);
    if (local) {
        /* its outcome may be in the store (other replicas see it) and
         * not yet published here: svc__finish holds state_mu from the
         * one to the other */
        pthread_mutex_lock(&s->state_mu);
        pthread_mutex_unlock(&s->state_mu);
        return j;
    }
    if (!j)
        return load_new(s, id);
    if (refresh(s, j) != 0) {
        svc_job_unref(j);
        errno = ENOENT;
        return NULL;
    }
    return j;
}

/* ------------------------------------------------------------ the sweep */

typedef struct {
    svc_job **job;
    int n, cap;
} job_list;

/* Lock held: j in the list with a reference. */
static void list_add_locked(job_list *l, svc_job *j)
{
    if (l->n == l->cap) {
        int cap = l->cap ? 2 * l->cap : 16;
        void *p = realloc(l->job, (size_t)cap * sizeof *l->job);
        if (!p)
            return;            /* the next sweep */
        l->job = p;
        l->cap = cap;
    }
    j->refs++;
    l->job[l->n++] = j;
}

static void follow_line(const char *line, size_t len, void *arg)
{
    svc_job *j = arg;

    pthread_mutex_lock(&j->svc->mu);
    svc__remote_progress(j, line, len);
    pthread_mutex_unlock(&j->svc->mu);
}

/* Another replica's job: its state, and its progress lines while it
 * runs there (the cursor is the sweep's alone). */
static void sweep_remote(svc_t *s, svc_job *j)
{
    svc_store *st = s->store;
    int running;

    if (refresh(s, j) != 0)
        return;
    pthread_mutex_lock(&s->mu);
    running = !j->run_here && j->status == SVC_JOB_RUNNING;
    pthread_mutex_unlock(&s->mu);
    if (running)
        st->ops->follow(st, j->id, j->ev_after, follow_line, j);
}

/* A job this replica runs: a cancel asked on another replica
 * (svc__cancel_elsewhere) sets its flag. */
static void sweep_own(svc_t *s, svc_job *j)
{
    svc_store *st = s->store;
    char *text = NULL;
    size_t len;
    int reason = SVC_CANCEL_USER;
    cJSON *o;

    if (st->ops->get(st, j->id, "cancel.json", &text, &len) != 0)
        return;
    if ((o = cJSON_Parse(text))) {
        const cJSON *e = cJSON_GetObjectItemCaseSensitive(o, "reason");
        if (cJSON_IsNumber(e) && (e->valueint == SVC_CANCEL_USER ||
                                  e->valueint == SVC_CANCEL_CLIENT))
            reason = e->valueint;
        cJSON_Delete(o);
    }
    free(text);
    pthread_mutex_lock(&s->mu);
    if (j->run_here && !j->cancel) {
        j->cancel_reason = (svc_cancel_reason)reason;
        j->cancel = 1;
    }
    pthread_mutex_unlock(&s->mu);
}

void svc__shared_sweep(svc_t *s)
{
    job_list remote = {NULL, 0, 0}, own = {NULL, 0, 0};
    svc_job *j;
    int b, i;

    pthread_mutex_lock(&s->mu);
    for (b = 0; b < SVC_NBUCKETS; b++)
        for (j = s->buckets[b]; j; j = j->hnext) {
            if (j->run_here && !j->cancel)
                list_add_locked(&own, j);
            else if (!j->run_here && !svc_job_status_terminal(j->status))
                list_add_locked(&remote, j);
        }
    pthread_mutex_unlock(&s->mu);
    for (i = 0; i < remote.n; i++) {
        sweep_remote(s, remote.job[i]);
        svc_job_unref(remote.job[i]);
    }
    for (i = 0; i < own.n; i++) {
        sweep_own(s, own.job[i]);
        svc_job_unref(own.job[i]);
    }
    free(remote.job);
    free(own.job);
}
