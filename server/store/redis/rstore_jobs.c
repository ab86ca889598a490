/* SPDX-License-Identifier: MIT */
/*
 * rstore_jobs.c - the job store in Redis (rstore.h says the keys and the
 * semantics): opening it, and the records and blobs (rstore_queue.c: the
 * queue, the reaper and progress; rstore_files.c: blobs in files;
 * rstore_cmd.c: the helpers every file uses).
 * Every step that reads and then writes is one Lua script, so replicas
 * racing for a job see one order.
 */
#include <errno.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "rstore_internal.h"

#define SLICE ((size_t)8 << 20)   /* bytes of one GETRANGE */
#define PROTO_DEFAULT ((size_t)512 << 20)   /* Redis's proto-max-bulk-len */
#define PROTO_SLACK 1024          /* a blob's command around its bytes */

/* --------------------------------------------------------- the scripts */

/* KEYS: hash, jobs, events. ARGV: blob prefix, ttl, id, name, data... */
static rds_script lua_create = {
    LUA_TOUCH LUA_WRITE
    "if redis.call('EXISTS', KEYS[1]) == 1 then\n"
    "  return redis.error_reply('EXISTS job exists') end\n"
    "redis.call('HSET', KEYS[1], 'runs', 0)\n"
    "for i = 4, #ARGV, 2 do write(KEYS[1], ARGV[1], ARGV[i], ARGV[i + 1]) end\n"
    "redis.call('SADD', KEYS[2], ARGV[3])\n"
    "touch(KEYS[1], ARGV[1], KEYS[3], ARGV[2])\n"
    "return 1\n", ""};

/* KEYS: hash, events. ARGV: blob prefix, ttl, name, data, fence (the
 * runner's consumer; "": none; " ": only while no replica runs it),
 * control prefix, id. A cancel.json of a job a replica runs is also
 * told to that replica's control stream (P:ctl:{consumer}). */
static rds_script lua_put = {
    LUA_TOUCH LUA_WRITE
    "if redis.call('EXISTS', KEYS[1]) == 0 then\n"
    "  return redis.error_reply('NOJOB no such job') end\n"
    "local runner = redis.call('HGET', KEYS[1], 'runner')\n"
    "if (ARGV[5] == ' ' and runner) or\n"
    "   (ARGV[5] ~= '' and ARGV[5] ~= ' ' and runner ~= ARGV[5]) then\n"
    "  return redis.error_reply('STALE another replica took the job over') "
    "end\n"
    "write(KEYS[1], ARGV[1], ARGV[3], ARGV[4])\n"
    LUA_MARK("ARGV[3]")
    "if ARGV[3] == 'cancel.json' and runner then\n"
    "  local c = ARGV[6] .. runner\n"
    "  redis.call('XADD', c, 'MAXLEN', '~', 1000, '*', 'job', ARGV[7])\n"
    "  redis.call('PEXPIRE', c, ARGV[2]) end\n"
    "touch(KEYS[1], ARGV[1], KEYS[2], ARGV[2])\n"
    "return 1\n", ""};

/* KEYS: hash, jobs, events. ARGV: blob prefix, id, quarantine prefix
 * ("": remove). */
static rds_script lua_remove = {
    "local f = redis.call('HKEYS', KEYS[1])\n"
    "local keys = {KEYS[1], KEYS[3]}\n"
    "for i = 1, #f do\n"
    "  if string.sub(f[i], 1, 2) == 's:' then\n"
    "    keys[#keys + 1] = ARGV[1] .. string.sub(f[i], 3) end\n"
    "end\n"
    "for _, k in ipairs(keys) do\n"
    "  if ARGV[3] == '' then redis.call('DEL', k)\n"
    "  elseif redis.call('EXISTS', k) == 1 then\n"
    "    redis.call('RENAME', k, ARGV[3] .. k) end\n"
    "end\n"
    "return redis.call('SREM', KEYS[2], ARGV[2])\n", ""};

