/* SPDX-License-Identifier: MIT */
/*
 * rds.h - mcfd's Redis client: connections to one Redis server on Debian's
 * hiredis 0.14, for the job store that replicas share (issue 22). hiredis
 * 0.14 predates RESP3 and has no stream helpers: every command, streams
 * included, is sent as plain arguments and its reply read as hiredis's
 * redisReply tree, whose shapes the rds_reply_* helpers check.
 *
 * What this layer adds to hiredis
 *   - Deadlines. Connecting takes at most connect_timeout; a command's
 *     reply must arrive within command_timeout (plus the time a BLOCK
 *     argument asks the server to wait: rds_cmd_block). The socket is
 *     non-blocking and every wait is a poll() with the time left, so no
 *     call blocks longer than its deadline. A command that misses it drops
 *     the connection (its reply may still come: the stream is out of step).
 *   - Reconnection with backoff. A lost or refused connection is made
 *     again by the next call, at the earliest after a backoff that starts
 *     at 50 ms and doubles to 2 s (with +-25% jitter, so replicas do not
 *     reconnect in step); a call made before then fails at once (RDS_EDOWN)
 *     with the last error and the time until the next attempt, so a caller
 *     answering a client (503 + Retry-After) never waits for a dead server.
 *   - AUTH from a file. The password is read from password_file at every
 *     connect (a rotated secret is picked up by the next connection), sent
 *     as an argument of AUTH, and appears in no message, URL or argv.
 *   - SELECT of the database of the URL, then the connection's own hook
 *     (rds_set_on_connect: a subscriber subscribes again, for instance).
 *   - Bounded memory. One reply may take at most max_reply bytes: counted
 *     as they are buffered and as hiredis builds the reply's objects (each
 *     string's length, each array's pointers, each object's header). A
 *     larger reply fails the call (RDS_EPROTO, "reply over N bytes") and
 *     drops the connection instead of growing without end: callers read
 *     large values in slices (GETRANGE) and lists with COUNT.
 *   - Clear errors. A failure is an rds_status and one line naming the
 *     server and what happened ("redis 127.0.0.1:6390: connection refused
 *     (next attempt in 0.4 s)", "redis 127.0.0.1:6390: XADD: ERR ...").
 *     Replies that say the server cannot serve now (LOADING while it reads
 *     its append-only file after a restart, MASTERDOWN, BUSY, TRYAGAIN) are
 *     RDS_EDOWN like a lost connection: the same "come back later".
 *
 * Threads: an rds is one connection, used by one thread at a time. An
 * rds_pool hands connections to any number of threads.
 *
 * Ownership: replies are the caller's (rds_reply_free, accepts NULL).
 */
#ifndef RDS_H
#define RDS_H

#include <stddef.h>

#include <hiredis/hiredis.h>

typedef enum {
    RDS_OK = 0,
    RDS_EDOWN,     /* unreachable, lost, timed out, or not serving now
                      (LOADING, MASTERDOWN, BUSY): transient */
    RDS_EREPLY,    /* the server answered with an error (-ERR, -WRONGTYPE,
                      -NOSCRIPT, -NOGROUP, -NOAUTH, ...) */
    RDS_EPROTO,    /* a reply over max_reply, or not of the expected shape */
    RDS_ECONFIG,   /* the password file cannot be read, bad arguments */
    RDS_ENOMEM
} rds_status;

typedef struct {
    char host[256];            /* name or address (IPv6 without brackets) */
    int port;                  /* default 6379 */
    int db;                    /* SELECTed after connecting, default 0 */
    char password_file[1024];  /* "": no AUTH */
    double connect_timeout;    /* seconds, default 2 */
    double command_timeout;    /* seconds, default 5 */
    size_t max_reply;          /* bytes of one reply, default 64 MiB */
} rds_config;

typedef struct rds rds;
typedef struct rds_pool rds_pool;

/* The defaults above, host "127.0.0.1". */
void rds_config_default(rds_config *cfg);

/* redis://HOST[:PORT][/DB] into cfg (its other fields unchanged); IPv6 as
 * [::1]. A password in the URL (redis://:pw@host) is refused: it would be
 * seen in `ps` and logs; use a password file. 0, or -1 and a one-line
 * reason in msg. */
int rds_url_parse(const char *url, rds_config *cfg, char *msg,
                  size_t msgsize);

/* A connection with a copy of cfg; it connects at its first command (or
 * rds_connect). NULL when out of memory. */
