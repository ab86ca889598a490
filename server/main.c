/* SPDX-License-Identifier: MIT */
/*
 * main.c - mcfd's process: configuration, the job service and its two
 * doors (door.h: REST and gRPC, started, ticked, drained and stopped
 * alike), the signal loop, graceful drain and exit; and `mcfd --probe`.
 *
 * Start-up order matters:
 *  1. BLAS threads are bounded to one per worker before the library
 *     starts its pool. OpenBLAS reads its variables in a constructor that
 *     runs before main(), so when the variables are not set yet, main sets
 *     them and re-executes itself once (same PID, same argv). An operator
 *     who sets them keeps their values.
 *  2. SIGTERM/SIGINT are blocked in every thread (the mask is inherited)
 *     and taken synchronously by this thread with sigtimedwait, which also
 *     gives the tick for the TTL sweep and the doors' deadlines (clients
 *     that hung up, slow heads and bodies). SIGPIPE is ignored.
 *  3. The service starts (its store recovered, its workers running)
 *     before a door opens, so the first request already sees recovered
 *     jobs.
 *  4. One line "mcfd listening on http://ADDRESS:PORT" goes to stdout
 *     (flushed) once the socket listens; --port 0 prints the real port.
 *     Then the gRPC door (grpc.cc) starts on --grpc-port unless it is off
 *     and prints "mcfd grpc listening on ADDRESS:PORT".
 *
 * On SIGTERM/SIGINT: /readyz turns 503 and new jobs get 503 + Retry-After
 * (gRPC: health NOT_SERVING, new Smooth/SubmitJob calls UNAVAILABLE)
 * while the socket stays open for probes and result downloads; running
 * jobs finish (or, after --drain-timeout, are checkpointed back to
 * `queued` on disk); every suspended connection is resumed and answered;
 * then the doors stop, then the service, and the process exits 0.
 */
#include <errno.h>
#include <malloc.h>
#include <netdb.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <pthread.h>
#include <time.h>
#include <unistd.h>

#include "grpc_door.h"
#include "prog.h"
#include "rest_door.h"
#include "service.h"
#include "srv.h"
#include "sandbox.h"

/* The doors, started in this order and stopped in the other. Each door's
 * threads read the others' (doors_health, doors_gauges) while the main
 * thread publishes or withdraws them: doors_mu guards the array, and a
 * door is withdrawn before it is stopped. */
static const srv_door_ops *const door_ops[] = {&rest_door, &mcfd_grpc_door};
#define NDOORS (sizeof door_ops / sizeof door_ops[0])
static void *doors[NDOORS];
static pthread_mutex_t doors_mu = PTHREAD_MUTEX_INITIALIZER;

/* /healthz and /readyz: every door must be able to take a connection (a
 * door that accepts nothing makes the daemon unhealthy, so that an
 * orchestrator restarts it), and the descriptors must not be gone. */
static int doors_health(void *ctx, char *why, size_t size)
{
    size_t i;
    int rc = 0;
    (void)ctx;
    if (srv_fds_health(why, size) != 0)
        return -1;
    pthread_mutex_lock(&doors_mu);
    for (i = 0; i < NDOORS && rc == 0; i++)
        if (doors[i] && door_ops[i]->health(doors[i], why, size) != 0)
            rc = -1;
    pthread_mutex_unlock(&doors_mu);
    return rc;
}

/* /metrics: every door's gauges. */
static void doors_gauges(void *ctx, srv_gauges *g)
{
    size_t i;
    (void)ctx;
    pthread_mutex_lock(&doors_mu);
    for (i = 0; i < NDOORS; i++)
        if (doors[i])
            door_ops[i]->gauges(doors[i], g);
    pthread_mutex_unlock(&doors_mu);
}

/* Requests and calls in flight, through every door. */
static int doors_active(void)
{
    size_t i;
    int n = 0;
    pthread_mutex_lock(&doors_mu);
    for (i = 0; i < NDOORS; i++)
        if (doors[i])
            n += door_ops[i]->active(doors[i]);
    pthread_mutex_unlock(&doors_mu);
    return n;
}

/* Stops the doors, the last started first (gRPC before REST: its calls
 * hold jobs and subscriptions too). */
static void doors_stop(void)
{
    size_t i;
    void *d;
    for (i = NDOORS; i-- > 0;) {
        pthread_mutex_lock(&doors_mu);
        d = doors[i];
        doors[i] = NULL;
        pthread_mutex_unlock(&doors_mu);
        door_ops[i]->stop(d);
    }
}

/* The address to connect to for a daemon bound to `bind`. */
static const char *probe_host(const char *bind)
{
    if (strcmp(bind, "0.0.0.0") == 0 || strcmp(bind, "") == 0)
        return "127.0.0.1";
    if (strcmp(bind, "::") == 0)
        return "::1";
    return bind;
}

