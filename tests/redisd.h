/* SPDX-License-Identifier: MIT */
/*
 * redisd.h - a real redis-server for the tests of the Redis store
 * (test_redis, test_rstore): Debian's 7.0, which `make deps` installs,
 * started on a free loopback port with the append-only file on (fsync at
 * every write) in a temporary directory of its own, and stopped by the
 * test (tl_track_child: also when a test fails or the binary is killed).
 */
#ifndef REDISD_H
#define REDISD_H

#include <sys/types.h>

#include "../server/store/redis/rds.h"

typedef struct {
    char dir[64];              /* its directory: AOF, log */
    int port;                  /* a free one is picked when 0 */
    pid_t pid;
    char why[256];             /* why it could not start ("" when up) */
} redisd;

/* A loopback port nobody listens on now. */
int redisd_free_port(void);
/* Starts it (the directory made when dir is ""): 0 once it answers PING
 * (within 20 s), else -1 with why. Again after a stop: the same port and
 * directory, so it reads its append-only file back. */
int redisd_start(redisd *d);
/* sig: SIGTERM (a clean stop) or SIGKILL. */
void redisd_stop(redisd *d, int sig);
/* Stops it and removes its directory. */
void redisd_cleanup(redisd *d);
/* Sleeps s seconds. */
void redisd_sleep(double s);
/* A client configuration for it (short deadlines for tests). */
rds_config redisd_config(const redisd *d);

#endif /* REDISD_H */
