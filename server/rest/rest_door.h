/* SPDX-License-Identifier: MIT */
/*
 * rest_door.h - the REST door of mcfd (http.c and the files of rest_internal.h, on
 * libmicrohttpd): the HTTP API of api/openapi.yaml, the page, the probes
 * and the metrics, on --bind:--port, beside the gRPC door, on the same job
 * service. Its face is door.h's, like the gRPC door's (grpc_door.h).
 *
 * start: resolves --bind, starts MHD's thread pool (--http-threads) with
 *   its connection caps (--max-connections, --max-connections-per-ip,
 *   --send-timeout as MHD's connection timeout) and answers from the first
 *   request; `where` is the URL ("http://127.0.0.1:8080", the real port
 *   when --port is 0).
 * expire: cancels the jobs whose only client hung up, ends the event
 *   streams whose client left, closes the connections past
 *   --header-timeout or --body-timeout (slowloris clients).
 * drain: /readyz says 503; new jobs are refused by the service.
 * stop: MHD stopped, every connection closed.
 */
#ifndef SRV_REST_DOOR_H
#define SRV_REST_DOOR_H

#include "door.h"

extern const srv_door_ops rest_door;

#endif /* SRV_REST_DOOR_H */
