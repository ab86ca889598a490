/* SPDX-License-Identifier: MIT */
/*
 * h2gate_limits.h - the gRPC door's gate (h2gate.h): its bounds
 * (h2gate_config, given to h2gate_start) and the accounting of client
 * addresses, connections and streams against them (h2gate_limits.c).
 * Pure: no sockets, threads, clock or globals (time comes in as `now`).
 * A leaf: it calls no other file of the gate.
 */
#ifndef SRV_H2GATE_LIMITS_H
#define SRV_H2GATE_LIMITS_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* The gate's configuration (h2gate_start copies it): where it listens,
 * its bounds, and the server it hands connections to. */
typedef struct {
    const char *bind;          /* numeric address or host name */
    int port;                  /* 0: a free one */
    int max_conns;             /* connections open at once, 0: no limit */
    int max_conns_per_ip;      /* from one address, 0: no limit */
    int fd_reserve;            /* descriptors kept free for the rest of
                                  the daemon: a connection is refused when
                                  the lowest free one is within this of
                                  RLIMIT_NOFILE */
    int streams_per_conn;      /* the server's MAX_CONCURRENT_STREAMS */
    int max_streams;           /* streams in the server at once, in all */
    int max_streams_per_ip;    /* ... from one address */
    double resets_per_s;       /* the pace the server is assumed to dispose
                                  of client-reset streams at */
    size_t max_header_block;   /* payload bytes of one header block */
    int max_header_frames;     /* its frames (HEADERS + CONTINUATION) */
    double header_timeout;     /* seconds for the preface and for each
                                  header block (0: no limit) */
    double message_timeout;    /* seconds for each stream's first whole
                                  message or the end of its side (0: no
                                  limit) */
    double unhealthy_after;    /* seconds of accept failing, or of the
                                  server not sending its preface on a new
                                  connection, before h2gate_health fails */
    /* Takes the inner end of a new connection's socketpair (non-blocking,
     * close-on-exec): from then on it is the server's to close. Called on
     * the gate's thread. */
    void (*adopt)(int fd, void *arg);
    void *adopt_arg;
} h2gate_config;

/* ------------------------------------------------------------ The limits
 * One object per gate: its bounds (a copy of the config's) and what
 * counts against them. Not thread-safe: the gate's thread alone calls it. */
typedef struct h2gate_limits h2gate_limits;
typedef struct h2gate_addr h2gate_addr;   /* a client address */

/* NULL when out of memory. now: where the reset backlog starts. */
h2gate_limits *h2gate_limits_create(const h2gate_config *cfg, double now);
/* Frees l and every address (NULL is fine). */
void h2gate_limits_free(h2gate_limits *l);
const h2gate_config *h2gate_limits_config(const h2gate_limits *l);
/* A new connection from ip whose socket is fd, the lowest free descriptor,
 * under RLIMIT_NOFILE fd_limit, while nconns are open: its address with
 * the connection counted, or NULL and why in `why` (a sentence for the
 * client's GOAWAY and the log): the descriptor reserve, a connection cap,
 * or out of memory. */
h2gate_addr *h2gate_limits_admit(h2gate_limits *l, const char *ip, int fd, int fd_limit,
                                 int nconns, char *why, size_t size);
/* A connection counted by h2gate_limits_admit has closed (its streams
 * ended first: h2gate_parser_end); a may be freed. */
void h2gate_limits_release(h2gate_limits *l, h2gate_addr *a);
const char *h2gate_addr_ip(const h2gate_addr *a);
/* A socket address as the limits count it: "192.0.2.1" (also for an IPv4
 * client of an IPv6 socket), "2001:db8::1", or "local". */
struct sockaddr;
void h2gate_addr_format(const struct sockaddr *sa, char *ip, size_t size);
/* Streams open in the server, in all (without the reset backlog). */
int h2gate_limits_streams(const h2gate_limits *l);
/* Whether a stream has ended since it was last cleared (clear: clear it),
 * i.e. whether waiting connections may find room now. */
int h2gate_limits_freed(h2gate_limits *l, int clear);
/* For the parser: whether a connection holding conn_streams streams,
 * from a, may open one more now; one opened; one ended (client_reset:
 * by the client, before the server ended it: it joins the backlog). */
int h2gate_limits_stream_room(h2gate_limits *l, h2gate_addr *a, int conn_streams, double now);
void h2gate_limits_stream_opened(h2gate_limits *l, h2gate_addr *a);
void h2gate_limits_stream_closed(h2gate_limits *l, h2gate_addr *a, int client_reset,
                                 double now);

#ifdef __cplusplus
}
#endif

#endif /* SRV_H2GATE_LIMITS_H */
