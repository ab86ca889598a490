/*
 * srv.h - declarations shared by the files of mcfd, the HTTP daemon.
 *
 * server/ is the only layer that knows about HTTP, configuration, signals,
 * files and logging. It is split by concern:
 *   main.c     process set-up, signal loop, drain and exit, --probe
 *   config.c   flags and MCFD_* environment variables -> srv_config
 *   http.c     libmicrohttpd: routing, uploads, suspend/resume, responses
 *   stream.c   streamed bodies: ndjson progress and Server-Sent Events
 *   reply.c    RFC 9457 problem+json, the mcf_status -> HTTP map, helpers
 *   jobs.c     job table, bounded queue, worker pool, the job runner
 *   spool.c    the crash-safe on-disk record of every accepted job
 *   metrics.c  Prometheus counters and histograms
 *   log.c      one JSON line per event on stderr
 *
 * Threads: MHD's small pool runs http.c/stream.c and never touches a mesh;
 * the worker pool (jobs.c) decodes, smooths and encodes. Every mutable job
 * field is guarded by the one job lock (srv_lock/srv_unlock); it is held
 * only for short bookkeeping, never across mesh work or disk I/O.
 */
#ifndef SRV_H
#define SRV_H

#include <pthread.h>
#include <stddef.h>
#include <stdint.h>

#include <microhttpd.h>

#include "../api/api.h"

/* ------------------------------------------------------------ configuration */

typedef enum {
    SRV_LOG_ERROR = 0,
    SRV_LOG_WARN,
    SRV_LOG_INFO,
    SRV_LOG_DEBUG
} srv_log_level;

typedef struct {
    char bind[256];            /* address to listen on (default 127.0.0.1) */
    int port;                  /* 0: any free port (default 8080) */
    int grpc_port;             /* gRPC door: 0 any free port, -1 off
                                  (default 50051) */
    int workers;               /* mesh worker threads (default: online CPUs) */
    int queue;                 /* queued jobs beyond the running ones */
    int http_threads;          /* MHD thread pool size (default 2) */
    int max_connections;       /* MHD connection limit */
    int max_connections_per_ip; /* from one address, 0: none; keeps one
                                   client from taking every slot */
    char spool[1024];          /* job spool directory (default ./var/mcfd) */
    int spool_max_jobs;        /* jobs kept before 503, 0: none */
    size_t spool_max_bytes;    /* bytes of jobs kept before 503 */
    api_limits lim;            /* limits on untrusted input */
    size_t max_body;           /* whole request body, derived from lim */
    double result_ttl;         /* seconds a finished job is kept */
    double job_timeout;        /* seconds of flow per job, 0: unlimited */
    double drain_timeout;      /* seconds SIGTERM waits for running jobs */
    double header_timeout;     /* seconds for a request's head, 0: none */
    char token_file[1024];     /* empty: no authentication */
    char token[512];           /* the bearer token read from token_file */
    size_t token_len;
    srv_log_level log_level;
    int probe;                 /* --probe: health-check a running daemon */
} srv_config;

/* Fills cfg from the embedded defaults, then MCFD_* variables, then argv
 * (flags win). Returns 0, or 1 after printing --help/--version (exit 0),
 * or -1 with a one-line reason in msg (exit 2). Reads the token file. */
int srv_config_load(srv_config *cfg, int argc, char **argv, char *msg,
                    size_t msgsize);
/* Whether an Authorization value ("Bearer <token>") carries the
 * configured token (always, when there is none); constant time in the
 * token's length. Both doors check with it. */
int srv_bearer_ok(const srv_config *cfg, const char *authorization);

/* ------------------------------------------------------------------ logging */

void srv_log_set_level(srv_log_level lvl);
int srv_log_enabled(srv_log_level lvl);
/* Adds "ts" and "level" to obj, prints it as one line on stderr and
 * deletes obj (accepts NULL). */
