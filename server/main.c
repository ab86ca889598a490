/*
 * main.c - mcfd's process: configuration, threads, the HTTP daemon, the
 * signal loop, graceful drain and exit; and `mcfd --probe`.
 *
 * Start-up order matters:
 *  1. BLAS threads are bounded to one per worker before the library
 *     starts its pool. OpenBLAS reads its variables in a constructor that
 *     runs before main(), so when the variables are not set yet, main sets
 *     them and re-executes itself once (same PID, same argv). An operator
 *     who sets them keeps their values.
 *  2. SIGTERM/SIGINT are blocked in every thread (the mask is inherited)
 *     and taken synchronously by this thread with sigtimedwait, which also
 *     gives the tick for the TTL sweep and the check for clients that
 *     hung up (srv_http_check_clients). SIGPIPE is ignored.
 *  3. The spool is recovered and the workers start before the socket
 *     opens, so the first request already sees recovered jobs.
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
 * then MHD stops and the process exits 0.
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
#include <time.h>
#include <unistd.h>

#include "grpc_door.h"
#include "http.h"
#include "service.h"
#include "srv.h"
#include "sandbox.h"

static void mhd_log(void *cls, const char *fmt, va_list ap)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 0)))
#endif
    ;
/* libmicrohttpd's messages, at a bounded rate: at EMFILE it retries
 * accept() in a loop and says so every time (447 MB of log in 14 s). */
static void mhd_log(void *cls, const char *fmt, va_list ap)
{
    static srv_log_limit lim;
    char msg[512];
    size_t n;

    (void)cls;
    vsnprintf(msg, sizeof msg, fmt, ap);
    n = strlen(msg);
    while (n > 0 && (msg[n - 1] == '\n' || msg[n - 1] == '\r'))
        msg[--n] = '\0';
    srv_logf_limited(&lim, SRV_LOG_WARN, "libmicrohttpd: %s", msg);
}

/* A REST connection is refused (closed at once) when it would take the
 * last half of the descriptors' reserve (fds.c). */
static enum MHD_Result mhd_accept(void *cls, const struct sockaddr *addr,
                                  socklen_t addrlen)
{
    static srv_log_limit lim;
    const srv_config *cfg = cls;
    (void)addr;
    (void)addrlen;
    if (srv_fds_headroom() > cfg->fd_reserve / 2)
        return MHD_YES;
    srv_logf_limited(&lim, SRV_LOG_WARN, "REST connection refused: the daemon is "
                     "out of descriptors for connections");
    return MHD_NO;
}

/* /healthz and /readyz: both doors must be able to take a connection (a
 * door that accepts nothing makes the daemon unhealthy, so that an
 * orchestrator restarts it). REST's own is the answer itself. */
static int doors_health(char *why, size_t size)
{
    if (srv_fds_health(why, size) != 0)
        return -1;
    return srv_grpc_health(why, size);
}