/* KEYS: hash. ARGV: none. The bytes of the job's blobs. */
static rds_script lua_usage = {
    "local f = redis.call('HGETALL', KEYS[1])\n"
    "local n = 0\n"
    "for i = 1, #f, 2 do\n"
    "  local p = string.sub(f[i], 1, 2)\n"
    "  if p == 's:' then n = n + tonumber(f[i + 1])\n"
    "  elseif p == 'b:' then n = n + #f[i + 1] end\n"
    "end\n"
    "return n\n", ""};


static int is_field(const char *name)
{
    size_t n = strlen(name);
    return n >= 5 && strcmp(name + n - 5, ".json") == 0;
}

/* ------------------------------------------------------------- open */

void rstore_config_default(rstore_config *cfg)
{
    char host[64] = "mcfd";
    struct timespec ts;

    memset(cfg, 0, sizeof *cfg);
    snprintf(cfg->prefix, sizeof cfg->prefix, "mcfd");
    (void)gethostname(host, sizeof host - 1);
    host[sizeof host - 1] = 0;
    /* with a nonce: a restarted container has the same host name and,
     * under tini, often the same pid */
    clock_gettime(CLOCK_REALTIME, &ts);
    snprintf(cfg->consumer, sizeof cfg->consumer, "%s:%ld:%08lx", host,
             (long)getpid(), (unsigned long)(ts.tv_nsec ^ ts.tv_sec) &
                                 0xffffffffUL);
    cfg->ttl = 86400;
    cfg->claim_idle = 30;
    cfg->block = 1;
    cfg->max_runs = 3;
    cfg->queue_max = 100000;
    cfg->ev_max = 10000;
    cfg->dead_max = 10000;
    cfg->max_blob = (size_t)512 << 20;
    cfg->pool = 8;
    cfg->blob_grace = 600;
    cfg->blob_sweep = 60;
}

/* proto-max-bulk-len, or Redis's default when CONFIG is refused (a
 * managed Redis renames it). */
static size_t proto_max(rds *c)
{
    redisReply *r = rds_cmdl(c, "CONFIG", "GET", "proto-max-bulk-len", NULL);
    long long v = 0;

    if (r && r->type == REDIS_REPLY_ARRAY && r->elements == 2 &&
        rds_reply_ll(r->element[1], &v) == 0 && v > PROTO_SLACK) {
        rds_reply_free(r);
        return (size_t)v;
    }
    rds_reply_free(r);
    return PROTO_DEFAULT;
}

rstore *rstore_open(const rds_config *rc, const rstore_config *cfg,
                    char *msg, size_t msgsize)
{
    rstore *s = calloc(1, sizeof *s);
    rds *c;
    size_t proto;

    if (!s) {
        snprintf(msg, msgsize, "out of memory");
        return NULL;
    }
    s->cfg = *cfg;
    if (!rstore__name_ok(cfg->prefix) || cfg->pool < 1 || cfg->max_runs < 1 ||
        cfg->ttl < 1 || cfg->claim_idle <= 0 || cfg->queue_max < 1) {
        snprintf(msg, msgsize, "redis store: bad configuration");
        free(s);
        return NULL;
    }
    snprintf(s->ttl_ms, sizeof s->ttl_ms, "%lld",
             (long long)(cfg->ttl * 1000));
    snprintf(s->k_jobs, KEY_MAX, "%s:jobs", cfg->prefix);
    snprintf(s->k_queue, KEY_MAX, "%s:queue", cfg->prefix);
    snprintf(s->k_front, KEY_MAX, "%s:front", cfg->prefix);
    snprintf(s->k_dead, KEY_MAX, "%s:dead", cfg->prefix);
    snprintf(s->p_ctl, KEY_MAX, "%s:ctl:", cfg->prefix);
    snprintf(s->k_ctl, KEY_MAX, "%s:ctl:%s", cfg->prefix, cfg->consumer);
    /* the consumer is new with each process (its nonce): all of its
     * control stream is for this one */
    snprintf(s->ctl_after, sizeof s->ctl_after, "0");
    pthread_mutex_init(&s->mu, NULL);
    if (!(s->pool = rds_pool_new(rc, cfg->pool))) {
        snprintf(msg, msgsize, "out of memory");
        rstore_close(s);
        return NULL;
    }
    c = rds_pool_get(s->pool);
    if (rstore__server_check(s, c, msg, msgsize) != 0) {
        rds_pool_put(s->pool, c);
        rstore_close(s);
        return NULL;
    }
    if (rstore__make_group(c, s->k_queue) != 0 ||
        rstore__make_group(c, s->k_front) != 0) {
        snprintf(msg, msgsize, "%s", rds_errmsg(c));
        rds_pool_put(s->pool, c);
        rstore_close(s);
        return NULL;
    }
    proto = proto_max(c);
    rds_pool_put(s->pool, c);
    s->max_blob = proto - PROTO_SLACK < cfg->max_blob ? proto - PROTO_SLACK
                                                      : cfg->max_blob;
    if (cfg->blob_dir[0]) {
        /* large blobs never pass through Redis: only max_blob bounds them */
        s->max_blob = cfg->max_blob;
        if (rstore__files_check(s, msg, msgsize) != 0) {
            rstore_close(s);
            return NULL;
        }
    }
    return s;
}

