/* SPDX-License-Identifier: MIT */
/*
 * door.h - what main.c knows of a door of mcfd (the REST door, rest_door.h;
 * the gRPC door, grpc_door.h): one face for both, so the process starts,
 * ticks, drains and stops them alike. A door reaches jobs only through
 * the job service (service.h) it is given.
 *
 * Life: start after svc_start (a door submits and reads jobs from its
 * first request); expire on every tick of the main thread (its deadlines:
 * headers, bodies, unread answers, clients that hung up); drain with
 * svc_drain (new jobs refused, readiness and health say so; reads and
 * streams already open go on); stop before svc_stop (every request or
 * call is ended, every job reference and subscription released, and the
 * door freed). active: requests or calls in flight (the drain waits for
 * them). Calls other than start and expire may be given NULL.
 */
#ifndef SRV_DOOR_H
#define SRV_DOOR_H

#include "service.h"
#include "srv.h"

#ifdef __cplusplus
extern "C" {
#endif

/* What the daemon tells a door about the rest of it: the health of the
 * other doors and descriptors (0, or -1 and why: /healthz, /readyz), and
 * their gauges (/metrics). Either may be NULL. */
typedef struct {
    int (*health)(void *ctx, char *why, size_t size);
    void (*gauges)(void *ctx, srv_gauges *g);
    void *ctx;
} srv_daemon;

typedef struct {
    const char *name;          /* "REST", "gRPC" */
    /* Listens and serves: 0 with *door and, in where, what it listens on
     * ("http://127.0.0.1:8080", "127.0.0.1:50051"); or -1 with a
     * one-line reason in msg. */
    int (*start)(const srv_config *cfg, svc_t *svc, const srv_daemon *dm,
                 void **door, char *where, size_t wsize, char *msg,
                 size_t msgsize);
    void (*drain)(void *door);
    void (*stop)(void *door);
    /* The tick: ends what is past a deadline of cfg (logged by the door).
     * Returns how many it ended. */
    int (*expire)(void *door, const srv_config *cfg);
    int (*active)(void *door);
    /* 0 when the door takes connections and answers them; else -1 and
     * why. */
    int (*health)(void *door, char *why, size_t size);
    /* Its gauges, into g (its own fields). */
    void (*gauges)(void *door, srv_gauges *g);
} srv_door_ops;

#ifdef __cplusplus
}
#endif

#endif /* SRV_DOOR_H */
