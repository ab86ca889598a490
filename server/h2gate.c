/*
 * h2gate.c - the gRPC door's socket, in front of gRPC (h2gate.h): the
 * daemon listens, accepts and admits HTTP/2 connections, and relays each
 * one to gRPC through a socketpair whose inner end gRPC adopts
 * (grpc::AddInsecureChannelFromFd, the use gRPC's own fd tests make of it),
 * reading frame headers on the way.
 *
 * Why not gRPC's own listener with its options. In gRPC 1.51:
 *  - the listener gives up for good on any accept error but EAGAIN, EINTR
 *    and ECONNABORTED (tcp_server_posix.cc, on_read: `goto error`), so one
 *    EMFILE and the door never accepts again (CVE-2023-4785); a door that
 *    owns its socket retries, and logs at a bounded rate;
 *  - nothing caps connections, in all or per address:
 *    GRPC_ARG_MAX_CONNECTION_IDLE_MS (set too, grpc.cc) closes a connection
 *    without calls after a while, but a flood inside that while still takes
 *    every descriptor; the resource quota's "memory pressure" drops new
 *    connections only in that listener;
 *  - the HPACK parser copies the unparsed part of a header block again for
 *    every piece of it that arrives (hpack_parser.cc, HPackParser::Parse)
 *    and checks GRPC_ARG_MAX_METADATA_SIZE only when a field is complete:
 *    a block in many pieces costs quadratic CPU before any limit
 *    (CVE-2023-33953). Here a header block is held until it is whole and
 *    within max_header_block bytes and max_header_frames frames, then
 *    passed on at once;
 *  - MAX_CONCURRENT_STREAMS is enforced only once the client has
 *    acknowledged the setting (parsing.cc: ACKED settings), and a stream a
 *    client resets before the server answers it leaves work queued inside
 *    gRPC that no limit counts (the rapid reset class, CVE-2023-44487):
 *    40,000 HEADERS + RST_STREAM took 1.4 GiB. Here new streams wait while
 *    the connection, its address or the daemon is at its bound, a reset
 *    stream counting until gRPC could have disposed of it;
 *  - a unary call whose message never comes is held by gRPC before any
 *    handler sees it: here a stream must send its first whole message (or
 *    end its side) within message_timeout, else it is reset both ways.
 * The resource quota (grpc.cc) stays as gRPC's own backstop behind this.
 * The price: two more descriptors per connection (the socketpair) and one
 * copy of the bytes each way, on this one thread.
 *
 * The relay. Each direction has an input queue (bytes read, not yet
 * parsed) and an output queue (bytes to write). The frame parser moves
 * input to output frame by frame and adds frames of its own (RST_STREAM,
 * GOAWAY) only between frames and outside header blocks. A source is not
 * read while its output holds QUEUE_HIGH bytes: a busy connection holds at
 * most a few of those, an idle one none (queues are freed when empty).
 *
 * Streams. A HEADERS frame that opens a stream is passed on only while the
 * connection, its address and the daemon are below their stream bounds;
 * else the connection waits (its bytes stay unread, and TCP's flow control
 * holds its client) in a FIFO served as streams end. A stream leaves the
 * count when the server ends it (END_STREAM, RST_STREAM), when the gate
 * resets it, or when the client resets it; in the last case before the
 * server ended it, it stays counted as "reset backlog" that drains at
 * resets_per_s, the pace gRPC is assumed to dispose of such streams at.
 *
 * One thread (epoll); the connection list is under a mutex only for
 * h2gate_peer, h2gate_health and the stats, which other threads read.
 */
#define _GNU_SOURCE 1

#include <errno.h>
#include <netdb.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <unistd.h>

#include "h2gate.h"
#include "srv.h"

#define QUEUE_HIGH (64 * 1024)  /* stop reading a source past this */
#define READ_CHUNK (16 * 1024)
#define ACCEPTS_PER_WAKE 64     /* then the connections get their turn */
#define READS_PER_WAKE 4
#define ACCEPT_RETRY 0.1        /* seconds between accepts after an error */
#define TICK 0.1
#define WAIT_POLL_MS 2

/* RFC 9113 frame types, flags and error codes */
enum { F_DATA = 0, F_HEADERS = 1, F_RST_STREAM = 3, F_SETTINGS = 4,
       F_PUSH_PROMISE = 5, F_GOAWAY = 7, F_CONTINUATION = 9 };
#define FL_END_STREAM 0x1
#define FL_END_HEADERS 0x4
#define FL_PADDED 0x8
#define E_PROTOCOL 0x1
#define E_CANCEL 0x8
#define E_CALM 0xb

static const char PREFACE[] = "PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n";
#define PREFACE_LEN 24

/* ------------------------------------------------------------------ queues */

typedef struct {
    char *p;
    size_t off, len, cap;      /* bytes p[off..len) */
} queue;

static size_t q_size(const queue *q) { return q->len - q->off; }

