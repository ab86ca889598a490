/* SPDX-License-Identifier: MIT */
/*
 * svc_internal.h - what the files of the job service share, and only
 * they: the service object, the job struct, and each file's part.
 *
 *   service.c   the service's life, admission and submit, delete,
 *               sweep, gauges
 *   svc_table.c the table of jobs by ID and the workers' wake-up (a leaf)
 *   svc_ref.c   a job's references and subscriptions
 *   svc_job.c   a job's life: every status transition (start, finish,
 *               park, cancel, recovery's, another replica's), progress;
 *               the only writer of a job's status
 *   svc_events.c a job's progress events: in memory, then in the store
 *   svc_read.c  the readers: lookup by ID, snapshots, metrics, events,
 *               result bytes
 *   svc_state.c the persisted forms (request.json, state.json) from plain
 *               copies, without a lock; the job's log line
 *   runner.c    one job on a worker (api_job_run): returns its outcome
 *   workers.c   the worker pool: claim, run, finish
 *   recovery.c  the store back into the table at start
 *   svc_shared.c a store shared by replicas: jobs loaded from it and
 *               refreshed, progress followed, cancels passed on
 *   svc_admit.c memory admission
 *   svc_error.c the columns of the table of problems (problem.h)
 *   spool.c     the local store (store.h)
 *
 * Locking (the lock order, outermost first):
 *   s->state_mu   one writer of state.json at a time: a snapshot and its
 *                 write go together, so the last taken is the last
 *                 written (svc_job.c). Held across one small write to
 *                 the store (its put: the store's own leaf locks only).
 *   the store's queue lock (spool.c's q_mu)
 *                 held by claim while it asks fits() (workers.c), which
 *                 takes s->mu and then s->admit.mu for a moment.
 *   s->mu         the service lock: the table, the counters, every
 *                 mutable field of every job, the subscription lists.
 *                 Held for bookkeeping only, never across mesh work or
 *                 I/O, and never while calling the store; subscription
 *                 callbacks run under it (service.h) and take the doors'
 *                 locks (REST: wait_mu; gRPC: its call's), which are
 *                 innermost there.
 *   s->admit.mu   the memory budget (svc_admit.c): innermost.
 */
#ifndef SVC_INTERNAL_H
#define SVC_INTERNAL_H

#include <pthread.h>

#include "service.h"
#include "srv.h"
#include "store.h"

#define SVC_NBUCKETS 4096
#define SVC_EVENTS_MAX ((size_t)16 << 20)   /* ndjson progress kept per job */
#define SVC_RESULT_MAX ((size_t)4 << 30)    /* an encoded result */
/* Retries of a job's step that met a resource a client can exhaust
 * (EMFILE, ENFILE, ENOSPC, EDQUOT, ENOMEM): 0.1 s doubling to 8 s, 37 s
 * in all (svc__retry), long enough for connections to time out or be
 * closed, short enough that a full disk fails the job within a minute. */
#define SVC_RETRY_TRIES 10
/* The tries of a synchronous job's outcome (a client waits on its
 * connection: POST /smooth): 0.1 + 0.2 + 0.4 + 0.8 = 1.5 s of waits,
 * then the client gets a 503 with Retry-After and the job is dropped,
 * well within the 30 s after which common proxies give up (issue 28). */
#define SVC_RETRY_SYNC_TRIES 4
#define SVC_FIELDS_FILE "fields.bin"        /* fields: api_fields_encode */

/* The memory budget of the running jobs and the uploads (svc_admit.c). */
typedef struct {
    pthread_mutex_t mu;
    pthread_cond_t freed;
    double used;               /* the holders' reservations */
    int holders;               /* jobs and uploads holding one */
} svc_admit_budget;

struct svc {
    pthread_mutex_t mu;        /* the service lock */
    pthread_cond_t work;       /* workers: a job may be claimable, or stop */
    pthread_cond_t idle;       /* drain: a worker finished its job */
    unsigned wakes;            /* signals of work so far (a worker waits
                                  only when none came since it looked) */
    pthread_mutex_t state_mu;  /* writers of state.json (above) */
    svc_config cfg;
    svc_store *store;
    svc_admit_budget admit;
    svc_job *buckets[SVC_NBUCKETS];
    int njobs;
    int queued;                /* jobs in the store's queue (not parked) */
    int reserved;              /* submissions admitted, not yet queued */
    int busy;                  /* workers running a job */
    int cores_held;            /* cores the running jobs hold, at most
                                  cfg.cores (workers.c) */
    size_t disk_bytes;         /* sum of disk_bytes of the jobs in the table */
    int draining, stopping;
    int closing;               /* doors must answer now, never wait */
    pthread_t *threads;
    int nthreads;
    /* a shared store: the follower thread (svc_shared.c) */
    pthread_t follower;
    pthread_cond_t follow_cv;  /* stop (its wait after a failure) */
    int follow_started, follow_stop;
    int urandom;
    uint64_t counter;
};

