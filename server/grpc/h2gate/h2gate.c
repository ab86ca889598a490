/* SPDX-License-Identifier: MIT */
/*
 * h2gate.c - the gRPC door's socket, in front of gRPC (h2gate.h): the
 * daemon listens, accepts and admits HTTP/2 connections, and relays each
 * one to gRPC through a socketpair whose inner end gRPC adopts
 * (grpc::AddInsecureChannelFromFd, the use gRPC's own fd tests make of it),
 * reading frame headers on the way.
 *
 * Why not gRPC's own listener: h2gate.h. The price: two more descriptors
 * per connection (the socketpair) and one copy of the bytes each way, on
 * this one thread.
 *
 * The relay. Each connection has a parser (h2gate_parser.c) that holds,
 * each way, the bytes read and not yet parsed and the bytes to write. A
 * source is not read while its output holds QUEUE_HIGH bytes: a busy
 * connection holds at most a few of those, an idle one none. A connection
 * whose next stream finds no room (h2gate_limits.c) waits, its bytes
 * unread so that TCP's flow control holds its client, in a FIFO served
 * as streams end and as the reset backlog drains.
 *
 * The listening socket is h2gate_listen.c's.
 *
 * One thread (epoll); the connection list is under a mutex only for
 * h2gate_peer, h2gate_health and the stats, which other threads read.
 */
#define _GNU_SOURCE 1

#include <errno.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <netinet/in.h>
#include <unistd.h>

#include "h2gate.h"
#include "h2gate_listen.h"
#include "h2gate_parser.h"
#include "srv.h"

#define QUEUE_HIGH (64 * 1024)  /* stop reading a source past this */
#define READ_CHUNK (16 * 1024)
#define ACCEPTS_PER_WAKE 64     /* then the connections get their turn */
#define READS_PER_WAKE 4
#define ACCEPT_RETRY 0.1        /* seconds between accepts after an error */
#define TICK 0.1
#define WAIT_POLL_MS 2

/* ------------------------------------------------------------------- state */

typedef struct conn conn;
typedef struct {               /* connections waiting for stream room */
    conn *h, *t;
    int n;
} wlist;
typedef struct {
    conn *c;
    int server;                /* 0: the client's socket, 1: our end of the pair */
} side;

struct conn {
    conn *next, *prev;         /* G.conns (under G.mu) */
    conn *wprev, *wnext;       /* in *wl while waiting */
    wlist *wl;
    side ends[2];
    int fd, pfd, inner;        /* client socket; our end; gRPC's end */
    unsigned ev[2];            /* epoll events registered (fd, pfd) */
    int dead;
    h2gate_addr *a;
    h2gate_parser *p;
    double adopted;
    int server_spoke;          /* gRPC has sent its preface */
};

/* The gate's state: a process singleton by design (one daemon has one gRPC
 * door, so one gate; h2gate_start and h2gate_stop, called once each by the
 * door, bracket it). Fields are the gate thread's unless a comment names
 * the lock (mu) or says other threads read them. */
static struct {
    h2gate_config cfg;
    pthread_mutex_t mu;        /* conns list, stats, health fields */
    pthread_t thread;
    int running, ep, lfd, wfd;
    int stop_accepting, quit;
    conn *conns;
    h2gate_limits *lim;        /* the thread's own */
    wlist wait;                /* FIFO of connections waiting for room */
    conn *grave;               /* closed this round, freed after it */
    int nconns;                /* the thread's; changed under mu */
    double listen_paused_until, fail_since, beat, mute_age;
    char fail_why[64];
    h2gate_stats stats;        /* counters; conns, streams, waiting
                                  published by tick */
} G = {.mu = PTHREAD_MUTEX_INITIALIZER, .ep = -1, .lfd = -1, .wfd = -1};

static int listen_tag, wake_tag;
static srv_log_limit lim_accept, lim_refuse, lim_close, lim_reset;