/* Room for n more bytes at p + len; -1 when out of memory. */
static int q_reserve(queue *q, size_t n)
{
    if (q->cap - q->len >= n)
        return 0;
    if (q->off > 0) {          /* move the live bytes to the front first */
        memmove(q->p, q->p + q->off, q->len - q->off);
        q->len -= q->off;
        q->off = 0;
        if (q->cap - q->len >= n)
            return 0;
    }
    {
        size_t want = q->cap ? q->cap : 4096;
        char *np;
        while (want - q->len < n)
            want *= 2;
        np = realloc(q->p, want);
        if (!np)
            return -1;
        q->p = np;
        q->cap = want;
    }
    return 0;
}

static int q_put(queue *q, const void *d, size_t n)
{
    if (q_reserve(q, n) != 0)
        return -1;
    memcpy(q->p + q->len, d, n);
    q->len += n;
    return 0;
}

/* Drops n bytes from the front; an empty queue gives its memory back. */
static void q_drop(queue *q, size_t n)
{
    q->off += n;
    if (q->off >= q->len) {
        free(q->p);
        memset(q, 0, sizeof *q);
    }
}

static void q_free(queue *q)
{
    free(q->p);
    memset(q, 0, sizeof *q);
}

/* ------------------------------------------------------------------- state */

typedef struct addr {
    struct addr *next;
    char ip[INET6_ADDRSTRLEN];
    int conns, streams;
    double z, z_at;            /* reset backlog (see the top) */
} addr;

typedef struct {
    uint32_t id;
    double opened;             /* srv_mono() of its HEADERS */
    unsigned first : 1;        /* its first message is whole, or its side ended */
    unsigned char prefix[5];   /* the first message's length prefix */
    uint64_t seen, need;       /* bytes of it seen; its size once known */
} stream;

/* One direction of a connection: client -> server or the way back. */
typedef struct {
    queue in, out;
    size_t held;               /* tail of out not to write yet (an incomplete header block) */
    int in_frame;              /* between a frame's header and its end */
    uint32_t left, pos;        /* payload bytes still to pass; passed */
    uint8_t type, flags, pad;
    uint32_t sid;
    int block;                 /* inside a header block */
    uint32_t block_sid;
    size_t block_bytes;
    int block_frames;
    double block_t0;
    uint32_t *inject;          /* RST_STREAMs to add at the next boundary */
    int ninject, capinject;
} dir;

typedef struct conn conn;
typedef struct {               /* connections waiting for stream room */
    conn *h, *t;
    int n;
} wlist;
typedef struct {
    conn *c;
    int server;                /* 0: the client's socket, 1: our end of the pair */
} side;

enum { S_PREFACE, S_OPEN };

struct conn {
    conn *next, *prev;         /* G.conns (under G.mu) */
    conn *wprev, *wnext;       /* in *wl while waiting */
    wlist *wl;
    unsigned long nopened;     /* streams it has opened */
    side ends[2];
    int fd, pfd, inner;        /* client socket; our end; gRPC's end */
    unsigned ev[2];            /* epoll events registered (fd, pfd) */
    int state, dead;
    addr *a;
    double opened, adopted;
    int server_spoke;          /* gRPC has sent its preface */
    dir c, s;                  /* client -> server, server -> client */
    stream *st;
    int nst, capst;
    uint32_t last_sid;
};

static struct {
    h2gate_config cfg;
    pthread_mutex_t mu;        /* conns list, stats, health fields */
    pthread_t thread;
    int running, ep, lfd, wfd;
    int stop_accepting, quit;
    conn *conns;
    addr *addrs;
    wlist wait;                /* FIFO of connections waiting for room */
    conn *grave;               /* closed this round, freed after it */
    int nconns, streams, freed;   /* the thread's own */
    double z, z_at;
    double listen_paused_until, fail_since, beat, mute_age;
    char fail_why[64];
    h2gate_stats stats;        /* counters; conns, streams, waiting
                                  published by tick */
} G = {.mu = PTHREAD_MUTEX_INITIALIZER, .ep = -1, .lfd = -1, .wfd = -1};

static int listen_tag, wake_tag;
static srv_log_limit lim_accept, lim_refuse, lim_close, lim_reset;

/* ------------------------------------------------------------- addresses */

static void addr_string(const struct sockaddr_storage *ss, char *ip, size_t n)
{
    if (ss->ss_family == AF_INET6) {
        const struct sockaddr_in6 *s6 = (const struct sockaddr_in6 *)ss;
        if (IN6_IS_ADDR_V4MAPPED(&s6->sin6_addr))
            inet_ntop(AF_INET, &s6->sin6_addr.s6_addr[12], ip, (socklen_t)n);
        else
            inet_ntop(AF_INET6, &s6->sin6_addr, ip, (socklen_t)n);
    } else if (ss->ss_family == AF_INET) {
        inet_ntop(AF_INET, &((const struct sockaddr_in *)ss)->sin_addr, ip, (socklen_t)n);
    } else {
        snprintf(ip, n, "local");
    }
}

