/* SPDX-License-Identifier: MIT */
/*
 * h2gate.h - the gRPC door's socket: the daemon listens, accepts and
 * admits HTTP/2 connections itself, and relays each admitted one to the
 * HTTP/2 server (gRPC) through a socketpair, reading the client's frames
 * on the way. Plain C; nothing here knows gRPC: the server is a function
 * that adopts the inner end of each socketpair.
 *
 * Three files, one concern each:
 *  - h2gate.c: the door (the functions below up to h2gate_get_stats): its
 *    thread, epoll loop, listening socket and the relay's sockets;
 *  - h2gate_limits.c: the accounting of addresses, connections and
 *    streams against the bounds ("The limits" below);
 *  - h2gate_parser.c: one connection's frame parser ("The parser").
 * The last two are pure (no sockets, threads, clock or globals: time
 * comes in as `now`, seconds on a monotonic clock), so that
 * tests/fuzz/fuzz_h2gate.c drives them exactly as the door does.
 *
 * What it bounds, beyond what gRPC 1.51 can (why each: below):
 *  - connections, in all and per client address, and the descriptors
 *    they take (a reserve is never touched); accept errors never stop the
 *    door and are logged at a bounded rate;
 *  - the client preface, each header block (bytes, frames, time), each
 *    stream's first message (time): the connection or stream is closed;
 *  - the streams gRPC holds: per connection (the advertised
 *    MAX_CONCURRENT_STREAMS, enforced even when the client never
 *    acknowledges it), per address and in all, plus the streams the
 *    client reset before gRPC answered them (gRPC disposes of those later,
 *    at its own pace): a client past a bound waits (its bytes are not
 *    read), it is not refused.
 *
 * Why not gRPC's own listener with its options. In gRPC 1.51:
 *  - the listener gives up for good on any accept error but EAGAIN, EINTR
 *    and ECONNABORTED (tcp_server_posix.cc, on_read: `goto error`), so one
 *    EMFILE and the door never accepts again (CVE-2023-4785); a door that
 *    owns its socket retries, and logs at a bounded rate;
 *  - nothing caps connections, in all or per address:
 *    GRPC_ARG_MAX_CONNECTION_IDLE_MS (set too, grpc.cc) closes a connection
 *    without calls after a while, but a flood inside that while still takes
 *    every descriptor; the resource quota's "memory pressure" drops new
 *    connections only in that listener;
 *  - the HPACK parser copies the unparsed part of a header block again for
 *    every piece of it that arrives (hpack_parser.cc, HPackParser::Parse)
 *    and checks GRPC_ARG_MAX_METADATA_SIZE only when a field is complete:
 *    a block in many pieces costs quadratic CPU before any limit
 *    (CVE-2023-33953). Here a header block is held until it is whole and
 *    within max_header_block bytes and max_header_frames frames, then
 *    passed on at once;
 *  - MAX_CONCURRENT_STREAMS is enforced only once the client has
 *    acknowledged the setting (parsing.cc: ACKED settings), and a stream a
 *    client resets before the server answers it leaves work queued inside
 *    gRPC that no limit counts (the rapid reset class, CVE-2023-44487):
 *    40,000 HEADERS + RST_STREAM took 1.4 GiB. Here new streams wait while
 *    the connection, its address or the daemon is at its bound, a reset
 *    stream counting until gRPC could have disposed of it;
 *  - a unary call whose message never comes is held by gRPC before any
 *    handler sees it: here a stream must send its first whole message (or
 *    end its side) within message_timeout, else it is reset both ways.
 * The resource quota (grpc.cc) stays as gRPC's own backstop behind this.
 */
#ifndef SRV_H2GATE_H
#define SRV_H2GATE_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

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

typedef struct {
    int conns;                 /* connections open (relayed or in preface) */
    int streams;               /* streams open in the server */
    int waiting;               /* connections waiting for stream room */
    unsigned long refused, closed; /* refused: caps or reserve; closed: by
                                  a bound (preface, header block,
                                  protocol) */
    unsigned long streams_reset; /* silent streams reset by the gate */
    unsigned long accept_errors;
} h2gate_stats;

/* Listens and starts the gate's thread. 0 and *port the port, or -1 with
 * a one-line reason in msg. cfg is copied; bind must outlive the gate. */
int h2gate_start(const h2gate_config *cfg, int *port, char *msg,
                 size_t msgsize);
/* Stops accepting (closes the listening socket); relayed connections go on. */
void h2gate_stop_accepting(void);
/* Closes every connection and stops the thread. Accepts a gate that never
 * started. */
void h2gate_stop(void);
/* The client address ("127.0.0.1", "::1") of the connection whose inner
 * end the server knows as descriptor inner_fd: 0, or -1 when none. */
