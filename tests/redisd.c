/* SPDX-License-Identifier: MIT */
/*
 * redisd.c - a real redis-server for the Redis store's tests (redisd.h).
 */
#include "redisd.h"

#include <errno.h>
#include <netinet/in.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "testlib.h"

int redisd_free_port(void)
{
    struct sockaddr_in a = {.sin_family = AF_INET,
                            .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    socklen_t len = sizeof a;
    int fd = socket(AF_INET, SOCK_STREAM, 0), port = -1;

    if (fd >= 0 && bind(fd, (struct sockaddr *)&a, sizeof a) == 0 &&
        getsockname(fd, (struct sockaddr *)&a, &len) == 0)
        port = ntohs(a.sin_port);
    if (fd >= 0)
        close(fd);
    return port;
}

rds_config redisd_config(const redisd *d)
{
    rds_config c;
    rds_config_default(&c);
    c.port = d->port;
    /* Room for a loaded machine: redis-server here fsyncs every write
     * (appendfsync always), and a 2 s command deadline ran out in a fresh
     * clone's make test at load 20 (test_records: "create: Resource
     * temporarily unavailable"). A dead server is still refused at once. */
    c.connect_timeout = 5;
    c.command_timeout = 10;
    return c;
}

void redisd_sleep(double s)
{
    struct timespec ts = {(time_t)s, (long)((s - (double)(time_t)s) * 1e9)};
    nanosleep(&ts, NULL);
}

int redisd_start(redisd *d)
{
    char port[16], log[128];
    double end;

    signal(SIGPIPE, SIG_IGN);   /* hiredis writes with write() */
    if (!d->dir[0]) {
        snprintf(d->dir, sizeof d->dir, "/tmp/mcfd-redis-test-XXXXXX");
        if (!mkdtemp(d->dir)) {
            snprintf(d->why, sizeof d->why, "mkdtemp: %s", strerror(errno));
            d->dir[0] = 0;
            return -1;
        }
    }
    if (!d->port)
        d->port = redisd_free_port();
    snprintf(port, sizeof port, "%d", d->port);
    snprintf(log, sizeof log, "%s/redis.log", d->dir);
    d->pid = fork();
    if (d->pid < 0) {
        snprintf(d->why, sizeof d->why, "fork: %s", strerror(errno));
        return -1;
    }
    if (d->pid == 0) {
        tl_child_own_group();
        execlp("redis-server", "redis-server", "--port", port, "--bind",
               "127.0.0.1", "--dir", d->dir, "--appendonly", "yes",
               "--appendfsync", "always", "--save", "", "--logfile", log,
               "--daemonize", "no", (char *)NULL);
        _exit(127);
    }
    tl_track_child(d->pid);
    for (end = rds_monotonic() + 20; rds_monotonic() < end;
         redisd_sleep(0.05)) {
        rds_config cfg = redisd_config(d);
        rds *c = rds_new(&cfg);
        redisReply *r = rds_cmdl(c, "PING", NULL);
        int st, up = r && r->type == REDIS_REPLY_STATUS;
        rds_reply_free(r);
        rds_free(c);
        if (up) {
            d->why[0] = 0;
            return 0;
        }
        if (waitpid(d->pid, &st, WNOHANG) == d->pid) {
            snprintf(d->why, sizeof d->why, "redis-server %s (see %s)",
                     WIFEXITED(st) && WEXITSTATUS(st) == 127
                         ? "is not installed (make deps installs it)"
                         : "exited at start", log);
            d->pid = 0;
            return -1;
        }
    }
    snprintf(d->why, sizeof d->why, "redis-server did not answer within 20 s");
    return -1;
}

void redisd_stop(redisd *d, int sig)
{
    if (d->pid > 0) {
        kill(d->pid, sig);
        waitpid(d->pid, NULL, 0);
    }
    d->pid = 0;
}

void redisd_cleanup(redisd *d)
{
    char cmd[128];

    redisd_stop(d, SIGTERM);
    if (d->dir[0]) {
        snprintf(cmd, sizeof cmd, "rm -rf '%s'", d->dir);
        if (system(cmd) != 0)
            fprintf(stderr, "redisd: could not remove %s\n", d->dir);
    }
}