static addr *addr_find(const char *ip)
{
    addr *a;
    for (a = G.addrs; a; a = a->next)
        if (strcmp(a->ip, ip) == 0)
            return a;
    return NULL;
}

static addr *addr_get(const char *ip)
{
    addr *a = addr_find(ip);
    if (a)
        return a;
    a = calloc(1, sizeof *a);
    if (!a)
        return NULL;
    snprintf(a->ip, sizeof a->ip, "%s", ip);
    a->next = G.addrs;
    G.addrs = a;
    return a;
}

static void addr_put(addr *a)
{
    addr **pp;
    if (a->conns > 0 || a->streams > 0)
        return;
    for (pp = &G.addrs; *pp; pp = &(*pp)->next)
        if (*pp == a) {
            *pp = a->next;
            free(a);
            return;
        }
}

/* The reset backlog now: what was counted, less what the server disposed
 * of since at resets_per_s. */
static double backlog(double *z, double *at, double now)
{
    double r = G.cfg.resets_per_s;
    if (*z > 0 && r > 0) {
        *z -= r * (now - *at);
        if (*z < 0)
            *z = 0;
    }
    *at = now;
    return *z;
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

/* A growing array p of *cap elements of elem bytes, n used, with room
 * for one more: the array (moved, perhaps), or NULL when out of memory
 * (p is unchanged). */
static void *grow(void *p, int *cap, int n, size_t elem)
{
    int want = *cap ? *cap * 2 : 8;
    void *np;
    if (n < *cap)
        return p;
    if (!(np = realloc(p, (size_t)want * elem)))
        return NULL;
    *cap = want;
    return np;
}

/* ---------------------------------------------------------------- streams */

static stream *stream_find(conn *c, uint32_t id)
{
    int i;
    for (i = 0; i < c->nst; i++)
        if (c->st[i].id == id)
            return &c->st[i];
    return NULL;
}

/* Whether c may open one more stream now. */
static int stream_room(conn *c, double now)
{
    const h2gate_config *k = &G.cfg;
    if (k->streams_per_conn > 0 && c->nst >= k->streams_per_conn)
        return 0;
    if (k->max_streams_per_ip > 0 &&
        c->a->streams + backlog(&c->a->z, &c->a->z_at, now) >= k->max_streams_per_ip)
        return 0;
    if (k->max_streams > 0 && G.streams + backlog(&G.z, &G.z_at, now) >= k->max_streams)
        return 0;
    return 1;
}

static int stream_open(conn *c, uint32_t id, double now)
{
    stream *s = grow(c->st, &c->capst, c->nst, sizeof *s);
    if (!s)
        return -1;
    c->st = s;
    s = &c->st[c->nst++];
    memset(s, 0, sizeof *s);
    s->id = id;
    s->opened = now;
    c->a->streams++;
    G.streams++;
    return 0;
}

/* The stream leaves the count; reset by the client before the server
 * ended it, it joins the reset backlog. */
static void stream_close(conn *c, stream *s, int client_reset, double now)
{
    if (client_reset) {
        backlog(&G.z, &G.z_at, now);
        backlog(&c->a->z, &c->a->z_at, now);
        G.z += 1;
        c->a->z += 1;
    }
    c->a->streams--;
    G.streams--;
    *s = c->st[--c->nst];
    G.freed = 1;
}

/* -------------------------------------------------------------- the relay */

static void conn_close(conn *c, const char *why);

static int inject_rst(dir *d, uint32_t id)
{
    uint32_t *n = grow(d->inject, &d->capinject, d->ninject, sizeof *n);
    if (!n)
        return -1;
    d->inject = n;
    d->inject[d->ninject++] = id;
    return 0;
}

static void frame_head(unsigned char *h, uint32_t len, int type, int flags, uint32_t sid)
{
    h[0] = (unsigned char)(len >> 16);
    h[1] = (unsigned char)(len >> 8);
    h[2] = (unsigned char)len;
    h[3] = (unsigned char)type;
    h[4] = (unsigned char)flags;
    h[5] = (unsigned char)((sid >> 24) & 0x7f);
    h[6] = (unsigned char)(sid >> 16);
    h[7] = (unsigned char)(sid >> 8);
    h[8] = (unsigned char)sid;
}

/* A frame header's length and stream (its type and flags are h[3], h[4]). */
static void read_head(const unsigned char *h, uint32_t *len, uint32_t *sid)
{
    *len = (uint32_t)h[0] << 16 | (uint32_t)h[1] << 8 | h[2];
    *sid = ((uint32_t)h[5] & 0x7f) << 24 | (uint32_t)h[6] << 16 | (uint32_t)h[7] << 8 | h[8];
}

/* Adds the pending RST_STREAMs when d is between frames and blocks. */
static int flush_injections(dir *d)
{
    int i;
    if (d->in_frame || d->block || d->ninject == 0)
        return 0;
    for (i = 0; i < d->ninject; i++) {
        unsigned char f[13];
        frame_head(f, 4, F_RST_STREAM, 0, d->inject[i]);
        f[9] = f[10] = f[11] = 0;
        f[12] = E_CANCEL;
        if (q_put(&d->out, f, sizeof f) != 0)
            return -1;
    }
    d->ninject = 0;
    return 0;
}

/* Passes n input bytes of the current frame to the output (held when they
 * belong to a header block). */
static int pass(dir *d, size_t n)
{
    if (q_put(&d->out, d->in.p + d->in.off, n) != 0)
        return -1;
    if (d->block)
        d->held += n;
    q_drop(&d->in, n);
    return 0;
}

/* DATA payload bytes [pos, pos + n) of the client's stream s: follows its
 * first message until it is whole. */
static void first_message(stream *s, const dir *d, const unsigned char *p, size_t n)
{
    size_t i;
    for (i = 0; i < n && !s->first; i++) {
        uint32_t at = d->pos + (uint32_t)i;
        uint32_t lo = (d->flags & FL_PADDED) ? 1 : 0, hi = d->pos + d->left;
        if (at < lo || at >= hi - d->pad)
            continue;          /* the pad length byte or the padding */
        if (s->seen < 5) {
            s->prefix[s->seen++] = p[i];
            if (s->seen == 5)
                s->need = 5 + ((uint64_t)s->prefix[1] << 24 | (uint64_t)s->prefix[2] << 16 |
                               (uint64_t)s->prefix[3] << 8 | s->prefix[4]);
        } else {
            /* the rest of the message at once */
            uint64_t want = s->need - s->seen, have = n - i;
            uint64_t stop = (uint64_t)(hi - d->pad) - at;
            uint64_t k = want < have ? want : have;
            if (k > stop)
                k = stop;
            s->seen += k;
            i += (size_t)k - 1;
        }
        if (s->seen >= 5 && s->seen >= s->need)
            s->first = 1;
    }
}

enum { GO, WAIT, KILL };

/* A client frame's header: whether to pass it, wait, or close. *why says
 * why a KILL. */
static int client_frame(conn *c, uint32_t len, int type, int flags, uint32_t sid,
                        double now, const char **why)
{
    const h2gate_config *k = &G.cfg;
    dir *d = &c->c;
    stream *s;

    if (d->block && type != F_CONTINUATION) {
        *why = "a frame inside a header block";
        return KILL;
    }
    switch (type) {
    case F_HEADERS:
        if (len > k->max_header_block) {
            *why = "a header block over the size limit";
            return KILL;
        }
        if ((sid & 1) && sid > c->last_sid) {   /* a new stream */
            if (!stream_room(c, now))
                return WAIT;
            if (stream_open(c, sid, now) != 0) {
                *why = "out of memory";
                return KILL;
            }
            c->last_sid = sid;
            c->nopened++;
            if (flags & FL_END_STREAM)
                stream_find(c, sid)->first = 1;
        }
        d->block = 1;          /* held until the frame with END_HEADERS ends */
        d->block_sid = sid;
        d->block_bytes = len;
        d->block_frames = 1;
        d->block_t0 = now;
        break;
    case F_CONTINUATION:
        if (!d->block || sid != d->block_sid) {
            *why = "a CONTINUATION outside a header block";
            return KILL;
        }
        d->block_bytes += len;
        if (d->block_bytes > k->max_header_block) {
            *why = "a header block over the size limit";
            return KILL;
        }
        if (++d->block_frames > k->max_header_frames) {
            *why = "a header block in too many frames";
            return KILL;
        }
        break;
    case F_DATA:
        if ((flags & FL_END_STREAM) && (s = stream_find(c, sid)))
            s->first = 1;      /* its side ended: nothing more to wait for */
        break;
    case F_RST_STREAM:
        if ((s = stream_find(c, sid)))
            stream_close(c, s, 1, now);
        break;
    default:
        break;
    }
    return GO;
}

/* Parses the client's input into the output for the server. 0, or -1
 * when the connection was closed. Stops early when it must wait. */
static int parse_client(conn *c, double now)
{
    dir *d = &c->c;
    for (;;) {
        size_t avail = q_size(&d->in);
        const unsigned char *p = (const unsigned char *)d->in.p + d->in.off;
        if (!d->in_frame) {
            uint32_t len, sid;
            const char *why = "";
            int rc;
            if (flush_injections(d) != 0) {
                conn_close(c, "out of memory");
                return -1;
            }
            if (avail < 9)
                return 0;
            read_head(p, &len, &sid);
            rc = client_frame(c, len, p[3], p[4], sid, now, &why);
            if (rc == KILL) {
                conn_close(c, why);
                return -1;
            }
            if (rc == WAIT) {
                if (!c->wl)
                    wl_push(&G.wait, c);
                return 0;
            }
            d->type = p[3];
            d->flags = p[4];
            d->sid = sid;
            d->left = len;
            d->pos = 0;
            d->pad = 0;
            d->in_frame = 1;
            if (pass(d, 9) != 0) {
                conn_close(c, "out of memory");
                return -1;
            }
            avail -= 9;
            p += 9;
        }
        if (d->left > 0) {
            size_t n = avail < d->left ? avail : d->left;
            if (n == 0)
                return 0;
            if (d->type == F_DATA) {
                stream *s = stream_find(c, d->sid);
                if (d->pos == 0 && (d->flags & FL_PADDED))
                    d->pad = p[0];
                if (s && !s->first)
                    first_message(s, d, p, n);
            }
            if (pass(d, n) != 0) {
                conn_close(c, "out of memory");
                return -1;
            }
            d->left -= (uint32_t)n;
            d->pos += (uint32_t)n;
            if (d->left > 0)
                return 0;
        }
        /* the frame's end */
        d->in_frame = 0;
        if ((d->type == F_HEADERS || d->type == F_CONTINUATION) &&
            (d->flags & FL_END_HEADERS)) {
            d->block = 0;      /* whole: release it at once */
            d->held = 0;
        }
    }
}

/* Parses the server's input into the output for the client: follows which
 * streams it answers and ends. */
static int parse_server(conn *c, double now)
{
    dir *d = &c->s;
    (void)now;
    for (;;) {
        size_t avail = q_size(&d->in);
        const unsigned char *p = (const unsigned char *)d->in.p + d->in.off;
        if (!d->in_frame) {
            uint32_t len, sid;
            int type, flags;
            stream *s;
            if (flush_injections(d) != 0) {
                conn_close(c, "out of memory");
                return -1;
            }
            if (avail < 9)
                return 0;
            read_head(p, &len, &sid);
            type = p[3];
            flags = p[4];
            s = sid ? stream_find(c, sid) : NULL;
            if (type == F_HEADERS || type == F_PUSH_PROMISE) {
                d->block = !(flags & FL_END_HEADERS);
            } else if (type == F_CONTINUATION && (flags & FL_END_HEADERS)) {
                d->block = 0;
            }
            if (s && (type == F_RST_STREAM ||
                      ((type == F_HEADERS || type == F_DATA) && (flags & FL_END_STREAM))))
                stream_close(c, s, 0, now);
            d->left = len;
            d->in_frame = 1;
            if (q_put(&d->out, p, 9) != 0) {
                conn_close(c, "out of memory");
                return -1;
            }
            q_drop(&d->in, 9);
            avail -= 9;
        }
        if (d->left > 0) {
            size_t n = avail < d->left ? avail : d->left;
            if (n == 0)
                return 0;
            if (q_put(&d->out, d->in.p + d->in.off, n) != 0) {
                conn_close(c, "out of memory");
                return -1;
            }
            q_drop(&d->in, n);
            d->left -= (uint32_t)n;
            if (d->left > 0)
                return 0;
        }
        d->in_frame = 0;
    }
}

/* ---------------------------------------------------------------- sockets */

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
    return !c->dead && !c->wl && q_size(&c->c.out) < QUEUE_HIGH;
}