void rstore_close(rstore *s)
{
    if (!s)
        return;
    rds_pool_free(s->pool);
    pthread_mutex_destroy(&s->mu);
    free(s);
}

const char *rstore_consumer(const rstore *s) { return s->cfg.consumer; }

/* ---------------------------------------------------- records and blobs */

int rstore_create(rstore *s, const char *id, const rstore_blob *b, int n)
{
    const char *argv[32];
    size_t lens[32];
    job_keys k;
    rstore_files f;
    int argc = 0;

    if (!rstore__name_ok(id) || n < 0 || 6 + 2 * n > 32) {
        errno = EINVAL;
        return -1;
    }
    rstore__keys(s, id, &k);
    argv[argc++] = k.hash;
    argv[argc++] = s->k_jobs;
    argv[argc++] = k.ev;
    argv[argc++] = k.blobs;
    argv[argc++] = s->ttl_ms;
    argv[argc++] = id;
    if (rstore__blob_args(s, id, b, n, argv, lens, &argc, &f) != 0)
        return -1;
    return rstore__files_end(
        s, &f, rstore__eval_int(s, &lua_create, 3, argc, argv, lens, NULL));
}

int rstore__blob_args(rstore *s, const char *id, const rstore_blob *b,
                      int n, const char **argv, size_t *lens, int *argc,
                      rstore_files *f)
{
    int i;

    f->n = 0;
    for (i = 0; i < *argc; i++)
        lens[i] = strlen(argv[i]);
    for (i = 0; i < n; i++) {
        if (!rstore__name_ok(b[i].name)) {
            errno = EINVAL;
            return -1;
        }
        if (b[i].len > s->max_blob) {
            errno = EFBIG;
            return -1;
        }
        if (s->cfg.blob_dir[0] && !is_field(b[i].name) && f->n < FILES_MAX) {
            int j = f->n;

            if (rstore__file_write(s, id, b[i].name, b[i].data, b[i].len,
                                   f->ref[j], sizeof f->ref[j]) != 0) {
                int e = errno;
                rstore__files_end(s, f, -1);
                errno = e;
                return -1;
            }
            f->n++;
            snprintf(f->name[j], sizeof f->name[j], "@%s", b[i].name);
            /* "SIZE REF" (arg has room for both) */
            memcpy(f->arg[j] + snprintf(f->arg[j], 24, "%zu ", b[i].len),
                   f->ref[j], strlen(f->ref[j]) + 1);
            argv[*argc] = f->name[j];
            lens[(*argc)++] = strlen(f->name[j]);
            argv[*argc] = f->arg[j];
            lens[(*argc)++] = strlen(f->arg[j]);
            continue;
        }
        argv[*argc] = b[i].name;
        lens[(*argc)++] = strlen(b[i].name);
        argv[*argc] = b[i].data ? b[i].data : "";
        lens[(*argc)++] = b[i].len;
    }
    return 0;
}

int rstore__files_end(rstore *s, rstore_files *f, int rc)
{
    int e = errno, i;

    if (rc != 0 && (e == ESTALE || e == ENOENT || e == EEXIST ||
                    e == ENOSPC || e == EINVAL || e == EFBIG))
        for (i = 0; i < f->n; i++)
            rstore__file_unlink(s, f->ref[i]);
    f->n = 0;
    errno = e;
    return rc;
}