/* The job service's part of the daemon's configuration. */
static void service_config(const srv_config *cfg, svc_config *out)
{
    memset(out, 0, sizeof *out);
    out->workers = cfg->workers;
    out->queue = cfg->queue;
    snprintf(out->spool, sizeof out->spool, "%s", cfg->spool);
    out->spool_max_jobs = cfg->spool_max_jobs;
    out->spool_max_bytes = cfg->spool_max_bytes;
    out->lim = cfg->lim;
    out->result_ttl = cfg->result_ttl;
    out->job_timeout = cfg->job_timeout;
    out->max_memory = cfg->max_memory;
    out->max_job_memory = cfg->max_job_memory;
    out->decode_cpu = cfg->decode_cpu;
    out->decode_memory = cfg->decode_memory;
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

/* Resolves the bind address (numeric or a host name) for MHD. */
static int resolve_bind(const srv_config *cfg, struct sockaddr_storage *ss,
                        int *ipv6, char *msg, size_t msgsize)
{
    struct addrinfo hints, *res = NULL;
    char port[16];
    int rc;

    memset(&hints, 0, sizeof hints);
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_PASSIVE;
    snprintf(port, sizeof port, "%d", cfg->port);
    rc = getaddrinfo(cfg->bind, port, &hints, &res);
    if (rc != 0 || !res) {
        snprintf(msg, msgsize, "--bind %s: %s", cfg->bind, gai_strerror(rc));
        return -1;
    }
    memset(ss, 0, sizeof *ss);
    memcpy(ss, res->ai_addr, res->ai_addrlen);
    *ipv6 = res->ai_family == AF_INET6;
    freeaddrinfo(res);
    return 0;
}

static void log_start(const srv_config *cfg, const char *url)
{
    cJSON *o = cJSON_CreateObject();
    if (!o)
        return;
    cJSON_AddStringToObject(o, "msg", "mcfd started");
    cJSON_AddStringToObject(o, "url", url);
    cJSON_AddNumberToObject(o, "workers", cfg->workers);
    cJSON_AddNumberToObject(o, "queue", cfg->queue);
    cJSON_AddNumberToObject(o, "http_threads", cfg->http_threads);
    cJSON_AddStringToObject(o, "spool", cfg->spool);
    cJSON_AddNumberToObject(o, "max_upload", (double)cfg->lim.max_input_bytes);
    cJSON_AddNumberToObject(o, "max_memory", (double)cfg->max_memory);
    cJSON_AddNumberToObject(o, "result_ttl_s", cfg->result_ttl);
    cJSON_AddBoolToObject(o, "auth", cfg->token_len > 0);
    cJSON_AddNumberToObject(o, "pid", getpid());
    srv_log_json(SRV_LOG_INFO, o);
}

/* MHD's per-connection pool: the request line, every header and MHD's
 * own records. MHD's default of 32 KiB overflowed on a few hundred
 * headers (431); the query no longer counts (http.c keeps it). */
#define SRV_CONN_MEMORY (64 * 1024)

/* Waits (polling, bounded) until no request or gRPC call is in flight. */
static void wait_requests(double seconds)
{
    double end = srv_mono() + seconds;
    struct timespec ts = {0, 20 * 1000 * 1000};

    while (srv_http_active() + srv_grpc_active() > 0 && srv_mono() < end)
        nanosleep(&ts, NULL);
}

int main(int argc, char **argv)
{
    srv_config cfg;
    svc_config scfg;
    char msg[512], url[300];
    struct sockaddr_storage ss;
    struct MHD_Daemon *d = NULL;
    const union MHD_DaemonInfo *info;
    sigset_t sigs;
    int rc, ipv6 = 0, sig;
    unsigned port;
    double t_sigterm;

    /* The hidden decode mode of the Draco sandbox (sandbox.c): a child
     * this daemon started, before anything else. */
    if (argc > 1 && strcmp(argv[1], SRV_SANDBOX_ARG) == 0)
        return srv_sandbox_child(argc, argv);
    api_bound_library_threads(argv, 1);
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

    if (srv_spool_init(cfg.spool, msg, sizeof msg) != 0 ||
        resolve_bind(&cfg, &ss, &ipv6, msg, sizeof msg) != 0) {
        fprintf(stderr, "mcfd: %s\n", msg);
        return 1;
    }
    srv_metrics_init();
    srv_http_init(&cfg, doors_health, srv_grpc_gauges);
    service_config(&cfg, &scfg);
    if (svc_start(&scfg, msg, sizeof msg) != 0) {
        fprintf(stderr, "mcfd: %s\n", msg);
        return 1;
    }
    d = MHD_start_daemon(
        MHD_USE_AUTO_INTERNAL_THREAD | MHD_ALLOW_SUSPEND_RESUME |
            MHD_USE_ERROR_LOG | (ipv6 ? MHD_USE_IPv6 : 0),
        (uint16_t)cfg.port, mhd_accept, &cfg, srv_http_handle, NULL,
        MHD_OPTION_EXTERNAL_LOGGER, mhd_log, NULL,
        MHD_OPTION_SOCK_ADDR, (struct sockaddr *)&ss,
        MHD_OPTION_THREAD_POOL_SIZE, (unsigned int)cfg.http_threads,
        MHD_OPTION_CONNECTION_LIMIT, (unsigned int)cfg.max_connections,
        MHD_OPTION_PER_IP_CONNECTION_LIMIT, srv_http_ip_backstop(&cfg),
        MHD_OPTION_CONNECTION_TIMEOUT, (unsigned int)cfg.send_timeout,
        MHD_OPTION_URI_LOG_CALLBACK, srv_http_uri_log, NULL,
        MHD_OPTION_NOTIFY_COMPLETED, srv_http_completed, NULL,
        MHD_OPTION_NOTIFY_CONNECTION, srv_http_connection, NULL,
        MHD_OPTION_CONNECTION_MEMORY_LIMIT, (size_t)SRV_CONN_MEMORY,
        MHD_OPTION_END);
    if (!d) {
        fprintf(stderr, "mcfd: cannot listen on %s:%d (%s)\n", cfg.bind,
                cfg.port, strerror(errno));
        svc_stop();
        return 1;
    }
    info = MHD_get_daemon_info(d, MHD_DAEMON_INFO_BIND_PORT);
    port = info ? info->port : (unsigned)cfg.port;
    snprintf(url, sizeof url, ipv6 ? "http://[%s]:%u" : "http://%s:%u",
             cfg.bind, port);
    printf("mcfd listening on %s\n", url);
    fflush(stdout);
    if (cfg.grpc_port >= 0) {
        int gport = 0;
        if (srv_grpc_start(&cfg, &gport, msg, sizeof msg) != 0) {
            fprintf(stderr, "mcfd: %s\n", msg);
            MHD_stop_daemon(d);
            svc_stop();
            return 1;
        }
        printf(ipv6 ? "mcfd grpc listening on [%s]:%d\n"
                    : "mcfd grpc listening on %s:%d\n", cfg.bind, gport);
        fflush(stdout);
    }
    log_start(&cfg, url);

    for (unsigned ticks = 0;; ticks++) {
        /* Four ticks a second: clients that hung up free their worker
         * within about 0.25 s plus the current step; the TTL sweep runs
         * once a second. */
        struct timespec tick = {0, 250 * 1000 * 1000};
        sig = sigtimedwait(&sigs, NULL, &tick);
        if (sig == SIGTERM || sig == SIGINT)
            break;
        srv_http_check_clients();
        srv_fds_watch(srv_mono());
        {
            int n = srv_http_expire_heads(cfg.header_timeout,
                                          cfg.max_connections,
                                          cfg.body_timeout);
            if (n > 0)
                srv_logf(SRV_LOG_WARN, "closed %d connection%s that sent no "
                         "complete request head within --header-timeout %g s "
                         "(2 s past --max-connections-per-ip) or no complete "
                         "body within --body-timeout %g s",
                         n, n == 1 ? "" : "s", cfg.header_timeout,
                         cfg.body_timeout);
        }
        if (cfg.grpc_port >= 0) {
            int n = srv_grpc_expire(cfg.header_timeout, cfg.body_timeout,
                                    cfg.send_timeout);
            if (n > 0)
                srv_logf(SRV_LOG_WARN, "ended %d gRPC call%s that sent no "
                         "header within --header-timeout %g s, no whole "
                         "upload within --body-timeout %g s, or read nothing "
                         "for --send-timeout %g s", n, n == 1 ? "" : "s",
                         cfg.header_timeout, cfg.body_timeout,
                         cfg.send_timeout);
        }
        if (ticks % 4 == 0)
            svc_sweep();
        /* Every 5 s, malloc's free pages go back to the system: a burst
         * of calls or connections (each thread of gRPC's allocates in its
         * own arena) otherwise stays in RSS after it ends. */
        if (ticks % 20 == 0)
            malloc_trim(0);
    }

    t_sigterm = srv_mono();
    srv_logf(SRV_LOG_INFO, "%s: draining (readyz 503, no new jobs, running "
             "jobs finish within %g s)", sig == SIGTERM ? "SIGTERM" : "SIGINT",
             cfg.drain_timeout);
    svc_drain();
    srv_grpc_drain();
    if (!svc_wait_idle(cfg.drain_timeout)) {
        srv_logf(SRV_LOG_WARN, "drain timeout: checkpointing running jobs; "
                 "they run again after the restart");
        svc_checkpoint_running();
        svc_wait_idle(60);
    }
    /* Let finished waiters and streams deliver, then wake whoever is left. */
    wait_requests(5);
    svc_close_waiters();
    wait_requests(2);
    /* gRPC before the job service: its calls hold jobs and subscriptions */
    srv_grpc_stop();
    MHD_stop_daemon(d);
    svc_stop();
    srv_logf(SRV_LOG_INFO, "stopped after %.3f s of drain", srv_mono() - t_sigterm);
    return 0;
}
