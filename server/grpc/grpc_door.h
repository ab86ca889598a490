/* SPDX-License-Identifier: MIT */
/*
 * grpc_door.h - the gRPC door of mcfd (server/grpc/grpc*.cc, the only C++ in
 * server/, sharing grpc_internal.h): api/mcfd.proto's mcfd.v1.Smoother served on --grpc-port with
 * gRPC's C++ callback API, beside the REST door, on the same job service.
 * Its face is door.h's, like the REST door's (rest_door.h). Plain C; no
 * gRPC type crosses it.
 *
 * start: the gate (h2gate.c) listens on --bind:--grpc-port (0: a free
 *   port), accepts and admits connections (--max-connections fitted to
 *   the descriptors, --max-connections-per-ip, the descriptor reserve)
 *   and relays them to gRPC; `where` is "ADDRESS:PORT".
 * expire: ends with DEADLINE_EXCEEDED (ETIMEOUT) the Smooth and SubmitJob
 *   calls whose header has not come within --header-timeout of the
 *   call's start, or whose whole upload has not come within
 *   --body-timeout: REST's, so a stalled or trickling client cannot hold
 *   a slot and its buffer; cancels the Smooth and WatchJob calls whose
 *   client has let one message go unread for --send-timeout (flow control
 *   holds the write): REST's connection timeout.
 * drain: health NOT_SERVING ("" and "mcfd.v1.Smoother"); new Smooth and
 *   SubmitJob calls UNAVAILABLE; reads and streams already open go on.
 * stop: every call ended (those still open after 2 s are cancelled), the
 *   server and its thread stopped.
 * health: the gate's (h2gate_health): it accepts, and gRPC answers.
 * gauges: the gate's connections, streams and refusals (grpc_ fields).
 * One gRPC door per process.
 */
#ifndef SRV_GRPC_DOOR_H
#define SRV_GRPC_DOOR_H

#include "door.h"

#ifdef __cplusplus
extern "C" {
#endif

extern const srv_door_ops mcfd_grpc_door;

#ifdef __cplusplus
}
#endif

#endif /* SRV_GRPC_DOOR_H */
