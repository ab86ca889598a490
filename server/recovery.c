/*
 * recovery.c - the job service at start: every job directory of the
 * spool back into the table. Queued jobs, and jobs that were running
 * when the process died, go back to the queue in their original order
 * (created, then ID) with their IDs; a job canceled while it ran stays
 * canceled; finished jobs are served again until their TTL runs out;
 * directories without a state.json (a crash before the job was
 * acknowledged) are removed; acknowledged ones whose state or request is
 * damaged, or whose result is not the size recorded, are moved to
 * <spool>/quarantine (never deleted, never served); temporary files a
 * crash left are removed. A finished job's progress events are read from
 * the spool, as before the restart.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "svc_internal.h"

typedef struct {
    svc_job **queued;
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

/* An acknowledged job whose files are damaged is kept for a person to
 * look at, never deleted (its result may be intact), and never served. */
static void quarantine(recover_ctx *rc, const char *id, const char *why)
{
    if (srv_spool_quarantine(svc__S.cfg.spool, id) == 0)
        srv_logf(SRV_LOG_ERROR, "spool: job %s moved to %s/quarantine: %s",
                 id, svc__S.cfg.spool, why);
    else
        srv_logf(SRV_LOG_ERROR, "spool: job %s is damaged (%s) and could not "
                 "be moved to quarantine (%s); not loaded", id, why,
                 strerror(errno));
    rc->quarantined++;
}

/* A succeeded job's result has the size state.json records (when it
 * records one: spools from before result_bytes), and its metrics.json is
 * there. */
static int result_intact(const svc_job *j)
{
    char path[1400];
    struct stat st;

    if (!j->result_name[0])
        return 1; /* nothing recorded to check against */
    if (srv_spool_path(path, sizeof path, svc__S.cfg.spool, j->id,
                       j->result_name) != 0 || stat(path, &st) != 0 ||
        (j->result_len > 0 && (size_t)st.st_size != j->result_len))
        return 0;
    return srv_spool_path(path, sizeof path, svc__S.cfg.spool, j->id,
                          "metrics.json") == 0 && stat(path, &st) == 0;
}

/* A finished job's progress events, when its run left them whole on the
 * spool (runner.c: events.idx's last end is events.ndjson's size); else
 * it has none, as when they could not be written. */
static void events_recover(svc_job *j)
{
    const char *spool = svc__S.cfg.spool;
    char path[1400];
    struct stat si, sd;
    size_t last;

    if (srv_spool_path(path, sizeof path, spool, j->id, "events.idx") != 0 ||
        stat(path, &si) != 0 || si.st_size <= 0 ||
        si.st_size % (off_t)sizeof last != 0 ||
        srv_spool_path(path, sizeof path, spool, j->id, "events.ndjson") != 0 ||
        stat(path, &sd) != 0 || (size_t)sd.st_size > SVC_EVENTS_MAX ||
        si.st_size / (off_t)sizeof last > (off_t)sd.st_size ||
        srv_spool_read_at(spool, j->id, "events.idx",
                          (size_t)si.st_size - sizeof last, &last,
                          sizeof last) != 0 ||
        last != (size_t)sd.st_size)
        return;
    j->nevents = (int)(si.st_size / (off_t)sizeof last);
    j->events_disk = last;
}

