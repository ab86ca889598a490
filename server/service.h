/*
 * service.h - the job service of mcfd: the one module that owns jobs
 * (table, queue, workers, runner, spool, recovery, drain), and the only
 * way a transport reaches them. Both doors use nothing else: the REST door
 * (http.c, stream.c, reply.c on libmicrohttpd) and the gRPC door. No
 * HTTP, MHD or gRPC type appears here, and no message here names a URL.
 *
 * Objects
 *   svc_job   an opaque, reference-counted handle. svc_submit and
 *             svc_job_get hand out a reference; svc_job_unref drops it.
 *             A handle stays valid (readable, never freed) while held,
 *             also after the job was deleted or expired: it then reads as
 *             it was last.
 *   svc_snap  a copy of a job's state taken at one instant, for readers.
 *   svc_sub   a subscription: "call fn(ctx, what) when this job moves".
 *
 * Threads and locking
 *   Every job function may be called from any thread (MHD's pool,
 *   gRPC's, the main thread) after svc_start and before svc_stop; the
 *   lifecycle functions from the main thread; svc_error_* and
 *   svc_record_* at any time. The service has
 *   one internal lock; it is held only for short bookkeeping, never
 *   across mesh work or disk I/O, and never while calling out, except for
 *   subscription callbacks (below). Callers hold no lock of the service:
 *   what they get back are copies.
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
 *   caller frees; cJSON objects are the caller's to cJSON_Delete.
 *   svc_submit takes the input and target buffers and the record's
 *   contents, also when it fails.
 *
 * Errors
 *   Failures are svc_error values: a transport-neutral code, the mcf
 *   status and stage they came from (when they came from the core or the
 *   codecs), a symbolic name (the REST "code": "EMESH", "EBUSY", ...), a
 *   precise detail in words, and a retry delay for transient refusals.
 *   The detail never names a URL, header or status code. Each door maps
 *   the code; both agree on this table:
 *
 *   code         meaning                           REST            gRPC
 *   EPARAMS      a parameter is wrong (named)      400 (mcf/stage) INVALID_ARGUMENT
 *   EINPUT       the mesh bytes are refused:       400, 413 limit, INVALID_ARGUMENT;
 *                unparsable, unknown format, over  415 format      ELIMIT:
 *                a limit                                           RESOURCE_EXHAUSTED
 *   EMESH        a well-formed mesh these          422             INVALID_ARGUMENT;
 *                parameters cannot smooth, or a                    ELIMIT:
 *                budget this mesh exceeds                          RESOURCE_EXHAUSTED
 *   ENOMEM       out of memory (transient)         503             RESOURCE_EXHAUSTED
 *   EBUSY        the queue is full (retry_after)   503             RESOURCE_EXHAUSTED
 *   EQUOTA       the spool's job or byte quota     503             RESOURCE_EXHAUSTED
 *   EDRAINING    shutting down (retry_after); also 503             UNAVAILABLE
 *                a job interrupted by the shutdown,
 *                which runs again after the restart
 *   ENOTFOUND    no job with that ID               404             NOT_FOUND
 *   ENOTREADY    queued or running, no result yet  409             FAILED_PRECONDITION
 *   ENORESULT    failed or canceled: no result     409             FAILED_PRECONDITION
 *   ECANCELED    canceled by a user or because its 409             CANCELLED
 *                only client left (cancel field)
 *   ETIMEOUT     ran longer than the job timeout   422 (ELIMIT)    DEADLINE_EXCEEDED
 *   ESTORAGE     the spool could not be read or    500 (EIO)       INTERNAL
 *                written
 *   EINTERNAL    anything else                     500             INTERNAL
 *
 *   For EPARAMS, EINPUT and EMESH the REST status comes from (mcf, stage)
 *   through the mcf_status map of reply.c, exactly as before the split.
 *   Codes are only ever appended.
 */
#ifndef SVC_SERVICE_H
#define SVC_SERVICE_H

#include <stddef.h>

#include "api.h"

/* ------------------------------------------------------------------ errors */

