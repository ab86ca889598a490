/* SPDX-License-Identifier: MIT */
/*
 * h2gate_listen.c - the gate's listening socket (h2gate_listen.h): the
 * bind address resolved (numeric or a host name), a
 * non-blocking TCP socket bound and listening on it, and the port it got
 * (port 0 asks the kernel for one). No state; the gate (h2gate.c) owns the
 * descriptor.
 */
#include <errno.h>
#include <netdb.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <unistd.h>

#include "h2gate_listen.h"

int h2gate_listen(const char *bind_addr, int port, int *bound_port, char *msg, size_t msgsize)
{
    struct addrinfo hints, *res = NULL;
    char ps[16];
    struct sockaddr_storage ss;
    socklen_t sl = sizeof ss;
    int one = 1, rc, fd;

    memset(&hints, 0, sizeof hints);
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_PASSIVE;
    snprintf(ps, sizeof ps, "%d", port);
    rc = getaddrinfo(bind_addr, ps, &hints, &res);
    if (rc != 0 || !res) {
        snprintf(msg, msgsize, "cannot listen for gRPC on %s:%d: %s", bind_addr, port,
                 gai_strerror(rc));
        return -1;
    }
    fd = socket(res->ai_family, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (fd < 0 || setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one) != 0 ||
        bind(fd, res->ai_addr, res->ai_addrlen) != 0 || listen(fd, SOMAXCONN) != 0 ||
        getsockname(fd, (struct sockaddr *)&ss, &sl) != 0) {
        snprintf(msg, msgsize, "cannot listen for gRPC on %s:%d: %s", bind_addr, port,
                 strerror(errno));
        freeaddrinfo(res);
        if (fd >= 0)
            close(fd);
        return -1;
    }
    freeaddrinfo(res);
    *bound_port = ntohs(ss.ss_family == AF_INET6 ? ((struct sockaddr_in6 *)&ss)->sin6_port
                                                 : ((struct sockaddr_in *)&ss)->sin_port);
    return fd;
}