int h2gate_peer(int inner_fd, char *addr, size_t size);
/* 0 when the door accepts and the server answers new connections; else -1
 * and why: the gate's thread stalled, accept has failed for a while (the
 * descriptors are gone), or the server sent no preface on a connection
 * handed to it, for unhealthy_after seconds. */
int h2gate_health(char *why, size_t size);
void h2gate_get_stats(h2gate_stats *out);

/* --------------------------------------------------- The listening socket */

/* A non-blocking TCP socket listening on bind_addr:port (h2gate_listen.c):
 * its descriptor, and *bound_port the port it got; or -1 with a one-line
 * reason in msg. */
int h2gate_listen(const char *bind_addr, int port, int *bound_port, char *msg, size_t msgsize);

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

/* ------------------------------------------------------------ The parser
 * One per connection, fed the bytes of either way as they arrive, in
 * chunks of any size; it answers what to do with a verdict and queues
 * the bytes to write on. Not thread-safe. Way H2GATE_UP: the client's
 * bytes in, the server's to write out; H2GATE_DOWN: the server's in, the
 * client's out. What it writes is what it read, whole frames in the same
 * order (the client preface first, up), plus RST_STREAM frames of its own
 * (h2gate_parser_reset_silent) between frames and outside header blocks;
 * bytes of a header block become writable only once the block is whole. */
typedef struct h2gate_parser h2gate_parser;
enum { H2GATE_UP = 0, H2GATE_DOWN = 1 };
typedef enum {
    H2GATE_MORE,   /* parsed what there is: read on */
    H2GATE_ADOPT,  /* (up, once) the client preface is whole and queued for
                      the server: hand the connection to it, parse again */
    H2GATE_WAIT,   /* (up) a new stream past a bound: the rest stays
                      unparsed; read no more from the client and parse
                      again when a stream ends or time passes */
    H2GATE_NOT_H2, /* (up) no client preface: close without a word */
    H2GATE_CLOSE   /* a bound, the protocol (up) or out of memory: close
                      with a GOAWAY saying *why (a static string) */
} h2gate_verdict;

/* NULL when out of memory. Its streams count against lim and a, which
 * must outlive it; now: when the connection opened. */
h2gate_parser *h2gate_parser_create(h2gate_limits *lim, h2gate_addr *a, double now);
/* Frees p (NULL is fine); call h2gate_parser_end first. */
void h2gate_parser_free(h2gate_parser *p);
/* The connection closes: its streams leave the count. */
void h2gate_parser_end(h2gate_parser *p, double now);
/* Input: room for n bytes of way's input (NULL when out of memory), then
 * how many were written there; or both at once from bytes (-1: memory). */
void *h2gate_parser_in(h2gate_parser *p, int way, size_t n);
void h2gate_parser_in_add(h2gate_parser *p, int way, size_t n);
int h2gate_parser_feed(h2gate_parser *p, int way, const void *bytes, size_t n);
/* Parses way's input as far as it may; *why is set for H2GATE_CLOSE. */
h2gate_verdict h2gate_parser_parse(h2gate_parser *p, int way, double now, const char **why);
/* Output: the bytes that may be written now (*n of them), then how many
 * were; and all queued, writable or held (to stop reading past a mark). */
const void *h2gate_parser_out(const h2gate_parser *p, int way, size_t *n);
void h2gate_parser_out_drop(h2gate_parser *p, int way, size_t n);
size_t h2gate_parser_out_size(const h2gate_parser *p, int way);
/* Streams open now; streams opened in all. */
int h2gate_parser_streams(const h2gate_parser *p);
unsigned long h2gate_parser_opened(const h2gate_parser *p);
/* Why the connection is out of time at now (a static string: its client
 * preface, or the header block it is inside, not whole within timeout
 * seconds), or NULL. */
const char *h2gate_parser_late(const h2gate_parser *p, double now, double timeout);
/* Resets, both ways, the streams that sent no whole first message (nor
 * ended their side) within timeout seconds: how many, or -1 when out of
 * memory (close the connection). */
int h2gate_parser_reset_silent(h2gate_parser *p, double now, double timeout);
/* A GOAWAY (ENHANCE_YOUR_CALM, text truncated to fit) for the client in
 * buf: its length, or 0 when the server's bytes are mid-frame or queued
 * (the client's stream of frames must stay whole: then close without). */
size_t h2gate_parser_goaway(const h2gate_parser *p, const char *text, unsigned char *buf,
                            size_t size);
/* A refused connection's answer, SETTINGS then GOAWAY (ENHANCE_YOUR_CALM,
 * text): its length in buf (0 when size < 26). */
size_t h2gate_refusal(const char *text, unsigned char *buf, size_t size);

#ifdef __cplusplus
}
#endif

#endif /* SRV_H2GATE_H */
