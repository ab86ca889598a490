/* SPDX-License-Identifier: MIT */
/*
 * rest_internal.h - the REST door of mcfd on libmicrohttpd, shared by its
 * files; its face is rest_door.h. The calls go one way: rest_door.c ->
 * the router http.c (http.h) -> upload.c, jobroutes.c, ui.c -> stream.c
 * -> waiter.c, reply.c -> request.c, the leaf that reads a request; no
 * file calls back up (make check-deps). The door reaches jobs only
 * through service.h: no job internals, no service lock. Its state is one
 * struct (rest_t), which every request, waiter and stream points to.
 *
 * A request object (rest_request) is made by the URI log callback, hangs
 * on con_cls, and is freed only in the completion callback (or when its
 * connection closes without one). The handler runs on MHD's small thread
 * pool and never touches a mesh. A request or stream waiting on a job
 * suspends its connection through an rest_waiter, which a subscription of
 * the service resumes.
 */
#ifndef SRV_REST_INTERNAL_H
#define SRV_REST_INTERNAL_H

#include <pthread.h>
#include <stdatomic.h>

#include <microhttpd.h>

#include "door.h"
#include "service.h"
#include "srv.h"

typedef struct conn_state conn_state;  /* http.c: a connection's bookkeeping */
typedef struct rest_waiter rest_waiter;

/* The REST door's state. Its locks (the door's): conns_mu guards the
 * connection list, active_mu the request count, wait_mu every waiter's
 * flags and the waiter list (waiter.c; taken inside the service's lock by
 * its subscription callback, so the door never calls the service with it
 * held). */
typedef struct rest_t {
    const srv_config *cfg;
    svc_t *svc;
    srv_daemon dm;             /* the rest of the daemon: health, gauges */
    struct MHD_Daemon *mhd;
    atomic_int draining;       /* set by drain (main thread), read by MHD's */
    pthread_mutex_t active_mu;
    int active;                /* requests between URI callback and end */
    pthread_mutex_t conns_mu;
    conn_state *conns;
    int nconns;
    void *ips;                 /* connections per client address (a tsearch
                                  tree, http.c) */
    pthread_mutex_t wait_mu;
    rest_waiter *waiters;
    int followers;             /* event streams open */
} rest_t;

/* ---------------------------------------------------------------- problems */

/* The problem (service.h's table: its HTTP status and name) as an RFC
 * 9457 JSON object (type, title, status, detail, instance, code, and job
 * when given). NULL on allocation failure. */
cJSON *rest_problem_json(const svc_error *e, const char *instance,
                         const char *job_id);
/* The reason phrase of an HTTP status ("Unprocessable Content"). */
const char *rest_http_reason(unsigned status);
/* The job document of the REST API (id, status, created/started/finished
 * as RFC 3339 or null, progress {step, steps, t, dt, energy, volume,
 * fraction}, cancel_requested, params, input_format, metrics when
 * succeeded, the error as a problem, the links). *snap (may be NULL):
 * the state it shows. NULL on allocation failure. */
cJSON *rest_job_json(const svc_job *j, svc_snap *snap);

/* ----------------------------------------------------------------- waiters */

/* A connection waiting on a job. Lives inside the request or stream that
 * owns it (which holds the job reference). The door's own lock guards
 * its flags; the service's subscription callback takes that lock. */
struct rest_waiter {
    rest_t *door;
    struct MHD_Connection *conn;
    char id[SVC_ID_LEN + 1];   /* its job's */
    svc_sub *sub;
    int want_events;           /* woken on every progress event */
    int cancel_on_hangup;      /* the job's only client: its hang-up
                                  cancels the job (rest_http_check_clients) */
    int suspended;             /* MHD_suspend_connection called, not resumed */
    int pending;               /* notified since rest_waiter_arm */
    int gone;                  /* its client hung up: end the stream */
    int retry;                 /* asleep on a store that could not be read:
                                  resumed by rest_http_check_clients */
    int linked;
    struct rest_waiter *prev, *next;
};

/* Subscribes w to j (progress too when want_events). 0, or -1 (ENOMEM). */
int rest_waiter_start(rest_waiter *w, rest_t *d, svc_job *j,
                      struct MHD_Connection *c, int want_events,
                      int cancel_on_hangup);
/* Ends the subscription (accepts a waiter never started). Call with no
 * lock held, before the connection goes. */
