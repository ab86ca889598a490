/* SPDX-License-Identifier: MIT */
/*
 * h2gate_limits.c - the gate's accounting (h2gate_limits.h): the
 * client addresses with their connections and streams, which new
 * connection is refused and why, and whether one more stream fits in the
 * server, per connection (the advertised MAX_CONCURRENT_STREAMS, which
 * gRPC 1.51 enforces only once the client has acknowledged it), per
 * address and in all.
 *
 * A stream counts from its HEADERS until the server ends it (END_STREAM,
 * RST_STREAM), the gate resets it or the client resets it; in the last
 * case before the server ended it, it stays counted as "reset backlog"
 * that drains at resets_per_s, the pace gRPC is assumed to dispose of
 * such streams at (a stream reset at once leaves work queued inside gRPC
 * that no limit of its own counts: the rapid reset class, CVE-2023-44487).
 *
 * No sockets, threads, clock or globals; one object per gate.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <arpa/inet.h>
#include <netinet/in.h>

#include "h2gate_limits.h"


struct h2gate_addr {
    h2gate_addr *next;
    char ip[INET6_ADDRSTRLEN];
    int conns, streams;
    double z, z_at;            /* reset backlog (see the top) */
};

struct h2gate_limits {
    h2gate_config cfg;
    h2gate_addr *addrs;
    int streams;               /* in the server, in all */
    double z, z_at;            /* reset backlog, in all */
    int freed;                 /* a stream ended since h2gate_limits_freed cleared it */
};

h2gate_limits *h2gate_limits_create(const h2gate_config *cfg, double now)
{
    h2gate_limits *l = calloc(1, sizeof *l);
    if (l) {
        l->cfg = *cfg;
        l->z_at = now;
    }
    return l;
}

void h2gate_limits_free(h2gate_limits *l)
{
    if (!l)
        return;
    while (l->addrs) {
        h2gate_addr *a = l->addrs;
        l->addrs = a->next;
        free(a);
    }
    free(l);
}

const h2gate_config *h2gate_limits_config(const h2gate_limits *l) { return &l->cfg; }
const char *h2gate_addr_ip(const h2gate_addr *a) { return a->ip; }
int h2gate_limits_streams(const h2gate_limits *l) { return l->streams; }

int h2gate_limits_freed(h2gate_limits *l, int clear)
{
    int f = l->freed;
    if (clear)
        l->freed = 0;
    return f;
}

/* ------------------------------------------------------------- addresses */

void h2gate_addr_format(const struct sockaddr *sa, char *ip, size_t n)
{
    if (sa->sa_family == AF_INET6) {
        const struct sockaddr_in6 *s6 = (const struct sockaddr_in6 *)(const void *)sa;
        if (IN6_IS_ADDR_V4MAPPED(&s6->sin6_addr))
            inet_ntop(AF_INET, &s6->sin6_addr.s6_addr[12], ip, (socklen_t)n);
        else
            inet_ntop(AF_INET6, &s6->sin6_addr, ip, (socklen_t)n);
    } else if (sa->sa_family == AF_INET) {
        inet_ntop(AF_INET, &((const struct sockaddr_in *)(const void *)sa)->sin_addr, ip,
                  (socklen_t)n);
    } else {
        snprintf(ip, n, "local");
    }
}

static h2gate_addr *addr_find(h2gate_limits *l, const char *ip)
{
    h2gate_addr *a;
    for (a = l->addrs; a; a = a->next)
        if (strcmp(a->ip, ip) == 0)
            return a;
    return NULL;
}

/* Forgets a without connections or streams (its reset backlog with it). */
static void addr_put(h2gate_limits *l, h2gate_addr *a)
{
    h2gate_addr **pp;
    if (a->conns > 0 || a->streams > 0)
        return;
    for (pp = &l->addrs; *pp; pp = &(*pp)->next)
        if (*pp == a) {
            *pp = a->next;
            free(a);
            return;
        }
}

h2gate_addr *h2gate_limits_admit(h2gate_limits *l, const char *ip, int fd, int fd_limit,
                                 int nconns, char *why, size_t size)
{
    const h2gate_config *k = &l->cfg;
    h2gate_addr *a = addr_find(l, ip);
    /* the lowest free descriptor was fd: all below are taken, and the
     * relay takes two more */
    if (fd + 3 + k->fd_reserve > fd_limit) {
        snprintf(why, size, "the daemon is out of descriptors for connections "
                 "(RLIMIT_NOFILE %d, %d kept for its own files)", fd_limit, k->fd_reserve);
        return NULL;
    }
    if (k->max_conns > 0 && nconns >= k->max_conns) {
        snprintf(why, size, "%d gRPC connections are open, the most this daemon "
                 "keeps (--max-connections, fitted to its descriptors)", nconns);
        return NULL;
    }
    if (k->max_conns_per_ip > 0 && a && a->conns >= k->max_conns_per_ip) {
        snprintf(why, size, "%d gRPC connections are open from your address, the "
                 "most one address may hold (--max-connections-per-ip %d)", a->conns,
                 k->max_conns_per_ip);
        return NULL;
    }
    if (!a) {
        if (!(a = calloc(1, sizeof *a))) {
            snprintf(why, size, "out of memory");
            return NULL;
        }
        snprintf(a->ip, sizeof a->ip, "%s", ip);
        a->next = l->addrs;
        l->addrs = a;
    }
    a->conns++;
    return a;
}

void h2gate_limits_release(h2gate_limits *l, h2gate_addr *a)
{
    a->conns--;
    addr_put(l, a);
}

/* --------------------------------------------------------------- streams */

/* The reset backlog now: what was counted, less what the server disposed
 * of since at resets_per_s. */
static double backlog(const h2gate_limits *l, double *z, double *at, double now)
{
    double r = l->cfg.resets_per_s;
    if (*z > 0 && r > 0) {
        *z -= r * (now - *at);
        if (*z < 0)
            *z = 0;
    }
    *at = now;
    return *z;
}

int h2gate_limits_stream_room(h2gate_limits *l, h2gate_addr *a, int conn_streams, double now)
{
    const h2gate_config *k = &l->cfg;
    if (k->streams_per_conn > 0 && conn_streams >= k->streams_per_conn)
        return 0;
    if (k->max_streams_per_ip > 0 &&
        a->streams + backlog(l, &a->z, &a->z_at, now) >= k->max_streams_per_ip)
        return 0;
    if (k->max_streams > 0 && l->streams + backlog(l, &l->z, &l->z_at, now) >= k->max_streams)
        return 0;
    return 1;
}

void h2gate_limits_stream_opened(h2gate_limits *l, h2gate_addr *a)
{
    a->streams++;
    l->streams++;
}

void h2gate_limits_stream_closed(h2gate_limits *l, h2gate_addr *a, int client_reset,
                                 double now)
{
    if (client_reset) {
        backlog(l, &l->z, &l->z_at, now);
        backlog(l, &a->z, &a->z_at, now);
        l->z += 1;
        a->z += 1;
    }
    a->streams--;
    l->streams--;
    l->freed = 1;
}
