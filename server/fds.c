/* SPDX-License-Identifier: MIT */
/*
 * fds.c - the daemon's descriptors. Clients must never take the last
 * ones: without a descriptor the spool cannot write a job's state, the
 * Draco sandbox cannot make its pipes and a probe cannot connect, and
 * libmicrohttpd and gRPC 1.51 misbehave at EMFILE (the first busy-loops
 * logging, the second stops accepting for good). So RLIMIT_NOFILE's soft
 * limit is raised to its hard limit at start, a reserve is kept for the
 * daemon's own files, and the doors' connection caps are fitted into the
 * rest; each door also checks the reserve when it accepts (srv_fds_room,
 * h2gate.c).
 */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <stdio.h>
#include <sys/resource.h>
#include <unistd.h>

#include "srv.h"

/* The largest soft limit asked for: a hard limit of 2^30 (some kernels'
 * default) would only make the doors' caps meaningless. */
#define FDS_MAX (1 << 20)

static int g_limit;            /* RLIMIT_NOFILE after raising it (a
                                  process may lower it later: prlimit) */
static int g_reserve;
static pthread_mutex_t g_mu = PTHREAD_MUTEX_INITIALIZER;
static double g_full_since;    /* srv_mono() since no connection fits, 0: one fits */

static int open_fds(void)
{
    DIR *d = opendir("/proc/self/fd");
    struct dirent *e;
    int n = 0;
    if (!d)
        return 16;             /* no /proc: a typical start */
    while ((e = readdir(d)))
        if (e->d_name[0] != '.')
            n++;
    closedir(d);
    return n - 1;              /* the directory's own */
}

void srv_fds_fit(srv_config *cfg)
{
    struct rlimit rl;
    long budget, rest, grpc;
    int want_rest = cfg->max_connections;
    int want_grpc = cfg->grpc_port >= 0 ? cfg->max_connections : 0;

    if (getrlimit(RLIMIT_NOFILE, &rl) == 0) {
        rlim_t hard = rl.rlim_max == RLIM_INFINITY || rl.rlim_max > FDS_MAX
                          ? FDS_MAX : rl.rlim_max;
        if (rl.rlim_cur < hard) {
            rl.rlim_cur = hard;
            if (setrlimit(RLIMIT_NOFILE, &rl) != 0)
                getrlimit(RLIMIT_NOFILE, &rl);
        }
        g_limit = rl.rlim_cur == RLIM_INFINITY || rl.rlim_cur > FDS_MAX ? FDS_MAX
                                                                         : (int)rl.rlim_cur;
    } else {
        g_limit = 1024;
    }
    /* the spool's files and a job's state writes, the sandbox's three
     * pipes per decode, gRPC's wake-up descriptors (one per thread it
     * polls with), libmicrohttpd's, the probes: 64, and 8 per worker */
    g_reserve = 64 + 8 * cfg->svc.workers;
    cfg->fd_reserve = g_reserve;
    budget = (long)g_limit - open_fds() - g_reserve;
    rest = want_rest;
    grpc = want_grpc;
    if (rest + 3 * grpc > budget) {
        /* half for each door; a gRPC connection takes three */
        rest = budget / 2 < want_rest ? budget / 2 : want_rest;
        grpc = want_grpc ? (budget - rest) / 3 : 0;
        if (grpc > want_grpc)
            grpc = want_grpc;
        if (rest < 4)
            rest = 4;
        if (want_grpc && grpc < 4)
            grpc = 4;
        srv_logf(SRV_LOG_WARN, "RLIMIT_NOFILE is %d (hard limit): REST connections "
                 "capped at %ld, gRPC connections at %ld (three descriptors each), %d "
                 "descriptors kept for the daemon's own files; --max-connections %d asks "
                 "for more", g_limit, rest, grpc, g_reserve, cfg->max_connections);
    }
    cfg->max_connections = (int)rest;
    cfg->grpc_max_connections = (int)grpc;
}

int srv_fds_limit(void)
{
    struct rlimit rl;
    if (getrlimit(RLIMIT_NOFILE, &rl) != 0 || rl.rlim_cur == RLIM_INFINITY ||
        rl.rlim_cur > FDS_MAX)
        return FDS_MAX;
    return (int)rl.rlim_cur;
}

int srv_fds_headroom(void)
{
    int t = fcntl(STDERR_FILENO, F_DUPFD_CLOEXEC, 0), room;
    if (t < 0)
        return errno == EMFILE ? 0 : FDS_MAX; /* no stderr to copy: cannot tell */
    room = srv_fds_limit() - t;
    close(t);
    return room;
}

void srv_fds_watch(double now)
{
    int room = srv_fds_headroom() > g_reserve;
    pthread_mutex_lock(&g_mu);
    if (room)
        g_full_since = 0;
    else if (g_full_since == 0)
        g_full_since = now;
    pthread_mutex_unlock(&g_mu);
}

int srv_fds_health(char *why, size_t size)
{
    double since;
    pthread_mutex_lock(&g_mu);
    since = g_full_since;
    pthread_mutex_unlock(&g_mu);
    if (since == 0 || srv_mono() - since < SRV_FDS_DEAD)
        return 0;
    snprintf(why, size, "no descriptor has been free for a new gRPC connection for "
             "%.0f s (RLIMIT_NOFILE %d, %d kept for the daemon's own files and probes)",
             srv_mono() - since, srv_fds_limit(), g_reserve);
    return -1;
}