static void update_events(conn *c)
{
    if (c->dead)
        return;
    set_events(c, 0, EPOLLRDHUP | (may_read_client(c) ? EPOLLIN : 0u) |
                         (q_size(&c->s.out) ? EPOLLOUT : 0u));
    if (c->pfd >= 0)
        set_events(c, 1, (q_size(&c->s.out) < QUEUE_HIGH ? EPOLLIN : 0u) |
                             (q_size(&c->c.out) > c->c.held ? EPOLLOUT : 0u));
}

/* Writes what may go of d's output to fd. 0, or -1 when the peer is gone. */
static int flush(dir *d, int fd)
{
    while (q_size(&d->out) > d->held) {
        ssize_t w = send(fd, d->out.p + d->out.off, q_size(&d->out) - d->held,
                         MSG_NOSIGNAL | MSG_DONTWAIT);
        if (w < 0)
            return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR ? 0 : -1;
        q_drop(&d->out, (size_t)w);
    }
    return 0;
}

/* Reads up to READ_CHUNK bytes from fd into q: >0, 0 at the end, -1 when
 * nothing now (EAGAIN), -2 on an error. */
static ssize_t read_into(int fd, queue *q)
{
    ssize_t r;
    if (q_reserve(q, READ_CHUNK) != 0)
        return -2;
    r = recv(fd, q->p + q->len, READ_CHUNK, MSG_DONTWAIT);
    if (r > 0)
        q->len += (size_t)r;
    else if (r < 0)
        return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR ? -1 : -2;
    return r;
}