int rstore_put(rstore *s, const char *id, const char *name,
               const void *data, size_t len, int fence)
{
    job_keys k;
    const char *argv[9];
    size_t lens[9];
    rstore_blob b = {name, data, len};
    rstore_files f;
    int argc = 4;

    if (rstore__keys(s, id, &k) != 0)
        return -1;
    argv[0] = k.hash;
    argv[1] = k.ev;
    argv[2] = k.blobs;
    argv[3] = s->ttl_ms;
    if (rstore__blob_args(s, id, &b, 1, argv, lens, &argc, &f) != 0)
        return -1;
    argv[6] = fence == RSTORE_UNCLAIMED ? " " : fence ? s->cfg.consumer : "";
    lens[6] = strlen(argv[6]);
    argv[7] = s->p_ctl;
    lens[7] = strlen(argv[7]);
    argv[8] = id;
    lens[8] = strlen(id);
    return rstore__files_end(
        s, &f, rstore__eval_int(s, &lua_put, 2, 9, argv, lens, NULL));
}

/* A large blob's size and version: 0, or -1 and errno (ENOENT). The
 * size is the server's word: bounded by max_blob before anyone trusts
 * it. */
static int blob_meta(rstore *s, const job_keys *k, const char *name,
                     size_t *size, long long *version, char ref[REF_MAX])
{
    char sf[RSTORE_ID_MAX + 2], vf[RSTORE_ID_MAX + 2],
        ff[RSTORE_ID_MAX + 2];
    const char *argv[5] = {"HMGET", k->hash, sf, vf, ff};
    redisReply *r;
    long long n, v = 0;

    snprintf(sf, sizeof sf, "s:%s", name);
    snprintf(vf, sizeof vf, "v:%s", name);
    snprintf(ff, sizeof ff, "f:%s", name);
    if (!(r = rstore__cmd(s, 0, 5, argv)))
        return -1;
    if (r->type != REDIS_REPLY_ARRAY || r->elements != 3 ||
        (r->element[2]->type == REDIS_REPLY_STRING &&
         r->element[2]->len >= REF_MAX)) {
        rds_reply_free(r);
        errno = EIO;
        return -1;
    }
    if (r->element[0]->type == REDIS_REPLY_NIL) {
        rds_reply_free(r);
        errno = ENOENT;
        return -1;
    }
    if (rds_reply_ll(r->element[0], &n) != 0 || n < 0 ||
        (unsigned long long)n > s->max_blob ||
        (r->element[1]->type != REDIS_REPLY_NIL &&
         rds_reply_ll(r->element[1], &v) != 0)) {
        rds_reply_free(r);
        errno = EIO;
        return -1;
    }
    ref[0] = 0;
    if (r->element[2]->type == REDIS_REPLY_STRING)
        memcpy(ref, r->element[2]->str, r->element[2]->len + 1);
    rds_reply_free(r);
    *size = (size_t)n;
    *version = v;
    return 0;
}

/* len bytes of key (or of file ref, of size bytes, when ref is not "")
 * at off, exactly: 0 or -1 and errno. */
static int read_range(rstore *s, const char *key, const char *ref,
                      size_t size, size_t off, char *buf, size_t len)
{
    if (ref[0]) {
        int fd = rstore__file_open(s, ref, size), rc, e;

        if (fd < 0)
            return -1;
        rc = rstore__file_read(fd, off, buf, len);
        e = errno;
        close(fd);
        errno = e;
        return rc;
    }
    while (len > 0) {
        size_t n = len < SLICE ? len : SLICE;
        char a[24], b[24];
        const char *argv[4] = {"GETRANGE", key, a, b};
        redisReply *r;

        snprintf(a, sizeof a, "%zu", off);
        snprintf(b, sizeof b, "%zu", off + n - 1);
        if (!(r = rstore__cmd(s, 0, 4, argv)))
            return -1;
        if (r->type != REDIS_REPLY_STRING || r->len != n) {
            /* shorter: the key expired or was replaced by a smaller one */
            int gone = r->type == REDIS_REPLY_STRING && r->len == 0;
            rds_reply_free(r);
            errno = gone ? ENOENT : EIO;
            return -1;
        }
        memcpy(buf, r->str, n);
        rds_reply_free(r);
        buf += n;
        off += n;
        len -= n;
    }
    return 0;
}