/* Adds n to one of G.stats' counters (other threads read them). */
static void count(unsigned long *counter, unsigned long n)
{
    pthread_mutex_lock(&G.mu);
    *counter += n;
    pthread_mutex_unlock(&G.mu);
}

static void wl_push(wlist *l, conn *c)
{
    c->wprev = l->t;
    c->wnext = NULL;
    if (l->t)
        l->t->wnext = c;
    else
        l->h = c;
    l->t = c;
    l->n++;
    c->wl = l;
}

static void wl_remove(conn *c)
{
    wlist *l = c->wl;
    if (!l)
        return;
    if (c->wprev)
        c->wprev->wnext = c->wnext;
    else
        l->h = c->wnext;
    if (c->wnext)
        c->wnext->wprev = c->wprev;
    else
        l->t = c->wprev;
    l->n--;
    c->wl = NULL;
}

/* ---------------------------------------------------------------- sockets */

static void conn_close(conn *c, const char *why);

static void set_events(conn *c, int which, unsigned want)
{
    int fd = which ? c->pfd : c->fd;
    struct epoll_event ev;
    if (fd < 0 || c->ev[which] == want)
        return;
    memset(&ev, 0, sizeof ev);
    ev.events = want;
    ev.data.ptr = &c->ends[which];
    if (epoll_ctl(G.ep, EPOLL_CTL_MOD, fd, &ev) == 0)
        c->ev[which] = want;
}

static int may_read_client(const conn *c)
{
    return !c->dead && !c->wl && h2gate_parser_out_size(c->p, H2GATE_UP) < QUEUE_HIGH;
}

static void update_events(conn *c)
{
    size_t up;
    if (c->dead)
        return;
    h2gate_parser_out(c->p, H2GATE_UP, &up);
    set_events(c, 0, EPOLLRDHUP | (may_read_client(c) ? EPOLLIN : 0u) |
                         (h2gate_parser_out_size(c->p, H2GATE_DOWN) ? EPOLLOUT : 0u));
    if (c->pfd >= 0)
        set_events(c, 1, (h2gate_parser_out_size(c->p, H2GATE_DOWN) < QUEUE_HIGH ? EPOLLIN : 0u) |
                             (up ? EPOLLOUT : 0u));
}

/* Writes what may go of way's output to fd (the server's end for
 * H2GATE_UP, the client's for H2GATE_DOWN). 0, or -1 when the peer is gone. */
static int flush(conn *c, int way)
{
    int fd = way == H2GATE_UP ? c->pfd : c->fd;
    for (;;) {
        size_t n;
        const void *b = h2gate_parser_out(c->p, way, &n);
        ssize_t w;
        if (n == 0)
            return 0;
        w = send(fd, b, n, MSG_NOSIGNAL | MSG_DONTWAIT);
        if (w < 0)
            return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR ? 0 : -1;
        h2gate_parser_out_drop(c->p, way, (size_t)w);
    }
}

/* Reads up to READ_CHUNK bytes from fd into way's input: >0, 0 at the
 * end, -1 when nothing now (EAGAIN), -2 on an error (errno). */
static ssize_t read_into(int fd, h2gate_parser *p, int way)
{
    void *b = h2gate_parser_in(p, way, READ_CHUNK);
    ssize_t r;
    if (!b) {
        errno = ENOMEM;
        return -2;
    }
    r = recv(fd, b, READ_CHUNK, MSG_DONTWAIT);
    if (r > 0)
        h2gate_parser_in_add(p, way, (size_t)r);
    else if (r < 0)
        return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR ? -1 : -2;
    return r;
}

/* Closes c (why: a bound it broke, logged, and a GOAWAY when the client's
 * frames allow one; NULL: a peer left). Freed after the current round of
 * events. */