/* mcfd --probe: GET /healthz on the configured address, 2 s budget.
 * Exit 0 on "HTTP/1.x 200", else 1. No curl needed in the image. */
static int probe(const srv_config *cfg)
{
    struct addrinfo hints, *res = NULL, *ai;
    char port[16], buf[64];
    const char *host = probe_host(cfg->bind);
    struct timeval tv = {2, 0};
    int fd = -1, ok = 0;
    size_t got = 0;

    memset(&hints, 0, sizeof hints);
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    snprintf(port, sizeof port, "%d", cfg->port);
    if (getaddrinfo(host, port, &hints, &res) != 0) {
        fprintf(stderr, "mcfd --probe: cannot resolve %s\n", host);
        return 1;
    }
    for (ai = res; ai && fd < 0; ai = ai->ai_next) {
        fd = socket(ai->ai_family, ai->ai_socktype, ai->ai_protocol);
        if (fd < 0)
            continue;
        setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
        setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
        if (connect(fd, ai->ai_addr, ai->ai_addrlen) != 0) {
            close(fd);
            fd = -1;
        }
    }
    freeaddrinfo(res);
    if (fd < 0) {
        fprintf(stderr, "mcfd --probe: cannot connect to %s:%d\n", host,
                cfg->port);
        return 1;
    }
    {
        static const char req[] = "GET /healthz HTTP/1.0\r\nHost: localhost\r\n"
                                  "\r\n";
        if (write(fd, req, sizeof req - 1) == (ssize_t)(sizeof req - 1)) {
            while (got < sizeof buf - 1) {
                ssize_t r = read(fd, buf + got, sizeof buf - 1 - got);
                if (r <= 0)
                    break;
                got += (size_t)r;
            }
        }
    }
    close(fd);
    buf[got] = '\0';
    ok = got >= 12 && memcmp(buf, "HTTP/1.", 7) == 0 &&
         memcmp(buf + 8, " 200", 4) == 0;
    if (!ok)
        fprintf(stderr, "mcfd --probe: unhealthy: %.40s\n",
                got ? buf : "(no answer)");
    return ok ? 0 : 1;
}

static void log_start(const srv_config *cfg, const char *url)
{
    cJSON *o = cJSON_CreateObject();
    if (!o)
        return;
    cJSON_AddStringToObject(o, "msg", "mcfd started");
    cJSON_AddStringToObject(o, "url", url);
    cJSON_AddNumberToObject(o, "workers", cfg->svc.workers);
    cJSON_AddNumberToObject(o, "queue", cfg->svc.queue);
    cJSON_AddNumberToObject(o, "http_threads", cfg->http_threads);
    cJSON_AddStringToObject(o, "spool", cfg->svc.spool);
    cJSON_AddStringToObject(o, "store", cfg->svc.store[0] ? cfg->svc.store : "spool");
    cJSON_AddNumberToObject(o, "max_upload", (double)cfg->svc.lim.max_input_bytes);
    cJSON_AddNumberToObject(o, "max_memory", (double)cfg->svc.max_memory);
    cJSON_AddNumberToObject(o, "result_ttl_s", cfg->svc.result_ttl);
    cJSON_AddBoolToObject(o, "auth", cfg->token_len > 0);
    cJSON_AddNumberToObject(o, "pid", getpid());
    srv_log_json(SRV_LOG_INFO, o);
}

/* Waits (polling, bounded) until no request or gRPC call is in flight. */
static void wait_requests(double seconds)
{
    double end = srv_mono() + seconds;
    struct timespec ts = {0, 20 * 1000 * 1000};

    while (doors_active() > 0 && srv_mono() < end)
        nanosleep(&ts, NULL);
}

/* Starts the doors (gRPC unless --grpc-port is off), each saying where it
 * listens on stdout. 0, or -1 with a reason in msg (the started ones
 * stopped). */
static int doors_start(const srv_config *cfg, svc_t *svc, char *url,
                       size_t urlsize, char *msg, size_t msgsize)
{
    static const char *const said[NDOORS] = {"mcfd listening on",
                                             "mcfd grpc listening on"};
    const srv_daemon dm = {doors_health, doors_gauges, NULL};
    char where[300];
    size_t i;
    void *d;

    for (i = 0; i < NDOORS; i++) {
        if (door_ops[i] == &mcfd_grpc_door && cfg->grpc_port < 0)
            continue;
        if (door_ops[i]->start(cfg, svc, &dm, &d, where, sizeof where, msg,
                               msgsize) != 0) {
            doors_stop();
            return -1;
        }
        pthread_mutex_lock(&doors_mu);
        doors[i] = d;
        pthread_mutex_unlock(&doors_mu);
        if (i == 0)
            snprintf(url, urlsize, "%s", where);
        printf("%s %s\n", said[i], where);
        fflush(stdout);
    }
    return 0;
}

