/* SPDX-License-Identifier: MIT */
/*
 * h2gate_parser.c - the gate's HTTP/2 frame parser, one per connection
 * (h2gate_parser.h). It checks the client preface, then moves the
 * client's bytes to the server frame by frame: a header block is held
 * until it is whole and within max_header_block bytes and
 * max_header_frames frames, then released at once (gRPC 1.51's HPACK
 * parser copies the unparsed rest of a block again for every piece that
 * arrives: CVE-2023-33953); a HEADERS frame that opens a stream passes
 * only while h2gate_limits.c finds room for it (else the parser stops
 * there: H2GATE_WAIT); each stream's first message is followed until it
 * is whole, so that h2gate_parser_reset_silent can reset the streams that
 * never send one. The server's bytes go back as they are, read only for
 * the streams they end. The parser adds frames of its own (RST_STREAM)
 * only between frames and outside header blocks.
 *
 * No sockets, threads, clock or globals: the gate's thread (h2gate.c) and
 * tests/fuzz/fuzz_h2gate.c feed it bytes and act on its verdicts. The
 * queues give their memory back when empty: an idle connection holds none.
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "h2gate_parser.h"

/* RFC 9113 frame types, flags and error codes */
enum { F_DATA = 0, F_HEADERS = 1, F_RST_STREAM = 3, F_SETTINGS = 4,
       F_PUSH_PROMISE = 5, F_GOAWAY = 7, F_CONTINUATION = 9 };
#define FL_END_STREAM 0x1
#define FL_END_HEADERS 0x4
#define FL_PADDED 0x8
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

/* Its bytes; NULL when it holds none (an empty queue has no memory, and
 * NULL + 0 is undefined in C: fuzz_h2gate's first finding). */
static const unsigned char *q_data(const queue *q)
{
    return q->p ? (const unsigned char *)q->p + q->off : NULL;
}

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

typedef struct {
    uint32_t id;
    double opened;             /* `now` of its HEADERS */
    unsigned first : 1;        /* its first message is whole, or its side ended */
    unsigned char prefix[5];   /* the first message's length prefix */
    uint64_t seen, need;       /* bytes of it seen; its size once known */
} stream;

/* One direction: client -> server (H2GATE_UP) or the way back. */
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

struct h2gate_parser {
    h2gate_limits *lim;
    h2gate_addr *a;
    int open;                  /* the client preface has passed */
    double opened;             /* `now` when the connection opened */
    dir way[2];                /* H2GATE_UP, H2GATE_DOWN */
    stream *st;
    int nst, capst;
    uint32_t last_sid;
    unsigned long nopened;     /* streams it has opened */
};

h2gate_parser *h2gate_parser_create(h2gate_limits *lim, h2gate_addr *a, double now)
{
    h2gate_parser *p = calloc(1, sizeof *p);
    if (p) {
        p->lim = lim;
        p->a = a;
        p->opened = now;
    }
    return p;
}