static void conn_close(conn *c, const char *why)
{
    if (c->dead)
        return;
    if (why) {
        unsigned char f[9 + 8 + 128];
        size_t n = h2gate_parser_goaway(c->p, why, f, sizeof f);
        if (n > 0)
            (void)!send(c->fd, f, n, MSG_NOSIGNAL | MSG_DONTWAIT);
        srv_logf_limited(&lim_close, SRV_LOG_WARN, "gRPC connection from %s closed: %s",
                         h2gate_addr_ip(c->a), why);
    }
    c->dead = 1;
    h2gate_parser_end(c->p, srv_mono());
    wl_remove(c);
    /* Out of the epoll set before the close: close() removes a descriptor
     * from it only when no other descriptor shares its open file (a child
     * forked meanwhile holds copies), and epoll would then go on reporting
     * events carrying c, freed by bury() (ASan: heap-use-after-free in
     * on_event, found by test_client's job handle under ASan). */
    epoll_ctl(G.ep, EPOLL_CTL_DEL, c->fd, NULL);
    close(c->fd);
    if (c->pfd >= 0) {
        epoll_ctl(G.ep, EPOLL_CTL_DEL, c->pfd, NULL);
        close(c->pfd);
    }
    pthread_mutex_lock(&G.mu);
    if (c->prev)
        c->prev->next = c->next;
    else
        G.conns = c->next;
    if (c->next)
        c->next->prev = c->prev;
    G.nconns--;
    if (why)
        G.stats.closed++;
    h2gate_limits_release(G.lim, c->a);
    c->a = NULL;
    pthread_mutex_unlock(&G.mu);
    c->next = G.grave;
    G.grave = c;
}

static void conn_free(conn *c)
{
    h2gate_parser_free(c->p);
    free(c);
}

/* The preface is whole: the socketpair, gRPC adopts its inner end. */
static int adopt(conn *c, double now)
{
    int sv[2];
    struct epoll_event ev;
    if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0, sv) != 0) {
        srv_logf_limited(&lim_refuse, SRV_LOG_WARN, "gRPC connection from %s closed: no "
                         "descriptors for its relay (%s)", h2gate_addr_ip(c->a), strerror(errno));
        conn_close(c, NULL);
        return -1;
    }
    c->pfd = sv[0];
    memset(&ev, 0, sizeof ev);
    ev.events = EPOLLIN;
    ev.data.ptr = &c->ends[1];
    if (epoll_ctl(G.ep, EPOLL_CTL_ADD, c->pfd, &ev) != 0) {
        close(sv[1]);
        conn_close(c, NULL);
        return -1;
    }
    c->ev[1] = EPOLLIN;
    pthread_mutex_lock(&G.mu);
    c->inner = sv[1];
    pthread_mutex_unlock(&G.mu);
    c->adopted = now;
    G.cfg.adopt(sv[1], G.cfg.adopt_arg);
    return 0;
}

/* Parses what the client sent: acts on the parser's verdicts (adopts the
 * connection once its preface is whole, makes it wait for stream room,
 * closes it). 0, or -1 when c closed. The caller writes the output on. */
static int relay_client(conn *c, double now)
{
    const char *why = "";
    for (;;) {
        switch (h2gate_parser_parse(c->p, H2GATE_UP, now, &why)) {
        case H2GATE_MORE:
            break;
        case H2GATE_ADOPT:
            if (adopt(c, now) != 0)
                return -1;
            continue;
        case H2GATE_WAIT:
            if (!c->wl)
                wl_push(&G.wait, c);
            break;
        case H2GATE_NOT_H2:
            srv_logf_limited(&lim_close, SRV_LOG_WARN, "gRPC connection from %s closed: "
                             "not HTTP/2 (no client preface)", h2gate_addr_ip(c->a));
            count(&G.stats.closed, 1);
            conn_close(c, NULL);
            return -1;
        case H2GATE_CLOSE:
            conn_close(c, why);
            return -1;
        }
        break;
    }
    return 0;
}

static void on_client(conn *c, double now)
{
    int i;
    for (i = 0; i < READS_PER_WAKE && !c->dead; i++) {
        ssize_t r;
        if (c->pfd >= 0 && !may_read_client(c))
            break;
        r = read_into(c->fd, c->p, H2GATE_UP);
        if (r == -1)
            break;
        if (r <= 0) {
            conn_close(c, r == -2 && errno == ENOMEM ? "out of memory" : NULL);
            return;
        }
        if (relay_client(c, now) != 0)
            return;
        if (c->pfd >= 0 && flush(c, H2GATE_UP) != 0) {
            conn_close(c, NULL);
            return;
        }
    }
}

