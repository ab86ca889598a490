/*
 * svc_internal.h - what the files of the job service share, and only
 * they (service.c, svc_read.c, svc_state.c, svc_error.c, runner.c,
 * workers.c, recovery.c, svc_admit.c): the job struct, the service's
 * state and its one lock. The doors include service.h, never this.
 *
 * Locking: svc__S.mu guards the table, the queue, the counters and every
 * mutable field of every job, and the subscription lists. It is held for
 * bookkeeping only, never across mesh work or disk I/O; subscription
 * callbacks run under it (service.h). svc_state_mu serializes the writers
 * of state.json and is taken before svc__S.mu.
 */
#ifndef SVC_INTERNAL_H
#define SVC_INTERNAL_H

#include <pthread.h>

#include "service.h"
#include "srv.h"

#define SVC_NBUCKETS 4096
#define SVC_EVENTS_MAX ((size_t)16 << 20)   /* ndjson progress kept per job */
#define SVC_RESULT_MAX ((size_t)4 << 30)    /* an encoded result */
/* Retries of a job's step that met a resource a client can exhaust
 * (EMFILE, ENFILE, ENOSPC, EDQUOT, ENOMEM): 0.1 s doubling to 8 s, 37 s
 * in all (runner.c), long enough for connections to time out or be
 * closed, short enough that a full disk fails the job within a minute. */
#define SVC_RETRY_TRIES 10
#define SVC_FIELDS_FILE "fields.bin"        /* fields=true: api_fields_encode */

struct svc_sub {
    svc_job *job;
    unsigned flags;
    svc_notify_fn fn;
    void *ctx;
    svc_sub *prev, *next;
};

struct svc_job {
    char id[SVC_ID_LEN + 1];
    int refs;                  /* table + every holder of a handle */
    int in_table;
    svc_job_status status;
    svc_record rec;
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
    int parked;                /* queued, out of the queue until retry_at:
                                  its outcome could not be recorded */
    int parks;                 /* times it was */
    double retry_at;           /* srv_mono() seconds */
    double mem_estimate;       /* estimated peak bytes (svc_admit.c) */
    double mem_held;           /* reserved while it runs */
    /* progress, written by the runner's progress callback */
    int step;
    double t, dt, energy, volume;
    int ready;                 /* decoded and checked: streams may start */
    mcf_cancel_flag cancel;    /* written under the lock, loaded without
                                  it by mcf_flow_run (params.cancel) */
    svc_cancel_reason cancel_reason;
    svc_cancel_reason cancel_asked; /* service.c: a cancel being written */
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
    char result_name[32];      /* "result.obj" in the job directory */
    size_t result_len;
    char *result;              /* encoded mesh kept for its submitter */
    int keep_result;
    svc_sub *subs;
    svc_job *hnext, *qnext;
};

extern struct svc_state {
    pthread_mutex_t mu;
    pthread_cond_t work;      /* workers: a job was queued, or stop */
    pthread_cond_t idle;      /* drain: a worker finished its job */
    svc_config cfg;
    svc_job *buckets[SVC_NBUCKETS];
    int njobs;
    svc_job *qhead, *qtail;
    int qlen, reserved, busy;
    size_t disk_bytes;        /* sum of disk_bytes of the jobs in the table */
    int draining, stopping;
    int closing;              /* doors must answer now, never wait */
    pthread_t *threads;
    int nthreads;
    int urandom;
    uint64_t counter;
} svc__S;

extern pthread_mutex_t svc_state_mu;

void svc__lock(void);
void svc__unlock(void);

/* service.c: jobs, table and queue (lock held unless said) */
svc_job *svc__job_new(void);
void svc__job_free(svc_job *j);
void svc__unref_locked(svc_job *j);
svc_job *svc__find_locked(const char *id);
void svc__table_insert(svc_job *j);
void svc__queue_push(svc_job *j);
svc_job *svc__queue_pop(void);
/* Calls the subscribers of j whose flags match what. */
void svc__notify(svc_job *j, unsigned what);

/* svc_state.c: the persisted forms */
char *svc__request_json(const svc_job *j);               /* request.json */
int svc__record_from_json(svc_record *r, const cJSON *o);
char *svc__state_json(const svc_job *j);                 /* lock held */
/* state.json parsed into j (status, times, formats, error...). */
int svc__state_load(svc_job *j, const cJSON *so);
/* Snapshot under the lock, write outside it (svc_state_mu around). */
int svc__write_state(svc_job *j, int durable);
/* One log line and the metrics of a finished job. */
void svc__log_job(const svc_job *j, int nv, int nf, double run_s);

/* runner.c: decode, smooth and encode one job (a worker, no lock). */
void svc__run_job(svc_job *j);

/* workers.c */
int svc__workers_start(char *msg, size_t msgsize);
void svc__workers_stop(void);

/* recovery.c: reloads the spool into the table and queue. */
int svc__recover(char *msg, size_t msgsize);

#endif /* SVC_INTERNAL_H */
