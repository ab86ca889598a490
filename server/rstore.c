/*
 * rstore.c - the job store in Redis (rstore.h says the keys and the
 * semantics): records and blobs, the queue as a stream with one consumer
 * group, taking a job, heartbeats, the reaper, dead letters and progress.
 * Every step that reads and then writes is one Lua script, so replicas
 * racing for a job see one order.
 */
#include "rstore.h"

#include <errno.h>
#include <limits.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#define GROUP "workers"
#define SLICE ((size_t)8 << 20)   /* bytes of one GETRANGE */
#define HELD_MAX 64               /* entries read but not taken yet */
#define KEY_MAX 320
#define PROTO_DEFAULT ((size_t)512 << 20)   /* Redis's proto-max-bulk-len */
#define PROTO_SLACK 1024          /* a blob's command around its bytes */

typedef struct {
    char id[RSTORE_ID_MAX];
    char entry[RSTORE_ID_MAX];
    int front;                 /* from P:front */
} held_entry;

struct rstore {
    rstore_config cfg;
    rds_pool *pool;
    size_t max_blob;           /* cfg's, bounded by proto-max-bulk-len */
    char ttl_ms[24];
    char k_jobs[KEY_MAX], k_queue[KEY_MAX], k_front[KEY_MAX],
        k_dead[KEY_MAX];
    pthread_mutex_t mu;        /* held, next_reap */
    held_entry held[HELD_MAX];
    int nheld;
    double next_reap;
};

/* --------------------------------------------------------- the scripts */

/* touch(hash, blob prefix, events key, ttl): every key of a job expires
 * ttl after now. */
#define LUA_TOUCH                                                         \
    "local function touch(h, bp, ev, ttl)\n"                              \
    "  local f = redis.call('HKEYS', h)\n"                                \
    "  for i = 1, #f do\n"                                                \
    "    if string.sub(f[i], 1, 2) == 's:' then\n"                        \
    "      redis.call('PEXPIRE', bp .. string.sub(f[i], 3), ttl) end\n"   \
    "  end\n"                                                             \
    "  redis.call('PEXPIRE', h, ttl)\n"                                   \
    "  redis.call('PEXPIRE', ev, ttl)\n"                                  \
    "end\n"
/* write(h, bp, name, data): one blob, in the hash or its own key */
#define LUA_WRITE                                                         \
    "local function write(h, bp, name, data)\n"                           \
    "  if string.sub(name, -5) == '.json' then\n"                         \
    "    redis.call('HSET', h, 'b:' .. name, data)\n"                     \
    "  else\n"                                                            \
    "    redis.call('SET', bp .. name, data)\n"                           \
    "    redis.call('HSET', h, 's:' .. name, #data)\n"                    \
    "    redis.call('HINCRBY', h, 'v:' .. name, 1)\n"                     \
    "  end\n"                                                             \
    "end\n"

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

