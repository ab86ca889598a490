/* SPDX-License-Identifier: MIT */
/*
 * h2gate.h - the gRPC door's socket: the daemon listens, accepts and
 * admits HTTP/2 connections itself, and relays each admitted one to the
 * HTTP/2 server (gRPC) through a socketpair, reading the client's frames
 * on the way. Plain C; nothing here knows gRPC: the server is a function
 * that adopts the inner end of each socketpair.
 *
 * Four files, one concern each, calls going one way (h2gate.c calls the
 * others, the parser calls the limits, the limits nothing):
 *  - h2gate.c: the door (this header): its thread, epoll loop, listening
 *    socket and the relay's sockets;
 *  - h2gate_listen.c: the listening socket (h2gate_listen.h);
 *  - h2gate_limits.c: the gate's bounds (h2gate_config) and the
 *    accounting of addresses, connections and streams against them
 *    (h2gate_limits.h);
 *  - h2gate_parser.c: one connection's frame parser (h2gate_parser.h).
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

#include "h2gate_limits.h"  /* h2gate_config */

#ifdef __cplusplus
extern "C" {
#endif

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
