/* SPDX-License-Identifier: MIT */
/*
 * recovery.c - the job service at start: every job of the store back
 * into the table. Queued jobs, and jobs that were running when the
 * process died, go back to the queue in their original order (created,
 * then ID) with their IDs; a job canceled while it ran stays canceled;
 * finished jobs are served again until their TTL runs out; jobs without
 * a state.json (a crash before the job was acknowledged) are removed;
 * acknowledged ones whose state or request is damaged, or whose result is
 * not the size recorded, are quarantined (never deleted, never served).
 * A finished job's progress events are read from the store, as before the
 * restart. Reading and parsing hold no lock: no worker runs yet.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "svc_internal.h"

typedef struct {
    svc_t *s;
    svc_job **queued;          /* jobs to queue again, in any order */
    int n, cap;
    int restored, dropped, quarantined;
} recover_ctx;

static int by_created(const void *a, const void *b)
{
    const svc_job *x = *(svc_job *const *)a, *y = *(svc_job *const *)b;
    if (x->created != y->created)
        return x->created < y->created ? -1 : 1;
    return strcmp(x->id, y->id);
}

static int valid_id(const char *id)
{
    size_t i;
    for (i = 0; id[i]; i++)
        if (!((id[i] >= '0' && id[i] <= '9') || (id[i] >= 'a' && id[i] <= 'f')))
            return 0;
    return i == SVC_ID_LEN;
}

/* An acknowledged job whose blobs are damaged is kept for a person to
 * look at, never deleted (its result may be intact), and never served. */
static void quarantine(recover_ctx *rc, const char *id, const char *why)
{
    svc_store *st = rc->s->store;

    if (st->ops->quarantine(st, id) == 0)
        srv_logf(SRV_LOG_ERROR, "spool: job %s moved to %s/quarantine: %s",
                 id, rc->s->cfg.spool, why);
    else
        srv_logf(SRV_LOG_ERROR, "spool: job %s is damaged (%s) and could not "
                 "be moved to quarantine (%s); not loaded", id, why,
                 strerror(errno));
    rc->quarantined++;
}

/* A succeeded job's result has the size state.json records (when it
 * records one: spools from before result_bytes), and its metrics.json is
 * there. */
static int result_intact(svc_store *st, const svc_state_rec *r)
{
    size_t size;

    if (!r->result_name[0])
        return 1; /* nothing recorded to check against */
    if (st->ops->stat(st, r->id, r->result_name, &size) != 0 ||
        (r->result_len > 0 && size != r->result_len))
        return 0;
    return st->ops->stat(st, r->id, "metrics.json", &size) == 0;
}

/* A finished job's progress events, when its run left them whole in the
 * store (svc_job.c: events.idx's last end is events.ndjson's size); else
 * it has none, as when they could not be written; -1 when the store
 * cannot say now (a shared store down or reconnecting). */
int svc__events_stored(svc_store *st, const char *id, int *n, size_t *bytes)
{
    size_t si, sd, last;

    if (st->ops->stat(st, id, "events.idx", &si) != 0 ||
        st->ops->stat(st, id, "events.ndjson", &sd) != 0)
        return errno == ENOENT ? 0 : -1;
    if (si == 0 || si % sizeof last != 0 || sd > SVC_EVENTS_MAX ||
        si / sizeof last > sd)
        return 0;
    if (st->ops->get_at(st, id, "events.idx", si - sizeof last, &last,
                        sizeof last) != 0)
        return errno == ENOENT || errno == EIO ? 0 : -1;
    if (last != sd)
        return 0;
    *n = (int)(si / sizeof last);
    *bytes = last;
    return 1;
}