static void on_server(conn *c, double now)
{
    int i;
    for (i = 0; i < READS_PER_WAKE && !c->dead &&
                h2gate_parser_out_size(c->p, H2GATE_DOWN) < QUEUE_HIGH; i++) {
        const char *why = "";
        ssize_t r = read_into(c->pfd, c->p, H2GATE_DOWN);
        if (r == -1)
            break;
        if (r <= 0) {          /* gRPC closed it: the rest goes, then the end */
            flush(c, H2GATE_DOWN);
            conn_close(c, NULL);
            return;
        }
        c->server_spoke = 1;
        if (h2gate_parser_parse(c->p, H2GATE_DOWN, now, &why) != H2GATE_MORE) {
            conn_close(c, why);
            return;
        }
        if (flush(c, H2GATE_DOWN) != 0) {
            conn_close(c, NULL);
            return;
        }
    }
}

/* ---------------------------------------------------------------- accept */

static void refuse(int fd, const char *ip, const char *why)
{
    unsigned char f[9 + 9 + 8 + 160];
    char text[160];
    snprintf(text, sizeof text, "mcfd: %s", why);
    (void)!send(fd, f, h2gate_refusal(text, f, sizeof f), MSG_NOSIGNAL | MSG_DONTWAIT);
    close(fd);
    count(&G.stats.refused, 1);
    srv_logf_limited(&lim_refuse, SRV_LOG_WARN, "gRPC connection from %s refused: %s", ip, why);
}

static void admit(int fd, const struct sockaddr *sa, double now)
{
    char ip[INET6_ADDRSTRLEN], why[160];
    h2gate_addr *a;
    conn *c;
    struct epoll_event ev;

    h2gate_addr_format(sa, ip, sizeof ip);
    if (!(a = h2gate_limits_admit(G.lim, ip, fd, srv_fds_limit(), G.nconns, why, sizeof why))) {
        refuse(fd, ip, why);
        return;
    }
    c = calloc(1, sizeof *c);
    if (!c || !(c->p = h2gate_parser_create(G.lim, a, now))) {
        free(c);
        h2gate_limits_release(G.lim, a);
        refuse(fd, ip, "out of memory");
        return;
    }
    c->fd = fd;
    c->pfd = c->inner = -1;
    c->ends[0].c = c->ends[1].c = c;
    c->ends[1].server = 1;
    c->a = a;
    memset(&ev, 0, sizeof ev);
    ev.events = EPOLLIN | EPOLLRDHUP;
    ev.data.ptr = &c->ends[0];
    if (epoll_ctl(G.ep, EPOLL_CTL_ADD, fd, &ev) != 0) {
        h2gate_limits_release(G.lim, a);
        conn_free(c);
        refuse(fd, ip, "cannot watch the socket");
        return;
    }
    c->ev[0] = EPOLLIN | EPOLLRDHUP;
    pthread_mutex_lock(&G.mu);
    c->next = G.conns;
    if (G.conns)
        G.conns->prev = c;
    G.conns = c;
    G.nconns++;
    pthread_mutex_unlock(&G.mu);
}

static void listen_watch(int on)
{
    struct epoll_event ev;
    memset(&ev, 0, sizeof ev);
    ev.events = EPOLLIN;
    ev.data.ptr = &listen_tag;
    if (G.lfd >= 0)
        epoll_ctl(G.ep, on ? EPOLL_CTL_ADD : EPOLL_CTL_DEL, G.lfd, &ev);
}

