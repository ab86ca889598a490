/* SPDX-License-Identifier: MIT */
/*
 * rstore.h - the job store in Redis that any number of mcfd replicas
 * share (issue 22): job records, the queue, result blobs, progress and
 * the reaper, as functions over rds (rds.h). Its operations are those of
 * the service's store interface (server/store.h of the redesign, issue
 * 18), so that the Redis backend is a thin table of them.
 *
 * Keys (P is the configured prefix, "mcfd" by default; {id} a job id)
 *   P:job:{id}        hash, the job's record: its small blobs (names
 *                     ending ".json": request, state, metrics) as fields
 *                     "b:NAME"; "s:NAME" = the size of each other blob;
 *                     "runner" (the consumer running it), "entry" (its
 *                     queue entry), "runs" (times a worker took it)
 *   P:blob:{id}:NAME  string, a large blob (input, target, result.EXT,
 *                     fields.bin, events.*): read in slices (GETRANGE)
 *   P:ev:{id}         stream, the progress lines of its runs (MAXLEN ~)
 *   P:jobs            set of the ids held (scan)
 *   P:queue           stream, the queue; consumer group "workers"
 *   P:front           stream, jobs put back at the head (read first)
 *   P:dead            stream, dead letters: {job, runs, reason} (MAXLEN ~)
 *   P:ctl:{consumer}  stream, a replica's control: {job} for each cancel
 *                     asked (on any replica) of a job it runs (MAXLEN ~)
 *   P:quarantine:...  the keys of a quarantined job, renamed
 * With blob_dir (--blob-dir), a large blob is instead the file
 * DIR/P/{id}/NAME.UNIQUE, named by the hash's field "f:NAME"; Redis
 * keeps records, queue and progress. A file is written whole under a
 * name no other write uses (temp file, fsync, rename, fsync of the
 * directory) before the script that publishes its name runs: the
 * script's fencing still decides the one visible result, and a reader
 * sees the old file or the new, never part of one. A refused write's
 * files are removed at once; rstore_sweep() (claim runs it every
 * blob_sweep seconds) removes the files no record names and older than
 * blob_grace: replaced blobs, a dead runner's, expired or removed jobs'.
 * Every key of a job expires ttl seconds after its last write (puts,
 * heartbeats and progress renew it): a job whose every replica died
 * leaves nothing behind for ever. The service removes jobs itself at
 * its result TTL; ttl is a bound above that.
 *
 * Semantics (tests/test_rstore.c checks each line on a real redis-server)
 *   - Atomic records. create() writes every blob, the record and the
 *     set entry in one Lua script (all or nothing; EEXIST when the job
 *     exists). put() replaces one blob whole (a reader sees the old bytes
 *     or the new). A blob over proto-max-bulk-len (read from the server
 *     at open; 512 MiB when CONFIG is not allowed) or over max_blob is
 *     refused with EFBIG before anything is sent.
 *   - Durability. A write is acknowledged after Redis appended it to its
 *     AOF buffer and wrote it to the file (Redis flushes the AOF before it
 *     replies), so a restart of redis-server (even kill -9) loses nothing
 *     acknowledged; with appendfsync always neither does a machine crash
 *     (everysec: up to a second of writes). docker/kubernetes-redis.yaml
 *     and compose-redis.yaml run Redis with appendfsync always.
 *   - Queue: at-least-once. push() XADDs to P:queue (front: P:front); a
 *     queue already holding queue_max entries refuses with EAGAIN (the
 *     service's 503) instead of trimming: MAXLEN would drop waiting jobs.
 *     A job already waiting is not queued twice; an entry of a job whose
 *     other entry runs with heartbeats is dropped when read (a job queued
 *     again, by a restart's recovery, while its run goes on).
 *     claim() reads P:front, then P:queue with XREADGROUP BLOCK; a read
 *     entry is offered to fits(): not fitting, it is held by this replica
 *     (offered again first, in order) without heartbeats, so the reaper of
 *     a replica with room takes it after claim_idle. Taking a job is one
 *     script: the entry must still be pending on this consumer; the job's
 *     runs is incremented and runner set. An acknowledged entry is deleted
 *     from the stream (XACK + XDEL): the queue holds only what is waiting
 *     or running.
 *   - Heartbeats and the reaper. heartbeat() resets the entry's idle time
 *     (XCLAIM ... JUSTID) only while this consumer owns it (else ESTALE:
 *     another replica took the job; ENOENT: its record is gone). The reaper (in claim, at most every
 *     claim_idle/4) takes entries idle longer than claim_idle with
 *     XAUTOCLAIM, from any consumer: a replica that died (kill -9, lost
 *     node) or held a job it had no room for. Entries whose stream entry
 *     was deleted are acknowledged.
 *   - Dead letters. A job taken more than max_runs times (its runners
 *     died each time) is not run again: it is XADDed to P:dead with the
 *     reason, acknowledged, and claim() reports it (RSTORE_DEAD) so the
 *     service marks it failed with that reason.
 *   - Fencing: one visible result. A put() or ack() with fence set, by a
 *     replica whose run was taken over (runner is another consumer), is
 *     refused with ESTALE and writes nothing; the new runner finds the
 *     state the old one left (the service runs only queued jobs; a
 *     takeover is reported by claim() as RSTORE_RETAKEN, so the service
 *     re-queues a job whose state says running).
 *   - One step at the end. finish() writes a run's blobs and acks its
 *     entry in one script, fenced like put() and ack().
 *   - Progress. progress() XADDs a line to P:ev:{id} (MAXLEN ~ ev_max);
 *     events() reads them after a given entry id, blocking up to a bound:
 *     a follower on any replica sees every line, in order, late or not.
 *     A put() of state.json or cancel.json and finish() add a mark to
 *     the same stream (an entry {s: NAME}), so that watch() wakes a
 *     follower at a change of state as at a step.
 *   - Redis unreachable or loading its AOF: every call fails at once with
 *     EAGAIN (rds's backoff), ready() says why; nothing blocks past
 *     command_timeout (claim: plus its block time).
 *
 * Threads: every function may be called from any thread; each takes a
 * connection of the store's pool for the call (claim holds one while it
 * blocks: the pool needs workers + a few).
 */
