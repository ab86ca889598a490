/* SPDX-License-Identifier: MIT */
/*
 * svc_shared.c - the job service on a store that several replicas share
 * (store.h, "A store shared by replicas"): a job this replica does not
 * run is the store's, so a reader loads it (a job another replica
 * accepted) or refreshes it (one another replica runs or finished) from
 * its state.json; the sweep refreshes the unfinished ones, follows the
 * progress lines of those running elsewhere (so SSE and WatchJob on any
 * replica follow every run) and passes a cancel asked on another replica
 * to the runs of this one. The follower thread does the same as it
 * happens (the store's watch: a blocking read) for the jobs followed
 * here and the cancels of this replica's runs; the sweep stays the
 * fallback. The status changes themselves are svc_job.c's.
 * Every store call is made without the service lock.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

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
 * without them: when the store cannot say now what they are (Redis
 * just back, this connection still in its backoff), a job held running
 * stays so until a later refresh (the sweep's, a second on) instead of
 * ending without its events for good; one loaded now (loaded) ends
 * with none. */
static void apply(svc_t *s, svc_job *j, const svc_state_rec *r, int loaded)
{
    int n = 0, ended, k = 0;
    size_t bytes = 0;

    pthread_mutex_lock(&s->mu);
    ended = svc_job_status_terminal(r->status) &&
            !svc_job_status_terminal(j->status) && !j->run_here;
    pthread_mutex_unlock(&s->mu);
    if (ended && (k = svc__events_stored(s->store, j->id, &n, &bytes)) < 0 &&
        !loaded)
        return;
    if (ended && k <= 0)
        n = 0, bytes = 0;
    pthread_mutex_lock(&s->mu);
    svc__remote_state(j, r, n, bytes);
    pthread_mutex_unlock(&s->mu);
}

/* A job of the store the table does not hold: loaded and inserted (or
 * the one another thread inserted meanwhile). A reference, or NULL and
 * errno (ENOENT: the store has no such job; EBADMSG: its state.json or
 * request.json does not parse; EAGAIN: it cannot say now). */