struct svc_sub {
    svc_job *job;
    unsigned flags;
    svc_notify_fn fn;
    void *ctx;
    svc_sub *prev, *next;
};

struct svc_job {
    svc_t *svc;                /* its service (constant) */
    char id[SVC_ID_LEN + 1];
    int refs;                  /* table + every holder of a handle */
    int in_table;
    svc_job_status status;
    /* the request: constant once the job is in the table */
    char filename[128];
    int has_target;
    int keep_fields;           /* fields: the fields document is kept */
    int measures;              /* the metrics document's measures and step
                                  log are taken (svc_request.measures) */
    char *params_json;         /* api_params_to_json, printed (shown) */
    char *params_given;        /* api_params_given_json, printed (its
                                  request.json: parses back to the job) */
    api_params params;         /* typed, as the door parsed them (a
                                  recovered job: from request.json) */
    double mem_estimate;       /* estimated peak bytes (svc_admit.c) */
    size_t disk_bytes;         /* its blobs in the store (quota) */
    char scheme[24];           /* scheme name (metrics label) */
    int steps_planned;         /* iterations when time is not set, else 0 */
    double time_planned;       /* total flow time when set, else 0 */
    double created, started, finished;   /* epoch seconds, 0: not yet */
    int recovered;             /* loaded from the store at start */
    int parked;                /* queued, out of the queue until retry_at:
                                  its outcome could not be recorded */
    int parks;                 /* times it was */
    double retry_at;           /* srv_mono() seconds */
    double mem_held;           /* reserved while it runs */
    int cores;                 /* cores it holds while it runs: 1, then
                                  its flow's threads (svc_admit_cores) */
    int run_here;              /* a worker of this replica runs it (a
                                  shared store: any other job's state is
                                  the store's, refreshed) */
    char ev_after[SVC_CURSOR_LEN];  /* the progress lines of another
                                  replica's run read so far (follow) */
    int following;             /* a thread reads its stream (the sweep or
                                  the follower): ev_after is its own */
    /* progress, written by the runner's progress hook (svc__progress) */
    int step;
    double t, dt, energy, volume;
    /* the core's milestones, written by the runner's work hook (svc__work):
     * the phase it is in ("noise", "passes", "steps", ...; "" before the
     * first) and its share of the work done, 0..1 */
    char phase[16];
    double work;
    double work_told;          /* the share the followers last heard of */
    svc_phase phases[SVC_PHASES_MAX];  /* the run's phase changes */
    int nphases;
    int ready;                 /* decoded and checked: streams may start */
    mcf_cancel_flag cancel;    /* written under the lock, loaded without
                                  it by the flow and the decode sandbox */
    svc_cancel_reason cancel_reason;
    svc_cancel_reason canceling;  /* a cancel being written (svc_cancel) */
    double timeout;            /* its job timeout, seconds; 0: none */
    double deadline;           /* srv_mono() the job timeout passes, 0 */
    double cpu_budget;         /* CPU seconds its run may take, 0: none */
    double cpu0, cpu_used;     /* its worker thread's CPU clock at its start;
                                  the seconds it took, the threads its flow
                                  started included */
    double cpu_threads;        /* those threads' share of cpu_used */
    api_buf events;            /* ndjson lines, one per step */
    size_t *event_end;         /* byte offset past each line */
    int nevents, event_cap;
    size_t events_disk;        /* once the job ends, its events are on the
                                  spool (events.ndjson, this many bytes, and
                                  events.idx, event_end's values) and no
                                  longer in memory; 0: in memory */
    /* outcome */
    svc_error err;             /* when failed or canceled */
    char in_format[16];
    char out_format[16];
    char result_name[32];      /* "result.obj" in the store */
    size_t result_len;
    char *result;              /* encoded mesh kept for its submitter */
    int keep_result;
    svc_sub *subs;
    svc_job *hnext;
};

/* What state.json holds of a job: a plain copy, taken under the lock
 * (svc__state_of) and written outside it (svc__state_json). */
typedef struct {
    char id[SVC_ID_LEN + 1];
    svc_job_status status;
    double created, started, finished;
    char scheme[24];
    int steps_planned;
    double time_planned;
    int step;
    double t;
    char in_format[16], out_format[16], result_name[32];
    size_t result_len;
    svc_cancel_reason cancel_requested;  /* of a job still running */
    const char *params_json;   /* the job's (constant: read without lock) */
    svc_error err;             /* failed or canceled */
} svc_state_rec;