rds *rds_new(const rds_config *cfg);
/* Closes and frees (accepts NULL). */
void rds_free(rds *c);
/* Called after every successful connect (AUTH and SELECT done): 0, or -1
 * (then the connection is dropped and the call fails with RDS_EDOWN). It
 * may send commands on c. */
void rds_set_on_connect(rds *c, int (*fn)(rds *c, void *ctx), void *ctx);
/* Connects now if not connected (honouring the backoff). 0 or -1. */
int rds_connect(rds *c);
/* Drops the connection (the next call reconnects without backoff). */
void rds_disconnect(rds *c);
/* Ends the backoff of a connection that is down: its next call tries the
 * server at once (another connection just reached it). No-op when up. */
void rds_retry_now(rds *c);
/* 1 while a connection is up. */
int rds_connected(const rds *c);
/* The last failure's status and words ("" after a success). */
rds_status rds_status_of(const rds *c);
const char *rds_errmsg(const rds *c);
/* Whether the last failure was an error reply whose first word is code
 * ("NOSCRIPT", "BUSYGROUP", "NOGROUP", "LOADING", ...). */
int rds_error_is(const rds *c, const char *code);
/* "HOST:PORT" of the server, for messages. */
const char *rds_where(const rds *c);

/* One command: argc arguments of lens bytes each (lens NULL: C strings).
 * Returns the reply, or NULL on failure (rds_status_of says which; an
 * error reply is RDS_EREPLY, its text in rds_errmsg). A connection the
 * server closed while it sat idle (a restart) is connected again first,
 * at once, as is the first command of a pipeline; rds_wait reports the
 * drop instead (RDS_EDOWN). */
redisReply *rds_cmd(rds *c, int argc, const char **argv,
                    const size_t *lens);
/* The same for a command that makes the server wait up to block seconds
 * (XREADGROUP ... BLOCK): its deadline is that plus command_timeout. */
redisReply *rds_cmd_block(rds *c, double block, int argc,
                          const char **argv, const size_t *lens);
/* A command of C-string arguments, NULL-terminated (at most 32). */
redisReply *rds_cmdl(rds *c, const char *arg0, ...);

/* Pipelining: queue commands, then read their replies in order. A queued
 * command is sent by the first rds_pipe_read; a failure drops whatever is
 * still queued. rds_pipe_read returns NULL like rds_cmd, also for a
 * -ERR reply, which leaves the connection usable for the next replies. */
int rds_pipe_add(rds *c, int argc, const char **argv,
                 const size_t *lens);
redisReply *rds_pipe_read(rds *c);

/* Waits up to timeout seconds for an unsolicited reply (a subscribed
 * connection's messages). 0 and *out, 1 when none came (the connection
 * stays up), -1 on failure. */
int rds_wait(rds *c, double timeout, redisReply **out);

/* A Lua script run by EVALSHA, loaded (SCRIPT LOAD) when the server does
 * not know it yet: after a restart or a SCRIPT FLUSH. src must outlive
 * the script; sha is filled by the first load. */
typedef struct {
    const char *src;
    char sha[41];
} rds_script;
/* EVALSHA sha numkeys key... arg...: argc arguments after numkeys. */
redisReply *rds_eval(rds *c, rds_script *s, int numkeys, int argc,
                     const char **argv, const size_t *lens);

void rds_reply_free(redisReply *r);

/* CLOCK_MONOTONIC in seconds (the deadlines' clock). */
double rds_monotonic(void);

/* ------------------------------------------------------- reply helpers */

/* A reply of the expected type (NULL-safe); else 0 and, when c is given,
 * RDS_EPROTO with "what: unexpected reply" in c. */
int rds_reply_is(rds *c, const redisReply *r, int type, const char *what);
/* A string reply's bytes as a long long: 0 and *v, or -1 (not a number). */
int rds_reply_ll(const redisReply *r, long long *v);
/* In a flat [field, value, ...] array (HGETALL, a stream entry's fields),
 * the value of field name, or NULL. */
const redisReply *rds_reply_field(const redisReply *r, const char *name);

/* ------------------------------------------------------------ the pool */

/* n connections made with cfg (each connects lazily). NULL when out of
 * memory. */
rds_pool *rds_pool_new(const rds_config *cfg, int n);
void rds_pool_free(rds_pool *p);
/* A connection for this thread's use, waiting while all are lent. */
rds *rds_pool_get(rds_pool *p);
/* Gives c back. When c is up, the idle connections still backing off from
 * an outage try the server at once at their next call: the server is
 * back, so a caller must not be refused by a connection whose backoff
 * has not yet run out (up to 2.5 s after the server's return). */
void rds_pool_put(rds_pool *p, rds *c);

#endif /* RDS_H */