/* Lock held (start-up: no other thread yet). */
static void recover_one(const char *id, void *arg)
{
    recover_ctx *rc = arg;
    const svc_config *cfg = &svc__S.cfg;
    char *state = NULL, *req = NULL;
    size_t len;
    cJSON *so = NULL, *ro = NULL;
    svc_job *j = NULL;

    if (!valid_id(id))
        return; /* not ours: leave it alone */
    srv_spool_clean_tmp(cfg->spool, id); /* writes a crash interrupted */
    if (srv_spool_read(cfg->spool, id, "state.json", &state, &len) != 0) {
        if (errno == ENOENT) {
            /* Never acknowledged (a crash between mkdir and state.json,
             * the last file a submission writes). */
            srv_logf(SRV_LOG_WARN, "spool: removing incomplete job %s", id);
            srv_spool_remove(cfg->spool, id);
            rc->dropped++;
        } else {
            srv_logf(SRV_LOG_ERROR, "spool: cannot read job %s (left as it "
                     "is, loaded at the next start): %s", id, strerror(errno));
        }
        goto out;
    }
    if (!(j = svc__job_new()))
        goto out;
    if (srv_spool_read(cfg->spool, id, "request.json", &req, &len) != 0 ||
        !(so = cJSON_Parse(state)) || !(ro = cJSON_Parse(req)) ||
        svc__record_from_json(&j->rec, ro) != 0 ||
        svc__state_load(j, so) != 0) {
        quarantine(rc, id, "its state.json or request.json is damaged");
        goto out;
    }
    snprintf(j->id, sizeof j->id, "%s", id);
    if (j->status == SVC_JOB_SUCCEEDED && !result_intact(j)) {
        quarantine(rc, id, "its result or metrics are missing or not the "
                   "size its state.json records");
        goto out;
    }
    j->disk_bytes = srv_spool_du(cfg->spool, id);
    j->recovered = 1;
    {   /* svc_admit.c; 0 (re-estimated after decoding) when absent */
        double e = cJSON_GetNumberValue(
            cJSON_GetObjectItemCaseSensitive(ro, "memory_estimate"));
        j->mem_estimate = e > 0 ? e : 0;
    }
    if (svc_job_status_terminal(j->status)) {
        if (srv_wall() - j->finished >= cfg->result_ttl) {
            srv_spool_remove(cfg->spool, id);
            goto out;
        }
        events_recover(j);
        svc__table_insert(j);
        j = NULL;
        rc->restored++;
        goto out;
    }
    if (j->cancel) {
        /* Canceled while it ran, and the process ended before the step
         * did: it stays canceled. */
        char *s;
        svc_cancel_reason why = j->cancel_reason;
        j->status = SVC_JOB_CANCELED;
        j->finished = srv_wall();
        svc_error_set(&j->err, SVC_ECANCELED, NULL, "canceled %s while it "
                      "ran, before the daemon restarted; it did not run "
                      "again", why == SVC_CANCEL_USER
                      ? "by request" : "when its client hung up");
        j->err.cancel = why;
        if ((s = svc__state_json(j)) != NULL) {
            if (srv_spool_write(cfg->spool, id, "state.json", s, strlen(s),
                                1) != 0)
                srv_logf(SRV_LOG_WARN, "spool: cannot record job %s as "
                         "canceled: %s", id, strerror(errno));
            free(s);
        }
        svc__table_insert(j);
        j = NULL;
        rc->restored++;
        goto out;
    }
    /* queued, or running when the process died: run it again */
    j->status = SVC_JOB_QUEUED;
    j->started = 0;
    j->step = 0;
    j->t = 0;
    if (rc->n == rc->cap) {
        int ncap = rc->cap ? 2 * rc->cap : 64;
        void *p = realloc(rc->queued, (size_t)ncap * sizeof *rc->queued);
        if (!p)
            goto out;
        rc->queued = p;
        rc->cap = ncap;
    }
    rc->queued[rc->n++] = j;
    j = NULL;
out:
    if (j)
        svc__job_free(j);
    cJSON_Delete(so);
    cJSON_Delete(ro);
    free(state);
    free(req);
}

int svc__recover(char *msg, size_t msgsize)
{
    recover_ctx rc;
    int i;

    memset(&rc, 0, sizeof rc);
    svc__lock();
    if (srv_spool_list(svc__S.cfg.spool, recover_one, &rc) != 0) {
        svc__unlock();
        snprintf(msg, msgsize, "cannot list the spool %s: %s",
                 svc__S.cfg.spool, strerror(errno));
        free(rc.queued);
        return -1;
    }
    if (rc.n > 1)
        qsort(rc.queued, (size_t)rc.n, sizeof *rc.queued, by_created);
    for (i = 0; i < rc.n; i++) {
        svc__table_insert(rc.queued[i]);
        svc__queue_push(rc.queued[i]);
    }
    svc__unlock();
    free(rc.queued);
    if (rc.n || rc.restored || rc.dropped || rc.quarantined)
        srv_logf(SRV_LOG_INFO, "spool %s: %d jobs queued again, %d finished "
                 "jobs restored, %d incomplete removed, %d damaged moved to "
                 "quarantine", svc__S.cfg.spool, rc.n, rc.restored, rc.dropped,
                 rc.quarantined);
    return 0;
}