#ifndef RSTORE_H
#define RSTORE_H

#include <stddef.h>

#include "rds.h"

#define RSTORE_ID_MAX 64       /* bytes of an id, NUL included */

typedef struct rstore rstore;

typedef struct {
    char prefix[64];           /* "mcfd" */
    char consumer[128];        /* this replica: default host:pid:nonce */
    double ttl;                /* seconds a job's keys outlive a write */
    double claim_idle;         /* seconds without heartbeat before the
                                  reaper takes a running job */
    double block;              /* seconds claim() waits for a job */
    int max_runs;              /* takes before a job is dead */
    long queue_max;            /* entries in P:queue before EAGAIN */
    long ev_max;               /* progress lines kept per job (~) */
    long dead_max;             /* dead letters kept (~) */
    size_t max_blob;           /* bytes of one blob */
    int pool;                  /* connections */
    char blob_dir[512];        /* "": large blobs in Redis; else in files
                                  under this shared directory */
    double blob_grace;         /* seconds an unnamed file is kept (a
                                  write whose script is on its way) */
    double blob_sweep;         /* seconds between sweeps (claim runs them) */
    int allow_eviction;        /* open even when the server's
                                  maxmemory-policy may evict keys */
} rstore_config;

typedef struct {
    const char *name;
    const void *data;
    size_t len;
} rstore_blob;

/* ttl 1 day, claim_idle 30 s, block 1 s, max_runs 3, queue_max 100000,
 * ev_max 10000, dead_max 10000, max_blob 512 MiB, pool 8, consumer
 * host:pid:nonce, blob_dir "", blob_grace 600 s, blob_sweep 60 s. */
void rstore_config_default(rstore_config *cfg);

/* Connects (once, to check the server and read proto-max-bulk-len) and
 * makes the consumer group. NULL with a one-line reason in msg; also
 * when the server's maxmemory-policy is not noeviction (every key of a
 * job has a TTL: volatile-* policies evict them too) or cannot be read,
 * unless cfg->allow_eviction. */
rstore *rstore_open(const rds_config *rc, const rstore_config *cfg,
                    char *msg, size_t msgsize);
void rstore_close(rstore *s);
/* 0, or -1 and why: Redis down or loading, refusing writes (noeviction
 * at maxmemory: a small write is tried), or P:queue or P:front of a type
 * other than stream (no job can be queued). */
int rstore_ready(rstore *s, char *why, size_t size);
/* What the server's settings found at open mean for the jobs, one line
 * for the log: the eviction policy, and what a restart of the server
 * loses (appendonly, appendfsync, save). *warn (may be NULL): 1 when
 * they may lose or evict acknowledged jobs. */
const char *rstore_notes(const rstore *s, int *warn);
/* The consumer name (this replica). */
const char *rstore_consumer(const rstore *s);