static svc_job *load_new(svc_t *s, const char *id)
{
    svc_job *n = NULL, *j;
    svc_state_rec r;

    int rc = strlen(id) == SVC_ID_LEN ? svc__load(s, id, &n, &r) : 1;

    if (rc != 0) {
        int e = rc == -1 ? errno : rc == -2 ? EBADMSG : ENOENT;
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
    apply(s, j, &r, 1);
    return j;
}

/* j, a job of the table this replica does not run, as the store has it
 * now; out of the table when the store no longer holds it (deleted or
 * expired on another replica). 0, or -1 when it is gone. */
static int refresh(svc_t *s, svc_job *j)
{
    svc_state_rec r;

    if (read_state(s, j->id, &r) == 0) {
        apply(s, j, &r, 0);
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
 * runs there, unless the follower thread reads them (the cursor is one
 * thread's at a time: following). */
static void sweep_remote(svc_t *s, svc_job *j)
{
    svc_store *st = s->store;
    int running;

    if (refresh(s, j) != 0)
        return;
    pthread_mutex_lock(&s->mu);
    running = !j->run_here && j->status == SVC_JOB_RUNNING && !j->following;
    j->following |= running;
    pthread_mutex_unlock(&s->mu);
    if (!running)
        return;
    st->ops->follow(st, j->id, j->ev_after, follow_line, j);
    pthread_mutex_lock(&s->mu);
    j->following = 0;
    pthread_mutex_unlock(&s->mu);
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

/* ---------------------------------------------------------- the follower */

/* The jobs of one watch: a new watcher is picked up when it ends; the
 * store answers as soon as an entry comes (a step, a change of state, a
 * cancel for this replica), so this bounds no follower's lag, only the
 * first read for a new one. Five commands a second per replica when
 * idle. */
#define FOLLOW_BLOCK 0.2
/* after a failed watch (Redis down: the connection's backoff answers at
 * once until its next attempt) */
#define FOLLOW_RETRY 0.25

typedef struct {
    svc_t *s;
    svc_job *job[SVC_WATCH_MAX];
    const char *id[SVC_WATCH_MAX];
    char after[SVC_WATCH_MAX][SVC_CURSOR_LEN];
    int n;
} watch_set;

/* A cancel asked on another replica of job id, which this replica
 * runs: its flag set now, not at the next sweep. */
static void cancel_asked(svc_t *s, const char *id, size_t len)
{
    char key[SVC_ID_LEN + 1];
    svc_job *j;

    if (len != SVC_ID_LEN)
        return;
    memcpy(key, id, len);
    key[len] = 0;
    pthread_mutex_lock(&s->mu);
    if ((j = svc__find_locked(s, key)) && j->run_here && !j->cancel)
        j->refs++;
    else
        j = NULL;
    pthread_mutex_unlock(&s->mu);
    if (j) {
        sweep_own(s, j);
        svc_job_unref(j);
    }
}

/* One entry of job i's stream: a mark (its state changed: read at once,
 * so a follower sees the run start and end without waiting for the
 * sweep) or a progress line (one of a run this replica still thinks
 * queued: its state first, the run has started). */
static void watched(void *ctx, int i, const char *line, size_t len)
{
    watch_set *w = ctx;
    svc_job *j;
    int queued;

    if (i < 0) {
        cancel_asked(w->s, line, len);
        return;
    }
    j = w->job[i];
    pthread_mutex_lock(&w->s->mu);
    queued = j->status == SVC_JOB_QUEUED;
    pthread_mutex_unlock(&w->s->mu);
    if (!line || queued)
        refresh(w->s, j);
    if (line)
        follow_line(line, len, j);
}

/* Lock held: the jobs to watch now, taken (following, a reference):
 * another replica's, unfinished, with a subscriber here. Ended jobs and
 * those whose subscribers left drop out at the next round. */
static void watch_take_locked(svc_t *s, watch_set *w)
{
    svc_job *j;
    int b;

    w->n = 0;
    for (b = 0; b < SVC_NBUCKETS && w->n < SVC_WATCH_MAX; b++)
        for (j = s->buckets[b]; j && w->n < SVC_WATCH_MAX; j = j->hnext)
            if (!j->run_here && j->subs && !j->following &&
                !svc_job_status_terminal(j->status)) {
                j->following = 1;
                j->refs++;
                w->job[w->n] = j;
                w->id[w->n] = j->id;
                memcpy(w->after[w->n], j->ev_after, SVC_CURSOR_LEN);
                w->n++;
            }
}

static void watch_give_locked(watch_set *w)
{
    int i;

    for (i = 0; i < w->n; i++) {
        memcpy(w->job[i]->ev_after, w->after[i], SVC_CURSOR_LEN);
        w->job[i]->following = 0;
        svc__unref_locked(w->job[i]);
    }
    w->n = 0;
}

static void wait_locked(svc_t *s, double seconds)
{
    struct timespec ts;

    clock_gettime(CLOCK_MONOTONIC, &ts);
    ts.tv_sec += (time_t)seconds;
    ts.tv_nsec += (long)((seconds - (double)(time_t)seconds) * 1e9);
    if (ts.tv_nsec >= 1000000000L) {
        ts.tv_sec++;
        ts.tv_nsec -= 1000000000L;
    }
    pthread_cond_timedwait(&s->follow_cv, &s->mu, &ts);
}

/* One connection of the store's pool, blocked in the watch most of the
 * time; reconnects are the store's (the next watch after Redis
 * returns). */
static void *follower_main(void *arg)
{
    svc_t *s = arg;
    svc_store *st = s->store;
    watch_set *w = calloc(1, sizeof *w);
    int rc;

    if (!w) {
        srv_logf(SRV_LOG_WARN, "follower: out of memory: progress of "
                 "other replicas' jobs comes with the sweep only");
        return NULL;
    }
    w->s = s;
    pthread_mutex_lock(&s->mu);
    while (!s->follow_stop) {
        watch_take_locked(s, w);
        pthread_mutex_unlock(&s->mu);
        rc = st->ops->watch(st, w->n, w->id, w->after, FOLLOW_BLOCK,
                            watched, w);
        pthread_mutex_lock(&s->mu);
        watch_give_locked(w);
        if (rc < 0 && !s->follow_stop)
            wait_locked(s, FOLLOW_RETRY);
    }
    pthread_mutex_unlock(&s->mu);
    free(w);
    return NULL;
}

int svc__follower_start(svc_t *s, char *msg, size_t msgsize)
{
    pthread_condattr_t ca;

    if (!s->store->ops->shared || !s->store->ops->watch)
        return 0;
    pthread_condattr_init(&ca);
    pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
    pthread_cond_init(&s->follow_cv, &ca);
    pthread_condattr_destroy(&ca);
    if (pthread_create(&s->follower, NULL, follower_main, s) != 0) {
        pthread_cond_destroy(&s->follow_cv);
        snprintf(msg, msgsize, "cannot start the follower thread");
        return -1;
    }
    s->follow_started = 1;
    return 0;
}

void svc__follower_stop(svc_t *s)
{
    if (!s->follow_started)
        return;
    pthread_mutex_lock(&s->mu);
    s->follow_stop = 1;
    pthread_cond_signal(&s->follow_cv);
    pthread_mutex_unlock(&s->mu);
    pthread_join(s->follower, NULL);
    pthread_cond_destroy(&s->follow_cv);
    s->follow_started = 0;
}
