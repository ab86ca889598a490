/* SPDX-License-Identifier: MIT */
/*
 * fuzz_h2gate.c - libFuzzer target: the gRPC door's gate (server/grpc/h2gate/
 * h2gate_parser.c, h2gate_limits.c) on arbitrary client bytes, driven as
 * h2gate.c drives it, with a stand-in for gRPC behind it.
 *
 * Input: three control bytes, then what the client sends. They choose
 * one or two connections (from one address or two), the bounds (streams per connection, per address, in all; header
 * block bytes and frames; the reset backlog's pace), how the bytes arrive
 * (all at once, byte by byte, in random pieces), and how the stand-in
 * server behaves: it reads the frames the gate passes it and answers each
 * stream it opens in full, resets it, or stays silent; or it sends back
 * arbitrary bytes (a slice of the input). Time advances between pieces and
 * the gate resets the streams that send no first message in time.
 *
 * Besides the sanitizers, it checks what h2gate_parser.h and
 * h2gate_limits.h promise:
 *  - the server gets the client preface, then whole frames, and never the
 *    beginning of a header block before its end; each block it gets, and
 *    what the gate holds, is within max_header_block bytes and
 *    max_header_frames frames;
 *  - streams in the server never exceed the connection's bound, and the
 *    limits count what the parser counts (all return to 0 at the close);
 *  - WAIT only when a bound is met; the server's bytes reach the client
 *    unchanged (plus the gate's RST_STREAMs); a GOAWAY is a whole frame.
 * Seeds: tests/fuzz/corpus_h2gate/ (tests/fuzz/make_h2gate_seeds.py).
 */
#define _GNU_SOURCE 1        /* memmem */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include "fuzz_common.h"
#include "h2gate_parser.h"