/* A small blob (a field of the hash): malloc'ed, NUL-terminated. */
static int get_field(rstore *s, const job_keys *k, const char *name,
                     char **data, size_t *len)
{
    char f[RSTORE_ID_MAX + 2];
    const char *argv[3] = {"HGET", k->hash, f};
    redisReply *r;

    snprintf(f, sizeof f, "b:%s", name);
    if (!(r = rstore__cmd(s, 0, 3, argv)))
        return -1;
    if (r->type != REDIS_REPLY_STRING) {
        errno = r->type == REDIS_REPLY_NIL ? ENOENT : EIO;
        rds_reply_free(r);
        return -1;
    }
    if (!(*data = malloc(r->len + 1))) {
        rds_reply_free(r);
        errno = ENOMEM;
        return -1;
    }
    memcpy(*data, r->str, r->len);
    (*data)[r->len] = 0;
    *len = r->len;
    rds_reply_free(r);
    return 0;
}

int rstore_get(rstore *s, const char *id, const char *name, char **data,
               size_t *len)
{
    job_keys k;
    char key[KEY_MAX + RSTORE_ID_MAX];
    int tries;

    if (!rstore__name_ok(id) || !rstore__name_ok(name)) {
        errno = EINVAL;
        return -1;
    }
    rstore__keys(s, id, &k);
    if (is_field(name))
        return get_field(s, &k, name, data, len);
    snprintf(key, sizeof key, "%s%s", k.blobs, name);
    /* read in slices; a put between them changes the version: again */
    for (tries = 0; tries < 3; tries++) {
        size_t size, size2;
        long long v, v2;
        char *buf, ref[REF_MAX], ref2[REF_MAX];

        if (blob_meta(s, &k, name, &size, &v, ref) != 0)
            return -1;
        if (!(buf = malloc(size + 1))) {
            errno = ENOMEM;
            return -1;
        }
        if (read_range(s, key, ref, size, 0, buf, size) == 0 &&
            blob_meta(s, &k, name, &size2, &v2, ref2) == 0 && v2 == v &&
            size2 == size) {
            buf[size] = 0;
            *data = buf;
            *len = size;
            return 0;
        }
        free(buf);
        if (errno != EIO && errno != ENOENT)
            return -1;
    }
    errno = EIO;
    return -1;
}

int rstore_get_at(rstore *s, const char *id, const char *name, size_t off,
                  void *buf, size_t len)
{
    job_keys k;
    char key[KEY_MAX + RSTORE_ID_MAX];
    size_t size;
    long long v;
    char ref[REF_MAX];

    if (!rstore__name_ok(id) || !rstore__name_ok(name) || is_field(name)) {
        errno = EINVAL;
        return -1;
    }
    rstore__keys(s, id, &k);
    if (blob_meta(s, &k, name, &size, &v, ref) != 0)
        return -1;
    if (off > size || len > size - off) {
        errno = EIO;
        return -1;
    }
    snprintf(key, sizeof key, "%s%s", k.blobs, name);
    return read_range(s, key, ref, size, off, buf, len);
}