static void do_accept(double now)
{
    int i;
    for (i = 0; i < ACCEPTS_PER_WAKE && G.lfd >= 0; i++) {
        struct sockaddr_storage ss;
        socklen_t sl = sizeof ss;
        int fd = accept4(G.lfd, (struct sockaddr *)&ss, &sl, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd >= 0 || errno == EAGAIN || errno == EWOULDBLOCK) {
            pthread_mutex_lock(&G.mu);
            G.fail_since = 0;  /* accept works (nothing is waiting, perhaps) */
            pthread_mutex_unlock(&G.mu);
            if (fd < 0)
                return;
            admit(fd, (const struct sockaddr *)&ss, now);
            continue;
        }
        if (errno == EINTR || errno == ECONNABORTED || errno == EPROTO || errno == EPERM)
            continue;          /* that connection only */
        /* EMFILE, ENFILE, ENOBUFS, ENOMEM: the daemon's, not the client's.
         * gRPC's listener stops for good here; this one waits and retries. */
        pthread_mutex_lock(&G.mu);
        if (G.fail_since == 0)
            G.fail_since = now;
        G.stats.accept_errors++;
        snprintf(G.fail_why, sizeof G.fail_why, "%s", strerror(errno));
        pthread_mutex_unlock(&G.mu);
        srv_logf_limited(&lim_accept, SRV_LOG_WARN, "gRPC door: accept failed: %s; "
                         "retrying every %g s", strerror(errno), ACCEPT_RETRY);
        listen_watch(0);
        G.listen_paused_until = now + ACCEPT_RETRY;
        return;
    }
}

/* ------------------------------------------------------------------ ticks */

/* Gives the waiting connections the room there is, in turn: one that
 * opened a stream and waits again goes behind those that could not (its
 * address or the daemon was full), so that a client resetting streams
 * as fast as it can does not take every turn from one that asks once. */
static void resume_waiters(double now)
{
    wlist stalled = {NULL, NULL, 0};
    int n = G.wait.n;
    h2gate_limits_freed(G.lim, 1);
    while (n-- > 0 && G.wait.h) {
        conn *c = G.wait.h;
        unsigned long before = h2gate_parser_opened(c->p);
        wl_remove(c);
        if (relay_client(c, now) != 0)
            continue;
        if (c->wl) {           /* waits again, at G.wait's tail; what it
                                  passed goes at its next event */
            if (h2gate_parser_opened(c->p) == before) {
                wl_remove(c);
                wl_push(&stalled, c);
            }
            continue;
        }
        if (flush(c, H2GATE_UP) != 0) {
            conn_close(c, NULL);
            continue;
        }
        on_client(c, now);     /* its bytes parsed: read on */
        update_events(c);
    }
    while (stalled.t) {        /* back in front, in their order */
        conn *c = stalled.t;
        wl_remove(c);
        c->wnext = G.wait.h;
        c->wprev = NULL;
        if (G.wait.h)
            G.wait.h->wprev = c;
        else
            G.wait.t = c;
        G.wait.h = c;
        G.wait.n++;
        c->wl = &G.wait;
    }
}

/* c's time limits: its preface, its header block, its streams' first
 * messages (reset when late). */
static void expire(conn *c, double now)
{
    const h2gate_config *k = &G.cfg;
    const char *late;
    int reset;
    if (k->header_timeout > 0 && (late = h2gate_parser_late(c->p, now, k->header_timeout))) {
        conn_close(c, late);
        return;
    }
    if (c->pfd < 0 || k->message_timeout <= 0)
        return;
    reset = h2gate_parser_reset_silent(c->p, now, k->message_timeout);
    if (reset < 0) {
        conn_close(c, "out of memory");
        return;
    }
    if (reset == 0)
        return;
    count(&G.stats.streams_reset, (unsigned long)reset);
    srv_logf_limited(&lim_reset, SRV_LOG_WARN, "gRPC: reset %d stream%s from %s "
                     "that sent no whole first message within %g s",
                     reset, reset == 1 ? "" : "s", h2gate_addr_ip(c->a), k->message_timeout);
    if (flush(c, H2GATE_UP) != 0 || flush(c, H2GATE_DOWN) != 0) {
        conn_close(c, NULL);
        return;
    }
    update_events(c);
}