/* KEYS: hash, events. ARGV: blob prefix, ttl, name, data, fence. */
static rds_script lua_put = {
    LUA_TOUCH LUA_WRITE
    "if redis.call('EXISTS', KEYS[1]) == 0 then\n"
    "  return redis.error_reply('NOJOB no such job') end\n"
    "if ARGV[5] ~= '' and redis.call('HGET', KEYS[1], 'runner') ~= ARGV[5] "
    "then\n"
    "  return redis.error_reply('STALE another replica took the job over') "
    "end\n"
    "write(KEYS[1], ARGV[1], ARGV[3], ARGV[4])\n"
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

/* KEYS: stream, hash. ARGV: id, queue_max. A job already waiting keeps
 * its entry. */
static rds_script lua_push = {
    "if redis.call('EXISTS', KEYS[2]) == 0 then\n"
    "  return redis.error_reply('NOJOB no such job') end\n"
    "local q = redis.call('HMGET', KEYS[2], 'queued', 'qstream')\n"
    "if q[1] and #redis.call('XRANGE', q[2], q[1], q[1]) > 0 then\n"
    "  return q[1] end\n"
    "if redis.call('XLEN', KEYS[1]) >= tonumber(ARGV[2]) then\n"
    "  return redis.error_reply('FULL the shared queue is full') end\n"
    "local e = redis.call('XADD', KEYS[1], '*', 'job', ARGV[1])\n"
    "redis.call('HSET', KEYS[2], 'queued', e, 'qstream', KEYS[1])\n"
    "return e\n", ""};

/* KEYS: stream, hash, dead. ARGV: group, entry, consumer, max_runs,
 * dead_max, id, claim_idle in ms. {0}: not ours (any more), {-1}: gone (acknowledged),
 * {1, runs, retaken}, {2, runs}: dead. */
static rds_script lua_take = {
    "local function done()\n"
    "  redis.call('XACK', KEYS[1], ARGV[1], ARGV[2])\n"
    "  redis.call('XDEL', KEYS[1], ARGV[2])\n"
    "end\n"
    "local p = redis.call('XPENDING', KEYS[1], ARGV[1], ARGV[2], ARGV[2], 1)\n"
    "if #p == 0 or p[1][2] ~= ARGV[3] then return {0} end\n"
    "if redis.call('EXISTS', KEYS[2]) == 0 or\n"
    "   #redis.call('XRANGE', KEYS[1], ARGV[2], ARGV[2]) == 0 then\n"
    "  done() return {-1} end\n"
    /* another entry of the job is running and heartbeating: this one is
     * a duplicate (a job queued again while its old entry was pending) */
    "local cur = redis.call('HMGET', KEYS[2], 'entry', 'stream')\n"
    "if cur[1] and cur[1] ~= ARGV[2] then\n"
    "  local q = redis.call('XPENDING', cur[2], ARGV[1], cur[1], cur[1], 1)\n"
    "  if #q > 0 and q[1][3] < tonumber(ARGV[7]) then done() return {-1} end\n"
    "  if #q > 0 then\n"
    "    redis.call('XACK', cur[2], ARGV[1], cur[1])\n"
    "    redis.call('XDEL', cur[2], cur[1]) end\n"
    "end\n"
    "local runs = redis.call('HINCRBY', KEYS[2], 'runs', 1)\n"
    "if runs > tonumber(ARGV[4]) then\n"
    "  redis.call('XADD', KEYS[3], 'MAXLEN', '~', ARGV[5], '*', 'job', "
    "ARGV[6], 'runs', runs - 1, 'reason', 'its replica stopped during each "
    "of ' .. (runs - 1) .. ' runs')\n"
    "  redis.call('HDEL', KEYS[2], 'runner', 'entry', 'stream', 'queued', "
    "'qstream')\n"
    "  done() return {2, runs - 1} end\n"
    "local prev = redis.call('HGET', KEYS[2], 'runner')\n"
    "redis.call('HSET', KEYS[2], 'runner', ARGV[3], 'entry', ARGV[2], "
    "'stream', KEYS[1])\n"
    "redis.call('HDEL', KEYS[2], 'queued', 'qstream')\n"
    "return {1, runs, prev and 1 or 0}\n", ""};

/* KEYS: hash, events. ARGV: group, consumer. 1 acknowledged, 0 nothing
 * running. */
static rds_script lua_ack = {
    "local r = redis.call('HMGET', KEYS[1], 'runner', 'entry', 'stream')\n"
    "if not r[1] then return 0 end\n"
    "if r[1] ~= ARGV[2] then\n"
    "  return redis.error_reply('STALE another replica took the job over') "
    "end\n"
    "redis.call('XACK', r[3], ARGV[1], r[2])\n"
    "redis.call('XDEL', r[3], r[2])\n"
    "redis.call('HDEL', KEYS[1], 'runner', 'entry', 'stream')\n"
    "return 1\n", ""};

/* KEYS: hash, events. 1 dropped, 0 not queued. */
static rds_script lua_drop = {
    "local r = redis.call('HMGET', KEYS[1], 'queued', 'qstream')\n"
    "if not r[1] then return 0 end\n"
    "redis.call('XDEL', r[2], r[1])\n"
    "redis.call('HDEL', KEYS[1], 'queued', 'qstream')\n"
    "return 1\n", ""};

/* KEYS: hash, events. ARGV: group, consumer, blob prefix, ttl. */
static rds_script lua_heartbeat = {
    LUA_TOUCH
    "local r = redis.call('HMGET', KEYS[1], 'runner', 'entry', 'stream')\n"
    "if r[1] ~= ARGV[2] then\n"
    "  return redis.error_reply('STALE another replica took the job over') "
    "end\n"
    "redis.call('XCLAIM', r[3], ARGV[1], ARGV[2], 0, r[2], 'JUSTID')\n"
    "touch(KEYS[1], ARGV[3], KEYS[2], ARGV[4])\n"
    "return 1\n", ""};

/* KEYS: lease. ARGV: consumer, ttl (0: give it up). 1 ours, else the
 * holder. */
static rds_script lua_lease = {
    "local h = redis.call('GET', KEYS[1])\n"
    "if h and h ~= ARGV[1] then return h end\n"
    "if tonumber(ARGV[2]) <= 0 then redis.call('DEL', KEYS[1])\n"
    "else redis.call('SET', KEYS[1], ARGV[1], 'PX', ARGV[2]) end\n"
    "return 1\n", ""};

/* KEYS: events. ARGV: line, ev_max, ttl. */
static rds_script lua_progress = {
    "local e = redis.call('XADD', KEYS[1], 'MAXLEN', '~', ARGV[2], '*', "
    "'l', ARGV[1])\n"
    "redis.call('PEXPIRE', KEYS[1], ARGV[3])\n"
    "return e\n", ""};

/* ------------------------------------------------------------ helpers */

/* errno for the failure c reports. */
static int fail_errno(rds *c)
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
static int name_ok(const char *s)
{
    size_t n = strlen(s);
    return n > 0 && n < RSTORE_ID_MAX &&
           strspn(s, "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                     "0123456789._-") == n;
}

static int is_field(const char *name)
{
    size_t n = strlen(name);
    return n >= 5 && strcmp(name + n - 5, ".json") == 0;
}

/* The keys of job id: its hash, its events, its blobs' prefix. */
typedef struct {
    char hash[KEY_MAX], ev[KEY_MAX], blobs[KEY_MAX];
} job_keys;

static void keys_of(const rstore *s, const char *id, job_keys *k)
{
    snprintf(k->hash, sizeof k->hash, "%s:job:%s", s->cfg.prefix, id);
    snprintf(k->ev, sizeof k->ev, "%s:ev:%s", s->cfg.prefix, id);
    snprintf(k->blobs, sizeof k->blobs, "%s:blob:%s:", s->cfg.prefix, id);
}

/* One script on a pooled connection: its reply, or NULL and errno. */
static redisReply *eval(rstore *s, rds_script *sc, int nkeys, int argc,
                        const char **argv, const size_t *lens)
{
    rds *c = rds_pool_get(s->pool);
    redisReply *r = rds_eval(c, sc, nkeys, argc, argv, lens);
    int e = r ? 0 : fail_errno(c);

    rds_pool_put(s->pool, c);
    errno = e;
    return r;
}

/* A script whose reply is an integer: 0 and *v, or -1 and errno. */
static int eval_int(rstore *s, rds_script *sc, int nkeys, int argc,
                    const char **argv, const size_t *lens, long long *v)
{
    redisReply *r = eval(s, sc, nkeys, argc, argv, lens);
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
static redisReply *cmd(rstore *s, double block, int argc, const char **argv)
{
    rds *c = rds_pool_get(s->pool);
    redisReply *r = rds_cmd_block(c, block, argc, argv, NULL);
    int e = r ? 0 : fail_errno(c);

    rds_pool_put(s->pool, c);
    errno = e;
    return r;
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

static int make_group(rds *c, const char *stream)
{
    redisReply *r = rds_cmdl(c, "XGROUP", "CREATE", stream, GROUP, "0",
                             "MKSTREAM", NULL);
    if (r || rds_error_is(c, "BUSYGROUP")) {
        rds_reply_free(r);
        return 0;
    }
    return -1;
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
    if (!name_ok(cfg->prefix) || cfg->pool < 1 || cfg->max_runs < 1 ||
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
    pthread_mutex_init(&s->mu, NULL);
    if (!(s->pool = rds_pool_new(rc, cfg->pool))) {
        snprintf(msg, msgsize, "out of memory");
        rstore_close(s);
        return NULL;
    }
    c = rds_pool_get(s->pool);
    if (make_group(c, s->k_queue) != 0 || make_group(c, s->k_front) != 0) {
        snprintf(msg, msgsize, "%s", rds_errmsg(c));
        rds_pool_put(s->pool, c);
        rstore_close(s);
        return NULL;
    }
    proto = proto_max(c);
    rds_pool_put(s->pool, c);
    s->max_blob = proto - PROTO_SLACK < cfg->max_blob ? proto - PROTO_SLACK
                                                      : cfg->max_blob;
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

int rstore_ready(rstore *s, char *why, size_t size)
{
    rds *c = rds_pool_get(s->pool);
    /* a read, not PING: a server loading its AOF answers PING */
    redisReply *r = rds_cmdl(c, "EXISTS", s->k_queue, NULL);

    if (!r)
        snprintf(why, size, "%s", rds_errmsg(c));
    rds_pool_put(s->pool, c);
    rds_reply_free(r);
    return r ? 0 : -1;
}

/* ---------------------------------------------------- records and blobs */

int rstore_create(rstore *s, const char *id, const rstore_blob *b, int n)
{
    const char *argv[32];
    size_t lens[32];
    job_keys k;
    int i, argc = 0;

    if (!name_ok(id) || n < 0 || 6 + 2 * n > 32) {
        errno = EINVAL;
        return -1;
    }
    keys_of(s, id, &k);
    argv[argc++] = k.hash;
    argv[argc++] = s->k_jobs;
    argv[argc++] = k.ev;
    argv[argc++] = k.blobs;
    argv[argc++] = s->ttl_ms;
    argv[argc++] = id;
    for (i = 0; i < argc; i++)
        lens[i] = strlen(argv[i]);
    for (i = 0; i < n; i++) {
        if (!name_ok(b[i].name)) {
            errno = EINVAL;
            return -1;
        }
        if (b[i].len > s->max_blob) {
            errno = EFBIG;
            return -1;
        }
        argv[argc] = b[i].name;
        lens[argc++] = strlen(b[i].name);
        argv[argc] = b[i].data;
        lens[argc++] = b[i].len;
    }
    return eval_int(s, &lua_create, 3, argc, argv, lens, NULL);
}

int rstore_put(rstore *s, const char *id, const char *name,
               const void *data, size_t len, int fence)
{
    job_keys k;
    const char *argv[7];
    size_t lens[7];
    int i;

    if (!name_ok(id) || !name_ok(name)) {
        errno = EINVAL;
        return -1;
    }
    if (len > s->max_blob) {
        errno = EFBIG;
        return -1;
    }
    keys_of(s, id, &k);
    argv[0] = k.hash;
    argv[1] = k.ev;
    argv[2] = k.blobs;
    argv[3] = s->ttl_ms;
    argv[4] = name;
    argv[6] = fence ? s->cfg.consumer : "";
    for (i = 0; i < 7; i++)
        lens[i] = i == 5 ? len : strlen(argv[i]);
    argv[5] = data ? data : "";
    return eval_int(s, &lua_put, 2, 7, argv, lens, NULL);
}

/* A large blob's size and version: 0, or -1 and errno (ENOENT). The
 * size is the server's word: bounded by max_blob before anyone trusts
 * it. */
static int blob_meta(rstore *s, const job_keys *k, const char *name,
                     size_t *size, long long *version)
{
    char sf[RSTORE_ID_MAX + 2], vf[RSTORE_ID_MAX + 2];
    const char *argv[4] = {"HMGET", k->hash, sf, vf};
    redisReply *r;
    long long n, v = 0;

    snprintf(sf, sizeof sf, "s:%s", name);
    snprintf(vf, sizeof vf, "v:%s", name);
    if (!(r = cmd(s, 0, 4, argv)))
        return -1;
    if (r->type != REDIS_REPLY_ARRAY || r->elements != 2) {
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
    rds_reply_free(r);
    *size = (size_t)n;
    *version = v;
    return 0;
}

/* len bytes of key at off, exactly: 0 or -1 and errno. */
static int read_range(rstore *s, const char *key, size_t off, char *buf,
                      size_t len)
{
    while (len > 0) {
        size_t n = len < SLICE ? len : SLICE;
        char a[24], b[24];
        const char *argv[4] = {"GETRANGE", key, a, b};
        redisReply *r;

        snprintf(a, sizeof a, "%zu", off);
        snprintf(b, sizeof b, "%zu", off + n - 1);
        if (!(r = cmd(s, 0, 4, argv)))
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
    if (!(r = cmd(s, 0, 3, argv)))
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

    if (!name_ok(id) || !name_ok(name)) {
        errno = EINVAL;
        return -1;
    }
    keys_of(s, id, &k);
    if (is_field(name))
        return get_field(s, &k, name, data, len);
    snprintf(key, sizeof key, "%s%s", k.blobs, name);
    /* read in slices; a put between them changes the version: again */
    for (tries = 0; tries < 3; tries++) {
        size_t size, size2;
        long long v, v2;
        char *buf;

        if (blob_meta(s, &k, name, &size, &v) != 0)
            return -1;
        if (!(buf = malloc(size + 1))) {
            errno = ENOMEM;
            return -1;
        }
        if (read_range(s, key, 0, buf, size) == 0 &&
            blob_meta(s, &k, name, &size2, &v2) == 0 && v2 == v &&
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

    if (!name_ok(id) || !name_ok(name) || is_field(name)) {
        errno = EINVAL;
        return -1;
    }
    keys_of(s, id, &k);
    if (blob_meta(s, &k, name, &size, &v) != 0)
        return -1;
    if (off > size || len > size - off) {
        errno = EIO;
        return -1;
    }
    snprintf(key, sizeof key, "%s%s", k.blobs, name);
    return read_range(s, key, off, buf, len);
}

int rstore_stat(rstore *s, const char *id, const char *name, size_t *size)
{
    job_keys k;
    long long v;

    if (!name_ok(id) || !name_ok(name)) {
        errno = EINVAL;
        return -1;
    }
    keys_of(s, id, &k);
    if (is_field(name)) {
        char f[RSTORE_ID_MAX + 2];
        const char *argv[3] = {"HSTRLEN", k.hash, f};
        const char *argx[3] = {"HEXISTS", k.hash, f};
        redisReply *r;
        long long n = 0, e = 0;

        snprintf(f, sizeof f, "b:%s", name);
        if (!(r = cmd(s, 0, 3, argv)))
            return -1;
        if (rds_reply_ll(r, &n) != 0 || n < 0) {
            rds_reply_free(r);
            errno = EIO;
            return -1;
        }
        rds_reply_free(r);
        if (n == 0) {
            if (!(r = cmd(s, 0, 3, argx)))
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
    return blob_meta(s, &k, name, size, &v);
}

static int remove_as(rstore *s, const char *id, const char *to)
{
    job_keys k;
    const char *argv[6];

    if (!name_ok(id)) {
        errno = EINVAL;
        return -1;
    }
    keys_of(s, id, &k);
    argv[0] = k.hash;
    argv[1] = s->k_jobs;
    argv[2] = k.ev;
    argv[3] = k.blobs;
    argv[4] = id;
    argv[5] = to;
    return eval_int(s, &lua_remove, 3, 6, argv, NULL, NULL);
}

int rstore_remove(rstore *s, const char *id)
{
    return remove_as(s, id, "");
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

    if (!name_ok(id))
        return 0;
    keys_of(s, id, &k);
    argv[0] = k.hash;
    if (eval_int(s, &lua_usage, 1, 1, argv, NULL, &n) != 0 || n < 0)
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

        if (e->type != REDIS_REPLY_STRING || !name_ok(e->str))
            continue;                  /* not ours: never a key */
        keys_of(s, e->str, &k);
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
    errno = rc == 0 ? 0 : rc == -2 ? EIO : fail_errno(c);
    rds_pool_put(s->pool, c);
    return rc == 0 ? 0 : -1;
}

/* ------------------------------------------------------------ queue */

int rstore_push(rstore *s, const char *id, int front)
{
    job_keys k;
    char max[24];
    const char *argv[4];
    redisReply *r;

    if (!name_ok(id)) {
        errno = EINVAL;
        return -1;
    }
    keys_of(s, id, &k);
    snprintf(max, sizeof max, "%ld", s->cfg.queue_max);
    argv[0] = front ? s->k_front : s->k_queue;
    argv[1] = k.hash;
    argv[2] = id;
    argv[3] = max;
    if (!(r = eval(s, &lua_push, 2, 4, argv, NULL)))
        return -1;
    rds_reply_free(r);
    return 0;
}

/* Appends an entry read from a stream to the held list (once). */
static void hold(rstore *s, const char *id, const char *entry, int front)
{
    int i;

    pthread_mutex_lock(&s->mu);
    for (i = 0; i < s->nheld; i++)
        if (strcmp(s->held[i].entry, entry) == 0)
            break;
    if (i == s->nheld && s->nheld < HELD_MAX) {
        held_entry *h = &s->held[s->nheld++];
        snprintf(h->id, sizeof h->id, "%s", id);
        snprintf(h->entry, sizeof h->entry, "%s", entry);
        h->front = front;
    }
    /* beyond HELD_MAX the entry stays pending on this consumer and the
     * reaper of some replica takes it after claim_idle */
    pthread_mutex_unlock(&s->mu);
}

/* Stream entries [[entry, [field, value...]], ...] into the held list;
 * the number of them. */
static int hold_entries(rstore *s, const redisReply *list, int front)
{
    size_t i;
    int n = 0;

    if (!list || list->type != REDIS_REPLY_ARRAY)
        return 0;
    for (i = 0; i < list->elements; i++) {
        const redisReply *e = list->element[i], *job;
        if (e->type != REDIS_REPLY_ARRAY || e->elements != 2 ||
            e->element[0]->type != REDIS_REPLY_STRING ||
            e->element[0]->len >= RSTORE_ID_MAX)
            continue;
        job = rds_reply_field(e->element[1], "job");
        if (!job || job->type != REDIS_REPLY_STRING || !name_ok(job->str))
            continue;                  /* the reaper acknowledges it */
        hold(s, job->str, e->element[0]->str, front);
        n++;
    }
    return n;
}

/* XAUTOCLAIM of one stream, a few pages: entries taken over. */
static int reap_stream(rstore *s, const char *stream, int front,
                       double min_idle)
{
    char idle[24], start[RSTORE_ID_MAX] = "0-0";
    int pages, n = 0;

    snprintf(idle, sizeof idle, "%lld", (long long)(min_idle * 1000));
    for (pages = 0; pages < 8; pages++) {
        const char *argv[8] = {"XAUTOCLAIM", stream, GROUP,
                               s->cfg.consumer, idle, start, "COUNT", "32"};
        rds *c = rds_pool_get(s->pool);
        redisReply *r = rds_cmd(c, 8, argv, NULL);
        int e = r ? 0 : fail_errno(c);

        rds_pool_put(s->pool, c);
        if (!r) {
            errno = e;
            return -1;
        }
        /* [next, [[entry, fields]...], [deleted...]] (7.0) */
        if (r->type != REDIS_REPLY_ARRAY || r->elements < 2 ||
            r->element[0]->type != REDIS_REPLY_STRING ||
            r->element[0]->len >= sizeof start) {
            rds_reply_free(r);
            errno = EIO;
            return -1;
        }
        n += hold_entries(s, r->element[1], front);
        snprintf(start, sizeof start, "%s", r->element[0]->str);
        rds_reply_free(r);
        if (strcmp(start, "0-0") == 0)
            break;
    }
    return n;
}

int rstore_reap(rstore *s, double min_idle)
{
    int a, b;

    if (min_idle < 0)
        min_idle = s->cfg.claim_idle;
    if ((a = reap_stream(s, s->k_front, 1, min_idle)) < 0)
        return -1;
    b = reap_stream(s, s->k_queue, 0, min_idle);
    return b < 0 ? -1 : a + b;
}

int rstore_lease(rstore *s, const char *name, double ttl, char *holder,
                 size_t size)
{
    char key[KEY_MAX], ms[24];
    const char *argv[3] = {key, s->cfg.consumer, ms};
    redisReply *r;
    int rc;

    if (!name_ok(name)) {
        errno = EINVAL;
        return -1;
    }
    snprintf(key, sizeof key, "%s:lease:%s", s->cfg.prefix, name);
    snprintf(ms, sizeof ms, "%lld", (long long)(ttl * 1000));
    if (!(r = eval(s, &lua_lease, 1, 3, argv, NULL)))
        return -1;
    rc = r->type == REDIS_REPLY_INTEGER ? 1 : 0;
    if (!rc)
        snprintf(holder, size, "%.*s", r->type == REDIS_REPLY_STRING
                                           ? (int)r->len : 0, r->str);
    rds_reply_free(r);
    return rc;
}

/* XREADGROUP of one entry from stream: 1 held, 0 none, -1. */
static int read_new(rstore *s, const char *stream, int front, double block)
{
    char ms[24];
    const char *argv[11] = {"XREADGROUP", "GROUP", GROUP, s->cfg.consumer,
                            "COUNT", "1", "BLOCK", ms, "STREAMS", stream,
                            ">"};
    rds *c = rds_pool_get(s->pool);
    redisReply *r;
    int n = 0, e = 0, again;

    snprintf(ms, sizeof ms, "%lld", (long long)(block * 1000));
    for (again = 0; again < 2; again++) {
        r = block > 0 ? rds_cmd_block(c, block, 11, argv, NULL)
                      : rds_cmd(c, 9, (const char *[]){argv[0], argv[1],
                                argv[2], argv[3], argv[4], argv[5], argv[8],
                                argv[9], argv[10]}, NULL);
        /* a Redis that lost the group (no AOF, or FLUSHALL): again */
        if (r || !rds_error_is(c, "NOGROUP") || make_group(c, stream) != 0)
            break;
    }
    if (!r)
        e = fail_errno(c);
    rds_pool_put(s->pool, c);
    if (!r) {
        errno = e;
        return -1;
    }
    /* nil, or [[stream, [[entry, fields]]]] */
    if (r->type == REDIS_REPLY_ARRAY && r->elements == 1 &&
        r->element[0]->type == REDIS_REPLY_ARRAY &&
        r->element[0]->elements == 2)
        n = hold_entries(s, r->element[0]->element[1], front);
    rds_reply_free(r);
    return n > 0;
}

/* The take script for h: RSTORE_*, 0 for "not ours", -1. */
static int take(rstore *s, const held_entry *h, char id[RSTORE_ID_MAX],
                int *runs)
{
    job_keys k;
    char max[16], dmax[24], idle[24];
    const char *argv[10];
    redisReply *r;
    long long code = 0, n = 0, retaken = 0;

    keys_of(s, h->id, &k);
    snprintf(max, sizeof max, "%d", s->cfg.max_runs);
    snprintf(dmax, sizeof dmax, "%ld", s->cfg.dead_max);
    argv[0] = h->front ? s->k_front : s->k_queue;
    argv[1] = k.hash;
    argv[2] = s->k_dead;
    argv[3] = GROUP;
    argv[4] = h->entry;
    argv[5] = s->cfg.consumer;
    argv[6] = max;
    argv[7] = dmax;
    argv[8] = h->id;
    argv[9] = idle;
    snprintf(idle, sizeof idle, "%lld",
             (long long)(s->cfg.claim_idle * 1000));
    if (!(r = eval(s, &lua_take, 3, 10, argv, NULL)))
        return -1;
    if (r->type != REDIS_REPLY_ARRAY || r->elements < 1 ||
        rds_reply_ll(r->element[0], &code) != 0 ||
        (r->elements > 1 && rds_reply_ll(r->element[1], &n) != 0) ||
        (r->elements > 2 && rds_reply_ll(r->element[2], &retaken) != 0)) {
        rds_reply_free(r);
        errno = EIO;
        return -1;
    }
    rds_reply_free(r);
    if (code != 1 && code != 2)
        return 0;
    snprintf(id, RSTORE_ID_MAX, "%s", h->id);
    if (runs)
        *runs = (int)n;
    return code == 2 ? RSTORE_DEAD : retaken ? RSTORE_RETAKEN : RSTORE_TAKEN;
}

/* The held head if fits() takes it: 1 and *out (removed from the list),
 * 0 when none or it does not fit. */
static int offer_head(rstore *s, int (*fits)(void *ctx, const char *id),
                      void *ctx, held_entry *out)
{
    int got = 0;

    pthread_mutex_lock(&s->mu);
    if (s->nheld > 0 && (!fits || fits(ctx, s->held[0].id))) {
        *out = s->held[0];
        memmove(&s->held[0], &s->held[1],
                (size_t)(--s->nheld) * sizeof *s->held);
        got = 1;
    }
    pthread_mutex_unlock(&s->mu);
    return got;
}

static int reap_due(rstore *s)
{
    double now = rds_monotonic();
    int due;

    pthread_mutex_lock(&s->mu);
    due = now >= s->next_reap;
    if (due)
        s->next_reap = now + s->cfg.claim_idle / 4;
    pthread_mutex_unlock(&s->mu);
    return due;
}

int rstore_claim(rstore *s, int (*fits)(void *ctx, const char *id),
                 void *ctx, char id[RSTORE_ID_MAX], int *runs)
{
    int step;

    /* a bounded number of rounds: entries that turn out not to be ours
     * (taken over, removed) are skipped, a few at a time */
    for (step = 0; step < 16; step++) {
        held_entry h;
        int rc, nheld;

        if (offer_head(s, fits, ctx, &h)) {
            rc = take(s, &h, id, runs);
            if (rc != 0)
                return rc;
            continue;
        }
        pthread_mutex_lock(&s->mu);
        nheld = s->nheld;
        pthread_mutex_unlock(&s->mu);
        if (nheld > 0)
            return RSTORE_EMPTY;       /* the head does not fit */
        if (reap_due(s) && rstore_reap(s, -1) > 0)
            continue;
        if ((rc = read_new(s, s->k_front, 1, 0)) < 0)
            return -1;
        if (rc == 0 && (rc = read_new(s, s->k_queue, 0, s->cfg.block)) < 0)
            return -1;
        if (rc == 0)
            return RSTORE_EMPTY;
    }
    return RSTORE_EMPTY;
}

/* A script on the job's hash, as this consumer (KEYS: hash, events;
 * ARGV: group, consumer, blob prefix, ttl): 0 or -1. */
static int job_script(rstore *s, rds_script *sc, const char *id)
{
    job_keys k;
    const char *argv[6];

    if (!name_ok(id)) {
        errno = EINVAL;
        return -1;
    }
    keys_of(s, id, &k);
    argv[0] = k.hash;
    argv[1] = k.ev;
    argv[2] = GROUP;
    argv[3] = s->cfg.consumer;
    argv[4] = k.blobs;
    argv[5] = s->ttl_ms;
    return eval_int(s, sc, 2, 6, argv, NULL, NULL);
}

int rstore_ack(rstore *s, const char *id)
{
    return job_script(s, &lua_ack, id);
}

int rstore_drop(rstore *s, const char *id)
{
    return job_script(s, &lua_drop, id);
}

int rstore_heartbeat(rstore *s, const char *id)
{
    return job_script(s, &lua_heartbeat, id);
}

/* ---------------------------------------------------------- progress */

int rstore_progress(rstore *s, const char *id, const char *line,
                    size_t len)
{
    job_keys k;
    char max[24];
    const char *argv[4];
    size_t lens[4];
    redisReply *r;

    if (!name_ok(id)) {
        errno = EINVAL;
        return -1;
    }
    keys_of(s, id, &k);
    snprintf(max, sizeof max, "%ld", s->cfg.ev_max);
    argv[0] = k.ev;
    argv[1] = line;
    argv[2] = max;
    argv[3] = s->ttl_ms;
    lens[0] = strlen(k.ev);
    lens[1] = len;
    lens[2] = strlen(max);
    lens[3] = strlen(s->ttl_ms);
    if (!(r = eval(s, &lua_progress, 1, 4, argv, lens)))
        return -1;
    rds_reply_free(r);
    return 0;
}

int rstore_events(rstore *s, const char *id, char after[RSTORE_ID_MAX],
                  double block,
                  void (*fn)(const char *line, size_t len, void *ctx),
                  void *ctx)
{
    job_keys k;
    char ms[24];
    const char *argv[8] = {"XREAD", "COUNT", "256", "BLOCK", ms, "STREAMS",
                           k.ev, after};
    redisReply *r, *list;
    size_t i;
    int n = 0;

    if (!name_ok(id)) {
        errno = EINVAL;
        return -1;
    }
    keys_of(s, id, &k);
    snprintf(ms, sizeof ms, "%lld", (long long)(block * 1000));
    if (!(r = cmd(s, block, 8, argv)))
        return -1;
    if (r->type == REDIS_REPLY_NIL) {
        rds_reply_free(r);
        return 0;
    }
    /* [[stream, [[entry, [l, line]]...]]] */
    if (r->type != REDIS_REPLY_ARRAY || r->elements != 1 ||
        r->element[0]->type != REDIS_REPLY_ARRAY ||
        r->element[0]->elements != 2 ||
        r->element[0]->element[1]->type != REDIS_REPLY_ARRAY) {
        rds_reply_free(r);
        errno = EIO;
        return -1;
    }
    list = r->element[0]->element[1];
    for (i = 0; i < list->elements; i++) {
        const redisReply *e = list->element[i], *l;
        if (e->type != REDIS_REPLY_ARRAY || e->elements != 2 ||
            e->element[0]->type != REDIS_REPLY_STRING ||
            e->element[0]->len >= RSTORE_ID_MAX)
            continue;
        snprintf(after, RSTORE_ID_MAX, "%s", e->element[0]->str);
        l = rds_reply_field(e->element[1], "l");
        if (l && l->type == REDIS_REPLY_STRING) {
            fn(l->str, l->len, ctx);
            n++;
        }
    }
    rds_reply_free(r);
    return n;
}