/* How a run ended (runner.c), for svc__finish. */
typedef struct {
    svc_job_status status;     /* SUCCEEDED, FAILED, CANCELED; QUEUED: it
                                  runs again after the restart */
    svc_error err;
    char out_format[16], result_name[32];
    size_t result_len;
    size_t disk_add;           /* bytes it wrote to the store */
    char *result;              /* the encoded result (kept for the
                                  submitter when it asked), or NULL */
    char *metrics;             /* a store with finish: its metrics.json */
    char *fields;              /* and its fields.bin (fields=true) */
    size_t fields_len;
    int nv, nf;
    double run_s;
} svc_outcome;

/* svc_table.c: the table (lock held). Called by the files that fill or
 * read it; calls none of them. */
svc_job *svc__find_locked(svc_t *s, const char *id);
/* The table takes the caller's reference. */
void svc__table_insert(svc_t *s, svc_job *j);
/* j out of the table, the table's reference dropped. */
void svc__table_remove(svc_t *s, svc_job *j);
/* Wakes the workers (lock held): something may be claimable. */
void svc__wake_locked(svc_t *s);

/* svc_events.c: a job's progress events (j->events, j->event_end). */
/* The longest ndjson line of one step. */
#define SVC_EVENT_LINE 320
/* One step's line ({"step", "t", "dt", "energy", "volume"}, non-finite
 * numbers as null) into line; its length. */
int svc__event_line(const api_job_step *st, char line[SVC_EVENT_LINE]);
/* Lock held: one more line in the job's event log (dropped when the log
 * is full or memory is short: the stream then skips it). */
void svc__event_add_locked(svc_job *j, const char *line, size_t n);
/* Lock held: the log emptied for a run from step 1; the events it put in
 * the store are uncounted till they are put again. */
void svc__events_reset_locked(svc_job *j);
/* The log as it is now (only its worker appends): its count, *data,
 * *len and the line ends. Takes the lock. */
int svc__events_now(svc_job *j, const char **data, size_t *len,
                    const size_t **ends);
/* After the log was written to the store (ok: len bytes and n ends) or
 * lost: out of memory either way, the bytes on disk counted. */
void svc__events_done(svc_job *j, int ok, size_t len, int n);
/* The run's events to the store and out of memory, before its outcome
 * is published (a store without finish). */
void svc__events_to_store(svc_job *j);

/* svc_ref.c: references and subscriptions */
svc_job *svc__job_new(svc_t *s);
void svc__job_free(svc_job *j);
void svc__unref_locked(svc_job *j);
/* Calls the subscribers of j whose flags match what (lock held). */
void svc__notify(svc_job *j, unsigned what);
/* The snapshot of j that state.json records (lock held). */
void svc__state_of(const svc_job *j, svc_state_rec *r);
/* Writes j's state as it is now (durable or not). 0 or -1 (errno). */
int svc__write_state(svc_job *j, int durable);
/* queued -> running (a worker's claim): 0 and the worker holds a
 * reference; -1 when the job is no longer queued (skip it); 1 when it
 * must wait (its cancel is being written, or the service drains: put it
 * back at the head of the queue). */
int svc__start(svc_job *j);
/* running -> its outcome, recorded first (with retries), then published;
 * a job whose outcome the store refuses is parked (queued again later). */
void svc__finish(svc_job *j, svc_outcome *o);
/* Whether a client waits on its connection for j's answer (POST
 * /smooth) on this replica: its tries are bounded by
 * SVC_RETRY_SYNC_TRIES. A local store only: on a shared one another
 * replica may run it, or be the one waiting. */
int svc__sync(const svc_job *j);
/* svc_job.c: a job's life */
/* A job that failed or was canceled: its input and target emptied in
 * the store now, not at its result TTL; best effort. */
void svc__drop_input(svc_job *j);
/* A transient error of the store or of memory (EMFILE, ENOSPC, ENOMEM,
 * ...): waits before try *tries + 2 (0.1 s doubling, SVC_RETRY_TRIES
 * times, SVC_RETRY_SYNC_TRIES for a synchronous job), watching the job's cancel (any, or with only_shutdown the
 * shutdown's). 1 to try again, 0 to give up; errno is kept. */
int svc__retry(svc_job *j, int *tries, int e, const char *what,
               int only_shutdown);
/* The error of a job stopped by its cancel flag after `steps` steps
 * (-1: before its flow); 1 when it must run again after a restart. */
int svc__canceled_error(svc_job *j, int steps, svc_error *e);
/* Whether j's cancel flag is set (the flow's, loaded without the lock),
 * and why. */
