/* SPDX-License-Identifier: MIT */
/*
 * rest_door.c - the REST door's face (rest_door.h, door.h): its state
 * made and freed, libmicrohttpd started on the bound address with the
 * door's callbacks (http.c) and caps, the tick's deadlines, the drain, the
 * gauges. What a request does is the other files of rest_internal.h's.
 */
#include <errno.h>
#include <netdb.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <arpa/inet.h>
#include <netinet/in.h>

#include "http.h"
#include "rest_door.h"

/* MHD's per-connection pool: the request line, every header and MHD's
 * own records. MHD's default of 32 KiB overflowed on a few hundred
 * headers (431); the query no longer counts (http.c keeps it). */
#define SRV_CONN_MEMORY (64 * 1024)

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
    const rest_t *d = cls;
    (void)addr;
    (void)addrlen;
    if (srv_fds_headroom() > d->cfg->fd_reserve / 2)
        return MHD_YES;
    srv_logf_limited(&lim, SRV_LOG_WARN, "REST connection refused: the daemon is "
                     "out of descriptors for connections");
    return MHD_NO;
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

static void door_free(rest_t *d)
{
    pthread_mutex_destroy(&d->active_mu);
    pthread_mutex_destroy(&d->conns_mu);
    pthread_mutex_destroy(&d->wait_mu);
    free(d);
}

static int rest_start(const srv_config *cfg, svc_t *svc, const srv_daemon *dm,
                      void **door, char *where, size_t wsize, char *msg,
                      size_t msgsize)
{
    struct sockaddr_storage ss;
    const union MHD_DaemonInfo *info;
    rest_t *d;
    int ipv6 = 0;

    *door = NULL;
    if (resolve_bind(cfg, &ss, &ipv6, msg, msgsize) != 0)
        return -1;
    if (!(d = calloc(1, sizeof *d))) {
        snprintf(msg, msgsize, "out of memory");
        return -1;
    }
    d->cfg = cfg;
    d->svc = svc;
    if (dm)
        d->dm = *dm;
    pthread_mutex_init(&d->active_mu, NULL);
    pthread_mutex_init(&d->conns_mu, NULL);
    pthread_mutex_init(&d->wait_mu, NULL);
    d->mhd = MHD_start_daemon(
        MHD_USE_AUTO_INTERNAL_THREAD | MHD_ALLOW_SUSPEND_RESUME |
            MHD_USE_ERROR_LOG | (ipv6 ? MHD_USE_IPv6 : 0),
        (uint16_t)cfg->port, mhd_accept, d, rest_http_handle, d,
        MHD_OPTION_EXTERNAL_LOGGER, mhd_log, NULL,
        MHD_OPTION_SOCK_ADDR, (struct sockaddr *)&ss,
        MHD_OPTION_THREAD_POOL_SIZE, (unsigned int)cfg->http_threads,
        MHD_OPTION_CONNECTION_LIMIT, (unsigned int)cfg->max_connections,
        MHD_OPTION_PER_IP_CONNECTION_LIMIT, rest_http_ip_backstop(cfg),
        MHD_OPTION_CONNECTION_TIMEOUT, (unsigned int)cfg->send_timeout,
        MHD_OPTION_URI_LOG_CALLBACK, rest_http_uri_log, d,
        MHD_OPTION_NOTIFY_COMPLETED, rest_http_completed, d,
        MHD_OPTION_NOTIFY_CONNECTION, rest_http_connection, d,
        MHD_OPTION_CONNECTION_MEMORY_LIMIT, (size_t)SRV_CONN_MEMORY,
        MHD_OPTION_END);
    if (!d->mhd) {
        snprintf(msg, msgsize, "cannot listen on %s:%d (%s)", cfg->bind,
                 cfg->port, strerror(errno));
        door_free(d);
        return -1;
    }
    info = MHD_get_daemon_info(d->mhd, MHD_DAEMON_INFO_BIND_PORT);
    snprintf(where, wsize, ipv6 ? "http://[%s]:%u" : "http://%s:%u", cfg->bind,
             info ? info->port : (unsigned)cfg->port);
    *door = d;
    return 0;
}

static void rest_drain(void *door)
{
    rest_t *d = door;
    if (d)
        atomic_store(&d->draining, 1);
}

static void rest_stop(void *door)
{
    rest_t *d = door;
    if (!d)
        return;
    MHD_stop_daemon(d->mhd);
    door_free(d);
}

static int rest_expire(void *door, const srv_config *cfg)
{
    rest_t *d = door;
    int n = 0;

    rest_http_check_clients(d);
    n = rest_http_expire_heads(d, cfg->header_timeout, cfg->max_connections,
                               cfg->body_timeout);
    if (n > 0)
        srv_logf(SRV_LOG_WARN, "closed %d connection%s that sent no complete "
                 "request head within --header-timeout %g s (2 s past "
                 "--max-connections-per-ip) or no complete body within "
                 "--body-timeout %g s", n, n == 1 ? "" : "s",
                 cfg->header_timeout, cfg->body_timeout);
    return n;
}

static int rest_active(void *door)
{
    rest_t *d = door;
    int n;

    if (!d)
        return 0;
    pthread_mutex_lock(&d->active_mu);
    n = d->active;
    pthread_mutex_unlock(&d->active_mu);
    return n;
}

/* REST's own health is the answer itself. */
static int rest_health(void *door, char *why, size_t size)
{
    (void)door;
    (void)why;
    (void)size;
    return 0;
}

static void rest_gauges(void *door, srv_gauges *g)
{
    if (door)
        g->followers = rest_waiter_followers(door);
}

const srv_door_ops rest_door = {
    "REST", rest_start, rest_drain, rest_stop, rest_expire, rest_active,
    rest_health, rest_gauges,
};
