/* SPDX-License-Identifier: MIT */
/*
 * service.h - the job service of mcfd: the one module that owns jobs
 * (table, queue, workers, runner, store, recovery, drain), and the only
 * way a transport reaches them. Both doors use nothing else: the REST door
 * (http.c and its files, on libmicrohttpd) and the gRPC door (grpc*.cc).
 * No HTTP, MHD or gRPC type appears here, and no message here names a URL.
 *
 * Objects
 *   svc_t     the service: made by svc_start, passed to every call that
 *             is not about one job, ended by svc_stop. Any number may
 *             live in one process, each with its own store and workers.
 *   svc_job   an opaque, reference-counted handle of one job of one
 *             service (the calls on a handle reach its service through
 *             it). svc_submit and svc_job_get hand out a reference;
 *             svc_job_unref drops it. A handle stays valid (readable,
 *             never freed) while held, also after the job was deleted or
 *             expired: it then reads as it was last.
 *   svc_snap  a copy of a job's state taken at one instant: everything a
 *             door shows of a job.
 *   svc_sub   a subscription: "call fn(ctx, what) when this job moves".
 *
 * Threads and locking
 *   Every call may be made from any thread (MHD's pool, gRPC's, the main
 *   thread) between svc_start and svc_stop; the lifecycle calls from one
 *   thread; svc_error_* and svc_problem_* at any time. Each service has
 *   one lock; it is held only for short bookkeeping, never across mesh
 *   work or I/O (disk, the store), and never while calling out, except
 *   for subscription callbacks (below). Callers hold no lock of the
 *   service: what they get back are copies.
 *
 * Subscriptions
 *   fn is called with the service lock held, from the thread that changed
 *   the job (a worker, or whoever called svc_cancel / svc_drain /
 *   svc_close_waiters). It must be quick and must not call back into the
 *   service; it typically takes the door's own lock, records "something
 *   happened" and wakes its connection or reactor, which then reads a
 *   snapshot. Lock order: service lock, then the door's locks. Because a
 *   change and its notification happen under the same lock, a door that
 *   (1) clears its "something happened" flag, (2) reads a snapshot and
 *   (3) goes to sleep only if the flag is still clear, never misses one.
 *   After svc_unsubscribe returns, fn is not running and is never called
 *   again; do not call svc_unsubscribe from fn or while holding a lock fn
 *   takes. The job's lifetime does not depend on its subscriptions: keep
 *   a reference for as long as the subscription.
 *
 * Ownership
 *   Strings and buffers returned through char ** are malloc'ed copies the
 *   caller frees. svc_submit takes the request's buffers and parameters,
 *   also when it fails.
 *
 * Errors
 *   Failures are svc_error values: a problem (a row of SVC_PROBLEMS in
 *   problem.h, the one table of client-visible errors), a precise detail
 *   in words, and a retry delay for transient refusals. The detail never
 *   names a URL, header or status code. Failures of the core and the
 *   codecs find their row from their mcf status and the stage they came
 *   from (svc_error_from_mcf: parameters, the bytes, or this mesh with
 *   these parameters).
 */
#ifndef SVC_SERVICE_H
#define SVC_SERVICE_H

#include <stddef.h>

#include "api.h"
#include "problem.h"  /* svc_problem, svc_code: the client-visible errors */

/* ------------------------------------------------------------------ errors */

/* Why a job was (asked to be) stopped. */
typedef enum {
    SVC_CANCEL_NONE = 0,
    SVC_CANCEL_USER,       /* a client asked (DELETE, CancelJob) */
    SVC_CANCEL_SHUTDOWN,   /* svc_checkpoint_running: runs again later */
    SVC_CANCEL_TIMEOUT,    /* the job timeout passed */
    SVC_CANCEL_CLIENT,     /* the job's only client left (a door saw it) */
    SVC_CANCEL_CPU         /* the job used its CPU budget (svc_config) */
} svc_cancel_reason;

typedef struct {
    svc_problem problem;
    svc_cancel_reason cancel;  /* ECANCELED: why */
    char detail[MCF_ERRMSG_SIZE + 128];
    double retry_after;        /* seconds, > 0 for transient refusals */
} svc_error;

