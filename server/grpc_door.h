/*
 * grpc_door.h - the gRPC door of mcfd (server/grpc.cc, the only C++ in
 * server/): api/mcfd.proto's mcfd.v1.Smoother served on --grpc-port with
 * gRPC's C++ callback API, beside the REST door, on the same job service
 * (service.h). Plain C; no gRPC type crosses it.
 *
 * Life: srv_grpc_start after svc_start (the door reads and submits jobs
 * from its first call), srv_grpc_drain with svc_drain (health turns
 * NOT_SERVING; new Smooth and SubmitJob calls get UNAVAILABLE; reads and
 * streams already open go on), srv_grpc_stop before svc_stop (every call
 * is ended and every job reference and subscription released).
 */
#ifndef SRV_GRPC_DOOR_H
#define SRV_GRPC_DOOR_H

#include "srv.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Listens on cfg->bind:cfg->grpc_port (0: a free port) and serves: the
 * gate (h2gate.c) accepts and admits connections (cfg->grpc_max_connections,
 * cfg->max_connections_per_ip, cfg->fd_reserve) and relays them to gRPC.
 * 0 and *port the port it listens on, or -1 with a one-line reason in msg. */
int srv_grpc_start(const srv_config *cfg, int *port, char *msg,
                   size_t msgsize);
/* Health NOT_SERVING ("" and "mcfd.v1.Smoother"); new jobs refused with
 * UNAVAILABLE. Accepts a door that never started. */
void srv_grpc_drain(void);
/* Ends every call (those still open after 2 s are cancelled), stops the
 * server and its thread. Accepts a door that never started. */
void srv_grpc_stop(void);
/* Ends with DEADLINE_EXCEEDED (ETIMEOUT) the Smooth and SubmitJob calls
 * whose header has not come within header_timeout seconds of the call's
 * start, or whose whole upload has not come within body_timeout: REST's
 * --header-timeout and --body-timeout, so a stalled or trickling client
 * cannot hold a slot and its buffer. Cancels the Smooth and WatchJob calls
 * whose client has let one message go unread for send_timeout seconds
 * (flow control holds the write): REST's connection timeout, so a client
 * that never reads cannot hold its result in memory. 0: no such limit.
 * Called from the main thread's tick. Returns how many calls it ended. */
int srv_grpc_expire(double header_timeout, double body_timeout,
                    double send_timeout);
/* Calls open now (a gauge for /metrics and the drain). */
int srv_grpc_active(void);
/* 0 when the door accepts connections and gRPC answers them (always, for
 * a door that is off); else -1 and why (h2gate_health). */
int srv_grpc_health(char *why, size_t size);
/* The gate's connections, streams and refusals, into g (its grpc_ fields). */
void srv_grpc_gauges(srv_gauges *g);

#ifdef __cplusplus
}
#endif

#endif /* SRV_GRPC_DOOR_H */