#define CHECK(c)                                                                 \
    do {                                                                         \
        if (!(c)) {                                                              \
            fprintf(stderr, "fuzz_h2gate: %s:%d: %s\n", __FILE__, __LINE__, #c); \
            abort();                                                             \
        }                                                                        \
    } while (0)

static const char PREFACE[] = "PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n";
#define TIMEOUT 2.0            /* message_timeout of the run, seconds */
#define HEADER_TIMEOUT 5.0     /* header_timeout */
#define MAX_SILENT 64

typedef struct run {
    h2gate_config cfg;
    h2gate_limits *lim;
    h2gate_addr *a;
    h2gate_parser *p;
    double *now;               /* the clock, shared */
    const struct run *peer;    /* the other connection, or NULL */
    size_t pos, end;           /* its part of the client's bytes */
    uint32_t rng;
    int mode, garbage, answer;
    const uint8_t *data;       /* the client's bytes, for the garbage server */
    size_t size;
    /* the stand-in server: what the gate passed it, frame by frame */
    unsigned char *acc;
    size_t acc_n, acc_cap, up_total;
    int got_preface, in_block, block_frames;
    uint32_t block_sid, last_sid;
    size_t block_bytes;
    uint32_t silent[MAX_SILENT];
    int nsilent;
    /* the way back */
    size_t down_fed, down_out, resets;
} run;

static uint32_t next(run *r)
{
    r->rng ^= r->rng << 13;
    r->rng ^= r->rng >> 17;
    r->rng ^= r->rng << 5;
    return r->rng;
}

static void frame(unsigned char *f, uint32_t len, int type, int flags, uint32_t sid)
{
    f[0] = (unsigned char)(len >> 16);
    f[1] = (unsigned char)(len >> 8);
    f[2] = (unsigned char)len;
    f[3] = (unsigned char)type;
    f[4] = (unsigned char)flags;
    f[5] = (unsigned char)(sid >> 24 & 0x7f);
    f[6] = (unsigned char)(sid >> 16);
    f[7] = (unsigned char)(sid >> 8);
    f[8] = (unsigned char)sid;
}

/* The server's bytes to the gate, parsed on, and what comes out for the
 * client drained. */
static void server_sends(run *r, const void *b, size_t n)
{
    const char *why = NULL;
    size_t k;
    CHECK(h2gate_parser_feed(r->p, H2GATE_DOWN, b, n) == 0);
    r->down_fed += n;
    CHECK(h2gate_parser_parse(r->p, H2GATE_DOWN, *r->now, &why) == H2GATE_MORE);
    h2gate_parser_out(r->p, H2GATE_DOWN, &k);
    CHECK(k == h2gate_parser_out_size(r->p, H2GATE_DOWN));   /* nothing held this way */
    h2gate_parser_out_drop(r->p, H2GATE_DOWN, k);
    r->down_out += k;
    if (!r->garbage)           /* whole frames in: all out, with the gate's resets */
        CHECK(r->down_out == r->down_fed + 13 * r->resets);
}

/* The server ends stream sid: an answer in full, or a reset. */
static void server_ends(run *r, uint32_t sid, int reset)
{
    unsigned char f[9 + 5 + 9 + 9 + 2 + 9 + 4];
    size_t n = 0;
    if (reset) {
        frame(f, 4, 3, 0, sid);
        memset(f + 9, 0, 4);
        f[12] = 8;
        n = 13;
    } else {
        frame(f, 1, 1, 4, sid);                  /* HEADERS :status 200 */
        f[9] = 0x88;
        frame(f + 10, 5, 0, 0, sid);              /* an empty message */
        memset(f + 19, 0, 5);
        frame(f + 24, 2, 1, 5, sid);              /* trailers, END_STREAM */
        f[33] = 0x40;
        f[34] = 0x00;
        n = 35;
    }
    server_sends(r, f, n);
}

/* The server meets a new stream: answers it, resets it or keeps it. */
static void server_meets(run *r, uint32_t sid)
{
    int what = r->answer ? (int)(next(r) % 3) : 2;
    if (what < 2 || r->nsilent == MAX_SILENT)
        server_ends(r, sid, what == 1);
    else
        r->silent[r->nsilent++] = sid;
}

/* The server ends every stream it kept. */
static void server_catches_up(run *r)
{
    while (r->nsilent > 0)
        server_ends(r, r->silent[--r->nsilent], 0);
}

/* The gate's frames for the server, whole ones, in order. */
static void server_reads(run *r)
{
    size_t off = 0;
    if (!r->got_preface) {
        if (r->acc_n < 24)
            return;
        CHECK(memcmp(r->acc, PREFACE, 24) == 0);
        r->got_preface = 1;
        off = 24;
        {                      /* gRPC's SETTINGS */
            unsigned char f[9];
            frame(f, 0, 4, 0, 0);
            server_sends(r, f, 9);
        }
    }
    while (r->acc_n - off >= 9) {
        const unsigned char *h = r->acc + off;
        uint32_t len = (uint32_t)h[0] << 16 | (uint32_t)h[1] << 8 | h[2];
        int type = h[3], flags = h[4];
        uint32_t sid = ((uint32_t)h[5] & 0x7f) << 24 | (uint32_t)h[6] << 16 |
                       (uint32_t)h[7] << 8 | h[8];
        if (r->acc_n - off - 9 < len)
            break;
        if (r->in_block)       /* a block goes on in CONTINUATIONs of its stream */
            CHECK(type == 9 && sid == r->block_sid);
        if (type == 1 || type == 9) {
            /* every block the server gets is within the bounds */
            r->block_frames = type == 1 ? 1 : r->block_frames + 1;
            r->block_bytes = (type == 1 ? 0 : r->block_bytes) + len;
            CHECK(r->block_frames <= r->cfg.max_header_frames);
            CHECK(r->block_bytes <= r->cfg.max_header_block);
            if (type == 1) {
                r->block_sid = sid;
                if ((sid & 1) && sid > r->last_sid) {
                    r->last_sid = sid;
                    if (flags & 4)
                        server_meets(r, sid);
                }
            }
            r->in_block = !(flags & 4);
            if (type == 9 && (flags & 4) && (sid & 1) && sid == r->last_sid)
                server_meets(r, sid);
        }
        off += 9 + len;
    }
    memmove(r->acc, r->acc + off, r->acc_n - off);
    r->acc_n -= off;
}

/* What the gate may write to the server now goes to the stand-in. */
static void drain_up(run *r)
{
    const h2gate_config *k = &r->cfg;
    size_t n;
    const void *b = h2gate_parser_out(r->p, H2GATE_UP, &n);
    if (n > 0) {
        if (r->acc_cap - r->acc_n < n) {
            r->acc_cap = (r->acc_n + n) * 2;
            CHECK((r->acc = realloc(r->acc, r->acc_cap)) != NULL);
        }
        memcpy(r->acc + r->acc_n, b, n);
        r->acc_n += n;
        r->up_total += n;
        h2gate_parser_out_drop(r->p, H2GATE_UP, n);
        server_reads(r);
    }
    /* never the beginning of a block without its end: what is written
     * stops at a frame's end or inside a DATA-like frame */
    CHECK(!r->in_block);
    if (r->got_preface && r->acc_n > 0)
        CHECK(r->acc_n >= 9 && r->acc[3] != 1 && r->acc[3] != 9);
    /* what is held: one incomplete header block within its bounds */
    CHECK(h2gate_parser_out_size(r->p, H2GATE_UP) <=
          k->max_header_block + 9 * (size_t)k->max_header_frames);
}

static void check_counts(run *r)
{
    int n = h2gate_parser_streams(r->p);
    int all = n + (r->peer && r->peer->p ? h2gate_parser_streams(r->peer->p) : 0);
    CHECK(h2gate_limits_streams(r->lim) == all);
    if (r->cfg.streams_per_conn > 0)
        CHECK(n <= r->cfg.streams_per_conn);
}

/* Parses what the client sent: 0, or 1 when the connection is over. */
static int gate_parses(run *r)
{
    int tries = 0;
    for (;;) {
        const char *why = NULL;
        unsigned char g[9 + 8 + 128];
        size_t n;
        h2gate_verdict v = h2gate_parser_parse(r->p, H2GATE_UP, *r->now, &why);
        check_counts(r);
        switch (v) {
        case H2GATE_MORE:
            drain_up(r);
            return 0;
        case H2GATE_ADOPT:
            CHECK(!r->got_preface);
            drain_up(r);
            CHECK(r->got_preface);
            continue;
        case H2GATE_NOT_H2:
            CHECK(!r->got_preface);
            return 1;
        case H2GATE_CLOSE:
            CHECK(why != NULL && why[0] != '\0');
            n = h2gate_parser_goaway(r->p, why, g, sizeof g);
            CHECK(n == 0 || (n >= 17 && g[3] == 7 &&
                             ((size_t)g[0] << 16 | (size_t)g[1] << 8 | g[2]) == n - 9));
            return 1;
        case H2GATE_WAIT:
            CHECK(!h2gate_limits_stream_room(r->lim, r->a, h2gate_parser_streams(r->p), *r->now));
            drain_up(r);
            if (++tries > 8)
                return 1;      /* a client the bounds hold for good */
            server_catches_up(r);
            *r->now += 1.0;     /* the reset backlog drains */
            continue;
        }
    }
}

static void setup(run *r, const uint8_t *data, size_t size)
{
    static const int spc[4] = {1, 2, 100, 0}, per_ip[4] = {0, 3, 8, 256},
                     all[4] = {0, 4, 1024, 2}, hframes[4] = {16, 1, 2, 4};
    static const size_t hblock[4] = {16384, 64, 1024, 16};
    int c0 = data[0], c1 = data[1];
    memset(r, 0, sizeof *r);
    r->cfg.streams_per_conn = spc[c0 & 3];
    r->cfg.max_streams_per_ip = per_ip[c0 >> 2 & 3];
    r->cfg.max_streams = all[c0 >> 4 & 3];
    r->garbage = c0 >> 6 & 1;
    r->cfg.max_header_block = hblock[c1 & 3];
    r->cfg.max_header_frames = hframes[c1 >> 2 & 3];
    r->mode = c1 >> 4 & 3;
    r->cfg.resets_per_s = (c1 & 0x40) ? 1 : 1000;
    r->answer = !(c1 & 0x80);
    r->cfg.message_timeout = (c0 & 0x80) ? TIMEOUT : 0;
    r->rng = 0x9e3779b9u ^ (uint32_t)(c0 << 8 | c1 | data[2] << 16) ^ (uint32_t)size;
    r->data = data + 3;
    r->size = size - 3;
}

/* A connection from ip opens, for the client's bytes [pos, end). */
static void conn_open(run *r, const char *ip, size_t pos, size_t end)
{
    char why[160];
    CHECK((r->a = h2gate_limits_admit(r->lim, ip, 10, 1024, 0, why, sizeof why)));
    CHECK((r->p = h2gate_parser_create(r->lim, r->a, *r->now)) != NULL);
    r->pos = pos;
    r->end = end;
}

static void conn_close(run *r)
{
    if (!r->p)
        return;
    h2gate_parser_end(r->p, *r->now);
    h2gate_parser_free(r->p);
    r->p = NULL;
    h2gate_limits_release(r->lim, r->a);
    free(r->acc);
    r->acc = NULL;
}

/* The next piece of r's bytes, then the server's and the clock's turn:
 * 0, or 1 when the connection is over. */
static int step(run *r)
{
    const char *late;
    size_t n = r->end - r->pos;
    int reset;
    switch (r->mode) {
    case 1: n = 1; break;
    case 2: n = 1 + next(r) % 16; break;
    case 3: n = 1 + next(r) % 512; break;
    default: break;
    }
    if (n > r->end - r->pos)
        n = r->end - r->pos;
    CHECK(h2gate_parser_feed(r->p, H2GATE_UP, r->data + r->pos, n) == 0);
    r->pos += n;
    if (gate_parses(r))
        return 1;
    if (r->garbage && r->got_preface) {      /* a server that talks nonsense */
        size_t at = next(r) % r->size, k = 1 + next(r) % 64;
        server_sends(r, r->data + at, k < r->size - at ? k : r->size - at);
    }
    *r->now += 0.25 * (next(r) % 4);
    if ((late = h2gate_parser_late(r->p, *r->now, HEADER_TIMEOUT))) {
        /* the preface, or a block the gate holds (its HEADERS at least) */
        CHECK(!r->got_preface || h2gate_parser_out_size(r->p, H2GATE_UP) >= 9);
        return 1;
    }
    if (r->cfg.message_timeout > 0 && r->got_preface) {
        CHECK((reset = h2gate_parser_reset_silent(r->p, *r->now, r->cfg.message_timeout)) >= 0);
        r->resets += (size_t)reset;
        check_counts(r);
        drain_up(r);
    }
    return r->pos == r->end;
}

/* Input: three control bytes (setup: bounds, pieces, server; the third:
 * bit 0 two connections, the second from the bytes after the first's
 * (from a second client preface on, else the second half), bit 1 both from
 * one address), then the client's bytes. */
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    run r[2];
    char ip[2][INET6_ADDRSTRLEN];
    struct sockaddr_in6 sa;
    double now = 0;
    size_t split;
    int two, i;
    if (size < 3)
        return 0;
    setup(&r[0], data, size);
    two = data[2] & 1;
    memset(&sa, 0, sizeof sa);         /* the client's address, v4 mapped or not */
    sa.sin6_family = AF_INET6;
    memcpy(&sa.sin6_addr, &r[0].rng, sizeof r[0].rng);
    sa.sin6_addr.s6_addr[10] = sa.sin6_addr.s6_addr[11] = (r[0].rng & 1) ? 0xff : 0;
    h2gate_addr_format((const struct sockaddr *)&sa, ip[0], sizeof ip[0]);
    CHECK(ip[0][0] != '\0');
    snprintf(ip[1], sizeof ip[1], "%s", (data[2] & 2) ? ip[0] : "198.51.100.7");
    split = r[0].size;
    if (two && r[0].size > 24) {
        const void *at = memmem(r[0].data + 1, r[0].size - 1, PREFACE, 24);
        split = at ? (size_t)((const uint8_t *)at - r[0].data) : r[0].size / 2;
    }
    r[1] = r[0];
    r[1].rng ^= 0x5bd1e995u;
    CHECK((r[0].lim = r[1].lim = h2gate_limits_create(&r[0].cfg, now)) != NULL);
    for (i = 0; i < 2; i++) {
        r[i].now = &now;
        r[i].peer = two ? &r[1 - i] : NULL;
    }
    conn_open(&r[0], ip[0], 0, split);
    if (two)
        conn_open(&r[1], ip[1], split, r[0].size);
    while (r[0].p || r[1].p) {
        /* the connections take turns at random */
        i = !r[0].p || (r[1].p && (next(&r[0]) & 1));
        if (r[i].pos == r[i].end || step(&r[i])) {
            /* the server got at most what the client sent, the gate's resets added */
            CHECK(r[i].up_total <= r[i].end - (i ? split : 0) + 13 * r[i].resets);
            conn_close(&r[i]);
        }
    }
    CHECK(h2gate_limits_streams(r[0].lim) == 0);
    h2gate_limits_free(r[0].lim);
    return 0;
}
