/* SPDX-License-Identifier: MIT */
/*
 * store.h - where the job service keeps its jobs: the records, the queue,
 * the result blobs, and the progress of running jobs. One small interface
 * (a table of operations on an opaque store), so that where jobs live is
 * a choice the doors never see. The local spool (spool.c, a directory per
 * job) is the first implementation; a store shared by several replicas
 * (Redis) is a second one behind the same operations. Only the
 * job service's files include this header.
 *
 * Contract (what the service relies on; a backend must keep every line)
 *
 *   Threads. Every operation may be called from any thread at any time
 *   between open and close, concurrently. The service never calls one
 *   with its own lock held: an operation may block on I/O (a disk, the
 *   network). Operations return 0, or -1 with errno (ENOENT: no such job
 *   or blob; ENOSPC, EDQUOT: no room, transient; EMFILE, ENOMEM, EAGAIN:
 *   transient; anything else: failed).
 *
 *   Records. A job is a set of named blobs: "input", "target" (when
 *   given), "request.json" (what the client asked, written once),
 *   "state.json" (its state, rewritten at every change of status), the
 *   result ("result.<ext>"), "metrics.json", "fields.bin" (fields=true),
 *   and, once it has ended, its progress events ("events.ndjson",
 *   "events.idx"). create() makes them durable before it returns: the job
 *   exists from then on (a crash after create keeps it; a crash during
 *   create leaves nothing a scan reports). put() replaces one blob whole:
 *   a reader sees the old bytes or the new, never a mix; durable puts
 *   survive a crash once they return. remove() forgets every blob of a
 *   job, durably, or leaves the job whole when it fails. quarantine()
 *   moves a damaged job out of sight of scan and get, keeping its bytes
 *   for a person. scan() reports every job id the store holds (a crash's
 *   unfinished writes already cleaned); the service reads each one's
 *   request and state to rebuild its table at start. usage() is the bytes
 *   a job holds (the service's quotas). ready() says whether a job could
 *   be written now (readiness probes).
 *
 *   The queue. Job ids waiting for a worker, in order. push() appends an
 *   id (front: puts it back at the head), after create() or when a job
 *   must run again; a pushed id may be claimed at once by any worker of
 *   any replica sharing the store. claim() offers the head to fits() and
 *   takes it only when fits() says yes (the service's memory admission):
 *   1 and the id, or 0 when the queue is empty or the head does not fit
 *   (it stays the head: order is kept). A claimed id belongs to its
 *   claimer until ack(): the job's outcome is recorded. drop() takes an id
 *   out of the queue (a job canceled while queued); a backend that cannot
 *   may leave it: a worker skips a claimed job whose state is no longer
 *   queued, and acks it. An id may be claimed twice (at-least-once): the
 *   service runs only a job whose state is queued.
 *
 *   Progress. heartbeat() says the claimer of a running job is alive (a
 *   shared queue hands the job of a dead replica to another after a bound
 *   without heartbeats): the service calls it for every job it runs at
 *   each sweep (svc_sweep: once a second in mcfd), also while the job
 *   decodes or encodes. progress() publishes one progress event (an
 *   ndjson line, {"step","t","dt","energy","volume"}) for followers on
 *   other replicas, after every step, from the worker. The local store
 *   needs neither (the service keeps a running job's events in memory):
 *   both are no-ops there. Once the job ends, its events are put as the
 *   blobs "events.ndjson" (the lines) and "events.idx" (the byte offset
 *   past each line, as size_t), not durable, before its outcome.
 *
 *   Who calls what, and where the lock is: the service calls every
 *   operation without its own lock held (claim's fits() callback takes
 *   it briefly); create/push from svc_submit (a door's thread), claim/
 *   ack/put/get from the workers, get/get_at/open/stat from the readers
 *   (any door thread), remove/quarantine/scan from svc_delete, the sweep
 *   and recovery (svc_start, before the workers start).
 *
 *   A store shared by replicas (shared = 1; svc_shared.c does the
 *   service's part): any replica may hold a job in its table that
 *   another runs or finished, so a reader refreshes a job it does not run
 *   from its state.json (svc_job_get), a job it does not hold is loaded
 *   from its record (request.json and state.json, as recovery.c's load),
 *   and the sweep follows the progress of the jobs others run (follow())
 *   and tells its own running jobs of a cancel asked on another replica
 *   (the blob "cancel.json"); a store with watch() also pushes both to
 *   the service's follower thread (svc_shared.c) as they are written. claim() also says 2: the id was taken over
 *   from a replica that stopped heartbeating (its state may say running:
 *   the job is queued again), and 3: the id was dead-lettered (run too
 *   often; the service writes it failed). A put with durable
 *   SVC_PUT_UNCLAIMED (a cancel of a queued job) writes only while no
 *   replica has taken the job, else ESTALE: the store decides whether the
 *   cancel or the start came first, so exactly one replica ends (and
 *   counts) the job. Recovery at start is the
 *   store's own (its reaper): the service loads jobs lazily.
 */
#ifndef SVC_STORE_H
#define SVC_STORE_H

#include <stddef.h>

#include "service.h"