void h2gate_parser_free(h2gate_parser *p)
{
    int i;
    if (!p)
        return;
    for (i = 0; i < 2; i++) {
        q_free(&p->way[i].in);
        q_free(&p->way[i].out);
        free(p->way[i].inject);
    }
    free(p->st);
    free(p);
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

static stream *stream_find(h2gate_parser *p, uint32_t id)
{
    int i;
    for (i = 0; i < p->nst; i++)
        if (p->st[i].id == id)
            return &p->st[i];
    return NULL;
}

static int stream_open(h2gate_parser *p, uint32_t id, double now)
{
    stream *s = grow(p->st, &p->capst, p->nst, sizeof *s);
    if (!s)
        return -1;
    p->st = s;
    s = &p->st[p->nst++];
    memset(s, 0, sizeof *s);
    s->id = id;
    s->opened = now;
    h2gate_limits_stream_opened(p->lim, p->a);
    return 0;
}

/* The stream leaves the count (the last one takes its slot); reset by the
 * client before the server ended it, it joins the reset backlog. */
static void stream_close(h2gate_parser *p, stream *s, int client_reset, double now)
{
    h2gate_limits_stream_closed(p->lim, p->a, client_reset, now);
    *s = p->st[--p->nst];
}

void h2gate_parser_end(h2gate_parser *p, double now)
{
    while (p->nst > 0)
        stream_close(p, &p->st[0], 0, now);
}

int h2gate_parser_streams(const h2gate_parser *p) { return p->nst; }
unsigned long h2gate_parser_opened(const h2gate_parser *p) { return p->nopened; }

const char *h2gate_parser_late(const h2gate_parser *p, double now, double timeout)
{
    const dir *d = &p->way[H2GATE_UP];
    if (!p->open && now - p->opened > timeout)
        return "no client preface within --header-timeout";
    if (d->block && now - d->block_t0 > timeout)
        return "a header block not whole within --header-timeout";
    return NULL;
}

/* ------------------------------------------------------------------ bytes */

void *h2gate_parser_in(h2gate_parser *p, int way, size_t n)
{
    queue *q = &p->way[way].in;
    return q_reserve(q, n) == 0 ? q->p + q->len : NULL;
}

void h2gate_parser_in_add(h2gate_parser *p, int way, size_t n)
{
    p->way[way].in.len += n;
}

int h2gate_parser_feed(h2gate_parser *p, int way, const void *bytes, size_t n)
{
    void *b = n ? h2gate_parser_in(p, way, n) : NULL;
    if (n && !b)
        return -1;
    if (n)
        memcpy(b, bytes, n);
    h2gate_parser_in_add(p, way, n);
    return 0;
}

const void *h2gate_parser_out(const h2gate_parser *p, int way, size_t *n)
{
    const dir *d = &p->way[way];
    *n = q_size(&d->out) - d->held;
    return q_data(&d->out);
}

void h2gate_parser_out_drop(h2gate_parser *p, int way, size_t n)
{
    q_drop(&p->way[way].out, n);
}

size_t h2gate_parser_out_size(const h2gate_parser *p, int way)
{
    return q_size(&p->way[way].out);
}

/* ----------------------------------------------------------------- frames */

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

static int inject_rst(dir *d, uint32_t id)
{
    uint32_t *n = grow(d->inject, &d->capinject, d->ninject, sizeof *n);
    if (!n)
        return -1;
    d->inject = n;
    d->inject[d->ninject++] = id;
    return 0;
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
    if (q_put(&d->out, q_data(&d->in), n) != 0)
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

/* A client frame's header: whether to pass it (H2GATE_MORE), wait or
 * close (*why). */
static h2gate_verdict client_frame(h2gate_parser *p, uint32_t len, int type, int flags,
                                   uint32_t sid, double now, const char **why)
{
    const h2gate_config *k = h2gate_limits_config(p->lim);
    dir *d = &p->way[H2GATE_UP];
    stream *s;

    if (d->block && type != F_CONTINUATION) {
        *why = "a frame inside a header block";
        return H2GATE_CLOSE;
    }
    switch (type) {
    case F_HEADERS:
        if (len > k->max_header_block) {
            *why = "a header block over the size limit";
            return H2GATE_CLOSE;
        }
        if ((sid & 1) && sid > p->last_sid) {   /* a new stream */
            if (!h2gate_limits_stream_room(p->lim, p->a, p->nst, now))
                return H2GATE_WAIT;
            if (stream_open(p, sid, now) != 0) {
                *why = "out of memory";
                return H2GATE_CLOSE;
            }
            p->last_sid = sid;
            p->nopened++;
            if (flags & FL_END_STREAM)
                stream_find(p, sid)->first = 1;
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
            return H2GATE_CLOSE;
        }
        d->block_bytes += len;
        if (d->block_bytes > k->max_header_block) {
            *why = "a header block over the size limit";
            return H2GATE_CLOSE;
        }
        if (++d->block_frames > k->max_header_frames) {
            *why = "a header block in too many frames";
            return H2GATE_CLOSE;
        }
        break;
    case F_DATA:
        if ((flags & FL_END_STREAM) && (s = stream_find(p, sid)))
            s->first = 1;      /* its side ended: nothing more to wait for */
        break;
    case F_RST_STREAM:
        if ((s = stream_find(p, sid)))
            stream_close(p, s, 1, now);
        break;
    default:
        break;
    }
    return H2GATE_MORE;
}

/* The client's input into the output for the server, frame by frame;
 * stops early when it must wait or close. */
static h2gate_verdict parse_client(h2gate_parser *p, double now, const char **why)
{
    dir *d = &p->way[H2GATE_UP];
    *why = "out of memory";
    for (;;) {
        size_t avail = q_size(&d->in);
        const unsigned char *b = q_data(&d->in);
        if (!d->in_frame) {
            uint32_t len, sid;
            h2gate_verdict v;
            if (flush_injections(d) != 0)
                return H2GATE_CLOSE;
            if (avail < 9)
                return H2GATE_MORE;
            read_head(b, &len, &sid);
            v = client_frame(p, len, b[3], b[4], sid, now, why);
            if (v != H2GATE_MORE)
                return v;
            d->type = b[3];
            d->flags = b[4];
            d->sid = sid;
            d->left = len;
            d->pos = 0;
            d->pad = 0;
            d->in_frame = 1;
            if (pass(d, 9) != 0)
                return H2GATE_CLOSE;
            avail -= 9;
            b += 9;
        }
        if (d->left > 0) {
            size_t n = avail < d->left ? avail : d->left;
            if (n == 0)
                return H2GATE_MORE;
            if (d->type == F_DATA) {
                stream *s = stream_find(p, d->sid);
                if (d->pos == 0 && (d->flags & FL_PADDED))
                    d->pad = b[0];
                if (s && !s->first)
                    first_message(s, d, b, n);
            }
            if (pass(d, n) != 0)
                return H2GATE_CLOSE;
            d->left -= (uint32_t)n;
            d->pos += (uint32_t)n;
            if (d->left > 0)
                return H2GATE_MORE;
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

/* The server's input into the output for the client: follows which
 * streams it ends. */
static h2gate_verdict parse_server(h2gate_parser *p, double now, const char **why)
{
    dir *d = &p->way[H2GATE_DOWN];
    *why = "out of memory";
    for (;;) {
        size_t avail = q_size(&d->in);
        const unsigned char *b = q_data(&d->in);
        if (!d->in_frame) {
            uint32_t len, sid;
            int type, flags;
            stream *s;
            if (flush_injections(d) != 0)
                return H2GATE_CLOSE;
            if (avail < 9)
                return H2GATE_MORE;
            read_head(b, &len, &sid);
            type = b[3];
            flags = b[4];
            s = sid ? stream_find(p, sid) : NULL;
            if (type == F_HEADERS || type == F_PUSH_PROMISE) {
                d->block = !(flags & FL_END_HEADERS);
            } else if (type == F_CONTINUATION && (flags & FL_END_HEADERS)) {
                d->block = 0;
            }
            if (s && (type == F_RST_STREAM ||
                      ((type == F_HEADERS || type == F_DATA) && (flags & FL_END_STREAM))))
                stream_close(p, s, 0, now);
            d->left = len;
            d->in_frame = 1;
            if (q_put(&d->out, b, 9) != 0)
                return H2GATE_CLOSE;
            q_drop(&d->in, 9);
            avail -= 9;
        }
        if (d->left > 0) {
            size_t n = avail < d->left ? avail : d->left;
            if (n == 0)
                return H2GATE_MORE;
            if (q_put(&d->out, q_data(&d->in), n) != 0)
                return H2GATE_CLOSE;
            q_drop(&d->in, n);
            d->left -= (uint32_t)n;
            if (d->left > 0)
                return H2GATE_MORE;
        }
        d->in_frame = 0;
    }
}

h2gate_verdict h2gate_parser_parse(h2gate_parser *p, int way, double now, const char **why)
{
    dir *d = &p->way[H2GATE_UP];
    if (way == H2GATE_DOWN)
        return parse_server(p, now, why);
    if (!p->open) {
        size_t n = q_size(&d->in) < PREFACE_LEN ? q_size(&d->in) : PREFACE_LEN;
        if (n > 0 && memcmp(q_data(&d->in), PREFACE, n) != 0)
            return H2GATE_NOT_H2;
        if (n < PREFACE_LEN)
            return H2GATE_MORE;
        if (q_put(&d->out, PREFACE, PREFACE_LEN) != 0) {
            *why = "out of memory";
            return H2GATE_CLOSE;
        }
        q_drop(&d->in, PREFACE_LEN);
        p->open = 1;
        return H2GATE_ADOPT;
    }
    return parse_client(p, now, why);
}

/* -------------------------------------------------- the gate's own frames */

int h2gate_parser_reset_silent(h2gate_parser *p, double now, double timeout)
{
    int i = 0, reset = 0;
    while (i < p->nst) {
        stream *s = &p->st[i];
        if (!s->first && now - s->opened > timeout) {
            uint32_t id = s->id;
            stream_close(p, s, 0, now);   /* the slot is refilled: look again */
            if (inject_rst(&p->way[H2GATE_UP], id) != 0 ||
                inject_rst(&p->way[H2GATE_DOWN], id) != 0)
                return -1;
            reset++;
            continue;
        }
        i++;
    }
    if (reset && (flush_injections(&p->way[H2GATE_UP]) != 0 ||
                  flush_injections(&p->way[H2GATE_DOWN]) != 0))
        return -1;
    return reset;
}

size_t h2gate_parser_goaway(const h2gate_parser *p, const char *text, unsigned char *buf,
                            size_t size)
{
    const dir *d = &p->way[H2GATE_DOWN];
    size_t tl = strlen(text);
    if (d->in_frame || d->block || q_size(&d->out) > 0 || size < 17)
        return 0;
    if (tl > size - 17)
        tl = size - 17;
    frame_head(buf, (uint32_t)(8 + tl), F_GOAWAY, 0, 0);
    memset(buf + 9, 0, 8);
    buf[9 + 0] = (unsigned char)((p->last_sid >> 24) & 0x7f);
    buf[9 + 1] = (unsigned char)(p->last_sid >> 16);
    buf[9 + 2] = (unsigned char)(p->last_sid >> 8);
    buf[9 + 3] = (unsigned char)p->last_sid;
    buf[9 + 7] = E_CALM;
    memcpy(buf + 17, text, tl);
    return 17 + tl;
}

size_t h2gate_refusal(const char *text, unsigned char *buf, size_t size)
{
    size_t tl = strlen(text);
    if (size < 26)
        return 0;
    if (tl > size - 26)
        tl = size - 26;
    frame_head(buf, 0, F_SETTINGS, 0, 0);
    frame_head(buf + 9, (uint32_t)(8 + tl), F_GOAWAY, 0, 0);
    memset(buf + 18, 0, 8);
    buf[25] = E_CALM;
    memcpy(buf + 26, text, tl);
    return 26 + tl;
}