/* A GOAWAY for the client when nothing of the server's is mid-frame, then
 * the connection closes. */
static void goaway(conn *c, int code, const char *text)
{
    unsigned char f[9 + 8 + 128];
    size_t tl = strlen(text);
    if (tl > 128)
        tl = 128;
    if (c->s.in_frame || c->s.block || q_size(&c->s.out) > 0)
        return;
    frame_head(f, (uint32_t)(8 + tl), F_GOAWAY, 0, 0);
    memset(f + 9, 0, 8);
    f[9 + 0] = (unsigned char)((c->last_sid >> 24) & 0x7f);
    f[9 + 1] = (unsigned char)(c->last_sid >> 16);
    f[9 + 2] = (unsigned char)(c->last_sid >> 8);
    f[9 + 3] = (unsigned char)c->last_sid;
    f[9 + 7] = (unsigned char)code;
    memcpy(f + 17, text, tl);
    (void)!send(c->fd, f, 17 + tl, MSG_NOSIGNAL | MSG_DONTWAIT);
}

/* Closes c (why: a bound it broke, logged; NULL: a peer left). Freed after
 * the current round of events. */
static void conn_close(conn *c, const char *why)
{
    if (c->dead)
        return;
    if (why) {
        goaway(c, E_CALM, why);
        srv_logf_limited(&lim_close, SRV_LOG_WARN, "gRPC connection from %s closed: %s",
                         c->a->ip, why);
    }
    c->dead = 1;
    while (c->nst > 0)
        stream_close(c, &c->st[0], 0, srv_mono());
    wl_remove(c);
    close(c->fd);
    if (c->pfd >= 0)
        close(c->pfd);
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
    c->a->conns--;
    addr_put(c->a);
    c->a = NULL;
    pthread_mutex_unlock(&G.mu);
    c->next = G.grave;
    G.grave = c;
}