typedef struct svc_store svc_store;

/* put()'s durable: durable, and (a shared store) only while no replica
 * runs the job, else ESTALE (above). */
#define SVC_PUT_UNCLAIMED 2

/* One blob of a job: its name and bytes (create). */
typedef struct {
    const char *name;
    const void *data;
    size_t len;
} svc_blob;

#define SVC_CURSOR_LEN 64      /* a follow() cursor, NUL included */
#define SVC_WATCH_MAX 128      /* jobs of one watch() */

typedef struct {
    const char *name;          /* "spool" */
    void (*close)(svc_store *st);
    int (*ready)(svc_store *st, char *why, size_t size);

    /* records and blobs */
    int (*create)(svc_store *st, const char *id, const svc_blob *blobs,
                  int n);
    int (*put)(svc_store *st, const char *id, const char *name,
               const void *data, size_t len, int durable);
    /* the whole blob, malloc'ed and NUL-terminated */
    int (*get)(svc_store *st, const char *id, const char *name, char **data,
               size_t *len);
    /* len bytes at offset off (all of them, else -1 EIO) */
    int (*get_at)(svc_store *st, const char *id, const char *name,
                  size_t off, void *buf, size_t len);
    /* the blob's size (ENOENT when absent) */
    int (*stat)(svc_store *st, const char *id, const char *name,
                size_t *size);
    /* the blob as a read-only descriptor for zero-copy sending; ENOTSUP
     * when the store has none (the caller then uses get) */
    int (*open)(svc_store *st, const char *id, const char *name, int *fd,
                size_t *size);
    int (*remove)(svc_store *st, const char *id);
    int (*quarantine)(svc_store *st, const char *id);
    size_t (*usage)(svc_store *st, const char *id);
    int (*scan)(svc_store *st, void (*fn)(const char *id, void *ctx),
                void *ctx);

    /* the queue */
    int (*push)(svc_store *st, const char *id, int front);
    int (*claim)(svc_store *st, int (*fits)(void *ctx, const char *id),
                 void *ctx, char id[SVC_ID_LEN + 1]);
    int (*ack)(svc_store *st, const char *id);
    int (*drop)(svc_store *st, const char *id);

    /* progress of a running job */
    int (*heartbeat)(svc_store *st, const char *id);
    int (*progress)(svc_store *st, const char *id, const char *line,
                    size_t len);
    /* the progress lines other replicas published after cursor *after
     * (SVC_CURSOR_LEN bytes, "0": from the first), without waiting; the
     * cursor advanced. The number of lines, or -1 (0: a local store). */
    int (*follow)(svc_store *st, const char *id, char *after,
                  void (*fn)(const char *line, size_t len, void *ctx),
                  void *ctx);

    /* 0: only this process fills the queue (a push wakes the workers);
     * else the seconds an idle worker waits before claiming again (a
     * shared queue that other replicas fill) */
    /* the end of a run in one step, where the store can: the n blobs
     * put (durable, state.json among them) and the id acknowledged, all
     * or nothing (ESTALE: another replica took the job over). NULL: the
     * service puts each blob, then acks. */
    int (*finish)(svc_store *st, const char *id, const svc_blob *blobs,
                  int n);
    /* a shared store, one thread at a time: waits up to block seconds
     * for what other replicas publish on any of the n jobs ids[i] (0 to
     * SVC_WATCH_MAX) after cursor after[i] (advanced), then calls fn(ctx,
     * i, line, len) per progress line, fn(ctx, i, NULL, 0) when the
     * job's state.json or cancel.json was written, and fn(ctx, -1, id,
     * len) when a cancel.json was put for a job this replica runs, in
     * order. The number of calls (0: none within the block), or -1.
     * NULL: the store has none (the sweep's follow() alone). */
    int (*watch)(svc_store *st, int n, const char *const *ids,
                 char (*after)[SVC_CURSOR_LEN], double block,
                 void (*fn)(void *ctx, int i, const char *line, size_t len),
                 void *ctx);

    double poll;
    int shared;                /* other replicas share it (above) */
} svc_store_ops;

struct svc_store {
    const svc_store_ops *ops;
};

/* The local spool (spool.c): a directory per job under dir/jobs, made when
 * missing. NULL with a one-line reason in msg when dir cannot be used. */
svc_store *store_spool_open(const char *dir, char *msg, size_t msgsize);

/* The store in Redis (store_redis.c, rstore.h says its keys and
 * semantics): url redis://HOST[:PORT][/DB], the password read from
 * password_file ("" or NULL: none) at every connect; connections for
 * workers threads; a job's keys kept at least ttl seconds after its last
 * write; blob_dir ("" or NULL: none): the mesh bytes in files there
 * (rstore.h). A server whose maxmemory-policy may evict keys is refused
 * unless allow_eviction; what its settings mean for the jobs (eviction,
 * what a restart loses) is logged. NULL with a one-line reason in msg. */
svc_store *store_redis_open(const char *url, const char *password_file,
                            const char *blob_dir, int workers, double ttl,
                            int allow_eviction, char *msg, size_t msgsize);

#endif /* SVC_STORE_H */
