/* SPDX-License-Identifier: MIT */
/*
 * h2gate_parser.h - the gRPC door's gate (h2gate.h): one connection's
 * HTTP/2 frame parser (h2gate_parser.c), whose streams count against the
 * limits (h2gate_limits.h). Pure: no sockets, threads, clock or globals.
 */
#ifndef SRV_H2GATE_PARSER_H
#define SRV_H2GATE_PARSER_H

#include <stddef.h>

#include "h2gate_limits.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------ The parser
 * One per connection, fed the bytes of either way as they arrive, in
 * chunks of any size; it answers what to do with a verdict and queues
 * the bytes to write on. Not thread-safe. Way H2GATE_UP: the client's
 * bytes in, the server's to write out; H2GATE_DOWN: the server's in, the
 * client's out. What it writes is what it read, whole frames in the same
 * order (the client preface first, up), plus RST_STREAM frames of its own
 * (h2gate_parser_reset_silent) between frames and outside header blocks;
 * bytes of a header block become writable only once the block is whole. */
typedef struct h2gate_parser h2gate_parser;
enum { H2GATE_UP = 0, H2GATE_DOWN = 1 };
typedef enum {
    H2GATE_MORE,   /* parsed what there is: read on */
    H2GATE_ADOPT,  /* (up, once) the client preface is whole and queued for
                      the server: hand the connection to it, parse again */
    H2GATE_WAIT,   /* (up) a new stream past a bound: the rest stays
                      unparsed; read no more from the client and parse
                      again when a stream ends or time passes */
    H2GATE_NOT_H2, /* (up) no client preface: close without a word */
    H2GATE_CLOSE   /* a bound, the protocol (up) or out of memory: close
                      with a GOAWAY saying *why (a static string) */
} h2gate_verdict;

/* NULL when out of memory. Its streams count against lim and a, which
 * must outlive it; now: when the connection opened. */
h2gate_parser *h2gate_parser_create(h2gate_limits *lim, h2gate_addr *a, double now);
/* Frees p (NULL is fine); call h2gate_parser_end first. */
void h2gate_parser_free(h2gate_parser *p);
/* The connection closes: its streams leave the count. */
void h2gate_parser_end(h2gate_parser *p, double now);
/* Input: room for n bytes of way's input (NULL when out of memory), then
 * how many were written there; or both at once from bytes (-1: memory). */
void *h2gate_parser_in(h2gate_parser *p, int way, size_t n);
void h2gate_parser_in_add(h2gate_parser *p, int way, size_t n);
int h2gate_parser_feed(h2gate_parser *p, int way, const void *bytes, size_t n);
/* Parses way's input as far as it may; *why is set for H2GATE_CLOSE. */
h2gate_verdict h2gate_parser_parse(h2gate_parser *p, int way, double now, const char **why);
/* Output: the bytes that may be written now (*n of them), then how many
 * were; and all queued, writable or held (to stop reading past a mark). */
const void *h2gate_parser_out(const h2gate_parser *p, int way, size_t *n);
void h2gate_parser_out_drop(h2gate_parser *p, int way, size_t n);
size_t h2gate_parser_out_size(const h2gate_parser *p, int way);
/* Streams open now; streams opened in all. */
int h2gate_parser_streams(const h2gate_parser *p);
unsigned long h2gate_parser_opened(const h2gate_parser *p);
/* Why the connection is out of time at now (a static string: its client
 * preface, or the header block it is inside, not whole within timeout
 * seconds), or NULL. */
const char *h2gate_parser_late(const h2gate_parser *p, double now, double timeout);
/* Resets, both ways, the streams that sent no whole first message (nor
 * ended their side) within timeout seconds: how many, or -1 when out of
 * memory (close the connection). */
int h2gate_parser_reset_silent(h2gate_parser *p, double now, double timeout);
/* A GOAWAY (ENHANCE_YOUR_CALM, text truncated to fit) for the client in
 * buf: its length, or 0 when the server's bytes are mid-frame or queued
 * (the client's stream of frames must stay whole: then close without). */
size_t h2gate_parser_goaway(const h2gate_parser *p, const char *text, unsigned char *buf,
                            size_t size);
/* A refused connection's answer, SETTINGS then GOAWAY (ENHANCE_YOUR_CALM,
 * text): its length in buf (0 when size < 26). */
size_t h2gate_refusal(const char *text, unsigned char *buf, size_t size);

#ifdef __cplusplus
}
#endif

#endif /* SRV_H2GATE_PARSER_H */
