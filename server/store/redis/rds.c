/* SPDX-License-Identifier: MIT */
/*
 * rds.c - mcfd's Redis client on hiredis 0.14 (rds.h says what it adds):
 * connect with a deadline, AUTH from a file, SELECT, commands and
 * pipelines on a non-blocking socket with poll() deadlines, replies
 * bounded in bytes, reconnection with jittered backoff, Lua scripts by
 * SHA (rds_pool.c: a pool of connections for many threads).
 *
 * hiredis is used for what it is good at, formatting commands and parsing
 * RESP, through its buffer functions (redisAppendCommandArgv,
 * redisBufferWrite, redisBufferRead, redisGetReplyFromReader); the waits
 * are ours. The context's REDIS_BLOCK flag is cleared and its socket set
 * O_NONBLOCK after the connect, which is how hiredis is driven by an
 * event loop: a read or write that would block returns "try again". The
 * process must ignore SIGPIPE (mcfd does): hiredis writes with write().
 */
#include "rds.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <poll.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#define BACKOFF_MIN 0.05       /* seconds before the first retry */
#define BACKOFF_MAX 2.0        /* ... doubling up to this */
#define PASSWORD_MAX 4096      /* bytes of a password file */
#define ARGS_MAX 32            /* rds_cmdl */

struct rds {
    rds_config cfg;
    char where[300];           /* "host:port" */
    redisContext *ctx;         /* NULL while disconnected */
    redisReplyObjectFunctions base, fn;  /* hiredis's, and ours around */
    size_t taken;              /* bytes of the reply being parsed */
    int over;                  /* it passed max_reply */
    int pending;               /* pipelined replies not read yet */
    double next_try;           /* monotonic seconds: earliest reconnect */
    double backoff;            /* the wait after the next failure */
    unsigned seed;             /* jitter */
    int (*on_connect)(rds *c, void *ctx);
    void *on_connect_ctx;
    rds_status status;
    double call_timeout;       /* the current call's, for messages */
    char down[512];            /* why the last connect failed */
    char code[32];             /* first word of the last error reply */
    char err[512];
};

