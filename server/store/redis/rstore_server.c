/* SPDX-License-Identifier: MIT */
/*
 * rstore_server.c - what the job store checks of the Redis it does not
 * own (issue 28): at open, the eviction policy (refused unless allowed:
 * any policy but noeviction may drop a job's keys, which all carry a
 * TTL) and what a restart of the server loses (appendonly, appendfsync,
 * save), said in one line for the log; at each readiness probe, that the
 * server answers reads, takes a write (noeviction at maxmemory refuses
 * them all) and that the queue's keys are streams.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "rstore_internal.h"

/* The value of "name:" in an INFO reply's text, into out ("" when
 * absent). */
static void info_field(const redisReply *r, const char *name, char *out,
                       size_t size)
{
    const char *p;
    size_t n = strlen(name), k;

    out[0] = 0;
    if (!r || r->type != REDIS_REPLY_STRING)
        return;
    for (p = r->str; p && *p; p = strchr(p, '\n'), p = p ? p + 1 : NULL)
        if (strncmp(p, name, n) == 0 && p[n] == ':') {
            p += n + 1;
            k = strcspn(p, "\r\n");
            if (k >= size)
                k = size - 1;
            memcpy(out, p, k);
            out[k] = 0;
            return;
        }
}

/* One parameter by CONFIG GET into out: 0, or -1 (CONFIG refused: a
 * managed Redis often renames it). */
static int config_get(rds *c, const char *name, char *out, size_t size)
{
    redisReply *r = rds_cmdl(c, "CONFIG", "GET", name, NULL);
    int rc = -1;

    if (r && r->type == REDIS_REPLY_ARRAY && r->elements == 2 &&
        r->element[1]->type == REDIS_REPLY_STRING) {
        snprintf(out, size, "%s", r->element[1]->str);
        rc = 0;
    }
    rds_reply_free(r);
    return rc;
}

/* The eviction policy, from INFO memory (answered where CONFIG is
 * renamed): 0, or -1 with why. */
static int eviction_policy(rds *c, char *policy, size_t size, char *why,
                           size_t whysize)
{
    redisReply *r = rds_cmdl(c, "INFO", "memory", NULL);

    if (!r) {
        snprintf(why, whysize, "%s", rds_errmsg(c));
        return -1;
    }
    info_field(r, "maxmemory_policy", policy, size);
    rds_reply_free(r);
    if (!policy[0]) {
        snprintf(why, whysize, "INFO memory has no maxmemory_policy");
        return -1;
    }
    return 0;
}

/* What a restart of the server loses, one sentence into out; 1 when it
 * may lose acknowledged jobs (a warning), 0 when it keeps them. */
static int persistence(rds *c, char *out, size_t size)
{
    redisReply *r = rds_cmdl(c, "INFO", "persistence", NULL);
    char aof[8] = "", fsync[16] = "", save[128] = "";
    int have_save;

    info_field(r, "aof_enabled", aof, sizeof aof);
    rds_reply_free(r);
    have_save = config_get(c, "save", save, sizeof save) == 0;
    (void)config_get(c, "appendfsync", fsync, sizeof fsync);
    if (strcmp(aof, "1") == 0 && strcmp(fsync, "always") == 0) {
        snprintf(out, size, "appendonly yes, appendfsync always: a restart "
                 "of this Redis, or a crash of its machine, keeps every "
                 "acknowledged job");
        return 0;
    }
    if (strcmp(aof, "1") == 0) {
        snprintf(out, size, "appendonly yes, appendfsync %s: a restart of "
                 "this Redis keeps every acknowledged job; a crash of its "
                 "machine loses the writes of the last %s", fsync[0] ? fsync
                 : "unknown (CONFIG refused)", strcmp(fsync, "everysec") == 0
                 ? "second" : "30 s or so (what the OS had not flushed)");
        return strcmp(fsync, "everysec") != 0;
    }
    if (!aof[0]) {
        snprintf(out, size, "persistence unknown (INFO persistence "
                 "refused): a restart of this Redis may lose every job");
        return 1;
    }
    if (have_save && !save[0]) {
        snprintf(out, size, "appendonly no, save \"\": a restart of this "
                 "Redis loses every job, acknowledged or not (records, "
                 "inputs, results); run it with appendonly yes, "
                 "appendfsync always");
        return 1;
    }
    snprintf(out, size, "appendonly no, save \"%s\": a restart of this "
             "Redis loses every job acknowledged since its last snapshot; "
             "run it with appendonly yes, appendfsync always",
             have_save ? save : "unknown (CONFIG refused)");
    return 1;
}