#define SVC_CODES(X)                                                   \
    X(OK,        "success")                                           \
    X(EPARAMS,   "invalid parameters")                                \
    X(EINPUT,    "the input mesh is refused")                         \
    X(EMESH,     "the mesh cannot be smoothed with these parameters") \
    X(ENOMEM,    "out of memory")                                     \
    X(EBUSY,     "the job queue is full")                             \
    X(EQUOTA,    "the spool is full")                                 \
    X(EDRAINING, "the service is shutting down")                      \
    X(ENOTFOUND, "no such job")                                       \
    X(ENOTREADY, "the job has not finished")                          \
    X(ENORESULT, "the job has no result")                             \
    X(ECANCELED, "the job was canceled")                              \
    X(ETIMEOUT,  "the job ran out of time")                           \
    X(ESTORAGE,  "the spool failed")                                  \
    X(EINTERNAL, "internal error")

typedef enum {
#define X(name, text) SVC_##name,
    SVC_CODES(X)
#undef X
} svc_code;

/* Where an mcf_status came from (it decides REST's 400 against 422). */
typedef enum {
    SVC_STAGE_NONE = 0,    /* not from the core or the codecs */
    SVC_STAGE_PARAMS,      /* parameter parsing and range checks */
    SVC_STAGE_DECODE,      /* bytes -> mesh */
    SVC_STAGE_RUN          /* the flow, encoding, comparison */
} svc_stage;

/* Why a job was (asked to be) stopped. */
typedef enum {
    SVC_CANCEL_NONE = 0,
    SVC_CANCEL_USER,       /* a client asked (DELETE, CancelJob) */
    SVC_CANCEL_SHUTDOWN,   /* svc_checkpoint_running: runs again later */
    SVC_CANCEL_TIMEOUT,    /* the job timeout passed */
    SVC_CANCEL_CLIENT      /* the job's only client left (a door saw it) */
} svc_cancel_reason;

typedef struct {
    svc_code code;
    mcf_status mcf;            /* MCF_OK when not from the core/codecs */
    svc_stage stage;
    svc_cancel_reason cancel;  /* ECANCELED: why */
    char name[24];             /* "EMESH", "EBUSY", "ESPOOLFULL", "EIO" */
    char detail[MCF_ERRMSG_SIZE + 128];
    double retry_after;        /* seconds, > 0 for transient refusals */
} svc_error;

/* "EPARAMS" for SVC_EPARAMS, "" when unknown. */
const char *svc_code_name(svc_code c);
/* A failure of the core or the codecs: code from (s, stage), name is
 * mcf_status_name(s), detail "prefix: message" (prefix may be NULL). */
void svc_error_from_mcf(svc_error *e, mcf_status s, svc_stage stage,
                        const char *prefix, const mcf_error *err);
