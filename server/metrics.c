/* SPDX-License-Identifier: MIT */
/*
 * metrics.c - Prometheus counters, histograms and gauges of mcfd.
 *
 * Exposed at GET /metrics in the text format 0.0.4:
 *   mcfd_http_requests_total{route,code}       counter
 *   mcfd_grpc_calls_total{method,code}         counter (gRPC status names)
 *   mcfd_jobs_total{scheme,status}             counter
 *   mcfd_job_duration_seconds                  histogram (run time)
 *   mcfd_upload_bytes                          histogram (mesh uploads)
 *   mcfd_spool_quarantined_total               counter (damaged jobs)
 *   mcfd_jobs_cpu_budget_exceeded_total        counter (jobs stopped)
 *   mcfd_queue_depth, mcfd_queue_capacity, mcfd_workers,
 *   mcfd_workers_busy, mcfd_jobs_in_memory, mcfd_draining   gauges
 * Label sets are small and bounded (routes are a fixed list, codes are
 * the few this daemon answers, schemes come from the core's table), so a
 * flat array with a linear search under one mutex is enough.
 */
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "srv.h"

#define MAX_SERIES 256

typedef struct {
    char a[24], b[24];
    double value;
} series;

typedef struct {
    const double *bounds;
    int nb;
    unsigned long counts[16];   /* per bucket, not cumulative; last: +Inf */
    double sum;
    unsigned long n;
} histogram;

static const double duration_bounds[] = {0.005, 0.01, 0.025, 0.05, 0.1, 0.25,
                                         0.5, 1, 2.5, 5, 10, 30, 60, 300};
static const double upload_bounds[] = {1024, 10240, 102400, 1048576,
                                       10485760, 104857600, 1073741824};

static struct {
    pthread_mutex_t mu;
    series req[MAX_SERIES];
    int nreq;
    series jobs[MAX_SERIES];
    int njobs;
    series grpc[MAX_SERIES];    /* 6 methods x 17 codes at most */
    int ngrpc;
    histogram duration, upload;
    double start;
    double quarantined;
    double cpu_budget;
} M = {.mu = PTHREAD_MUTEX_INITIALIZER};

void srv_metrics_init(void)
{
    pthread_mutex_lock(&M.mu);
    M.nreq = M.njobs = M.ngrpc = 0;
    memset(&M.duration, 0, sizeof M.duration);
    memset(&M.upload, 0, sizeof M.upload);
    M.duration.bounds = duration_bounds;
    M.duration.nb = (int)(sizeof duration_bounds / sizeof duration_bounds[0]);
    M.upload.bounds = upload_bounds;
    M.upload.nb = (int)(sizeof upload_bounds / sizeof upload_bounds[0]);
    M.start = srv_wall();
    pthread_mutex_unlock(&M.mu);
}

/* Adds one to the series (a, b), creating it; lock held. */
static void bump(series *s, int *n, const char *a, const char *b)
{
    int i;

    for (i = 0; i < *n; i++)
        if (strcmp(s[i].a, a) == 0 && strcmp(s[i].b, b) == 0) {
            s[i].value += 1;
            return;
        }
    if (*n == MAX_SERIES)
        return; /* bounded by construction; never reached in practice */
    snprintf(s[*n].a, sizeof s[*n].a, "%s", a);
    snprintf(s[*n].b, sizeof s[*n].b, "%s", b);
    s[*n].value = 1;
    (*n)++;
}

static void observe(histogram *h, double v)
{
    int i = 0;

    while (i < h->nb && v > h->bounds[i])
        i++;
    h->counts[i]++;
    h->sum += v;
    h->n++;
}

void srv_metrics_request(const char *route, unsigned status)
{
    char code[8];

    snprintf(code, sizeof code, "%u", status);
    pthread_mutex_lock(&M.mu);
    bump(M.req, &M.nreq, route, code);
    pthread_mutex_unlock(&M.mu);
}

void srv_metrics_grpc(const char *method, const char *code)
{
    pthread_mutex_lock(&M.mu);
    bump(M.grpc, &M.ngrpc, method, code);
    pthread_mutex_unlock(&M.mu);
}

void srv_metrics_upload(size_t bytes)
{
    pthread_mutex_lock(&M.mu);
    observe(&M.upload, (double)bytes);
    pthread_mutex_unlock(&M.mu);
}

void srv_metrics_job(const char *scheme, const char *status, double seconds)
{
    pthread_mutex_lock(&M.mu);
    bump(M.jobs, &M.njobs, scheme, status);
    observe(&M.duration, seconds);
    pthread_mutex_unlock(&M.mu);
}

void srv_metrics_quarantined(void)
{
    pthread_mutex_lock(&M.mu);
    M.quarantined++;
    pthread_mutex_unlock(&M.mu);
}

void srv_metrics_cpu_budget(void)
{
    pthread_mutex_lock(&M.mu);
    M.cpu_budget++;
    pthread_mutex_unlock(&M.mu);
}