int svc__load(svc_t *s, const char *id, svc_job **j, svc_state_rec *r)
{
    svc_store *st = s->store;
    char *state = NULL, *req = NULL, *shown = NULL;
    size_t len;
    cJSON *so = NULL, *ro = NULL;
    int rc = -2, e = 0;

    *j = NULL;
    if (st->ops->get(st, id, "state.json", &state, &len) != 0)
        return errno == ENOENT ? 1 : -1;
    if (!(*j = svc__job_new(s))) {
        free(state);
        return -1;
    }
    snprintf((*j)->id, sizeof (*j)->id, "%s", id);
    if (st->ops->get(st, id, "request.json", &req, &len) != 0 &&
        (e = errno) != ENOENT)
        rc = -1;               /* the store cannot say now: not damaged */
    else if (req && (so = cJSON_Parse(state)) && (ro = cJSON_Parse(req)) &&
        svc__state_parse(so, r, &shown) == 0) {
        /* the parameters shown are the ones recorded at submission */
        (*j)->params_json = shown;
        shown = NULL;
        if (svc__request_load(*j, ro, &s->cfg.lim) == 0)
            rc = 0;
    }
    snprintf(r->id, sizeof r->id, "%s", id);
    free(shown);
    cJSON_Delete(so);
    cJSON_Delete(ro);
    free(state);
    free(req);
    errno = e;
    return rc;
}

static void recover_one(const char *id, void *arg)
{
    recover_ctx *rc = arg;
    svc_t *s = rc->s;
    svc_store *st = s->store;
    svc_state_rec r;
    svc_job *j;
    int k;

    if (!valid_id(id))
        return; /* not ours: leave it alone */
    k = svc__load(s, id, &j, &r);
    if (k == 1) {
        /* Never acknowledged (a crash before state.json, the last blob a
         * submission writes). */
        srv_logf(SRV_LOG_WARN, "spool: removing incomplete job %s", id);
        st->ops->remove(st, id);
        rc->dropped++;
    } else if (k == -1) {
        srv_logf(SRV_LOG_ERROR, "spool: cannot read job %s (left as it is, "
                 "loaded at the next start): %s", id, strerror(errno));
    } else if (k == -2) {
        quarantine(rc, id, "its state.json or request.json is damaged");
    } else if (r.status == SVC_JOB_SUCCEEDED && !result_intact(st, &r)) {
        quarantine(rc, id, "its result or metrics are missing or not the "
                   "size its state.json records");
    } else if (svc_job_status_terminal(r.status) &&
               srv_wall() - r.finished >= s->cfg.result_ttl) {
        st->ops->remove(st, id);
    } else {
        j->disk_bytes = st->ops->usage(st, id);
        if (!svc__recovered(j, &r)) { /* finished: served until its TTL */
            if (svc_job_status_terminal(r.status))
                svc__events_stored(st, id, &j->nevents, &j->events_disk);
            pthread_mutex_lock(&s->mu);
            svc__table_insert(s, j);
            pthread_mutex_unlock(&s->mu);
            rc->restored++;
            return;
        }
        if (rc->n == rc->cap) {
            int ncap = rc->cap ? 2 * rc->cap : 64;
            void *p = realloc(rc->queued, (size_t)ncap * sizeof *rc->queued);
            if (p) {
                rc->queued = p;
                rc->cap = ncap;
            }
        }
        if (rc->n < rc->cap) {
            rc->queued[rc->n++] = j;
            return;
        }
        srv_logf(SRV_LOG_ERROR, "spool: out of memory loading job %s", id);
    }
    if (j)
        svc__job_free(j);
}

int svc__recover(svc_t *s, char *msg, size_t msgsize)
{
    recover_ctx rc;
    int i, failed;

    if (s->store->ops->shared)
        return 0; /* the store's reaper hands over what a replica left */
    memset(&rc, 0, sizeof rc);
    rc.s = s;
    failed = s->store->ops->scan(s->store, recover_one, &rc) != 0;
    if (failed)
        snprintf(msg, msgsize, "cannot list the spool %s: %s", s->cfg.spool,
                 strerror(errno));
    if (rc.n > 1)
        qsort(rc.queued, (size_t)rc.n, sizeof *rc.queued, by_created);
    for (i = 0; i < rc.n; i++) {
        svc_job *j = rc.queued[i];
        pthread_mutex_lock(&s->mu);
        svc__table_insert(s, j);
        s->queued++;
        pthread_mutex_unlock(&s->mu);
        s->store->ops->push(s->store, j->id, 0);
    }
    free(rc.queued);
    if (rc.n || rc.restored || rc.dropped || rc.quarantined)
        srv_logf(SRV_LOG_INFO, "spool %s: %d jobs queued again, %d finished "
                 "jobs restored, %d incomplete removed, %d damaged moved to "
                 "quarantine", s->cfg.spool, rc.n, rc.restored, rc.dropped,
                 rc.quarantined);
    return failed ? -1 : 0;
}
