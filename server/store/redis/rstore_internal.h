/* SPDX-License-Identifier: MIT */
/*
 * rstore_internal.h - what the Redis store's files share: the store's
 * state, the keys of a job, the Lua helpers of the scripts, and the calls
 * on a pooled connection. Only rstore*.c include it. Calls go one way:
 * rstore_queue.c (the queue) over rstore_jobs.c (open, records, blobs)
 * over rstore_files.c (blobs in files) and rstore_server.c (the server's
 * settings); all over rstore_cmd.c (keys, commands).
 */
#ifndef RSTORE_INTERNAL_H
#define RSTORE_INTERNAL_H

#include <pthread.h>

#include "rstore.h"

#define GROUP "workers"
#define HELD_MAX 64               /* entries read but not taken yet */
#define KEY_MAX 320
#define REF_MAX (KEY_MAX + 128) /* a blob file's name under blob_dir */

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
    char p_ctl[KEY_MAX];       /* P:ctl: (+ a consumer: its control stream) */
    char k_ctl[KEY_MAX];       /* this replica's control stream */
    char ctl_after[RSTORE_ID_MAX];  /* read so far (watch: one thread) */
    pthread_mutex_t mu;        /* held, next_reap */
    held_entry held[HELD_MAX];
    int nheld;
    double next_reap;
    double next_sweep;
    char notes[1024];          /* what the server's settings mean for the
                                  jobs (rstore_server.c) */
    int notes_warn;            /* they may lose or evict jobs */
};

/* The blobs of one call written to files (--blob-dir): each one's
 * "@NAME" and "SIZE REF" arguments, and REF to remove when the script
 * refused them. */
#define FILES_MAX 16
typedef struct {
    char name[FILES_MAX][RSTORE_ID_MAX + 1];
    char arg[FILES_MAX][KEY_MAX + 160];
    char ref[FILES_MAX][REF_MAX];
    int n;
} rstore_files;

/* The keys of job id: its hash, its events, its blobs' prefix. */
typedef struct {
    char hash[KEY_MAX], ev[KEY_MAX], blobs[KEY_MAX];
} job_keys;

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
/* A mark {s: NAME} on the job's events stream (KEYS[2]) when the blob
 * written (a Lua expression) is its state or a cancel: rstore_watch
 * wakes the followers on other replicas at once. */
#define LUA_MARK(name)                                                    \
    "if " name " == 'state.json' or " name " == 'cancel.json' then\n"     \
    "  redis.call('XADD', KEYS[2], '*', 's', " name ") end\n"
/* write(h, bp, name, data): one blob, in the hash or its own key; a
 * name "@NAME": data is "SIZE FILE", the file holding NAME's bytes
 * (--blob-dir), published as field f:NAME */
#define LUA_WRITE                                                         \
    "local function write(h, bp, name, data)\n"                           \
    "  if string.sub(name, -5) == '.json' then\n"                         \
    "    redis.call('HSET', h, 'b:' .. name, data)\n"                     \
    "  elseif string.sub(name, 1, 1) == '@' then\n"                      \
    "    local n = string.sub(name, 2)\n"                                  \
    "    local sp = string.find(data, ' ', 1, true)\n"                     \
    "    redis.call('HSET', h, 's:' .. n, string.sub(data, 1, sp - 1),\n"  \
    "               'f:' .. n, string.sub(data, sp + 1))\n"                \
    "    redis.call('HINCRBY', h, 'v:' .. n, 1)\n"                         \
    "  else\n"                                                            \
    "    redis.call('SET', bp .. name, data)\n"                           \
    "    redis.call('HSET', h, 's:' .. name, #data)\n"                    \
    "    redis.call('HINCRBY', h, 'v:' .. name, 1)\n"                     \
    "  end\n"                                                             \
    "end\n"


/* rstore_cmd.c: keys and commands. */
/* errno for the failure c reports. */
int rstore__errno(rds *c);
/* Ids and blob names become parts of keys: letters, digits, . _ - */
int rstore__name_ok(const char *s);
/* The keys of job id: 0, or -1 and EINVAL when id cannot be a key. */
int rstore__keys(const rstore *s, const char *id, job_keys *k);
/* One script on a pooled connection: its reply, or NULL and errno. */
redisReply *rstore__eval(rstore *s, rds_script *sc, int nkeys, int argc,
                         const char **argv, const size_t *lens);
/* A script whose reply is an integer: 0 and *v, or -1 and errno. */
int rstore__eval_int(rstore *s, rds_script *sc, int nkeys, int argc,
                     const char **argv, const size_t *lens, long long *v);
/* A command of C strings on a pooled connection. */
redisReply *rstore__cmd(rstore *s, double block, int argc,
                        const char **argv);
/* The consumer group on stream, made when missing: 0 or -1. */
int rstore__make_group(rds *c, const char *stream);

/* rstore_jobs.c: a call's blobs. */
/* The lengths of argv[0..*argc) (C strings), then the name and bytes of
 * each of the n blobs appended (*argc advanced; room for 2n more): 0, or
 * -1 and errno (EINVAL: a name that cannot be a key, EFBIG: over
 * max_blob). */
int rstore__blob_args(rstore *s, const char *id, const rstore_blob *b,
                      int n, const char **argv, size_t *lens, int *argc,
                      rstore_files *f);
/* After the script of a call whose blobs went to files: rc its result;
 * refused (errno ESTALE, ENOENT, EEXIST, ENOSPC), the files go (when the
 * reply was lost they stay: the sweep removes them if unnamed). rc. */
int rstore__files_end(rstore *s, rstore_files *f, int rc);

/* rstore_server.c: the server's eviction policy (refused unless
 * cfg.allow_eviction: msg says why) and persistence, into notes: 0 or
 * -1. */
int rstore__server_check(rstore *s, rds *c, char *msg, size_t msgsize);

/* rstore_files.c: the blob directory (--blob-dir). */
int rstore__files_check(rstore *s, char *msg, size_t msgsize);
int rstore__file_write(rstore *s, const char *id, const char *name,
                       const void *data, size_t len, char *ref,
                       size_t refsize);
void rstore__file_unlink(rstore *s, const char *ref);
int rstore__file_open(rstore *s, const char *ref, size_t size);
int rstore__file_read(int fd, size_t off, char *buf, size_t len);
void rstore__files_remove(rstore *s, const char *id);

#endif /* RSTORE_INTERNAL_H */