/* The error's service code (its row's). */
svc_code svc_error_code(const svc_error *e);
/* A failure of the core or the codecs at a stage: the row of (the
 * stage's code, s), detail "prefix: message" (prefix may be NULL; err
 * NULL: mcf_strerror(s)). */
void svc_error_from_mcf(svc_error *e, mcf_status s, api_job_stage stage,
                        const char *prefix, const mcf_error *err);
/* Any failure: problem p with the detail; retry_after from its code
 * (EBUSY, EQUOTA, ENOMEM: 1 s; EDRAINING: 5 s). */
void svc_error_set(svc_error *e, svc_problem p, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* ------------------------------------------------------------------ set-up */

typedef struct svc svc_t;

typedef struct {
    int workers;               /* worker threads */
    int cores;                 /* the cores the running jobs share: one
                                  each, and a big job's flow every core
                                  free as it starts (workers.c); 0: one
                                  per worker */
    int queue;                 /* queued jobs beyond the running ones */
    char spool[1024];          /* the local store's directory (made when
                                  missing) */
    char store[1024];          /* redis://HOST[:PORT][/DB]: the jobs in
                                  Redis (store_redis.c); "": the spool */
    char store_password_file[1024]; /* its password's file, "": none */
    char blob_dir[512];        /* Redis store: mesh bytes in files here,
                                  "": in Redis */
    int redis_allow_eviction;  /* Redis store: opened even when its
                                  maxmemory-policy may evict keys */
    int spool_max_jobs;        /* jobs kept before EQUOTA, 0: none */
    size_t spool_max_bytes;    /* bytes of jobs kept before EQUOTA */
    api_limits lim;            /* limits on untrusted input */
    double result_ttl;         /* seconds a finished job is kept */
    double job_timeout;        /* seconds a job may run from its start,
                                  plus job_timeout_per_mib per MiB of its
                                  memory estimate; 0: unlimited */
    double job_timeout_per_mib; /* 0.5 s by default (the CPU budget's
                                  slope: a big scan on one core is not cut
                                  before its budget), 0 once --job-timeout
                                  is given (MCFD_JOB_TIMEOUT_PER_MIB) */
    size_t max_memory;         /* estimated peak of the running jobs */
    size_t max_job_memory;     /* estimated peak of one job (svc_admit.c) */
    double decode_cpu;         /* CPU seconds of a sandboxed decode, floor */
    double job_cpu;            /* a job's CPU budget: these seconds plus
                                  job_cpu_per_mib per MiB of its memory
                                  estimate, on its worker's thread; 0:
                                  none */
    double job_cpu_per_mib;    /* 0.5 s (MCFD_JOB_CPU_PER_MIB) */
    size_t decode_memory;      /* its memory limit, floor (sandbox.c) */
} svc_config;

/* Opens the store, recovers it (queued and interrupted jobs queued again
 * in their order with their IDs, finished ones reloaded until their TTL),
 * then starts the workers. cfg is copied. 0 and *out, or -1 with a reason
 * in msg. */
int svc_start(const svc_config *cfg, svc_t **out, char *msg, size_t msgsize);
/* Stops accepting jobs (EDRAINING); running jobs continue, queued ones
 * stay in the store for the next start. Subscribers of queued jobs hear. */
void svc_drain(svc_t *s);
/* Waits until no job runs or timeout seconds pass. 1 when idle. */
int svc_wait_idle(svc_t *s, double timeout);
/* Stops the running jobs for a restart: they stay `queued` in the store
 * and run again on the next start (unless a user or client canceled
 * them). */
void svc_checkpoint_running(svc_t *s);
/* From now on every door must answer with what it has and never wait
 * again (snapshots say closing); every subscriber is notified. */
void svc_close_waiters(svc_t *s);
/* Joins the workers, frees every job and the service. Every handle and
 * subscription must have been released before (the doors stop first): a
 * handle's calls reach the service through it. Accepts NULL. */
void svc_stop(svc_t *s);
/* Forgets the jobs finished more than the TTL ago (memory and store), and
 * queues again the jobs whose outcome could not be recorded. Called now
 * and then from one thread. */
void svc_sweep(svc_t *s);

typedef struct {
    int queue_depth, queue_capacity;
    int workers, workers_busy;
    int jobs_in_memory;
    int draining;
    double spool_bytes;        /* bytes of the jobs kept */
} svc_gauges;

svc_gauges svc_get_gauges(svc_t *s);
/* Whether a submission now would find room (a hint before the body). */
int svc_can_accept(svc_t *s);
int svc_draining(svc_t *s);
/* Readiness of the store: 0, or -1 and why (a job could not be written
 * now: /readyz). */
int svc_ready(svc_t *s, char *why, size_t size);
/* The limits on untrusted input the service applies (its config's). */
const api_limits *svc_limits(const svc_t *s);

/* Memory for an upload in flight (both doors): its bytes are reserved in
 * --max-memory beside the running jobs' estimates and the other uploads'
 * (svc_admit.c) before they are buffered, so that uploads held open
 * cannot take more than the budget (16 of 40 MiB took 665 MiB). *held is
 * the upload's reservation; this grows it to want bytes (its declared
 * size at once, else SVC_UPLOAD_STEP at a time as bytes come). 0, or -1
 * and EBUSY in e (retry after 1 s) when they do not fit beside what the
 * others hold (an upload alone always fits); then *held is unchanged.
 * Each upload also holds SVC_UPLOAD_AROUND for the memory around its
 * bytes: its connection's buffers, the transport's read slices, the
 * daemon's allocator pools that grow with it (measured: four gRPC uploads
 * at once grew the daemon's resting size by 2-5 MiB). */
#define SVC_UPLOAD_STEP (1024 * 1024)
#define SVC_UPLOAD_AROUND (2 * 1024 * 1024)
int svc_upload_reserve(svc_t *s, size_t *held, size_t want, svc_error *e);
/* Gives it back (the bytes are in the store or dropped): *held 0. */
void svc_upload_release(svc_t *s, size_t *held);

/* --------------------------------------------------------------------- jobs */

#define SVC_ID_LEN 32          /* 128 random bits in lowercase hex */

typedef struct svc_job svc_job;
typedef struct svc_sub svc_sub;

typedef enum {
    SVC_JOB_QUEUED = 0,
    SVC_JOB_RUNNING,
    SVC_JOB_SUCCEEDED,
    SVC_JOB_FAILED,
    SVC_JOB_CANCELED
} svc_job_status;

/* "queued", "running", ... */
const char *svc_job_status_name(svc_job_status s);
/* succeeded, failed or canceled. */
int svc_job_status_terminal(svc_job_status s);

/* A job as a door hands it over: the parameters it parsed (typed, once),
 * the upload's bytes and what the door wants kept. */
typedef struct {
    api_params params;         /* parsed and checked by the door */
    char *input;               /* the mesh's bytes (malloc'ed, len > 0) */
    size_t input_len;
    char *target;              /* a clean mesh to compare with, or NULL */
    size_t target_len;
    char filename[128];        /* sanitized base name of the upload */
    int fields;                /* keep the per-vertex fields document
                                  (svc_job_fields_open) */
    int measures;              /* measure the meshes and keep the step log
                                  for the metrics document (also implied
                                  by a target and by fields); else its
                                  light form (api_job_request.light) */
    int keep_result;           /* keep the encoded result in memory for
                                  the submitter (svc_job_result, TAKE) */
} svc_request;

/* The daemon's own keys of a request's query string (REST's `stream`,
 * `phases`, `fields`, `measures`), NULL-terminated: the parameter parser skips them
 * (api_params_parse_request's `ignore`). */
extern const char *const svc_query_keys[];
/* The query's boolean daemon key `key` ("fields": whether the per-vertex
 * fields document is kept; "measures": whether the metrics document's
 * measures are taken), the last one winning; absent: 0. 0 and *on, or -1
 * and *err. */
int svc_query_flag(const char *query, const char *key, int *on, svc_error *err);

/* An empty request (default parameters, no bytes). */
void svc_request_init(svc_request *rq);
/* Frees what it holds and empties it. */
void svc_request_free(svc_request *rq);

/* Accepts a job: checks its budgets (EPARAMS: the parameters alone
 * exceed a limit; ELIMIT: its estimated memory), admission (EDRAINING,
 * EBUSY, EQUOTA), assigns the ID, writes input, request and state
 * durably to the store (ESTORAGE), then queues it. Takes rq's contents in
 * every case. 0 and *out holds a reference for the caller, or -1 and
 * *err. */
int svc_submit(svc_t *s, svc_request *rq, svc_job **out, svc_error *err);
/* A new reference to the job with that ID (a NUL-terminated string of
 * any content), or NULL and errno: ENOENT (no such job), EAGAIN (a
 * shared store that cannot answer now), ENOMEM. */
svc_job *svc_job_get(svc_t *s, const char *id);
/* svc_job_get for a door: NULL sets *err (ENOTFOUND; ESPOOL with a
 * retry delay when the store cannot say whether the job exists). */
svc_job *svc_job_find(svc_t *s, const char *id, svc_error *err);
/* One more reference to a handle the caller holds; returns j. */
svc_job *svc_job_ref(svc_job *j);
/* Drops a reference (accepts NULL). */
void svc_job_unref(svc_job *j);
/* The job's ID (constant for the handle's life; takes no lock). */
const char *svc_job_id(const svc_job *j);

/* Cancels a queued job at once, or asks a running one to stop at its
 * next step (reason USER or CLIENT), durably first. 1 when this call
 * changed the job, 0 when it had finished or was already canceled, -1
 * when the store could not record it (errno): then nothing changed. */
int svc_cancel(svc_job *j, svc_cancel_reason reason);

typedef enum {
    SVC_DELETE_CANCELED = 0,   /* was queued, now canceled */
    SVC_DELETE_STOPPING,       /* runs, stops at its next step */
    SVC_DELETE_FORGOTTEN       /* had finished: gone (memory and store) */
} svc_delete_result;

/* DELETE semantics: cancels a queued or running job (reason USER) and
 * forgets a finished one. 0 and *res, or -1 and *err: ENOTFOUND, or
 * ESTORAGE when the store could not record it (then nothing changed:
 * the job goes on, or is kept). *before: the status it had (also on
 * ESTORAGE). */
int svc_delete(svc_t *s, const char *id, svc_delete_result *res,
               svc_job_status *before, svc_error *err);

/* ---------------------------------------------------------------- readers */

typedef struct {
    char id[SVC_ID_LEN + 1];
    svc_job_status status;
    int ready;                 /* decoded and checked: streams may start */
    int cancel_requested;      /* by a user, while it still runs */
    int recovered;             /* reloaded from the store at start */
    int step;                  /* steps done */
    double t, dt, energy, volume;  /* the last step's (step > 0) */
    int steps_planned;         /* iterations when time is not set, else 0 */
    double time_planned;       /* total flow time when set, else 0 */
    double cpu_s;              /* CPU seconds its run took, as its budget
                                  counts them at its last step: its worker's
                                  thread and the threads its flow started
                                  (0 without a budget, --job-cpu 0) */
    double cpu_threads_s;      /* the latter's share */
    int cores;                 /* the cores it holds while it runs (its
                                  flow's threads once decoded), else 0 */
    double fraction;           /* of the run done, 0..1 (1: succeeded):
                                  the core's share of its work when this
                                  replica runs it, else steps or time */
    char phase[16];            /* the core's phase while it runs ("noise",
                                  "passes", "steps", ...; "" none yet or
                                  not this replica's run) */
    double created, started, finished;  /* epoch seconds, 0: not yet */
    char scheme[24];
    char in_format[16], out_format[16];  /* api_format names, "" unknown */
    char filename[128];        /* the upload's base name */
    char result_name[32];      /* "result.obj" */
    size_t result_len;
    int nevents;               /* progress events kept (svc_job_events) */
    svc_error error;           /* failed or canceled (and EDRAINING for a
                                  job a shutdown interrupted: it runs
                                  again after the restart) */
    int draining, closing;     /* the service's, at the same instant */
    /* svc_job_document only (else NULL; svc_snap_free frees them): */
    char *params;              /* the normalized parameters, JSON text */
    char *metrics;             /* a succeeded job's metrics document */
} svc_snap;

/* A copy of the job's state (params and metrics NULL: nothing to free). */
void svc_job_snapshot(const svc_job *j, svc_snap *s);
/* The same, with the parameters and, once it has succeeded, the metrics
 * document (read from the store; NULL when they cannot be): everything a
 * door shows of a job. 0, or -1 (ENOMEM). svc_snap_free it. */
int svc_job_document(const svc_job *j, svc_snap *s);
void svc_snap_free(svc_snap *s);
/* The metrics document (JSON text, malloc'ed) of a succeeded job, from
 * the store. 0, or -1 and *err (ENOTREADY, ENORESULT, ESTORAGE,
 * ENOMEM). */
int svc_job_metrics(const svc_job *j, char **json, size_t *len,
                    svc_error *err);

/* Progress events from index from (0-based) on: one JSON object per
 * line, {"step","t","dt","energy","volume"}, whole lines only, at most
 * max_bytes of them (but at least one line when there is one). *data is
 * malloc'ed (NULL when *n is 0); *n is how many events it holds. A
 * finished job's events are on the spool, read from there (kept as long
 * as the job). 0 or -1 (errno: ENOMEM, or the spool's). */
/* The core's phase changes in the job's run (the default request's spike
 * repair, graph, creases, noise reading, set-up, passes, output, ...; an
 * MCF scheme's set-up and steps): the first SVC_PHASES_MAX, kept with the
 * job, so a follower gets each of them however late it reads. */
enum { SVC_PHASES_MAX = 48 };
/* The share of work by which a running job's milestone is news between
 * its phase changes: the service notifies its followers, and the doors
 * send one, at each such move. */
#define SVC_WORK_STEP 0.01
typedef struct {
    char phase[16];
    int step;                  /* steps done when it began */
    double fraction;           /* the job's share of work then, 0..1 */
} svc_phase;
/* Entries from index from on into out (at most n); returns how many the
 * run has in all. */
int svc_job_phases(const svc_job *j, int from, svc_phase *out, int n);

int svc_job_events(const svc_job *j, int from, size_t max_bytes, char **data,
                   size_t *len, int *n);

enum { SVC_RESULT_TAKE = 1 };
/* The encoded result of a succeeded job. With SVC_RESULT_TAKE the kept
 * in-memory copy (keep_result) is handed over when there is one (only
 * its submitter should ask); otherwise, or when none is kept, the store's
 * is read. 0, or -1 and *err. */
int svc_job_result(svc_job *j, unsigned flags, char **data, size_t *len,
                   svc_error *err);
/* The result as a read-only descriptor (for zero-copy sending) and its
 * size; *fd -1 with *data and *size holding the bytes when the store has
 * no descriptors. 0, or -1 and *err. The caller closes *fd or frees
 * *data. */
int svc_job_result_open(const svc_job *j, int *fd, char **data, size_t *size,
                        svc_error *err);
/* The per-vertex fields of a succeeded job submitted with fields
 * (api_fields_encode's document), as svc_job_result_open. 0, or -1 and
 * *err: ENOTREADY, ENORESULT (failed, canceled, or submitted without
 * fields), ESTORAGE. */
int svc_job_fields_open(const svc_job *j, int *fd, char **data, size_t *size,
                        svc_error *err);
/* The submitter will not take the kept copy: it is freed (and none is
 * kept from now on). */
void svc_job_release_result(svc_job *j);

/* ----------------------------------------------------------- subscriptions */

enum {
    SVC_NOTIFY_STATE = 1,      /* started, ready, finished, canceled, and
                                  the service draining or closing */
    SVC_NOTIFY_PROGRESS = 2    /* every progress event */
};

/* what: the SVC_NOTIFY_* bits of this change. Called with the service lock
 * held; see "Subscriptions" above. */
typedef void (*svc_notify_fn)(void *ctx, unsigned what);

/* Calls fn(ctx, what) on the changes of j that match flags (STATE is
 * always included). 0, or -1 (ENOMEM) with *sub NULL. */
int svc_subscribe(svc_job *j, unsigned flags, svc_notify_fn fn, void *ctx,
                  svc_sub **sub);
/* Ends a subscription (accepts NULL); fn is not running on return. */
void svc_unsubscribe(svc_sub *sub);
/* How many subscriptions of j want SVC_NOTIFY_PROGRESS (followers), from
 * either door. A door starts no follower beyond SVC_FOLLOWERS_PER_JOB (one
 * job's followers are woken one by one on every step, under the lock). */
#define SVC_FOLLOWERS_PER_JOB 64
int svc_followers(const svc_job *j);

#endif /* SVC_SERVICE_H */