static void conn_free(conn *c)
{
    int i;
    for (i = 0; i < 2; i++) {
        dir *d = i ? &c->s : &c->c;
        q_free(&d->in);
        q_free(&d->out);
        free(d->inject);
    }
    free(c->st);
    free(c);
}

/* The preface is whole: the socketpair, gRPC adopts its inner end. */
static int adopt(conn *c, double now)
{
    int sv[2];
    struct epoll_event ev;
    if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0, sv) != 0) {
        srv_logf_limited(&lim_refuse, SRV_LOG_WARN, "gRPC connection from %s closed: no "
                         "descriptors for its relay (%s)", c->a->ip, strerror(errno));
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
    c->state = S_OPEN;
    c->adopted = now;
    G.cfg.adopt(sv[1], G.cfg.adopt_arg);
    return 0;
}

static void on_client(conn *c, double now)
{
    int i;
    for (i = 0; i < READS_PER_WAKE && !c->dead; i++) {
        ssize_t r;
        if (c->state == S_OPEN && !may_read_client(c))
            break;
        r = read_into(c->fd, &c->c.in);
        if (r == -1)
            break;
        if (r <= 0) {
            conn_close(c, r == -2 && errno == ENOMEM ? "out of memory" : NULL);
            return;
        }
        if (c->state == S_PREFACE) {
            size_t n = q_size(&c->c.in) < PREFACE_LEN ? q_size(&c->c.in) : PREFACE_LEN;
            if (memcmp(c->c.in.p + c->c.in.off, PREFACE, n) != 0) {
                srv_logf_limited(&lim_close, SRV_LOG_WARN, "gRPC connection from %s closed: "
                                 "not HTTP/2 (no client preface)", c->a->ip);
                pthread_mutex_lock(&G.mu);
                G.stats.closed++;
                pthread_mutex_unlock(&G.mu);
                conn_close(c, NULL);
                return;
            }
            if (n < PREFACE_LEN)
                continue;
            if (q_put(&c->c.out, PREFACE, PREFACE_LEN) != 0 || adopt(c, now) != 0) {
                conn_close(c, NULL);
                return;
            }
            q_drop(&c->c.in, PREFACE_LEN);
        }
        if (parse_client(c, now) != 0)
            return;
        if (flush(&c->c, c->pfd) != 0) {
            conn_close(c, NULL);
            return;
        }
    }
}