static void render_histogram(api_buf *b, const char *name, const char *help,
                             const histogram *h)
{
    unsigned long cum = 0;
    int i;

    api_buf_printf(b, "# HELP %s %s\n# TYPE %s histogram\n", name, help, name);
    for (i = 0; i < h->nb; i++) {
        cum += h->counts[i];
        api_buf_printf(b, "%s_bucket{le=\"%.17g\"} %lu\n", name, h->bounds[i],
                       cum);
    }
    cum += h->counts[h->nb];
    api_buf_printf(b, "%s_bucket{le=\"+Inf\"} %lu\n", name, cum);
    api_buf_printf(b, "%s_sum %.17g\n%s_count %lu\n", name, h->sum, name,
                   h->n);
}

static void gauge(api_buf *b, const char *name, const char *help, double v)
{
    api_buf_printf(b, "# HELP %s %s\n# TYPE %s gauge\n%s %.17g\n", name, help,
                   name, name, v);
}

static void counter1(api_buf *b, const char *name, const char *help, double v)
{
    api_buf_printf(b, "# HELP %s %s\n# TYPE %s counter\n%s %.17g\n", name, help,
                   name, name, v);
}

/* A counter family with two labels, la and lb (a and b of each series). */
static void counter(api_buf *b, const char *name, const char *help,
                    const char *la, const char *lb, const series *s, int n)
{
    int i;

    api_buf_printf(b, "# HELP %s %s\n# TYPE %s counter\n", name, help, name);
    for (i = 0; i < n; i++)
        api_buf_printf(b, "%s{%s=\"%s\",%s=\"%s\"} %.17g\n", name, la, s[i].a,
                       lb, s[i].b, s[i].value);
}

char *srv_metrics_render(const srv_gauges *g, size_t *len)
{
    api_buf b;

    api_buf_init(&b, 16u << 20);
    pthread_mutex_lock(&M.mu);
    counter(&b, "mcfd_http_requests_total",
            "HTTP responses by route and status code.", "route", "code",
            M.req, M.nreq);
    counter(&b, "mcfd_grpc_calls_total", "gRPC calls by method and status code.",
            "method", "code", M.grpc, M.ngrpc);
    counter(&b, "mcfd_jobs_total", "Finished jobs by scheme and final status.",
            "scheme", "status", M.jobs, M.njobs);
    render_histogram(&b, "mcfd_job_duration_seconds",
                     "Job run time from start to finish (queue wait excluded).",
                     &M.duration);
    render_histogram(&b, "mcfd_upload_bytes", "Size of uploaded meshes.",
                     &M.upload);
    gauge(&b, "mcfd_start_time_seconds", "Start time since the epoch.",
          M.start);
    api_buf_printf(&b, "# HELP mcfd_spool_quarantined_total Damaged job "
                   "directories moved to <spool>/quarantine.\n# TYPE "
                   "mcfd_spool_quarantined_total counter\n"
                   "mcfd_spool_quarantined_total %.17g\n", M.quarantined);
    api_buf_printf(&b, "# HELP mcfd_jobs_cpu_budget_exceeded_total Jobs stopped "
                   "for using their CPU budget (--job-cpu + 0.5 s per MiB of "
                   "their memory estimate).\n# TYPE "
                   "mcfd_jobs_cpu_budget_exceeded_total counter\n"
                   "mcfd_jobs_cpu_budget_exceeded_total %.17g\n", M.cpu_budget);
    pthread_mutex_unlock(&M.mu);
    gauge(&b, "mcfd_queue_depth", "Jobs waiting for a worker.", g->queue_depth);
    gauge(&b, "mcfd_queue_capacity", "Longest queue before 503.",
          g->queue_capacity);
    gauge(&b, "mcfd_workers", "Mesh worker threads.", g->workers);
    gauge(&b, "mcfd_workers_busy", "Workers running a job.", g->workers_busy);
    gauge(&b, "mcfd_jobs_in_memory", "Job records held (queued to expired).",
          g->jobs_in_memory);
    gauge(&b, "mcfd_draining", "1 after SIGTERM/SIGINT.", g->draining);
    gauge(&b, "mcfd_followers", "Event streams (SSE, ndjson) open.",
          g->followers);
    gauge(&b, "mcfd_spool_bytes", "Bytes of the jobs kept on the spool.",
          g->spool_bytes);
    gauge(&b, "mcfd_grpc_connections", "gRPC connections open.", g->grpc_connections);
    gauge(&b, "mcfd_grpc_streams", "gRPC streams open in gRPC.", g->grpc_streams);
    gauge(&b, "mcfd_grpc_connections_waiting",
          "gRPC connections held at a stream bound (not read).", g->grpc_waiting);
    counter1(&b, "mcfd_grpc_connections_refused_total",
             "gRPC connections refused at a cap or the descriptor reserve.", g->grpc_refused);
    counter1(&b, "mcfd_grpc_connections_closed_total",
             "gRPC connections closed for a bound (preface, header block, protocol).",
             g->grpc_closed);
    counter1(&b, "mcfd_grpc_streams_reset_total",
             "gRPC streams reset for sending no first message in time.", g->grpc_reset);
    counter1(&b, "mcfd_grpc_accept_errors_total",
             "accept() failures of the gRPC door (out of descriptors or memory).",
             g->grpc_accept_errors);
    return api_buf_detach(&b, len);
}