void rest_waiter_stop(rest_waiter *w);
/* The wait protocol: rest_waiter_arm, then read a snapshot and answer
 * what can be answered; else rest_waiter_sleep, which suspends the
 * connection (1) unless a notification came since the arm (0: look
 * again). A suspended connection is resumed by the next notification. */
void rest_waiter_arm(rest_waiter *w);
int rest_waiter_sleep(rest_waiter *w);
/* Before rest_waiter_sleep: the next sleep ends at the main thread's next
 * check of the clients (a quarter of a second) even without a
 * notification, to read the store again. */
void rest_waiter_retry(rest_waiter *w);
/* Whether the client of a stream left while it slept. */
int rest_waiter_gone(rest_waiter *w);
/* Event streams open now (the mcfd_followers gauge). */
int rest_waiter_followers(rest_t *d);
/* Ends the event streams whose client has closed its connection, and
 * cancels (SVC_CANCEL_CLIENT) the jobs whose only client, a waiting
 * request, has. Called a few times a second (the door's expire).
 * Returns how many jobs it canceled. */
int rest_http_check_clients(rest_t *d);

/* ------------------------------------------------------------------ stream */

typedef enum { SRV_STREAM_NDJSON = 0, SRV_STREAM_SSE } rest_stream_kind;

/* A chunked response that follows the job's events until it finishes.
 * Holds its own job reference. last_id: SSE Last-Event-ID (-1: none).
 * phases: the core's milestones between the steps too (SSE's "work"
 * events always: an EventSource hears only the types it listens to). */
struct MHD_Response *rest_stream_response(rest_t *d, svc_job *j,
                                          rest_stream_kind kind, int phases,
                                          struct MHD_Connection *conn,
                                          long last_id);
/* Whether one more follower of j may start (at most SVC_FOLLOWERS_PER_JOB
 * per job, counting gRPC's, and half of --max-connections in all); else 0
 * and a 503. */
int rest_stream_admit(rest_t *d, const svc_job *j, svc_error *e);

typedef struct rest_asset rest_asset; /* ui_assets.h */

/* ---------------------------------------------------------------- requests */

typedef enum {
    RT_HEALTHZ = 0,
    RT_READYZ,
    RT_METRICS,
    RT_OPENAPI,
    RT_SCHEMES,
    RT_SMOOTH,
    RT_JOBS,
    RT_JOB,
    RT_JOB_RESULT,
    RT_JOB_METRICS,
    RT_JOB_EVENTS,
    RT_JOB_FIELDS,
    RT_UI,
    RT_OTHER
} rest_route;

typedef enum { MODE_SYNC = 0, MODE_MIXED, MODE_NDJSON, MODE_ASYNC } rest_mode;

typedef struct {
    rest_t *door;
    char *uri;                 /* raw request target, query included */
    char path[256];
    char method[16];
    char id[SVC_ID_LEN + 1];
    double t0;
    rest_route rt;
    const rest_asset *asset;    /* RT_UI: the page's file */
    unsigned status;           /* of the queued response, 0 before */
    int started;
    int deferred;              /* answered once the (absent) body is read */
    void *conn;                /* its connection's conn_state, or NULL */
    /* upload */
    int multipart;
    struct MHD_PostProcessor *pp;
    api_buf mesh, target, params;
    int has_mesh, has_target, has_params;
    cJSON *fields;             /* [[key, value], ...] plain form fields */
    size_t fields_bytes;
    char filename[128];
    size_t bytes_in;
    svc_error perr;            /* refused: at its head (perr_head), answered
                                  once the body is read and discarded, or
                                  while reading, answered at once on the
                                  socket (answered) */
    int has_perr;
    int perr_head;             /* perr was set from the head */
    int answered;              /* perr written on the socket: the rest of
                                  the body is discarded, then the
                                  connection closed */
    size_t perr_at;            /* bytes_in + 1 when perr was first seen */
    size_t declared;           /* its Content-Length, 0: none */
    size_t mem_held;           /* its bytes' reservation in --max-memory
                                  (svc_upload_reserve) */
    /* waiting on a job */
    rest_mode md;
    int phases;                /* stream=ndjson&phases=true: the core's
                                  milestones too (stream.c) */
    svc_job *job;
    rest_waiter w;
    int waiting;
    int sync_owner;            /* this request takes the kept result */
} rest_request;

/* request.c: what a request says, read by every file of the door (a leaf:
 * it calls no other file of the door). */

