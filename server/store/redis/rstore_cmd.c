/* SPDX-License-Identifier: MIT */
/*
 * rstore_cmd.c - what every file of the Redis store uses (rstore_internal.h):
 * a job's keys and the names allowed in them, a command or a script on a
 * pooled connection, errno from a failure, the workers' consumer group.
 * A leaf: it calls no other file of the store (make check-graph).
 */
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "rstore_internal.h"

/* errno for the failure c reports. */
int rstore__errno(rds *c)
{
    static const struct {
        const char *code;
        int err;
    } codes[] = {{"OOM", ENOSPC}, {"STALE", ESTALE}, {"EXISTS", EEXIST},
                 {"NOJOB", ENOENT}, {"FULL", EAGAIN}};
    size_t i;

    switch (rds_status_of(c)) {
    case RDS_EDOWN:
        return EAGAIN;
    case RDS_ENOMEM:
        return ENOMEM;
    case RDS_ECONFIG:
        return EINVAL;
    case RDS_EREPLY:
        for (i = 0; i < sizeof codes / sizeof *codes; i++)
            if (rds_error_is(c, codes[i].code))
                return codes[i].err;
        return EIO;
    default:
        return EIO;
    }
}

/* Ids and blob names become parts of keys: letters, digits, . _ - */
int rstore__name_ok(const char *s)
{
    size_t n = strlen(s);
    return n > 0 && n < RSTORE_ID_MAX &&
           strspn(s, "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                     "0123456789._-") == n;
}


int rstore__keys(const rstore *s, const char *id, job_keys *k)
{
    if (!rstore__name_ok(id)) {
        errno = EINVAL;
        return -1;
    }
    snprintf(k->hash, sizeof k->hash, "%s:job:%s", s->cfg.prefix, id);
    snprintf(k->ev, sizeof k->ev, "%s:ev:%s", s->cfg.prefix, id);
    snprintf(k->blobs, sizeof k->blobs, "%s:blob:%s:", s->cfg.prefix, id);
    return 0;
}

/* One script on a pooled connection: its reply, or NULL and errno. */
redisReply *rstore__eval(rstore *s, rds_script *sc, int nkeys, int argc,
                         const char **argv, const size_t *lens)
{
    rds *c = rds_pool_get(s->pool);
    redisReply *r = rds_eval(c, sc, nkeys, argc, argv, lens);
    int e = r ? 0 : rstore__errno(c);

    rds_pool_put(s->pool, c);
    errno = e;
    return r;
}

/* A script whose reply is an integer: 0 and *v, or -1 and errno. */
int rstore__eval_int(rstore *s, rds_script *sc, int nkeys, int argc,
                     const char **argv, const size_t *lens, long long *v)
{
    redisReply *r = rstore__eval(s, sc, nkeys, argc, argv, lens);
    long long x;

    if (!r)
        return -1;
    if (rds_reply_ll(r, &x) != 0) {
        rds_reply_free(r);
        errno = EIO;
        return -1;
    }
    rds_reply_free(r);
    if (v)
        *v = x;
    return 0;
}

/* A command of C strings on a pooled connection. */
redisReply *rstore__cmd(rstore *s, double block, int argc,
                        const char **argv)
{
    rds *c = rds_pool_get(s->pool);
    redisReply *r = rds_cmd_block(c, block, argc, argv, NULL);
    int e = r ? 0 : rstore__errno(c);

    rds_pool_put(s->pool, c);
    errno = e;
    return r;
}

int rstore__make_group(rds *c, const char *stream)
{
    redisReply *r = rds_cmdl(c, "XGROUP", "CREATE", stream, GROUP, "0",
                             "MKSTREAM", NULL);
    if (r || rds_error_is(c, "BUSYGROUP")) {
        rds_reply_free(r);
        return 0;
    }
    return -1;
}