/* The tick of the main thread: the doors' deadlines and hung-up clients,
 * the descriptors' health, the TTL sweep once a second, and malloc's free
 * pages back to the system every 5 s (a burst of calls or connections,
 * each thread of gRPC's allocating in its own arena, otherwise stays in
 * RSS after it ends). */
static void tick(const srv_config *cfg, svc_t *svc, unsigned ticks)
{
    size_t i;

    for (i = 0; i < NDOORS; i++)
        if (doors[i])
            door_ops[i]->expire(doors[i], cfg);
    srv_fds_watch(srv_mono());
    if (ticks % 4 == 0)
        svc_sweep(svc);
    if (ticks % 20 == 0)
        malloc_trim(0);
}

/* SIGTERM: readiness 503 and no new jobs through every door, running jobs
 * finish (or are checkpointed back to queued after --drain-timeout),
 * answers in flight are delivered, then every waiter is woken. */
static void drain(const srv_config *cfg, svc_t *svc)
{
    size_t i;

    svc_drain(svc);
    for (i = 0; i < NDOORS; i++)
        door_ops[i]->drain(doors[i]);
    if (!svc_wait_idle(svc, cfg->drain_timeout)) {
        srv_logf(SRV_LOG_WARN, "drain timeout: checkpointing running jobs; "
                 "they run again after the restart");
        svc_checkpoint_running(svc);
        svc_wait_idle(svc, 60);
    }
    /* Let finished waiters and streams deliver, then wake whoever is left. */
    wait_requests(5);
    svc_close_waiters(svc);
    wait_requests(2);
}

int main(int argc, char **argv)
{
    srv_config cfg;
    svc_t *svc = NULL;
    char msg[512], url[300];
    sigset_t sigs;
    int rc, sig;
    unsigned ticks;
    double t_sigterm;

    /* The hidden decode mode of the Draco sandbox (sandbox.c): a child
     * this daemon started, before anything else. */
    if (argc > 1 && strcmp(argv[1], SANDBOX_ARG) == 0)
        return sandbox_child(argc, argv);
    {
        /* the heap on huge pages (prog_heap.c): a big job's arrays, mapped
         * anew in its worker's arena, fault 2 MiB at a time */
        int huge = prog_heap_huge_pages();
        prog_bound_blas_threads(argv);
        if (huge)
            prog_reexec(argv);
    }
    rc = srv_config_load(&cfg, argc, argv, msg, sizeof msg);
    if (rc > 0)
        return 0;
    if (rc < 0) {
        fprintf(stderr, "mcfd: %s\n", msg);
        return 2;
    }
    if (cfg.probe)
        return probe(&cfg);
    srv_log_set_level(cfg.log_level);
    srv_fds_fit(&cfg);
    /* Buffers of 256 KiB and more (uploads, results, meshes) are mapped on
     * their own: freed, they go back to the system; grown, they are
     * remapped, not copied. glibc's default threshold rises after the
     * first large free (to 32 MiB), after which an upload's buffer grew in
     * the heap by copying, the old and new copies both resident. */
    mallopt(M_MMAP_THRESHOLD, 256 * 1024);

    signal(SIGPIPE, SIG_IGN);
    sigemptyset(&sigs);
    sigaddset(&sigs, SIGTERM);
    sigaddset(&sigs, SIGINT);
    pthread_sigmask(SIG_BLOCK, &sigs, NULL);

    srv_metrics_init();
    if (svc_start(&cfg.svc, &svc, msg, sizeof msg) != 0 ||
        doors_start(&cfg, svc, url, sizeof url, msg, sizeof msg) != 0) {
        fprintf(stderr, "mcfd: %s\n", msg);
        svc_stop(svc);
        return 1;
    }
    log_start(&cfg, url);

    /* Four ticks a second: clients that hung up free their worker within
     * about 0.25 s plus the current step. */
    for (ticks = 0;; ticks++) {
        struct timespec t = {0, 250 * 1000 * 1000};
        sig = sigtimedwait(&sigs, NULL, &t);
        if (sig == SIGTERM || sig == SIGINT)
            break;
        tick(&cfg, svc, ticks);
    }

    t_sigterm = srv_mono();
    srv_logf(SRV_LOG_INFO, "%s: draining (readyz 503, no new jobs, running "
             "jobs finish within %g s)", sig == SIGTERM ? "SIGTERM" : "SIGINT",
             cfg.drain_timeout);
    drain(&cfg, svc);
    /* the doors before the job service: their calls hold jobs and
     * subscriptions */
    doors_stop();
    svc_stop(svc);
    srv_logf(SRV_LOG_INFO, "stopped after %.3f s of drain", srv_mono() - t_sigterm);
    return 0;
}