static void tick(double now)
{
    conn *c, *next;
    double mute = 0;
    if (G.listen_paused_until > 0 && now >= G.listen_paused_until && G.lfd >= 0) {
        G.listen_paused_until = 0;
        listen_watch(1);
        do_accept(now);
    }
    for (c = G.conns; c; c = next) {
        next = c->next;
        expire(c, now);
        if (!c->dead && c->pfd >= 0 && !c->server_spoke && now - c->adopted > mute)
            mute = now - c->adopted;
    }
    pthread_mutex_lock(&G.mu);
    G.beat = now;
    G.mute_age = mute;
    G.stats.streams = h2gate_limits_streams(G.lim);
    G.stats.waiting = G.wait.n;
    pthread_mutex_unlock(&G.mu);
}

/* One socket's events. */
static void on_event(side *x, unsigned e, double now)
{
    conn *c = x->c;
    if (c->dead)
        return;
    if (x->server) {
        if (e & EPOLLOUT && flush(c, H2GATE_UP) != 0)
            conn_close(c, NULL);
        else if (e & (EPOLLIN | EPOLLHUP | EPOLLERR))
            on_server(c, now);
    } else {
        if (e & EPOLLOUT && flush(c, H2GATE_DOWN) != 0)
            conn_close(c, NULL);
        else if (c->wl && (e & (EPOLLRDHUP | EPOLLHUP | EPOLLERR)))
            conn_close(c, NULL);   /* left while it waited */
        else if (e & (EPOLLIN | EPOLLHUP | EPOLLERR))
            on_client(c, now);
    }
    update_events(c);
}

static void bury(void)
{
    while (G.grave) {
        conn *c = G.grave;
        G.grave = c->next;
        conn_free(c);
    }
}

static void *gate_main(void *arg)
{
    struct epoll_event evs[64];
    double last_tick = 0, last_resume = 0;
    (void)arg;
    for (;;) {
        /* connections waiting for stream room: the reset backlog drains
         * continuously, so look every WAIT_POLL */
        int n = epoll_wait(G.ep, evs, 64, G.wait.h ? WAIT_POLL_MS : (int)(TICK * 1000));
        double now = srv_mono();
        int i, stop, quit;
        for (i = 0; i < n; i++) {
            void *tag = evs[i].data.ptr;
            if (tag == &listen_tag) {
                do_accept(now);
            } else if (tag == &wake_tag) {
                uint64_t v;
                (void)!read(G.wfd, &v, sizeof v);
            } else {
                on_event(tag, evs[i].events, now);
            }
        }
        if (G.wait.h && (h2gate_limits_freed(G.lim, 0) ||
                         now - last_resume >= WAIT_POLL_MS / 1000.0)) {
            last_resume = now;
            resume_waiters(now);
        }
        if (now - last_tick >= TICK) {
            last_tick = now;
            tick(now);
        }
        bury();
        pthread_mutex_lock(&G.mu);
        stop = G.stop_accepting;
        quit = G.quit;
        pthread_mutex_unlock(&G.mu);
        if (stop && G.lfd >= 0) {
            listen_watch(0);
            close(G.lfd);
            G.lfd = -1;
            G.listen_paused_until = 0;
        }
        if (quit)
            break;
    }
    while (G.conns)
        conn_close(G.conns, NULL);
    bury();
    return NULL;
}

/* ------------------------------------------------------------- interface */

static void wake(void)
{
    uint64_t one = 1;
    if (G.wfd >= 0)
        (void)!write(G.wfd, &one, sizeof one);
}

