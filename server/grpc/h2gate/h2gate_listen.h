/* SPDX-License-Identifier: MIT */
/*
 * h2gate_listen.h - the gRPC door's gate (h2gate.h): its listening socket
 * (h2gate_listen.c).
 */
#ifndef SRV_H2GATE_LISTEN_H
#define SRV_H2GATE_LISTEN_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* A non-blocking TCP socket listening on bind_addr:port (h2gate_listen.c):
 * its descriptor, and *bound_port the port it got; or -1 with a one-line
 * reason in msg. */
int h2gate_listen(const char *bind_addr, int port, int *bound_port, char *msg, size_t msgsize);

#ifdef __cplusplus
}
#endif

#endif /* SRV_H2GATE_LISTEN_H */