/* Any failure; name NULL: svc_code_name(code). Clears mcf and stage. */
void svc_error_set(svc_error *e, svc_code code, const char *name,
                   const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;

/* ------------------------------------------------------------------ set-up */

typedef struct {
    int workers;               /* worker threads */
    int queue;                 /* queued jobs beyond the running ones */
    char spool[1024];          /* spool directory (exists) */
    int spool_max_jobs;        /* jobs kept before EQUOTA, 0: none */
    size_t spool_max_bytes;    /* bytes of jobs kept before EQUOTA */
    api_limits lim;            /* limits on untrusted input */
    double result_ttl;         /* seconds a finished job is kept */
    double job_timeout;        /* seconds of flow per job, 0: unlimited */
    size_t max_memory;         /* estimated peak of the running jobs */
    size_t max_job_memory;     /* estimated peak of one job (svc_admit.c) */
    double decode_cpu;         /* CPU seconds of a sandboxed decode, floor */
    size_t decode_memory;      /* its memory limit, floor (sandbox.c) */
} svc_config;

/* Recovers the spool (queued and interrupted jobs queued again in their
 * order with their IDs, finished ones reloaded until their TTL), then
 * starts the workers. cfg is copied. 0, or -1 with a reason in msg. */
int svc_start(const svc_config *cfg, char *msg, size_t msgsize);
/* Stops accepting jobs (EDRAINING); running jobs continue, queued ones
 * stay spooled for the next start. Subscribers of queued jobs hear. */
void svc_drain(void);
/* Waits until no job runs or timeout seconds pass. 1 when idle. */
int svc_wait_idle(double timeout);
/* Stops the running jobs for a restart: they stay `queued` on disk and
 * run again on the next start (unless a user or client canceled them). */
void svc_checkpoint_running(void);
/* From now on every door must answer with what it has and never wait
 * again (snapshots say closing); every subscriber is notified. */
void svc_close_waiters(void);
/* Joins the workers and frees every job. Handles still held are freed
 * when released. */
void svc_stop(void);
/* Forgets the jobs finished more than the TTL ago (memory and spool).
 * Called now and then from one thread. */
void svc_sweep(void);

typedef struct {
    int queue_depth, queue_capacity;
    int workers, workers_busy;
    int jobs_in_memory;
    int draining;
    double spool_bytes;        /* bytes of the jobs kept */
} svc_gauges;

svc_gauges svc_get_gauges(void);
/* Whether a submission now would find room (a hint before the body). */
int svc_can_accept(void);
int svc_draining(void);

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
int svc_upload_reserve(size_t *held, size_t want, svc_error *e);
/* Gives it back (the bytes are on the spool or dropped): *held 0. */
void svc_upload_release(size_t *held);

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

/* What the client sent, enough to rebuild the parameters at any time
 * (also after a restart: it is persisted as the job's request). The
 * parameters are applied as: params JSON, then the fields in order, then
 * the query string, later sources overriding earlier ones; every source
 * goes through api/ and its messages name the parameter. A door with
 * typed parameters builds a params JSON object. */
typedef struct {
    char *query;               /* raw query string, NULL if none */
    char *params_json;         /* a JSON object of parameters, or NULL */
    cJSON *fields;             /* [[key, value], ...] or NULL */
    char filename[128];        /* sanitized base name of the upload */
    int has_target;            /* set by svc_submit */
} svc_record;

/* The query's `fields` (a daemon key, like `stream`: query only, the last
 * one wins): whether the worker keeps the job's per-vertex fields for
 * svc_job_fields_open. 0 and *on, or -1 and *err (EPARAMS). */
int svc_record_fields(const svc_record *r, int *on, svc_error *err);
/* Frees the record's contents and zeroes it (the struct is the caller's). */
void svc_record_free(svc_record *r);
/* api_params from a record (keys the doors handle, "stream", skipped). */
mcf_status svc_record_params(const svc_record *r, const api_limits *lim,
                             api_params *p, mcf_error *err);

enum {
    SVC_KEEP_RESULT = 1        /* keep the encoded result in memory for the
                                  submitter (svc_job_result with TAKE) */
};

/* Accepts a job: checks the parameters (EPARAMS), admission (EDRAINING,
 * EBUSY, EQUOTA), assigns the ID, writes input, request and state
 * durably to the spool (ESTORAGE), then queues it. Takes input (len > 0),
 * target (NULL: none) and rec's contents in every case. 0 and *out holds
 * a reference for the caller, or -1 and *err. */
int svc_submit(svc_record *rec, char *input, size_t input_len, char *target,
               size_t target_len, unsigned flags, svc_job **out,
               svc_error *err);
/* A new reference to the job with that ID (a NUL-terminated string of
 * any content), or NULL. */
svc_job *svc_job_get(const char *id);
/* One more reference to a handle the caller holds; returns j. */
svc_job *svc_job_ref(svc_job *j);
/* Drops a reference (accepts NULL). */
void svc_job_unref(svc_job *j);
/* The job's ID (constant for the handle's life; takes no lock). */
const char *svc_job_id(const svc_job *j);

/* Cancels a queued job at once, or asks a running one to stop at its
 * next step (reason USER or CLIENT), durably first. 1 when this call
 * changed the job, 0 when it had finished or was already canceled, -1
 * when the spool could not record it (errno): then nothing changed. */
int svc_cancel(svc_job *j, svc_cancel_reason reason);

typedef enum {
    SVC_DELETE_CANCELED = 0,   /* was queued, now canceled */
    SVC_DELETE_STOPPING,       /* runs, stops at its next step */
    SVC_DELETE_FORGOTTEN       /* had finished: gone (memory and spool) */
} svc_delete_result;

/* DELETE semantics: cancels a queued or running job (reason USER) and
 * forgets a finished one. 0 and *res, or -1 and *err: ENOTFOUND, or
 * ESTORAGE when the spool could not record it (then nothing changed:
 * the job goes on, or is kept). *before:
 * the status it had (also on ESTORAGE). */
int svc_delete(const char *id, svc_delete_result *res, svc_job_status *before,
               svc_error *err);

/* ---------------------------------------------------------------- readers */

typedef struct {
    char id[SVC_ID_LEN + 1];
    svc_job_status status;
    int ready;                 /* decoded and checked: streams may start */
    int cancel_requested;      /* by a user, while it still runs */
    int recovered;             /* reloaded from the spool at start */
    int step;                  /* steps done */
    double t, dt, energy, volume;  /* the last step's (step > 0) */
    int steps_planned;         /* iterations when time is not set, else 0 */
    double time_planned;       /* total flow time when set, else 0 */
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
} svc_snap;

/* A copy of the job's state. */
void svc_job_snapshot(const svc_job *j, svc_snap *s);
/* The job as JSON: id, status, created/started/finished (RFC 3339 or
 * null), progress {step, steps, t, dt, energy, volume, fraction},
 * cancel_requested, params, input_format, metrics when succeeded. No
 * error and no links: a door adds them its way (the snapshot, taken at
 * the same instant, has the error). NULL on allocation failure. */
cJSON *svc_job_json(const svc_job *j, svc_snap *s);
/* The normalized parameters as JSON text (malloc'ed), or NULL. */
char *svc_job_params(const svc_job *j);
/* The metrics document (JSON text, malloc'ed) of a succeeded job, from
 * memory or the spool. 0, or -1 and *err (ENOTREADY, ENORESULT,
 * ESTORAGE, ENOMEM). */
int svc_job_metrics(const svc_job *j, char **json, size_t *len,
                    svc_error *err);

/* Progress events from index from (0-based) on: one JSON object per
 * line, {"step","t","dt","energy","volume"}, whole lines only, at most
 * max_bytes of them (but at least one line when there is one). *data is
 * malloc'ed (NULL when *n is 0); *n is how many events it holds. A
 * finished job's events are on the spool, read from there (kept as long
 * as the job). 0 or -1 (errno: ENOMEM, or the spool's). */
int svc_job_events(const svc_job *j, int from, size_t max_bytes, char **data,
                   size_t *len, int *n);

enum { SVC_RESULT_TAKE = 1 };
/* The encoded result of a succeeded job. With SVC_RESULT_TAKE the kept
 * in-memory copy (SVC_KEEP_RESULT) is handed over when there is one
 * (only its submitter should ask); otherwise, or when none is kept, the
 * spool file is read. 0, or -1 and *err. */
int svc_job_result(svc_job *j, unsigned flags, char **data, size_t *len,
                   svc_error *err);
/* The result file opened read-only (for zero-copy sending) and its size.
 * 0, or -1 and *err. The caller closes *fd. */
int svc_job_result_open(const svc_job *j, int *fd, size_t *size,
                        svc_error *err);
/* The per-vertex fields of a succeeded job submitted with fields=true
 * (svc_record_fields; api_fields_encode's document), opened read-only, and
 * its size. 0, or -1 and *err: ENOTREADY, ENORESULT (failed, canceled, or
 * submitted without fields=true), ESTORAGE. The caller closes *fd. */
int svc_job_fields_open(const svc_job *j, int *fd, size_t *size,
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