void srv_log_json(srv_log_level lvl, cJSON *obj);
/* A free-form event: {"ts","level","msg"}. */
void srv_logf(srv_log_level lvl, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

/* Wall clock, seconds since the epoch, and its RFC 3339 form (UTC, ms):
 * for timestamps only (they persist in the spool). */
double srv_wall(void);
/* CLOCK_MONOTONIC seconds: every deadline and timeout (a wall clock set
 * back or forward would stretch or cut them). */
double srv_mono(void);
void srv_time_rfc3339(double t, char *buf, size_t size);

/* ---------------------------------------------------------------- problems */

/* An error as the client will see it: HTTP status, the symbolic mcf code
 * ("EMESH", or a server code such as "ENOTFOUND") and a precise detail. */
typedef struct {
    unsigned http;
    char code[24];
    char detail[MCF_ERRMSG_SIZE + 128];
} srv_problem;

/* Where an mcf_status came from decides its HTTP status. */
typedef enum {
    SRV_STAGE_PARAMS = 0,  /* parameter parsing and range checks */
    SRV_STAGE_DECODE,      /* bytes -> mesh */
    SRV_STAGE_RUN,         /* the flow, encoding, comparison */
} srv_stage;

/* The HTTP status of a failure (table in reply.c, from MCF_ERRORS). */
unsigned srv_http_status(mcf_status s, srv_stage stage);
/* Fills p from an mcf failure; detail is the mcf_error message. */
void srv_problem_from(srv_problem *p, mcf_status s, srv_stage stage,
                      const char *prefix, const mcf_error *err);
void srv_problem_set(srv_problem *p, unsigned http, const char *code,
                     const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;
/* The problem as an RFC 9457 JSON object (type, title, status, detail,
 * instance, code, and job when given). NULL on allocation failure. */
cJSON *srv_problem_json(const srv_problem *p, const char *instance,
                        const char *job_id);
/* The reason phrase of an HTTP status ("Unprocessable Content"). */
const char *srv_http_reason(unsigned status);

/* -------------------------------------------------------------------- spool */

/* Creates dir and its jobs/ subfolder (mkdir -p). 0 or -1 with errno. */
int srv_spool_init(const char *dir, char *msg, size_t msgsize);
/* The path of a job file: <spool>/jobs/<id>/<name> (name may be ""). */
int srv_spool_path(char *buf, size_t size, const char *spool, const char *id,
                   const char *name);
/* Writes data to <dir>/<name> through a temporary file, fsync()s it when
 * durable, and renames it into place. 0 or -1 with errno. */
int srv_spool_write(const char *spool, const char *id, const char *name,
                    const void *data, size_t len, int durable);
/* Makes the job directory (and fsyncs jobs/ so it survives a crash). */
int srv_spool_mkjob(const char *spool, const char *id);
/* Reads a whole job file (malloc'ed, NUL-terminated). 0 or -1. */
int srv_spool_read(const char *spool, const char *id, const char *name,
                   char **data, size_t *len);
/* Removes a job directory and everything in it: first renamed to a
 * tombstone and jobs/ fsynced (durable), then deleted. 0, or -1 with
 * errno and the job left whole. */
int srv_spool_remove(const char *spool, const char *id);
/* Readiness: 0 when a file can be made in the spool and the last spool
 * write did not fail (since the last that succeeded); else -1 and why. */
int srv_spool_ready(const char *spool, char *why, size_t size);
/* Bytes of the files of a job directory (0 when unreadable). */
size_t srv_spool_du(const char *spool, const char *id);
/* Calls fn for every job directory name in the spool. */
int srv_spool_list(const char *spool, void (*fn)(const char *id, void *ctx),
                   void *ctx);

/* ------------------------------------------------------------------ metrics */

void srv_metrics_init(void);
/* route: a fixed label ("smooth", "jobs", "job", ...). */
void srv_metrics_request(const char *route, unsigned status);
void srv_metrics_upload(size_t bytes);
/* One gRPC call: method ("Smooth", ...) and status code name ("OK"). */
void srv_metrics_grpc(const char *method, const char *code);
/* One finished job: scheme name ("unknown" before parsing), final status
 * and wall seconds from start to finish (queue wait excluded). */
void srv_metrics_job(const char *scheme, const char *status, double seconds);

typedef struct {
    int queue_depth, queue_capacity;
    int workers, workers_busy;
    int jobs_in_memory;
    int draining;
    int followers;             /* event streams (SSE, ndjson) open */
    double spool_bytes;        /* bytes of the jobs kept */
} srv_gauges;

/* The Prometheus text exposition (format 0.0.4), malloc'ed. */
char *srv_metrics_render(const srv_gauges *g, size_t *len);

/* --------------------------------------------------------------------- jobs */

#define SRV_ID_LEN 32          /* 128 random bits in lowercase hex */

typedef enum {
    SRV_JOB_QUEUED = 0,
    SRV_JOB_RUNNING,
    SRV_JOB_SUCCEEDED,
    SRV_JOB_FAILED,
    SRV_JOB_CANCELED
} srv_job_status;

const char *srv_job_status_name(srv_job_status s);

/* Why a running job was asked to stop. */
enum { SRV_CANCEL_NONE = 0, SRV_CANCEL_USER, SRV_CANCEL_SHUTDOWN,
       SRV_CANCEL_TIMEOUT, SRV_CANCEL_CLIENT };

/* A suspended connection waiting on a job. Lives inside the request or
 * stream object that owns it; linked into job->waiters under the lock. */
typedef struct srv_waiter {
    struct MHD_Connection *conn;
    int suspended;             /* MHD_suspend_connection called, not resumed */
    int want_events;           /* woken on every progress step */
    int gone;                  /* its client hung up: end the stream */
    int cancel_on_hangup;      /* the job's only client: its hang-up
                                  cancels the job (srv_jobs_check_clients) */
    int linked;
    struct srv_waiter *prev, *next;
} srv_waiter;

/* What the client sent, enough to rebuild the parameters at any time
 * (also after a restart, from request.json). */
typedef struct {
    char *query;               /* raw query string, NULL if none */
    char *params_json;         /* multipart `params` field, NULL if none */
    cJSON *fields;             /* other form fields: array of [key, value] */
    char filename[128];        /* sanitized base name of the upload */
    int has_target;
} srv_record;

void srv_record_free(srv_record *r);
/* api_params from a record: JSON, then form fields, then the query string
 * (later sources override earlier ones). Keys the daemon handles itself
 * (stream) are skipped. */
mcf_status srv_record_params(const srv_record *r, const api_limits *lim,
                             api_params *p, mcf_error *err);

typedef struct srv_job srv_job;
struct srv_job {
    char id[SRV_ID_LEN + 1];
    int refs;                  /* table + every request/stream holding it */
    int in_table;
    srv_job_status status;
    srv_record rec;
    size_t disk_bytes;         /* its files on the spool (quota) */
    char *input;               /* upload bytes until the worker takes them */
    size_t input_len;
    char *target;
    size_t target_len;
    char scheme[24];           /* parsed scheme name (metrics label) */
    char *params_json;         /* api_params_to_json, printed */
    int steps_planned;         /* iterations when time is not set, else 0 */
    double time_planned;       /* total flow time when set, else 0 */
    double created, started, finished;   /* epoch seconds, 0: not yet */
    int recovered;             /* loaded from the spool at start */
    /* progress, written by the worker's progress callback */
    int step;
    double t, dt, energy, volume;
    int ready;                 /* decoded and checked: streams may start */
    mcf_cancel_flag cancel;    /* written under the lock, loaded without
                                  it by mcf_flow_run (params.cancel) */
    int cancel_reason;
    api_buf events;            /* ndjson lines, one per step */
    int nevents;
    /* outcome */
    srv_problem err;           /* when failed or canceled */
    char *metrics_json;        /* when succeeded */
    char in_format[16];
    char out_format[16];
    char result_name[32];      /* "result.obj" in the job directory */
    size_t result_len;
    char *result;              /* encoded mesh kept for a waiting client */
    int keep_result;           /* a synchronous client will take it */
    srv_waiter *waiters;
    srv_job *hnext, *qnext;
};

/* Starts the job system: recovers the spool (re-queues queued and
 * interrupted jobs, reloads finished ones), then the workers. */
int srv_jobs_start(const srv_config *cfg, char *msg, size_t msgsize);
/* Stops accepting work; running jobs continue. Queued ones stay spooled. */
void srv_jobs_drain(void);
int srv_jobs_draining(void);
int srv_jobs_draining_locked(void);
/* After srv_jobs_resume_all: waiters must answer, never suspend again. */
int srv_jobs_closing_locked(void);
/* Whether a submission now would find room (a hint before the body). */
int srv_jobs_can_accept(void);
/* Waits until no job runs (or timeout seconds pass). 1 when idle. */
int srv_jobs_wait_idle(double timeout);
/* Cancels the running jobs for a restart: they go back to `queued` on
 * disk and run again on the next start. */
void srv_jobs_checkpoint_running(void);
/* Resumes every suspended connection for good (before MHD_stop_daemon):
 * from now on waiters answer with what they have. */
void srv_jobs_resume_all(void);
/* Joins the workers and frees every job. */
void srv_jobs_stop(void);
/* Forgets jobs finished more than the TTL ago (memory and spool). */
void srv_jobs_sweep(void);
/* Cancels the queued or running jobs whose waiting client (a suspended
 * connection with cancel_on_hangup) has closed its connection. Called a
 * few times a second from the main thread. Returns how many. */
int srv_jobs_check_clients(void);

void srv_lock(void);
void srv_unlock(void);

/* Accepts a job: assigns the ID, spools it durably, queues it. Takes the
 * input/target buffers and the record (also on failure). On success *out
 * holds a reference for the caller. Fails with 503 (queue full, draining)
 * or 500 (spool). */
int srv_jobs_submit(srv_record *rec, char *input, size_t input_len,
                    char *target, size_t target_len, int keep_result,
                    srv_job **out, srv_problem *prob);
/* A new reference to the job with that ID, or NULL. */
srv_job *srv_jobs_get(const char *id);
void srv_job_unref(srv_job *j);
/* DELETE: -1 no such job; 0 it was queued and is now canceled; 1 it runs
 * and will stop at its next step; 2 it had finished and is forgotten
 * (memory and spool); -2 the spool could not record it (errno; a queued
 * or running job is canceled in memory all the same, a finished one is
 * kept). *before: the status it had. */
int srv_jobs_delete(const char *id, srv_job_status *before);
/* The job as JSON (id, status, progress, timestamps, params, metrics or
 * error, links). Call with the lock held. */
cJSON *srv_job_json(const srv_job *j);
srv_gauges srv_jobs_gauges(void);
const srv_config *srv_jobs_config(void);

/* Waiters, with the lock held: link, unlink, suspend (records it). */
void srv_waiter_link(srv_job *j, srv_waiter *w);
void srv_waiter_unlink(srv_job *j, srv_waiter *w);
void srv_waiter_suspend(srv_waiter *w);
/* Resumes waiters of j (all, or only those wanting every event). */
void srv_job_wake(srv_job *j, int progress_only);

/* ------------------------------------------------------------------- stream */

typedef enum { SRV_STREAM_NDJSON = 0, SRV_STREAM_SSE } srv_stream_kind;

/* A chunked response that follows the job's events until it finishes.
 * Holds its own job reference. last_id: SSE Last-Event-ID (-1: none). */
struct MHD_Response *srv_stream_response(srv_job *j, srv_stream_kind kind,
                                         struct MHD_Connection *conn,
                                         long last_id);
/* Whether one more follower of j may start (at most SRV_FOLLOWERS_PER_JOB
 * per job and half of --max-connections in all); else 0 and a 503. */
#define SRV_FOLLOWERS_PER_JOB 64
int srv_stream_admit(const srv_job *j, srv_problem *p);
/* Streams following a job now (the mcfd_followers gauge). */
int srv_stream_followers(void);

/* The final ndjson line of a job (metrics and result URL, or the error).
 * Lock held. */
cJSON *srv_stream_final_json(const srv_job *j);

/* --------------------------------------------------------------------- http */

/* The request handler and its companions for MHD_start_daemon. */
enum MHD_Result srv_http_handle(void *cls, struct MHD_Connection *c,
                                const char *url, const char *method,
                                const char *version, const char *upload_data,
                                size_t *upload_data_size, void **con_cls);
void *srv_http_uri_log(void *cls, const char *uri, struct MHD_Connection *c);
void srv_http_completed(void *cls, struct MHD_Connection *c, void **con_cls,
                        enum MHD_RequestTerminationCode toe);
/* Closes the connections that have waited longer than timeout seconds
 * for a complete request head (request line and headers), since they
 * opened or since their last answer, and uploads older than timeout that
 * averaged under 4 KiB/s since their head: slowloris clients. With nine
 * tenths of max_connections open the timeout is 2 s at most. The main
 * loop calls it with --header-timeout. Returns how many. */
int srv_http_expire_heads(double timeout, int max_connections);
/* MHD_OPTION_NOTIFY_CONNECTION: tracks connections for the header
 * deadline; releases a request MHD never completed. */
void srv_http_connection(void *cls, struct MHD_Connection *c,
                         void **socket_context,
                         enum MHD_ConnectionNotificationCode code);
/* Requests between the URI callback and completion (drain waits on it). */
int srv_http_active(void);

/* The API description embedded at build time (build/server/openapi_yaml.c). */
extern const unsigned char srv_openapi_yaml[];
extern const size_t srv_openapi_yaml_len;

#endif /* SRV_H */