int h2gate_start(const h2gate_config *cfg, int *port, char *msg, size_t msgsize)
{
    struct epoll_event ev;

    pthread_mutex_lock(&G.mu);  /* other threads read it (h2gate_health) */
    G.cfg = *cfg;
    pthread_mutex_unlock(&G.mu);
    if ((G.lfd = h2gate_listen(cfg->bind, cfg->port, port, msg, msgsize)) < 0)
        return -1;
    G.ep = epoll_create1(EPOLL_CLOEXEC);
    G.wfd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    memset(&ev, 0, sizeof ev);
    ev.events = EPOLLIN;
    ev.data.ptr = &wake_tag;
    if (G.ep < 0 || G.wfd < 0 || epoll_ctl(G.ep, EPOLL_CTL_ADD, G.wfd, &ev) != 0) {
        snprintf(msg, msgsize, "gRPC door: %s", strerror(errno));
        goto fail;
    }
    G.beat = srv_mono();
    if (!(G.lim = h2gate_limits_create(cfg, G.beat))) {
        snprintf(msg, msgsize, "gRPC door: out of memory");
        goto fail;
    }
    listen_watch(1);
    G.quit = G.stop_accepting = 0;
    pthread_mutex_lock(&G.mu);
    G.running = 1;
    pthread_mutex_unlock(&G.mu);
    if (pthread_create(&G.thread, NULL, gate_main, NULL) != 0) {
        snprintf(msg, msgsize, "gRPC door: cannot start its thread");
        pthread_mutex_lock(&G.mu);
        G.running = 0;
        pthread_mutex_unlock(&G.mu);
        goto fail;
    }
    return 0;
fail:
    h2gate_limits_free(G.lim);
    G.lim = NULL;
    if (G.ep >= 0)
        close(G.ep);
    if (G.wfd >= 0)
        close(G.wfd);
    close(G.lfd);
    G.ep = G.wfd = G.lfd = -1;
    return -1;
}

static int running(void)
{
    int r;
    pthread_mutex_lock(&G.mu);
    r = G.running;
    pthread_mutex_unlock(&G.mu);
    return r;
}

void h2gate_stop_accepting(void)
{
    if (!running())
        return;
    pthread_mutex_lock(&G.mu);
    G.stop_accepting = 1;
    pthread_mutex_unlock(&G.mu);
    wake();
}

void h2gate_stop(void)
{
    if (!running())
        return;
    pthread_mutex_lock(&G.mu);
    G.stop_accepting = 1;
    G.quit = 1;
    pthread_mutex_unlock(&G.mu);
    wake();
    pthread_join(G.thread, NULL);
    pthread_mutex_lock(&G.mu);
    G.running = 0;
    pthread_mutex_unlock(&G.mu);
    close(G.ep);
    close(G.wfd);
    if (G.lfd >= 0)
        close(G.lfd);
    G.ep = G.wfd = G.lfd = -1;
    h2gate_limits_free(G.lim);
    G.lim = NULL;
}

int h2gate_peer(int inner_fd, char *out, size_t size)
{
    conn *c;
    int rc = -1;
    pthread_mutex_lock(&G.mu);
    for (c = G.conns; c; c = c->next)
        if (c->inner == inner_fd && c->a) {
            snprintf(out, size, "%s", h2gate_addr_ip(c->a));
            rc = 0;
            break;
        }
    pthread_mutex_unlock(&G.mu);
    return rc;
}

int h2gate_health(char *why, size_t size)
{
    double now = srv_mono();
    int rc = 0;
    pthread_mutex_lock(&G.mu);
    if (!G.running)
        ;
    else if (now - G.beat > 5)
        snprintf(why, size, "the gRPC door's thread has not run for %.0f s", now - G.beat), rc = -1;
    else if (G.fail_since > 0 && now - G.fail_since > G.cfg.unhealthy_after)
        snprintf(why, size, "the gRPC door has not accepted a connection for %.0f s: %s",
                 now - G.fail_since, G.fail_why), rc = -1;
    else if (G.mute_age > G.cfg.unhealthy_after)
        snprintf(why, size, "gRPC has not answered a connection handed to it %.0f s ago",
                 G.mute_age), rc = -1;
    pthread_mutex_unlock(&G.mu);
    return rc;
}

void h2gate_get_stats(h2gate_stats *out)
{
    pthread_mutex_lock(&G.mu);
    *out = G.stats;
    out->conns = G.nconns;
    pthread_mutex_unlock(&G.mu);
}