int rstore_stat(rstore *s, const char *id, const char *name, size_t *size)
{
    job_keys k;
    long long v;
    char ref[REF_MAX];

    if (!rstore__name_ok(id) || !rstore__name_ok(name)) {
        errno = EINVAL;
        return -1;
    }
    rstore__keys(s, id, &k);
    if (is_field(name)) {
        char f[RSTORE_ID_MAX + 2];
        const char *argv[3] = {"HSTRLEN", k.hash, f};
        const char *argx[3] = {"HEXISTS", k.hash, f};
        redisReply *r;
        long long n = 0, e = 0;

        snprintf(f, sizeof f, "b:%s", name);
        if (!(r = rstore__cmd(s, 0, 3, argv)))
            return -1;
        if (rds_reply_ll(r, &n) != 0 || n < 0) {
            rds_reply_free(r);
            errno = EIO;
            return -1;
        }
        rds_reply_free(r);
        if (n == 0) {
            if (!(r = rstore__cmd(s, 0, 3, argx)))
                return -1;
            (void)rds_reply_ll(r, &e);
            rds_reply_free(r);
            if (!e) {
                errno = ENOENT;
                return -1;
            }
        }
        *size = (size_t)n;
        return 0;
    }
    return blob_meta(s, &k, name, size, &v, ref);
}

static int remove_as(rstore *s, const char *id, const char *to)
{
    job_keys k;
    const char *argv[6];

    if (rstore__keys(s, id, &k) != 0)
        return -1;
    argv[0] = k.hash;
    argv[1] = s->k_jobs;
    argv[2] = k.ev;
    argv[3] = k.blobs;
    argv[4] = id;
    argv[5] = to;
    return rstore__eval_int(s, &lua_remove, 3, 6, argv, NULL, NULL);
}

int rstore_remove(rstore *s, const char *id)
{
    int rc = remove_as(s, id, "");

    if (rc == 0)
        rstore__files_remove(s, id);
    return rc;
}

int rstore_quarantine(rstore *s, const char *id)
{
    char to[KEY_MAX];

    snprintf(to, sizeof to, "%s:quarantine:", s->cfg.prefix);
    return remove_as(s, id, to);
}

size_t rstore_usage(rstore *s, const char *id)
{
    job_keys k;
    const char *argv[1];
    long long n = 0;

    if (!rstore__name_ok(id))
        return 0;
    rstore__keys(s, id, &k);
    argv[0] = k.hash;
    if (rstore__eval_int(s, &lua_usage, 1, 1, argv, NULL, &n) != 0 || n < 0)
        return 0;
    return (size_t)n;
}

/* One SSCAN page: the ids whose hash is gone (expired) leave the set. */
static int scan_page(rstore *s, rds *c, const redisReply *ids,
                     void (*fn)(const char *id, void *ctx), void *ctx)
{
    size_t i;

    for (i = 0; i < ids->elements; i++) {
        const redisReply *e = ids->element[i];
        job_keys k;
        redisReply *r;
        long long n = 0;

        if (e->type != REDIS_REPLY_STRING || !rstore__name_ok(e->str))
            continue;                  /* not ours: never a key */
        rstore__keys(s, e->str, &k);
        if (!(r = rds_cmdl(c, "EXISTS", k.hash, NULL)))
            return -1;
        (void)rds_reply_ll(r, &n);
        rds_reply_free(r);
        if (n) {
            fn(e->str, ctx);
        } else {
            rds_reply_free(rds_cmdl(c, "SREM", s->k_jobs, e->str, NULL));
        }
    }
    return 0;
}

int rstore_scan(rstore *s, void (*fn)(const char *id, void *ctx),
                void *ctx)
{
    rds *c = rds_pool_get(s->pool);
    char cursor[32] = "0";
    int rc = 0;

    do {
        redisReply *r = rds_cmdl(c, "SSCAN", s->k_jobs, cursor, "COUNT",
                                 "256", NULL);
        if (!r) {
            rc = -1;
            break;
        }
        if (r->type != REDIS_REPLY_ARRAY || r->elements != 2 ||
            r->element[0]->type != REDIS_REPLY_STRING ||
            r->element[0]->len >= sizeof cursor ||
            r->element[1]->type != REDIS_REPLY_ARRAY) {
            rds_reply_free(r);
            rc = -2;
            break;
        }
        snprintf(cursor, sizeof cursor, "%s", r->element[0]->str);
        rc = scan_page(s, c, r->element[1], fn, ctx);
        rds_reply_free(r);
    } while (rc == 0 && strcmp(cursor, "0") != 0);
    errno = rc == 0 ? 0 : rc == -2 ? EIO : rstore__errno(c);
    rds_pool_put(s->pool, c);
    return rc == 0 ? 0 : -1;
}