int rstore__server_check(rstore *s, rds *c, char *msg, size_t msgsize)
{
    char policy[64], why[400], keep[400];
    int warn;

    if (eviction_policy(c, policy, sizeof policy, why, sizeof why) != 0) {
        if (!s->cfg.allow_eviction) {
            snprintf(msg, msgsize, "redis %s: cannot read maxmemory-policy "
                     "(%s): start mcfd with --redis-allow-eviction to run "
                     "without knowing whether Redis may evict its keys",
                     rds_where(c), why);
            return -1;
        }
        snprintf(policy, sizeof policy, "unknown");
    }
    if (strcmp(policy, "noeviction") != 0 && !s->cfg.allow_eviction) {
        snprintf(msg, msgsize, "redis %s: maxmemory-policy %s may evict "
                 "mcfd's keys (each has a TTL, so volatile-* policies evict "
                 "them too): accepted jobs would fail or vanish; set "
                 "maxmemory-policy noeviction, or start mcfd with "
                 "--redis-allow-eviction to accept that", rds_where(c),
                 policy);
        return -1;
    }
    warn = persistence(c, keep, sizeof keep);
    if (strcmp(policy, "noeviction") != 0) {
        warn = 1;
        snprintf(s->notes, sizeof s->notes, "redis %s: maxmemory-policy %s "
                 "may evict mcfd's keys (--redis-allow-eviction): a job "
                 "evicted fails or becomes 404; %s", rds_where(c), policy,
                 keep);
    } else {
        snprintf(s->notes, sizeof s->notes, "redis %s: maxmemory-policy "
                 "noeviction; %s", rds_where(c), keep);
    }
    s->notes_warn = warn;
    return 0;
}

const char *rstore_notes(const rstore *s, int *warn)
{
    if (warn)
        *warn = s->notes_warn;
    return s->notes;
}

/* The type of key, "none" when it does not exist: 0, or -1. */
static int key_type(rds *c, const char *key, char *out, size_t size)
{
    redisReply *r = rds_cmdl(c, "TYPE", key, NULL);

    if (!r)
        return -1;
    snprintf(out, size, "%s", r->type == REDIS_REPLY_STATUS ||
                              r->type == REDIS_REPLY_STRING ? r->str : "?");
    rds_reply_free(r);
    return 0;
}

int rstore_ready(rstore *s, char *why, size_t size)
{
    rds *c = rds_pool_get(s->pool);
    const char *keys[2] = {s->k_queue, s->k_front};
    char type[32], probe[KEY_MAX + 8];
    redisReply *r;
    int i, rc = -1;

    /* a read, not PING: a server loading its AOF answers PING */
    for (i = 0; i < 2; i++) {
        if (key_type(c, keys[i], type, sizeof type) != 0) {
            snprintf(why, size, "%s", rds_errmsg(c));
            goto out;
        }
        if (strcmp(type, "stream") != 0 && strcmp(type, "none") != 0) {
            snprintf(why, size, "redis %s: %s is a %s, not a stream: no job "
                     "can be queued until it is removed", rds_where(c),
                     keys[i], type);
            goto out;
        }
    }
    /* a write: noeviction at maxmemory refuses them all (OOM) while
     * reads go on */
    snprintf(probe, sizeof probe, "%s:ready", s->k_ctl);
    if (!(r = rds_cmdl(c, "SET", probe, "1", "PX", "60000", NULL))) {
        if (rds_status_of(c) == RDS_EREPLY)
            snprintf(why, size, "redis %s refuses writes: %s", rds_where(c),
                     rds_errmsg(c));
        else
            snprintf(why, size, "%s", rds_errmsg(c));
        goto out;
    }
    rds_reply_free(r);
    rc = 0;
out:
    rds_pool_put(s->pool, c);
    return rc;
}