/* Records and blobs: 0, or -1 with errno (ENOENT, EEXIST, EFBIG, ESTALE,
 * EAGAIN: Redis down or busy, ENOSPC: Redis out of memory, ENOMEM, EIO:
 * a reply not as expected). fence: 1 while this replica runs the job;
 * RSTORE_UNCLAIMED: only while no replica runs it (else ESTALE). */
#define RSTORE_UNCLAIMED 2
int rstore_create(rstore *s, const char *id, const rstore_blob *b, int n);
int rstore_put(rstore *s, const char *id, const char *name,
               const void *data, size_t len, int fence);
/* The whole blob, malloc'ed and NUL-terminated. */
int rstore_get(rstore *s, const char *id, const char *name, char **data,
               size_t *len);
int rstore_get_at(rstore *s, const char *id, const char *name, size_t off,
                  void *buf, size_t len);
int rstore_stat(rstore *s, const char *id, const char *name, size_t *size);
int rstore_remove(rstore *s, const char *id);
int rstore_quarantine(rstore *s, const char *id);
/* Bytes the job holds in the store, Redis or blob_dir (0 when unknown). */
size_t rstore_usage(rstore *s, const char *id);
int rstore_scan(rstore *s, void (*fn)(const char *id, void *ctx),
                void *ctx);

/* The queue. */
int rstore_push(rstore *s, const char *id, int front);

enum {
    RSTORE_EMPTY = 0,          /* nothing to run now (or the head does not
                                  fit) */
    RSTORE_TAKEN = 1,          /* id is this replica's to run */
    RSTORE_RETAKEN = 2,        /* the same, taken over from a replica that
                                  stopped heartbeating: its state may say
                                  running */
    RSTORE_DEAD = 3            /* id ran max_runs times: dead-lettered,
                                  acknowledged; *runs says how often */
};
/* RSTORE_* or -1 with errno. fits may be NULL (everything fits). */
int rstore_claim(rstore *s, int (*fits)(void *ctx, const char *id),
                 void *ctx, char id[RSTORE_ID_MAX], int *runs);
/* The outcome is recorded: the entry leaves the queue (ESTALE when
 * another replica took the job over). */
int rstore_ack(rstore *s, const char *id);
/* The end of a run in one round trip: the n blobs written (as put()
 * with fence) and the entry acknowledged (as ack()), all or nothing;
 * ESTALE when another replica took the job over. */
int rstore_finish(rstore *s, const char *id, const rstore_blob *b, int n);
/* A queued job canceled: its entry leaves the queue (0 also when it was
 * not queued). */
int rstore_drop(rstore *s, const char *id);
int rstore_heartbeat(rstore *s, const char *id);
/* Runs the reaper now (claim runs it on its own, min_idle < 0: with
 * claim_idle): entries idle over min_idle seconds taken over, or -1. */
int rstore_reap(rstore *s, double min_idle);

/* The blob directory's sweep (above): files removed, or -1 (Redis down:
 * nothing removed). 0 without blob_dir. */
int rstore_sweep(rstore *s);

/* Progress. */
int rstore_progress(rstore *s, const char *id, const char *line,
                    size_t len);
/* Calls fn for each line after entry `after` ("0": from the first),
 * waiting up to block seconds for the first one (0: not at all); after
 * is advanced to the last line given (size RSTORE_ID_MAX); marks are
 * passed over, and the control stream is watch()'s alone. The number of
 * lines, or -1. */
int rstore_events(rstore *s, const char *id, char after[RSTORE_ID_MAX],
                  double block,
                  void (*fn)(const char *line, size_t len, void *ctx),
                  void *ctx);

/* The streams of n jobs at once (0 to RSTORE_WATCH_MAX) and this
 * replica's control stream, one command: waits up to block seconds (0:
 * not at all) for an entry after after[i] on any of them (the control
 * stream's cursor is the store's: one thread at a time calls watch),
 * then calls fn(ctx, i, line, len) for each progress line of job ids[i],
 * fn(ctx, i, NULL, 0) for each mark (its state.json or cancel.json was
 * written: put() and finish() add one), and fn(ctx, -1, id, len) for
 * each cancel of a job this replica runs (a put() of its cancel.json,
 * from any replica), in order; the cursors advanced. The number of
 * calls (0: none within the block), or -1 and errno. */
#define RSTORE_WATCH_MAX 128
typedef void (*rstore_watch_fn)(void *ctx, int i, const char *line,
                                size_t len);
int rstore_watch(rstore *s, int n, const char *const *ids,
                 char (*after)[RSTORE_ID_MAX], double block,
                 rstore_watch_fn fn, void *ctx);

#endif /* RSTORE_H */