double rds_monotonic(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static void fail(rds *c, rds_status st, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
static void fail(rds *c, rds_status st, const char *fmt, ...)
{
    va_list ap;
    int n = snprintf(c->err, sizeof c->err, "redis %s: ", c->where);

    va_start(ap, fmt);
    if (n > 0 && (size_t)n < sizeof c->err)
        vsnprintf(c->err + n, sizeof c->err - (size_t)n, fmt, ap);
    va_end(ap);
    c->status = st;
}

static void ok(rds *c)
{
    c->status = RDS_OK;
    c->err[0] = c->code[0] = 0;
}

/* ------------------------------------------------------- configuration */

void rds_config_default(rds_config *cfg)
{
    memset(cfg, 0, sizeof *cfg);
    snprintf(cfg->host, sizeof cfg->host, "127.0.0.1");
    cfg->port = 6379;
    cfg->connect_timeout = 2;
    cfg->command_timeout = 5;
    cfg->max_reply = (size_t)64 << 20;
}

static int parse_uint(const char *s, size_t n, long max, long *out)
{
    long v = 0;
    size_t i;

    if (n == 0 || n > 10)
        return -1;
    for (i = 0; i < n; i++) {
        if (s[i] < '0' || s[i] > '9')
            return -1;
        v = v * 10 + (s[i] - '0');
    }
    if (v > max)
        return -1;
    *out = v;
    return 0;
}

int rds_url_parse(const char *url, rds_config *cfg, char *msg,
                  size_t msgsize)
{
    const char *p, *h, *he, *end;
    long port = 6379, db = 0;

    if (strncmp(url, "redis://", 8) != 0) {
        snprintf(msg, msgsize, "%s: not a redis://HOST:PORT[/DB] URL", url);
        return -1;
    }
    p = url + 8;
    end = p + strcspn(p, "/");
    if (memchr(p, '@', (size_t)(end - p))) {
        snprintf(msg, msgsize, "redis URL: a password in the URL would show "
                 "in ps and logs; give it in a file (--store-password-file)");
        return -1;
    }
    if (*p == '[') {                        /* [v6]:port */
        h = p + 1;
        he = memchr(h, ']', (size_t)(end - h));
        if (!he) {
            snprintf(msg, msgsize, "%s: unclosed [ in the host", url);
            return -1;
        }
        p = he + 1;
    } else {
        h = p;
        he = p + strcspn(p, ":/");
        p = he;
    }
    if (he == h || (size_t)(he - h) >= sizeof cfg->host) {
        snprintf(msg, msgsize, "%s: %s host", url,
                 he == h ? "no" : "too long a");
        return -1;
    }
    if (*p == ':') {
        const char *pe = p + 1 + strcspn(p + 1, "/");
        if (parse_uint(p + 1, (size_t)(pe - p - 1), 65535, &port) != 0 ||
            port == 0) {
            snprintf(msg, msgsize, "%s: the port is not in 1..65535", url);
            return -1;
        }
        p = pe;
    } else if (*p != '/' && *p != 0) {
        snprintf(msg, msgsize, "%s: unexpected '%c' after the host", url, *p);
        return -1;
    }
    if (*p == '/' && p[1] != 0 &&
        parse_uint(p + 1, strlen(p + 1), INT_MAX, &db) != 0) {
        snprintf(msg, msgsize, "%s: the database is not a number", url);
        return -1;
    }
    memcpy(cfg->host, h, (size_t)(he - h));
    cfg->host[he - h] = 0;
    cfg->port = (int)port;
    cfg->db = (int)db;
    return 0;
}

/* --------------------------------------------------- bounded replies */

/* hiredis's object constructors, wrapped: each adds what it allocates to
 * the reply's count and refuses (NULL: hiredis's "out of memory") past
 * max_reply. The reader's privdata is the rds. */
#define OBJ_BYTES 64           /* a redisReply and its allocator's header */

static int charge(rds *c, size_t n)
{
    if (c->over || n > c->cfg.max_reply - c->taken) {
        c->over = 1;
        return -1;
    }
    c->taken += n;
    return 0;
}

static void *mk_string(const redisReadTask *t, char *s, size_t n)
{
    rds *c = t->privdata;
    return charge(c, OBJ_BYTES + n) ? NULL : c->base.createString(t, s, n);
}

static void *mk_array(const redisReadTask *t, int n)
{
    rds *c = t->privdata;
    return charge(c, OBJ_BYTES + (size_t)(n > 0 ? n : 0) * sizeof(void *))
               ? NULL : c->base.createArray(t, n);
}

static void *mk_integer(const redisReadTask *t, long long v)
{
    rds *c = t->privdata;
    return charge(c, OBJ_BYTES) ? NULL : c->base.createInteger(t, v);
}

static void *mk_nil(const redisReadTask *t)
{
    rds *c = t->privdata;
    return charge(c, OBJ_BYTES) ? NULL : c->base.createNil(t);
}

/* ---------------------------------------------------------- connecting */

void rds_disconnect(rds *c)
{
    if (c->ctx)
        redisFree(c->ctx);
    c->ctx = NULL;
    c->pending = 0;
    c->taken = 0;
    c->over = 0;
}

/* The connection is gone or out of step: drop it; the next call may
 * reconnect at once (a server that is really gone then backs off). */
static void drop(rds *c)
{
    rds_disconnect(c);
}

static void backoff(rds *c)
{
    double now = rds_monotonic(),
           jitter = 0.75 + 0.5 * (double)rand_r(&c->seed) /
                                                (double)RAND_MAX;

    snprintf(c->down, sizeof c->down, "%s", c->err);
    c->next_try = now + c->backoff * jitter;
    c->backoff = c->backoff * 2 > BACKOFF_MAX ? BACKOFF_MAX : c->backoff * 2;
}

static int wait_fd(rds *c, short events, double deadline, const char *what)
{
    for (;;) {
        struct pollfd pfd = {.fd = c->ctx->fd, .events = events};
        double left = deadline - rds_monotonic();
        int ms, n;

        if (left <= 0) {
            fail(c, RDS_EDOWN, "%s: no answer within %.3g s", what,
                 c->call_timeout);
            return -1;
        }
        ms = (int)(left * 1000) + 1;
        n = poll(&pfd, 1, ms);
        if (n > 0)
            return 0;
        if (n < 0 && errno != EINTR) {
            fail(c, RDS_EDOWN, "%s: poll: %s", what, strerror(errno));
            return -1;
        }
    }
}

static int flush_out(rds *c, double deadline, const char *what)
{
    int done = 0;

    for (;;) {
        if (redisBufferWrite(c->ctx, &done) != REDIS_OK) {
            fail(c, RDS_EDOWN, "%s: %s", what, c->ctx->errstr);
            return -1;
        }
        if (done)
            return 0;
        if (wait_fd(c, POLLOUT, deadline, what) != 0)
            return -1;
    }
}

/* Nothing of a reply is buffered: every byte read is consumed and no
 * reply is begun. hiredis 0.14 leaves ridx at 0 (not -1) once it has
 * looked for a reply in a consumed buffer, with its first task's type
 * still unread (-1); a begun reply has read its type byte. */
static int between_replies(const redisReader *rd)
{
    return rd->len == rd->pos &&
           (rd->ridx == -1 || (rd->ridx == 0 && rd->rstack[0].type < 0));
}

/* One reply: 0 and *out, 1 when the deadline passed with nothing of a
 * reply buffered and quiet is set (a subscriber's idle wait), -1. */
static int read_reply(rds *c, double deadline, int quiet, const char *what,
                      redisReply **out)
{
    for (;;) {
        void *rep = NULL;
        redisReader *rd = c->ctx->reader;

        if (redisGetReplyFromReader(c->ctx, &rep) != REDIS_OK) {
            if (c->over)
                fail(c, RDS_EPROTO, "%s: reply over %zu bytes", what,
                     c->cfg.max_reply);
            else
                fail(c, RDS_EPROTO, "%s: %s", what, c->ctx->errstr);
            return -1;
        }
        if (rep) {
            c->taken = 0;
            *out = rep;
            return 0;
        }
        if (rd->len - rd->pos > c->cfg.max_reply) {
            fail(c, RDS_EPROTO, "%s: reply over %zu bytes", what,
                 c->cfg.max_reply);
            return -1;
        }
        if (quiet && between_replies(rd)) {
            /* between replies: the deadline only ends the wait */
            struct pollfd pfd = {.fd = c->ctx->fd, .events = POLLIN};
            double left = deadline - rds_monotonic();
            int n = poll(&pfd, 1, left > 0 ? (int)(left * 1000) + 1 : 0);
            if (n == 0)
                return 1;
            if (n < 0 && errno != EINTR) {
                fail(c, RDS_EDOWN, "%s: poll: %s", what, strerror(errno));
                return -1;
            }
            if (n < 0)
                continue;
        } else {
            if (quiet) {  /* a reply has begun: it gets a command's time */
                quiet = 0;
                deadline = rds_monotonic() + c->cfg.command_timeout;
            }
            if (wait_fd(c, POLLIN, deadline, what) != 0)
                return -1;
        }
        if (redisBufferRead(c->ctx) != REDIS_OK) {
            fail(c, RDS_EDOWN, "%s: %s", what, c->ctx->errstr);
            return -1;
        }
    }
}

/* An error reply: its first word in c->code, RDS_EDOWN for "not now",
 * RDS_EREPLY otherwise. Frees r. */
static void error_reply(rds *c, redisReply *r, const char *what)
{
    static const char *const later[] = {"LOADING", "MASTERDOWN", "BUSY",
                                        "TRYAGAIN", "CLUSTERDOWN"};
    size_t n = strcspn(r->str, " ");
    size_t i;
    rds_status st = RDS_EREPLY;

    snprintf(c->code, sizeof c->code, "%.*s", (int)n, r->str);
    for (i = 0; i < sizeof later / sizeof *later; i++)
        if (strcmp(c->code, later[i]) == 0)
            st = RDS_EDOWN;
    fail(c, st, "%s: %s", what, r->str);
    freeReplyObject(r);
}

/* A command on a connected c, no reconnect: the reply, or NULL. */
static redisReply *exchange(rds *c, double extra, int argc,
                            const char **argv, const size_t *lens)
{
    redisReply *r = NULL;
    char what[32];
    double deadline = rds_monotonic() + c->cfg.command_timeout + extra;

    c->call_timeout = c->cfg.command_timeout + extra;
    snprintf(what, sizeof what, "%.*s", (int)(lens ? lens[0] : strlen(argv[0])),
             argv[0]);
    if (c->pending) {
        fail(c, RDS_EPROTO, "%s: pipelined replies are unread", what);
        return NULL;
    }
    if (redisAppendCommandArgv(c->ctx, argc, argv, lens) !=
        REDIS_OK) {
        fail(c, RDS_ENOMEM, "%s: out of memory", what);
        drop(c);
        return NULL;
    }
    if (flush_out(c, deadline, what) != 0 ||
        read_reply(c, deadline, 0, what, &r) != 0) {
        drop(c);
        return NULL;
    }
    if (r->type == REDIS_REPLY_ERROR) {
        error_reply(c, r, what);
        return NULL;
    }
    ok(c);
    return r;
}

/* The password, read now: 0 and buf (NUL-terminated, a trailing newline
 * removed), or -1 with the reason in c. */
static int read_password(rds *c, char *buf, size_t size)
{
    int fd = open(c->cfg.password_file, O_RDONLY | O_CLOEXEC);
    ssize_t n = 0, got;

    if (fd < 0) {
        fail(c, RDS_ECONFIG, "password file %s: %s", c->cfg.password_file,
             strerror(errno));
        return -1;
    }
    while ((size_t)n < size &&
           (got = read(fd, buf + n, size - (size_t)n)) != 0) {
        if (got < 0 && errno == EINTR)
            continue;
        if (got < 0) {
            fail(c, RDS_ECONFIG, "password file %s: %s",
                 c->cfg.password_file, strerror(errno));
            close(fd);
            return -1;
        }
        n += got;
    }
    close(fd);
    if ((size_t)n == size) {
        fail(c, RDS_ECONFIG, "password file %s: longer than %zu bytes",
             c->cfg.password_file, size - 1);
        return -1;
    }
    while (n > 0 && (buf[n - 1] == '\n' || buf[n - 1] == '\r'))
        n--;
    buf[n] = 0;
    if (n == 0) {
        fail(c, RDS_ECONFIG, "password file %s is empty",
             c->cfg.password_file);
        return -1;
    }
    return 0;
}

static void wipe(char *p, size_t n)
{
    volatile char *v = p;
    while (n--)
        *v++ = 0;
}

static int handshake(rds *c)
{
    redisReply *r;

    if (c->cfg.password_file[0]) {
        char pw[PASSWORD_MAX + 1];
        const char *argv[2] = {"AUTH", pw};
        if (read_password(c, pw, sizeof pw) != 0)
            return -1;
        r = exchange(c, 0, 2, argv, NULL);
        wipe(pw, sizeof pw);
        if (!r)
            return -1;
        freeReplyObject(r);
    }
    if (c->cfg.db != 0) {
        char db[16];
        const char *argv[2] = {"SELECT", db};
        snprintf(db, sizeof db, "%d", c->cfg.db);
        if (!(r = exchange(c, 0, 2, argv, NULL)))
            return -1;
        freeReplyObject(r);
    }
    if (c->on_connect && c->on_connect(c, c->on_connect_ctx) != 0) {
        if (c->status == RDS_OK)
            fail(c, RDS_EDOWN, "the connection's set-up failed");
        return -1;
    }
    return 0;
}

/* 1 when the server has closed c's idle connection (a restart, its
 * timeout): the socket reads end-of-file or an error, with nothing
 * pending. A peek, non-blocking: data waiting (a subscriber's messages,
 * a blocked command's reply) or nothing yet means the connection stands. */
static int closed_by_server(const rds *c)
{
    char b;
    ssize_t n;

    if (c->pending > 0 || c->ctx->reader->len > c->ctx->reader->pos)
        return 0;           /* replies owed, or read and not yet parsed */
    n = recv(c->ctx->fd, &b, 1, MSG_PEEK | MSG_DONTWAIT);
    return n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR);
}

int rds_connect(rds *c)
{
    struct timeval tv;
    redisContext *ctx;
    double now;
    int fl;

    if (c->ctx)
        return 0;
    now = rds_monotonic();
    if (now < c->next_try) {
        snprintf(c->err, sizeof c->err, "%.440s (next attempt in %.2f s)",
                 c->down, c->next_try - now);
        c->status = RDS_EDOWN;
        return -1;
    }
    tv.tv_sec = (time_t)c->cfg.connect_timeout;
    tv.tv_usec = (suseconds_t)((c->cfg.connect_timeout - (double)tv.tv_sec) *
                               1e6);
    ctx = redisConnectWithTimeout(c->cfg.host, c->cfg.port, tv);
    if (!ctx || ctx->err) {
        fail(c, ctx ? RDS_EDOWN : RDS_ENOMEM, "%s",
             ctx ? ctx->errstr : "out of memory");
        if (ctx)
            redisFree(ctx);
        backoff(c);
        return -1;
    }
    fl = fcntl(ctx->fd, F_GETFL);
    if (fl < 0 || fcntl(ctx->fd, F_SETFL, fl | O_NONBLOCK) < 0) {
        fail(c, RDS_EDOWN, "fcntl: %s", strerror(errno));
        redisFree(ctx);
        backoff(c);
        return -1;
    }
    ctx->flags &= ~REDIS_BLOCK;
    (void)redisEnableKeepAlive(ctx);
    c->base = *ctx->reader->fn;
    c->fn = c->base;
    c->fn.createString = mk_string;
    c->fn.createArray = mk_array;
    c->fn.createInteger = mk_integer;
    c->fn.createNil = mk_nil;
    ctx->reader->fn = &c->fn;
    ctx->reader->privdata = c;
    c->ctx = ctx;
    c->taken = 0;
    c->over = 0;
    if (handshake(c) != 0) {
        drop(c);
        if (c->status == RDS_EDOWN)
            backoff(c);
        else  /* a wrong password or file: not worth a fast retry */
            c->next_try = rds_monotonic() + BACKOFF_MAX;
        return -1;
    }
    c->backoff = BACKOFF_MIN;
    c->next_try = 0;
    ok(c);
    return 0;
}

/* ------------------------------------------------------------ public */

rds *rds_new(const rds_config *cfg)
{
    rds *c = calloc(1, sizeof *c);

    if (!c)
        return NULL;
    c->cfg = *cfg;
    if (c->cfg.max_reply < 4096)
        c->cfg.max_reply = 4096;
    snprintf(c->where, sizeof c->where,
             strchr(cfg->host, ':') ? "[%s]:%d" : "%s:%d", cfg->host,
             cfg->port);
    c->backoff = BACKOFF_MIN;
    c->seed = (unsigned)((uintptr_t)c ^ (uintptr_t)time(NULL));
    return c;
}

void rds_free(rds *c)
{
    if (!c)
        return;
    rds_disconnect(c);
    free(c);
}

void rds_set_on_connect(rds *c, int (*fn)(rds *c, void *ctx), void *ctx)
{
    c->on_connect = fn;
    c->on_connect_ctx = ctx;
}

void rds_retry_now(rds *c)
{
    if (c->ctx)
        return;
    c->next_try = 0;
    c->backoff = BACKOFF_MIN;
}

int rds_connected(const rds *c) { return c->ctx != NULL; }
rds_status rds_status_of(const rds *c) { return c->status; }
const char *rds_errmsg(const rds *c) { return c->err; }
const char *rds_where(const rds *c) { return c->where; }

int rds_error_is(const rds *c, const char *code)
{
    return c->status == RDS_EREPLY || c->status == RDS_EDOWN
               ? strcmp(c->code, code) == 0 : 0;
}

/* rds_connect for a command: a connection the server closed while it
 * sat idle (its restart) is dropped and connected again at once, so the
 * command does not fail on a dead socket (a replica's /readyz said 200
 * with Redis back and its next submission got 503 on another pooled
 * connection: test_replicas). rds_wait does not: a subscriber learns of
 * the drop (RDS_EDOWN) and of what it may have missed. */
static int connect_for_command(rds *c)
{
    if (c->ctx && closed_by_server(c))
        drop(c);
    return rds_connect(c);
}

redisReply *rds_cmd_block(rds *c, double block, int argc,
                          const char **argv, const size_t *lens)
{
    if (argc < 1) {
        fail(c, RDS_ECONFIG, "no command");
        return NULL;
    }
    if (connect_for_command(c) != 0)
        return NULL;
    return exchange(c, block, argc, argv, lens);
}

redisReply *rds_cmd(rds *c, int argc, const char **argv,
                    const size_t *lens)
{
    return rds_cmd_block(c, 0, argc, argv, lens);
}

redisReply *rds_cmdl(rds *c, const char *arg0, ...)
{
    const char *argv[ARGS_MAX];
    int argc = 0;
    va_list ap;

    va_start(ap, arg0);
    for (const char *a = arg0; a; a = va_arg(ap, const char *)) {
        if (argc == ARGS_MAX) {
            va_end(ap);
            fail(c, RDS_ECONFIG, "%s: more than %d arguments", arg0,
                 ARGS_MAX);
            return NULL;
        }
        argv[argc++] = a;
    }
    va_end(ap);
    return rds_cmd(c, argc, argv, NULL);
}

int rds_pipe_add(rds *c, int argc, const char **argv,
                 const size_t *lens)
{
    if (connect_for_command(c) != 0)
        return -1;
    if (redisAppendCommandArgv(c->ctx, argc, argv, lens) !=
        REDIS_OK) {
        fail(c, RDS_ENOMEM, "pipeline: out of memory");
        drop(c);
        return -1;
    }
    c->pending++;
    return 0;
}

redisReply *rds_pipe_read(rds *c)
{
    redisReply *r = NULL;
    double deadline = rds_monotonic() + c->cfg.command_timeout;

    c->call_timeout = c->cfg.command_timeout;
    if (!c->ctx || c->pending == 0) {
        if (c->status == RDS_OK)
            fail(c, RDS_EPROTO, "pipeline: no reply pending");
        return NULL;
    }
    if (flush_out(c, deadline, "pipeline") != 0 ||
        read_reply(c, deadline, 0, "pipeline", &r) != 0) {
        drop(c);
        return NULL;
    }
    c->pending--;
    if (r->type == REDIS_REPLY_ERROR) {
        error_reply(c, r, "pipeline");
        return NULL;
    }
    ok(c);
    return r;
}

int rds_wait(rds *c, double timeout, redisReply **out)
{
    int rc;

    *out = NULL;
    if (rds_connect(c) != 0)
        return -1;
    c->call_timeout = c->cfg.command_timeout;
    rc = read_reply(c, rds_monotonic() + timeout, 1, "waiting", out);
    if (rc < 0)
        drop(c);
    return rc;
}

/* The scripts' SHAs are shared by every connection (a script is a static
 * of its user): one lock around reading and writing them. */
static pthread_mutex_t script_mu = PTHREAD_MUTEX_INITIALIZER;

static int script_load(rds *c, rds_script *s, char sha[41])
{
    const char *argv[3] = {"SCRIPT", "LOAD", s->src};
    redisReply *r = rds_cmd(c, 3, argv, NULL);

    if (!r)
        return -1;
    if (r->type != REDIS_REPLY_STRING || r->len != 40) {
        freeReplyObject(r);
        fail(c, RDS_EPROTO, "SCRIPT LOAD: unexpected reply");
        return -1;
    }
    memcpy(sha, r->str, 40);
    sha[40] = 0;
    freeReplyObject(r);
    pthread_mutex_lock(&script_mu);
    memcpy(s->sha, sha, 41);
    pthread_mutex_unlock(&script_mu);
    return 0;
}

redisReply *rds_eval(rds *c, rds_script *s, int numkeys, int argc,
                     const char **argv, const size_t *lens)
{
    const char *av[ARGS_MAX + 3];
    size_t lv[ARGS_MAX + 3];
    char sha[41], nk[16];
    redisReply *r;
    int i, tries;

    if (argc > ARGS_MAX || numkeys > argc) {
        fail(c, RDS_ECONFIG, "EVALSHA: %d arguments", argc);
        return NULL;
    }
    pthread_mutex_lock(&script_mu);
    memcpy(sha, s->sha, 41);
    pthread_mutex_unlock(&script_mu);
    if (!sha[0] && script_load(c, s, sha) != 0)
        return NULL;
    snprintf(nk, sizeof nk, "%d", numkeys);
    av[0] = "EVALSHA";
    av[1] = sha;
    av[2] = nk;
    lv[0] = 7;
    lv[1] = 40;
    lv[2] = strlen(nk);
    for (i = 0; i < argc; i++) {
        av[i + 3] = argv[i];
        lv[i + 3] = lens ? lens[i] : strlen(argv[i]);
    }
    for (tries = 0;; tries++) {
        r = rds_cmd(c, argc + 3, av, lv);
        if (r || tries > 0 || !rds_error_is(c, "NOSCRIPT"))
            return r;
        if (script_load(c, s, sha) != 0)   /* a restarted server */
            return NULL;
    }
}

void rds_reply_free(redisReply *r)
{
    if (r)
        freeReplyObject(r);
}

/* ------------------------------------------------------- reply helpers */

int rds_reply_is(rds *c, const redisReply *r, int type, const char *what)
{
    if (r && r->type == type)
        return 1;
    if (c)
        fail(c, RDS_EPROTO, "%s: unexpected reply (type %d)", what,
             r ? r->type : 0);
    return 0;
}

int rds_reply_ll(const redisReply *r, long long *v)
{
    char buf[32], *end;
    long long x;

    if (!r)
        return -1;
    if (r->type == REDIS_REPLY_INTEGER) {
        *v = r->integer;
        return 0;
    }
    if (r->type != REDIS_REPLY_STRING || r->len == 0 ||
        r->len >= sizeof buf)
        return -1;
    memcpy(buf, r->str, r->len);
    buf[r->len] = 0;
    errno = 0;
    x = strtoll(buf, &end, 10);
    if (errno || *end)
        return -1;
    *v = x;
    return 0;
}

const redisReply *rds_reply_field(const redisReply *r, const char *name)
{
    size_t i, n = strlen(name);

    if (!r || r->type != REDIS_REPLY_ARRAY)
        return NULL;
    for (i = 0; i + 1 < r->elements; i += 2) {
        const redisReply *k = r->element[i];
        if (k->type == REDIS_REPLY_STRING && k->len == n &&
            memcmp(k->str, name, n) == 0)
            return r->element[i + 1];
    }
    return NULL;
}
