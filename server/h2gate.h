/*
 * h2gate.h - the gRPC door's socket (h2gate.c): the daemon listens,
 * accepts and admits HTTP/2 connections itself, and relays each admitted
 * one to the HTTP/2 server (gRPC) through a socketpair, reading the
 * client's frames on the way. Plain C; nothing here knows gRPC: the server
 * is a function that adopts the inner end of each socketpair.
 *
 * What it bounds, beyond what gRPC 1.51 can (h2gate.c says why each):
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

#ifdef __cplusplus
}
#endif

#endif /* SRV_H2GATE_H */