static void on_server(conn *c, double now)
{
    int i;
    for (i = 0; i < READS_PER_WAKE && !c->dead && q_size(&c->s.out) < QUEUE_HIGH; i++) {
        ssize_t r = read_into(c->pfd, &c->s.in);
        if (r == -1)
            break;
        if (r <= 0) {          /* gRPC closed it: the rest goes, then the end */
            flush(&c->s, c->fd);
            conn_close(c, NULL);
            return;
        }
        c->server_spoke = 1;
        if (parse_server(c, now) != 0)
            return;
        if (flush(&c->s, c->fd) != 0) {
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
    size_t tl;
    snprintf(text, sizeof text, "mcfd: %s", why);
    tl = strlen(text);
    frame_head(f, 0, F_SETTINGS, 0, 0);
    frame_head(f + 9, (uint32_t)(8 + tl), F_GOAWAY, 0, 0);
    memset(f + 18, 0, 8);
    f[25] = E_CALM;
    memcpy(f + 26, text, tl);
    (void)!send(fd, f, 26 + tl, MSG_NOSIGNAL | MSG_DONTWAIT);
    close(fd);
    pthread_mutex_lock(&G.mu);
    G.stats.refused++;
    pthread_mutex_unlock(&G.mu);
    srv_logf_limited(&lim_refuse, SRV_LOG_WARN, "gRPC connection from %s refused: %s", ip, why);
}

static void admit(int fd, const struct sockaddr_storage *ss, double now)
{
    const h2gate_config *k = &G.cfg;
    char ip[INET6_ADDRSTRLEN], why[160];
    addr *a;
    conn *c;
    struct epoll_event ev;
    int limit;

    addr_string(ss, ip, sizeof ip);
    a = addr_find(ip);
    why[0] = '\0';
    /* the lowest free descriptor was this one: all below are taken, and
     * the relay takes two more */
    if (fd + 3 + k->fd_reserve > (limit = srv_fds_limit()))
        snprintf(why, sizeof why, "the daemon is out of descriptors for connections "
                 "(RLIMIT_NOFILE %d, %d kept for its own files)", limit, k->fd_reserve);
    else if (k->max_conns > 0 && G.nconns >= k->max_conns)
        snprintf(why, sizeof why, "%d gRPC connections are open, the most this daemon "
                 "keeps (--max-connections, fitted to its descriptors)", G.nconns);
    else if (k->max_conns_per_ip > 0 && a && a->conns >= k->max_conns_per_ip)
        snprintf(why, sizeof why, "%d gRPC connections are open from your address, the "
                 "most one address may hold (--max-connections-per-ip %d)", a->conns,
                 k->max_conns_per_ip);
    if (why[0]) {
        refuse(fd, ip, why);
        return;
    }
    c = calloc(1, sizeof *c);
    if (!c || !(a = addr_get(ip))) {
        free(c);
        refuse(fd, ip, "out of memory");
        return;
    }
    c->fd = fd;
    c->pfd = c->inner = -1;
    c->ends[0].c = c->ends[1].c = c;
    c->ends[1].server = 1;
    c->opened = now;
    c->a = a;
    memset(&ev, 0, sizeof ev);
    ev.events = EPOLLIN | EPOLLRDHUP;
    ev.data.ptr = &c->ends[0];
    if (epoll_ctl(G.ep, EPOLL_CTL_ADD, fd, &ev) != 0) {
        addr_put(a);
        free(c);
        refuse(fd, ip, "cannot watch the socket");
        return;
    }
    c->ev[0] = EPOLLIN | EPOLLRDHUP;
    a->conns++;
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
        if (fd >= 0) {
            pthread_mutex_lock(&G.mu);
            G.fail_since = 0;
            pthread_mutex_unlock(&G.mu);
            admit(fd, &ss, now);
            continue;
        }
        if (errno == EAGAIN || errno == EWOULDBLOCK) {
            pthread_mutex_lock(&G.mu);
            G.fail_since = 0;  /* accept works: nothing is waiting */
            pthread_mutex_unlock(&G.mu);
            return;
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
    G.freed = 0;
    while (n-- > 0 && G.wait.h) {
        conn *c = G.wait.h;
        unsigned long before = c->nopened;
        wl_remove(c);
        if (parse_client(c, now) != 0)
            continue;
        if (c->wl) {           /* waits again, at G.wait's tail */
            if (c->nopened == before) {
                wl_remove(c);
                wl_push(&stalled, c);
            }
            continue;
        }
        if (flush(&c->c, c->pfd) != 0) {
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

static void tick(double now)
{
    const h2gate_config *k = &G.cfg;
    conn *c, *next;
    double mute = 0;
    if (G.listen_paused_until > 0 && now >= G.listen_paused_until && G.lfd >= 0) {
        G.listen_paused_until = 0;
        listen_watch(1);
        do_accept(now);
    }
    for (c = G.conns; c; c = next) {
        next = c->next;
        if (c->state == S_PREFACE) {
            if (k->header_timeout > 0 && now - c->opened > k->header_timeout)
                conn_close(c, "no client preface within --header-timeout");
            continue;
        }
        if (k->header_timeout > 0 && c->c.block && now - c->c.block_t0 > k->header_timeout) {
            conn_close(c, "a header block not whole within --header-timeout");
            continue;
        }
        if (!c->server_spoke && now - c->adopted > mute)
            mute = now - c->adopted;
        if (k->message_timeout > 0) {
            int i = 0, reset = 0;
            while (i < c->nst) {
                stream *s = &c->st[i];
                if (!s->first && now - s->opened > k->message_timeout) {
                    uint32_t id = s->id;
                    stream_close(c, s, 0, now);   /* the slot is refilled: look again */
                    if (inject_rst(&c->c, id) != 0 || inject_rst(&c->s, id) != 0) {
                        conn_close(c, "out of memory");
                        break;
                    }
                    reset++;
                    continue;
                }
                i++;
            }
            if (reset && !c->dead) {
                pthread_mutex_lock(&G.mu);
                G.stats.streams_reset += (unsigned long)reset;
                pthread_mutex_unlock(&G.mu);
                srv_logf_limited(&lim_reset, SRV_LOG_WARN, "gRPC: reset %d stream%s from %s "
                                 "that sent no whole first message within %g s",
                                 reset, reset == 1 ? "" : "s", c->a->ip, k->message_timeout);
                if (flush_injections(&c->c) != 0 || flush_injections(&c->s) != 0 ||
                    flush(&c->c, c->pfd) != 0 || flush(&c->s, c->fd) != 0) {
                    conn_close(c, NULL);
                    continue;
                }
                update_events(c);
            }
        }
    }
    pthread_mutex_lock(&G.mu);
    G.beat = now;
    G.mute_age = mute;
    G.stats.streams = G.streams;
    G.stats.waiting = G.wait.n;
    pthread_mutex_unlock(&G.mu);
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
        int i;
        for (i = 0; i < n; i++) {
            void *tag = evs[i].data.ptr;
            unsigned e = evs[i].events;
            if (tag == &listen_tag) {
                do_accept(now);
            } else if (tag == &wake_tag) {
                uint64_t v;
                (void)!read(G.wfd, &v, sizeof v);
            } else {
                side *x = tag;
                conn *c = x->c;
                if (c->dead)
                    continue;
                if (x->server) {
                    if (e & EPOLLOUT && flush(&c->c, c->pfd) != 0)
                        conn_close(c, NULL);
                    else if (e & (EPOLLIN | EPOLLHUP | EPOLLERR))
                        on_server(c, now);
                } else {
                    if (e & EPOLLOUT && flush(&c->s, c->fd) != 0)
                        conn_close(c, NULL);
                    else if (c->wl && (e & (EPOLLRDHUP | EPOLLHUP | EPOLLERR)))
                        conn_close(c, NULL);   /* left while it waited */
                    else if (e & (EPOLLIN | EPOLLHUP | EPOLLERR))
                        on_client(c, now);
                }
                update_events(c);
            }
        }
        if (G.wait.h && (G.freed || now - last_resume >= WAIT_POLL_MS / 1000.0)) {
            last_resume = now;
            resume_waiters(now);
        }
        if (now - last_tick >= TICK) {
            last_tick = now;
            tick(now);
        }
        while (G.grave) {
            conn *c = G.grave;
            G.grave = c->next;
            conn_free(c);
        }
        {
            int stop, quit;
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
    }
    while (G.conns)
        conn_close(G.conns, NULL);
    while (G.grave) {
        conn *c = G.grave;
        G.grave = c->next;
        conn_free(c);
    }
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
    struct addrinfo hints, *res = NULL;
    char ps[16];
    struct sockaddr_storage ss;
    socklen_t sl = sizeof ss;
    struct epoll_event ev;
    int one = 1, rc;

    pthread_mutex_lock(&G.mu);  /* other threads read it (h2gate_health) */
    G.cfg = *cfg;
    pthread_mutex_unlock(&G.mu);
    memset(&hints, 0, sizeof hints);
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_PASSIVE;
    snprintf(ps, sizeof ps, "%d", cfg->port);
    rc = getaddrinfo(cfg->bind, ps, &hints, &res);
    if (rc != 0 || !res) {
        snprintf(msg, msgsize, "cannot listen for gRPC on %s:%d: %s", cfg->bind, cfg->port,
                 gai_strerror(rc));
        return -1;
    }
    G.lfd = socket(res->ai_family, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (G.lfd < 0 || setsockopt(G.lfd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one) != 0 ||
        bind(G.lfd, res->ai_addr, res->ai_addrlen) != 0 || listen(G.lfd, SOMAXCONN) != 0 ||
        getsockname(G.lfd, (struct sockaddr *)&ss, &sl) != 0) {
        snprintf(msg, msgsize, "cannot listen for gRPC on %s:%d: %s", cfg->bind, cfg->port,
                 strerror(errno));
        freeaddrinfo(res);
        if (G.lfd >= 0)
            close(G.lfd);
        G.lfd = -1;
        return -1;
    }
    freeaddrinfo(res);
    *port = ntohs(ss.ss_family == AF_INET6 ? ((struct sockaddr_in6 *)&ss)->sin6_port
                                           : ((struct sockaddr_in *)&ss)->sin_port);
    G.ep = epoll_create1(EPOLL_CLOEXEC);
    G.wfd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    memset(&ev, 0, sizeof ev);
    ev.events = EPOLLIN;
    ev.data.ptr = &wake_tag;
    if (G.ep < 0 || G.wfd < 0 || epoll_ctl(G.ep, EPOLL_CTL_ADD, G.wfd, &ev) != 0) {
        snprintf(msg, msgsize, "gRPC door: %s", strerror(errno));
        goto fail;
    }
    listen_watch(1);
    G.quit = G.stop_accepting = 0;
    G.beat = srv_mono();
    G.z_at = G.beat;
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
    while (G.addrs) {
        addr *a = G.addrs;
        G.addrs = a->next;
        free(a);
    }
}

int h2gate_peer(int inner_fd, char *out, size_t size)
{
    conn *c;
    int rc = -1;
    pthread_mutex_lock(&G.mu);
    for (c = G.conns; c; c = c->next)
        if (c->inner == inner_fd && c->a) {
            snprintf(out, size, "%s", c->a->ip);
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