int svc__canceled(const svc_job *j);
svc_cancel_reason svc__cancel_reason(const svc_job *j);
/* The runner's hooks: ready (the scheme that runs and the input format),
 * one progress event, one of the core's milestones (threads_cpu_s: the CPU
 * seconds of the threads the flow started so far). Both check the job
 * timeout and the CPU budget and set the cancel flag past either, which
 * the flow loads before its next step or pass (the default request's
 * filter reports milestones and no step until its end); svc__progress
 * also returns nonzero to stop. */
void svc__ready(svc_job *j, const char *scheme, const char *in_format);
int svc__progress(svc_job *j, const api_job_step *st);
void svc__work(svc_job *j, const char *phase, double done,
               double threads_cpu_s);
/* A job loaded from the store (recovery.c, before the workers start):
 * its recorded state r applied; a job that was running when the process
 * died runs again, one canceled while it ran stays canceled (recorded).
 * 1 when it must be queued. */
int svc__recovered(svc_job *j, const svc_state_rec *r);

/* A shared store (svc_shared.c's part, lock held): the state another
 * replica recorded applied to j unless j runs here or is terminal here;
 * subscribers notified of a change; a job that ends takes the events its
 * run left in the store (nevents lines, events_bytes bytes: 0 none). 1
 * when j changed. */
int svc__remote_state(svc_job *j, const svc_state_rec *r, int nevents,
                      size_t events_bytes);
/* One progress line of another replica's run of j (lock held): kept
 * only when it is the next step of those held. */
void svc__remote_progress(svc_job *j, const char *line, size_t len);
/* A job claimed after its runner stopped heartbeating: a running state
 * left by that replica goes back to queued (lock held). */
void svc__retaken_locked(svc_job *j);
/* A dead-lettered job (run too often, its replica stopping each time):
 * recorded and published failed. */
void svc__dead(svc_job *j);
/* Tells the replica running j of a cancel asked here (no lock). */
void svc__cancel_elsewhere(svc_job *j, svc_cancel_reason reason);

/* svc_state.c: the persisted forms, pure (no lock) */
char *svc__request_json(const svc_job *j);            /* request.json */
/* request.json back: params (typed and both texts), filename, target,
 * fields, created, memory estimate. 0, or -1 (damaged). */
int svc__request_load(svc_job *j, const cJSON *o, const api_limits *lim);
char *svc__state_json(const svc_state_rec *r);        /* state.json */
/* state.json back into a copy; *params_json the shown parameters
 * (malloc'ed, NULL when absent). 0, or -1 (damaged). */
int svc__state_parse(const cJSON *so, svc_state_rec *r, char **params_json);
/* One log line of a finished job. */
void svc__log_job(const svc_job *j, int nv, int nf, double run_s);

/* svc_error.c: the row of a service code and a name (a persisted error):
 * 0 and *p, or -1. */
int svc__problem_find(svc_code code, const char *name, svc_problem *p);

/* runner.c: one job on a worker, no lock: its outcome in *o. */
void svc__run(svc_job *j, svc_outcome *o);

/* workers.c */
int svc__workers_start(svc_t *s, char *msg, size_t msgsize);
void svc__workers_stop(svc_t *s);

/* recovery.c: reloads the store into the table and queue (a shared
 * store: nothing, its reaper recovers). */
int svc__recover(svc_t *s, char *msg, size_t msgsize);
/* request.json and state.json of job id, parsed into a new job (*j) and
 * its recorded state (*r): 0; 1 when it was never acknowledged; -1 when
 * it cannot be read now; -2 when damaged. */
int svc__load(svc_t *s, const char *id, svc_job **j, svc_state_rec *r);
/* A finished job's progress events as its run left them in the store:
 * 1 and their count and bytes, else 0 (none). No lock. */
int svc__events_stored(svc_store *st, const char *id, int *n, size_t *bytes);

/* svc_shared.c */
/* svc_job_get on a shared store: j (or NULL) refreshed, or loaded when
 * the table does not hold it. A reference, or NULL. */
svc_job *svc__shared_get(svc_t *s, const char *id);
/* The sweep's part: other replicas' jobs refreshed and followed (those
 * the follower does not), cancels asked elsewhere of the jobs this
 * replica runs. */
void svc__shared_sweep(svc_t *s);
/* The follower thread (a store with watch): the jobs other replicas run
 * that have subscribers here followed as their runner publishes. Start:
 * 0 or -1 (msg); stop joins it (accepts one never started). */
int svc__follower_start(svc_t *s, char *msg, size_t msgsize);
void svc__follower_stop(svc_t *s);

#endif /* SVC_INTERNAL_H */