/* The route's label in metrics and logs ("smooth", "job", ...). */
const char *rest_route_name(rest_route rt);

/* The query string of the request target, NULL when there is none. */
const char *rest_query_of(const rest_request *r);
/* The decoded value of `key` in the raw query (last one wins), into out;
 * NULL when absent. %XX and '+' are decoded. */
const char *rest_query_value(const rest_request *r, const char *key, char *out,
                             size_t size);

/* Responses (reply.c). Each queues resp (NULL: MHD_NO) with status and
 * counts it in the request metrics. */
enum MHD_Result rest_respond(rest_request *r, struct MHD_Connection *c,
                             unsigned status, struct MHD_Response *resp);
/* A response holding o printed (takes o), with a trailing newline when
 * asked and the given Content-Type; NULL when out of memory. */
struct MHD_Response *rest_json_response(cJSON *o, const char *ctype,
                                        int newline);
/* Takes o. */
enum MHD_Result rest_send_json(rest_request *r, struct MHD_Connection *c,
                               unsigned status, cJSON *o);
/* Takes text (malloc'ed). */
enum MHD_Result rest_send_text(rest_request *r, struct MHD_Connection *c,
                               unsigned status, const char *ctype, char *text,
                               size_t len);
/* problem+json with the row's status, Retry-After on a transient
 * refusal (e->retry_after), WWW-Authenticate on 401, Allow on 405 and
 * X-Job-Id when job is given. */
enum MHD_Result rest_send_problem(rest_request *r, struct MHD_Connection *c,
                                  const svc_error *e, const char *job);
enum MHD_Result rest_send_problemf(rest_request *r, struct MHD_Connection *c,
                                   svc_problem p, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;
/* An empty response (204, HEAD). */
struct MHD_Response *rest_empty_response(void);
/* The problem written straight to the connection's socket, with
 * Connection: close, for a body MHD is still reading (libmicrohttpd
 * 0.9.75 queues no answer then: MHD_queue_response says MHD_NO), then
 * the socket's sending side shut (the client reads the answer and an
 * end, not a reset): the caller discards what still comes, and returns
 * MHD_NO, which closes the connection. Counted and logged like
 * rest_send_problem's. */
void rest_send_problem_raw(rest_request *r, struct MHD_Connection *c,
                           const svc_error *e);

/* upload.c: the checks of an upload's head (415, 413, 503 before the
 * body), the body's bytes, and the submission once it is complete. */
enum MHD_Result rest_upload_begin(rest_request *r, struct MHD_Connection *c);
void rest_upload_consume(rest_request *r, const char *data, size_t size);
enum MHD_Result rest_upload_submit(rest_request *r, struct MHD_Connection *c);
/* A body refused from its head (a busy daemon's 503 to a client that
 * did not wait for 100 Continue) is read and discarded, so that a client
 * sending it all before it reads hears why: to its declared end (at most
 * this: above it, refused before it is read), or without a declared
 * length up to this much, then the answer is written on the socket and
 * the connection closed. A refusal found in the body (a part over
 * --max-upload, a body past it, broken multipart) is written on the
 * socket at once, and up to this much more of the body discarded before
 * the close. */
#define SRV_DRAIN_MAX ((unsigned long long)16 << 20)

/* jobroutes.c: the /v1/jobs/ID routes, and a waiting /smooth request
 * (after submit and after every resume): answers when there is
 * something to say, else suspends again. */
enum MHD_Result rest_route_job(rest_request *r, struct MHD_Connection *c,
                               const char *method);
enum MHD_Result rest_wait_or_answer(rest_request *r, struct MHD_Connection *c);
/* The request ends: drops its subscription, kept result and reference. */
void rest_request_release_job(rest_request *r);

/* The media type of GET /v1/jobs/ID/fields (api_fields_encode's document). */
#define SRV_FIELDS_MIME "application/vnd.mcfd.fields"

/* ui.c: the page (GET / and /ui/NAME), public, from the files embedded
 * at build time, and /ui/config.json. 1 when path is one of them (*asset
 * set; NULL for the config), else 0. */
int rest_ui_find(const char *path, const rest_asset **asset);
enum MHD_Result rest_ui_send(rest_request *r, struct MHD_Connection *c,
                             const rest_asset *a);

/* The API description embedded at build time (build/server/openapi_yaml.c). */
extern const unsigned char rest_openapi_yaml[];
extern const size_t rest_openapi_yaml_len;

#endif /* SRV_REST_INTERNAL_H */
