/* SPDX-License-Identifier: MIT */
/*
 * srvlib.h - what the daemon's integration tests share (test_server*.c):
 * starting and stopping real mcfd processes on loopback, HTTP exchanges
 * with libcurl, the JSON and problem checks, the job and metrics polls, the
 * group fixtures (one shared daemon, g_main, per test binary) and the
 * clean-up of what a failing test leaves (locked directories, small
 * mounts, stray daemons). Each test file holds one concern's tests.
 */
#ifndef TESTS_SRVLIB_H
#define TESTS_SRVLIB_H

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <linux/fs.h>
#include <sys/time.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <dirent.h>
#include <time.h>
#include <unistd.h>

#include <curl/curl.h>

#include "testlib.h"
#include "../api/api.h"

#define SRV_ID_BUF 33   /* a job ID: 32 hex digits and the NUL */
#define SRV_FOLLOWERS 64 /* event streams one job may have (srv.h) */

/* ------------------------------------------------------------ processes */

typedef struct {
    pid_t pid;
    int port;
    char log[512];
    char spool[512];
} daemon_t;

/* ------------------------------------------------------------ HTTP */

typedef struct {
    long code;
    api_buf body, hdr;
    double t_first, t_last;   /* arrival of the first and last body bytes */
    int chunks;
    const char *watch;        /* http_watch: set `seen` once the body has it */
    int seen;                 /* read with watch_seen from another thread */
    char err[CURL_ERROR_SIZE];
} resp_t;

typedef struct {
    const char *mesh;          /* test mesh (or absolute path), multipart field */
    const char *params;        /* multipart field params (JSON) */
    const char *target;        /* test mesh (or absolute path) */
    const char *field, *value; /* one plain form field */
    const void *raw;           /* raw body instead of multipart */
    size_t raw_len;
} upload_t;

/* A request in its own thread (pthread_create(..., live_client, &lc)),
 * watched with watch_seen; the sphere as the multipart mesh with `mesh`. */
typedef struct {
    const daemon_t *d;
    const char *method, *path, *watch;
    int mesh;
    resp_t r;
} live_client_t;

extern char g_tmp[256];
extern char g_bin[512];
/* Every daemon started, so that a test failing half-way (cmocka jumps out
 * of it) leaves no process behind: the group teardown kills the rest. */
extern pid_t g_started[64];
extern int g_nstarted;
extern daemon_t g_main;   /* shared by the tests that need no special flags */

void sleep_ms(int ms);

void print_log_tail(const daemon_t *d);

/* Starts mcfd with the given extra flags on spool <tmp>/<name>. Returns 0
 * and fills d, or -1 (after printing why). */
int start_daemon(daemon_t *d, const char *name, const char *spool,
                 const char *const *extra);

/* Waits for the process to exit; 1 and *status when it did in time. */
int wait_exit(pid_t pid, double seconds, int *status);

/* SIGKILL its process group and reap (teardown, or a test that already
 * failed). */
void reap(daemon_t *d);

/* SIGTERM; the daemon must exit 0 within the bound. */
void stop_daemon(daemon_t *d);

void rm_rf(const char *path);

void resp_init(resp_t *r);

void resp_free(resp_t *r);

size_t on_body(char *p, size_t s, size_t n, void *ud);

size_t on_hdr(char *p, size_t s, size_t n, void *ud);

/* A test mesh by name (tl_need_mesh: the test is skipped when it is not
 * available), or an absolute path as it is. */
void mesh_path(char *buf, size_t size, const char *name);

/* One request; returns the HTTP status, 0 on a transport error. With
 * watch, r->seen turns 1 (atomically: another thread may wait for it with
 * watch_seen) as soon as the body received so far contains that string;
 * the headers are complete by then. */
long http_watch(const daemon_t *d, const char *method, const char *path,
                const char *const *headers, const upload_t *up,
                resp_t *r, const char *watch);

long http(const daemon_t *d, const char *method, const char *path,
          const char *const *headers, const upload_t *up, resp_t *r);

/* Waits until the body that another thread is receiving into r (with
 * http_watch) holds the watched string; fails after `seconds`. */
void watch_seen(const daemon_t *d, resp_t *r, double seconds,
                const char *what);

void *live_client(void *arg);

/* The last value of a response header (the final response's), or NULL. */
const char *header(const resp_t *r, const char *name, char *out,
                   size_t size);

void expect_status(const daemon_t *d, const resp_t *r, long want,
                   const char *what);

cJSON *body_json(const resp_t *r, const char *what);

double jnum(const cJSON *o, const char *path);

const char *jstr(const cJSON *o, const char *key);

/* An RFC 9457 problem with the given status, code and a detail holding
 * `needle` (when given). */
void expect_problem(const daemon_t *d, const resp_t *r, long status,
                    const char *code, const char *needle,
                    const char *what);

mcf_mesh *decode_body(const resp_t *r, api_format *fmt);

/* Polls GET /v1/jobs/ID until the status is `want` (or, with want NULL,
 * any final status); returns the job JSON. */
cJSON *poll_job(const daemon_t *d, const char *id, const char *want,
                double seconds);

/* Waits until the job runs and has done at least one step. */
void wait_running(const daemon_t *d, const char *id);

/* POST /v1/jobs; returns the new ID (static buffer per call site). */
void submit(const daemon_t *d, const char *query, char *id);

/* The value of a Prometheus sample line "name{labels} value": 1 and *v
 * when the series is there, else 0. */
int metric_find(const char *text, const char *series, double *v);

/* metric_find, or the test fails: a series that is not there (a renamed
 * metric, a label that changed, a counter that never counted) must not
 * pass for 0. */
double metric(const char *text, const char *series);

/* Polls /metrics until the gauge has the value (bounded). */
void wait_gauge(const daemon_t *d, const char *name, double want);

/* ------------------------------------------------------------ fixtures */

int group_setup(void **state);

/* The shared daemon must also stop cleanly (under ASan: without leaks,
 * which would turn its exit status non-zero). */
int group_teardown(void **state);

/* After every test: a daemon of its own that a failing test left running
 * is killed with its process group (testlib also does so at exit and on
 * SIGINT, SIGTERM, SIGHUP, SIGQUIT and SIGABRT). */
int kill_strays(void **state);

/* How many times needle occurs in hay. */
int count_of(const char *hay, const char *needle);

/* Directories made unwritable by a test (root: the immutable flag, which
 * root's writes respect; others: mode 0555), restored by unlock_dirs. */
extern char g_locked[4][800];
extern int g_nlocked;

int set_writable(const char *path, int writable);

void unlock_dirs(void);

/* A connection from source address `from` (127.0.0.x) to d, the request
 * `req` sent; returns the socket. */
int connect_from(const daemon_t *d, const char *from, const char *req);

/* A size field of a process's status ("VmRSS", "VmHWM": its peak) in
 * KiB, -1 when /proc cannot say. */
long status_kib(pid_t pid, const char *field);

/* ------------------------------------------------------------ a full spool */

/* Small filesystems mounted by a test (tmpfs with size=), unmounted by
 * unmount_all at the end of the test or the group. */
extern char g_mounted[2][800];
extern int g_nmounted;

void unmount_all(void);

/* POSTs a file of tests/data as the raw body of path. */
long post_file(const daemon_t *d, const char *path, const char *name,
               resp_t *r);

/* Polls /metrics until the gauge has the value, at most `seconds`. */
void wait_gauge_within(const daemon_t *d, const char *name, double want,
                       double seconds, const char *what);

#endif /* TESTS_SRVLIB_H */
