/* SPDX-License-Identifier: MIT */
/*
 * srv.h - the daemon's own declarations, shared by the files of mcfd:
 * configuration, logging and clocks, descriptors, the Prometheus
 * metrics. No transport type appears here.
 *
 * server/ is the only layer that knows about HTTP, configuration, signals,
 * files and logging. Its top holds the process, one file per concern:
 *   main.c      process set-up, signal loop, drain and exit, --probe
 *   config.c    flags and MCFD_* environment variables -> srv_config
 *               (whose svc_config, cfg.svc, goes to svc_start as it is)
 *   log.c       one JSON line per event on stderr
 *   metrics.c   Prometheus counters and histograms
 *   fds.c       descriptors: the limit raised, the doors' caps fitted to it
 *   fsio.c      whole writes and directory syncs, for every durable file
 * with the contracts between the modules below: service.h (the job
 * service), problem.h (the client-visible errors), door.h (a door, to
 * main.c). One folder per module, each with its own export prefix:
 * service/ (svc_), sandbox/ (sandbox_), store/ and store/redis/ (store_,
 * rstore_, rds_), rest/ (rest_), grpc/ (mcfd_grpc) and grpc/h2gate/
 * (h2gate_); docs/internals.md has the map, the lock order and one
 * request of each door file by file.
 *
 * Threads: MHD's small pool runs the REST door and never touches a mesh;
 * the service's worker pool decodes, smooths and encodes.
 */
#ifndef SRV_H
#define SRV_H

#include <stddef.h>
#include <stdint.h>

#include "api.h"
#include "service.h"  /* svc_config */

/* ------------------------------------------------------------ configuration */

typedef enum {
    SRV_LOG_ERROR = 0,
    SRV_LOG_WARN,
    SRV_LOG_INFO,
    SRV_LOG_DEBUG
} srv_log_level;

typedef struct {
    svc_config svc;            /* the job service's part, handed to
                                  svc_start as it is: its workers, queue,
                                  store, limits on untrusted input (lim),
                                  TTL, timeouts, memory and CPU budgets
                                  (defaults and flags: config.c) */
    char bind[256];            /* address to listen on (default 127.0.0.1) */
    int port;                  /* 0: any free port (default 8080) */
    int grpc_port;             /* gRPC door: 0 any free port, -1 off
                                  (default 50051) */
    int http_threads;          /* MHD thread pool size (default 2) */
    int max_connections;       /* MHD connection limit (fitted to the
                                  descriptors: srv_fds_fit) */
    int max_connections_per_ip; /* from one address, 0: none; keeps one
                                   client from taking every slot */
    int grpc_max_connections;  /* the gRPC door's: --max-connections
                                  fitted to the descriptors */
    int fd_reserve;            /* descriptors no connection may take */
    size_t max_body;           /* whole request body, derived from svc.lim */
    double drain_timeout;      /* seconds SIGTERM waits for running jobs */
    double header_timeout;     /* seconds for a request's head, 0: none */
    double body_timeout;       /* seconds for its whole body, 0: none */
    double send_timeout;       /* seconds an answer may go unread: MHD's
                                  connection timeout, gRPC's stalled write;
                                  0: none */
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

/* -------------------------------------------------------------- descriptors */

/* Raises RLIMIT_NOFILE's soft limit to its hard limit, then fits the
 * doors' connection caps in what is left after cfg->fd_reserve (set here:
 * the spool, the sandbox's pipes, gRPC's own, the probes): a REST
 * connection takes one descriptor, a gRPC one three (h2gate.c). Lowers
 * cfg->max_connections and sets cfg->grpc_max_connections, with a warning
 * when the limit does not hold what the flags ask. Before the doors start. */
void srv_fds_fit(srv_config *cfg);
/* RLIMIT_NOFILE's soft limit now, and how far the lowest free descriptor
 * is below it (0: none free). A gRPC connection is admitted while the
 * headroom is over cfg->fd_reserve + 2 (h2gate.c), a REST one while it
 * is over half the reserve: the other half is for the daemon's files and
 * the probes come over REST. */
int srv_fds_limit(void);
int srv_fds_headroom(void);
/* Health: how long the headroom has been within the reserve (the main
 * thread's tick calls srv_fds_watch); after SRV_FDS_DEAD seconds of that,
 * srv_fds_health is -1 with why: the gRPC door takes nothing. */
#define SRV_FDS_DEAD 5.0
void srv_fds_watch(double now);
int srv_fds_health(char *why, size_t size);

/* fsio.c. srv_write_all: all len bytes to fd (EINTR retried, a short
 * write continued); 0, or -1 and errno. srv_sync_dir: fsync() of the
 * directory dir, so a file renamed into it stays after a crash; 0, or -1
 * and errno. */
int srv_write_all(int fd, const void *data, size_t len);
int srv_sync_dir(const char *dir);

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

/* srv_logf for what a client can make happen as often as it likes (accept
 * errors, refused connections): at most SRV_LOG_BURST lines per
 * SRV_LOG_WINDOW seconds per limiter; the first line after that says how
 * many were left out ("suppressed"). A limiter is a static zeroed struct. */
#define SRV_LOG_BURST 5
#define SRV_LOG_WINDOW 10.0
typedef struct {
    double window;             /* srv_mono() the window opened */
    int lines;                 /* lines written in it */
    long suppressed;           /* lines left out in it */
} srv_log_limit;
void srv_logf_limited(srv_log_limit *l, srv_log_level lvl, const char *fmt,
                      ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* Wall clock, seconds since the epoch, and its RFC 3339 form (UTC, ms):
 * for timestamps only (they persist in the spool). */
double srv_wall(void);
/* CLOCK_MONOTONIC seconds: every deadline and timeout (a wall clock set
 * back or forward would stretch or cut them). */
double srv_mono(void);
void srv_time_rfc3339(double t, char *buf, size_t size);

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
/* One job directory moved to the spool's quarantine (spool.c). */
void srv_metrics_quarantined(void);
/* A job stopped for using its CPU budget. */
void srv_metrics_cpu_budget(void);

typedef struct {
    int queue_depth, queue_capacity;
    int workers, workers_busy;
    int jobs_in_memory;
    int draining;
    int followers;             /* event streams (SSE, ndjson) open */
    double spool_bytes;        /* bytes of the jobs kept */
    /* the gRPC door's gate (h2gate.c): gauges, then counters */
    int grpc_connections, grpc_streams, grpc_waiting;
    double grpc_refused, grpc_closed, grpc_reset, grpc_accept_errors;
} srv_gauges;

/* The Prometheus text exposition (format 0.0.4), malloc'ed. */
char *srv_metrics_render(const srv_gauges *g, size_t *len);

#endif /* SRV_H */
