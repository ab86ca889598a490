/* SPDX-License-Identifier: MIT */
/*
 * bench_server.c - `make bench`, the daemon's part (issue 4, Performance):
 * mcfd over HTTP on loopback, driven with libcurl, against `mcf smooth`,
 * measured in the same run.
 *
 *   1. Service overhead. `POST /smooth?scheme=desbrun2&iterations=10`
 *      (multipart field `mesh`, as `curl -F mesh=@FILE` sends it; a new
 *      connection per request) end to end, against `mcf smooth IN OUT
 *      --scheme desbrun2 --iterations 10` (fork, exec, read, smooth, write,
 *      exit) on the same file; default dt. bunny.drc and armadillo.obj
 *      (the goal), and sphere_cgal.obj (a small job, for the fixed costs),
 *      median of --reps runs each after one warm-up run of each, the two
 *      interleaved (alternating which goes first) so a load change on the
 *      shared machine hits both alike. mcf runs with the BLAS/OpenMP
 *      thread variables mcfd gives itself (1 unless set). The job's own
 *      split (decode, flow, encode, from GET /v1/jobs/ID/metrics) is shown
 *      too; the rest is HTTP, the spool (fsync'ed) and the queue.
 *      Goal: /smooth <= 1.15 x mcf + 20 ms. Sanity: the response body
 *      and mcf's output file hold the same bytes.
 *   2. Throughput of small jobs: sphere_cgal.obj (812 vertices), the same
 *      10 desbrun2 steps, N = 1, 2, 8, 32 concurrent clients (one thread and
 *      one curl handle each, connections kept alive) for --duration seconds
 *      each, against mcfd --workers 1 and 2 with --queue 64 (no client can
 *      be refused; both daemons up at once, the runs alternating between
 *      them so both meet the same load). Reported: jobs/s (200s over the
 *      wall time until the last client finished), p50/p99 latency of the
 *      200s, 503s. Then 32
 *      clients against --queue 2: refused clients honour Retry-After
 *      (sleep that long, bounded by the deadline) and retry.
 *      Sanity: no transport errors, no 503 with the long queue, every 503
 *      carries Retry-After, each client's first result decodes to 812
 *      vertices, and mcfd's /metrics counts the same 200s and 503s.
 *      The CPU seconds of the clients (this process), of mcfd and of
 *      everything else on the machine during each run are shown: all share
 *      the same cores, so "others" says how much of them a run really had.
 *
 * Every transfer has a curl timeout, every loop a deadline, every wait
 * for a process a bound after which it is killed. Exit status 1 only when
 * a sanity check fails or something cannot run; a goal marked FAIL is a
 * result, not an error.
 */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <dirent.h>
#include <time.h>
#include <unistd.h>

#include <cjson/cJSON.h>
#include <curl/curl.h>

#include "api.h"
#include "bench_common.h"
#include "mcf.h"

#define MAXREPS 32
#define MAXCLIENTS 32
#define MAXLAT 20000 /* latencies kept per client and run (bounds a run) */

/* The flow of every request, as a query string and as mcf flags. */
#define QUERY "scheme=desbrun2&iterations=10"
static const char *const MCF_FLAGS[] = {"--scheme", "desbrun2", "--iterations",
                                        "10", "--quiet", NULL};

/* Goal of issue 4: /smooth <= GOAL_FACTOR x mcf + GOAL_ADD seconds. */
#define GOAL_FACTOR 1.15
#define GOAL_ADD 0.020

static const char *g_mcf, *g_mcfd, *g_meshes;
static int g_reps = 5;
static double g_duration = 5.0;
static char g_tmp[256];

static void sleep_s(double s)
{
    struct timespec ts;
    if (s <= 0)
        return;
    ts.tv_sec = (time_t)s;
    ts.tv_nsec = (long)((s - (double)ts.tv_sec) * 1e9);
    nanosleep(&ts, NULL);
}

static void *xmalloc(size_t n)
{
    void *p = malloc(n ? n : 1);
    if (!p) {
        fprintf(stderr, "bench_server: out of memory\n");
        exit(1);
    }
    return p;
}

/* Removes a file or a directory tree (the daemons' spools, the temp dir). */
static void rm_rf(const char *path)
{
    struct stat st;
    if (lstat(path, &st) != 0)
        return;
    if (S_ISDIR(st.st_mode)) {
        DIR *dir = opendir(path);
        struct dirent *e;
        char sub[1024];
        while (dir && (e = readdir(dir)) != NULL) {
            if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
                continue;
            snprintf(sub, sizeof sub, "%s/%s", path, e->d_name);
            rm_rf(sub);
        }
        if (dir)
            closedir(dir);
        rmdir(path);
    } else {
        unlink(path);
    }
}

/* The whole mesh file dir/name; exits when it cannot be read. */
static void load(const char *name, char **buf, size_t *len)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", g_meshes, name);
    if (bench_read_file(path, buf, len) != 0) {
        fprintf(stderr, "bench_server: cannot read %s: %s\n", path, strerror(errno));
        exit(1);
    }
}

/* Waits for pid for at most `seconds`; 1 and *status when it exited. */
static int wait_exit(pid_t pid, double seconds, int *status)
{
    double end = mcf_now() + seconds;
    do {
        pid_t r = waitpid(pid, status, WNOHANG);
        if (r == pid)
            return 1;
        if (r < 0)
            return 0;
        sleep_s(2e-4); /* 0.2 ms: the resolution of an mcf wall time */
    } while (mcf_now() < end);
    return 0;
}

/* ------------------------------------------------------------ the daemon */

typedef struct {
    pid_t pid;
    int port;
    char spool[512], log[512];
} daemon_t;

static daemon_t *g_live[2]; /* killed at exit if still running */

static void print_log_tail(const daemon_t *d)
{
    char *buf = NULL;
    size_t len = 0;
    if (bench_read_file(d->log, &buf, &len) == 0) {
        fprintf(stderr, "---- tail of the mcfd log\n%s\n----\n",
                len > 3000 ? buf + len - 3000 : buf);
        free(buf);
    }
}

static void cleanup(void)
{
    for (int i = 0; i < 2; i++)
        if (g_live[i] && g_live[i]->pid > 0) {
            kill(g_live[i]->pid, SIGKILL);
            waitpid(g_live[i]->pid, NULL, 0);
            g_live[i]->pid = 0;
        }
    if (g_tmp[0])
        rm_rf(g_tmp);
}

/* Starts mcfd --workers W --queue Q on loopback, a fresh spool under the
 * temp dir and its stderr (JSON log) in a file; reads the port from the
 * "mcfd listening on http://127.0.0.1:PORT" line. Exits on failure. */
static void start_daemon(daemon_t *d, const char *name, int workers, int queue)
{
    char w[16], q[16], line[256];
    const char *argv[16];
    int pfd[2], n = 0;
    size_t got = 0;
    double end;

    memset(d, 0, sizeof *d);
    snprintf(d->spool, sizeof d->spool, "%s/%s", g_tmp, name);
    snprintf(d->log, sizeof d->log, "%s/%s.log", g_tmp, name);
    snprintf(w, sizeof w, "%d", workers);
    snprintf(q, sizeof q, "%d", queue);
    argv[n++] = g_mcfd;
    argv[n++] = "--bind";
    argv[n++] = "127.0.0.1";
    argv[n++] = "--port";
    argv[n++] = "0";
    argv[n++] = "--spool";
    argv[n++] = d->spool;
    argv[n++] = "--workers";
    argv[n++] = w;
    argv[n++] = "--queue";
    argv[n++] = q;
    argv[n] = NULL;
    if (pipe(pfd) != 0 || (d->pid = fork()) < 0) {
        perror("bench_server: pipe/fork");
        exit(1);
    }
    if (d->pid == 0) {
        int lf = open(d->log, O_WRONLY | O_CREAT | O_APPEND, 0644);
        dup2(pfd[1], 1);
        if (lf >= 0)
            dup2(lf, 2);
        close(pfd[0]);
        close(pfd[1]);
        execv(g_mcfd, (char *const *)(uintptr_t)argv);
        _exit(127);
    }
    g_live[g_live[0] ? 1 : 0] = d; /* callers run at most two at once */
    close(pfd[1]);
    line[0] = 0;
    end = mcf_now() + 20;
    while (got < sizeof line - 1 && !memchr(line, '\n', got)) {
        struct pollfd p = {pfd[0], POLLIN, 0};
        ssize_t r;
        int left = (int)((end - mcf_now()) * 1000);
        if (left <= 0 || poll(&p, 1, left) <= 0)
            break;
        r = read(pfd[0], line + got, sizeof line - 1 - got);
        if (r <= 0)
            break;
        got += (size_t)r;
        line[got] = 0;
    }
    close(pfd[0]);
    if (sscanf(line, "mcfd listening on http://127.0.0.1:%d", &d->port) != 1) {
        fprintf(stderr, "bench_server: %s did not start (stdout: \"%s\")\n", g_mcfd, line);
        print_log_tail(d);
        exit(1);
    }
}

/* SIGTERM; mcfd must exit 0 within 30 s (it has no job running here).
 * The spool is removed. Returns 1 when it did. */
static int stop_daemon(daemon_t *d)
{
    int st = 0, ok;
    kill(d->pid, SIGTERM);
    ok = wait_exit(d->pid, 30, &st) && WIFEXITED(st) && WEXITSTATUS(st) == 0;
    if (!ok) {
        fprintf(stderr, "bench_server: mcfd did not exit 0 after SIGTERM (0x%x)\n", st);
        print_log_tail(d);
        kill(d->pid, SIGKILL);
        waitpid(d->pid, NULL, 0);
    }
    d->pid = 0;
    for (int i = 0; i < 2; i++)
        if (g_live[i] == d)
            g_live[i] = NULL;
    rm_rf(d->spool);
    return ok;
}

/* ------------------------------------------------------------ HTTP */

typedef struct {
    long code;           /* 0: transport error (err holds why) */
    api_buf body;        /* kept only when keep is set */
    size_t bytes;        /* body bytes received */
    int keep;
    char err[CURL_ERROR_SIZE];
    char job[40];        /* X-Job-Id */
    double retry_after;  /* Retry-After in seconds; -1 when absent */
} reply_t;

static size_t on_body(char *p, size_t s, size_t n, void *ud)
{
    reply_t *r = ud;
    r->bytes += s * n;
    if (r->keep)
        return api_buf_append(&r->body, p, s * n) == MCF_OK ? s * n : 0;
    return s * n;
}

/* One request on handle c (its connection is reused when alive). With a
 * mesh: POST multipart (field `mesh`, file name `fname`, from memory);
 * without: GET. r->body is reset first. Returns the status, 0 on a
 * transport error. */
static long request(CURL *c, int port, const char *path, const char *mesh,
                    size_t len, const char *fname, long timeout, reply_t *r)
{
    char url[512];
    curl_mime *mime = NULL;
    struct curl_header *h;

    r->code = 0;
    r->bytes = 0;
    r->err[0] = 0;
    r->job[0] = 0;
    r->retry_after = -1;
    r->body.len = 0;
    if (r->body.data)
        r->body.data[0] = 0;
    snprintf(url, sizeof url, "http://127.0.0.1:%d%s", port, path);
    curl_easy_setopt(c, CURLOPT_URL, url);
    curl_easy_setopt(c, CURLOPT_NOSIGNAL, 1L);
    curl_easy_setopt(c, CURLOPT_CONNECTTIMEOUT, 5L);
    curl_easy_setopt(c, CURLOPT_TIMEOUT, timeout);
    curl_easy_setopt(c, CURLOPT_WRITEFUNCTION, on_body);
    curl_easy_setopt(c, CURLOPT_WRITEDATA, r);
    curl_easy_setopt(c, CURLOPT_ERRORBUFFER, r->err);
    if (mesh) {
        curl_mimepart *part;
        mime = curl_mime_init(c);
        part = curl_mime_addpart(mime);
        curl_mime_name(part, "mesh");
        curl_mime_filename(part, fname);
        curl_mime_data(part, mesh, len);
        curl_easy_setopt(c, CURLOPT_MIMEPOST, mime);
    } else {
        curl_easy_setopt(c, CURLOPT_HTTPGET, 1L);
    }
    if (curl_easy_perform(c) == CURLE_OK)
        curl_easy_getinfo(c, CURLINFO_RESPONSE_CODE, &r->code);
    if (r->code &&
        curl_easy_header(c, "X-Job-Id", 0, CURLH_HEADER, -1, &h) == CURLHE_OK)
        snprintf(r->job, sizeof r->job, "%s", h->value);
    if (r->code &&
        curl_easy_header(c, "Retry-After", 0, CURLH_HEADER, -1, &h) == CURLHE_OK)
        r->retry_after = strtod(h->value, NULL);
    curl_easy_setopt(c, CURLOPT_MIMEPOST, NULL);
    curl_mime_free(mime);
    return r->code;
}

static CURL *xcurl(void)
{
    CURL *c = curl_easy_init();
    if (!c) {
        fprintf(stderr, "bench_server: curl_easy_init failed\n");
        exit(1);
    }
    return c;
}

/* The value of one series in Prometheus text (0 when absent). */
static double prom(const char *text, const char *series)
{
    const char *p = text;
    size_t n = strlen(series);
    while (p && *p) {
        if (strncmp(p, series, n) == 0 && p[n] == ' ')
            return strtod(p + n + 1, NULL);
        p = strchr(p, '\n');
        if (p)
            p++;
    }
    return 0;
}

static double jnum(const cJSON *o, const char *a, const char *b)
{
    const cJSON *x = cJSON_GetObjectItemCaseSensitive(o, a);
    x = cJSON_GetObjectItemCaseSensitive(x, b);
    return cJSON_IsNumber(x) ? x->valuedouble : -1;
}

/* CPU seconds (user + system) so far of this process (all its threads). */
static double self_cpu(void)
{
    struct rusage u;
    if (getrusage(RUSAGE_SELF, &u) != 0)
        return 0;
    return (double)u.ru_utime.tv_sec + 1e-6 * (double)u.ru_utime.tv_usec +
           (double)u.ru_stime.tv_sec + 1e-6 * (double)u.ru_stime.tv_usec;
}

/* Busy CPU seconds of the whole machine so far, all CPUs (/proc/stat:
 * user, nice, system, irq, softirq, steal; 0 when it cannot be read). */
static double machine_cpu(void)
{
    unsigned long long v[8] = {0};
    FILE *f = fopen("/proc/stat", "r");
    int n = f ? fscanf(f, "cpu %llu %llu %llu %llu %llu %llu %llu %llu", &v[0],
                       &v[1], &v[2], &v[3], &v[4], &v[5], &v[6], &v[7]) : 0;
    if (f)
        fclose(f);
    if (n != 8)
        return 0;
    /* v[3] idle and v[4] iowait are not busy */
    return (double)(v[0] + v[1] + v[2] + v[5] + v[6] + v[7]) /
           (double)sysconf(_SC_CLK_TCK);
}

/* CPU seconds (user + system) so far of process pid, from /proc (0 when
 * it cannot be read). */
static double proc_cpu(pid_t pid)
{
    char path[64], line[1024], *p;
    unsigned long ut = 0, st = 0;
    FILE *f;

    snprintf(path, sizeof path, "/proc/%ld/stat", (long)pid);
    f = fopen(path, "r");
    if (!f)
        return 0;
    p = fgets(line, sizeof line, f) ? strrchr(line, ')') : NULL;
    fclose(f);
    /* after "pid (comm)": state is field 3, utime 14, stime 15 */
    if (!p || sscanf(p + 1, " %*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %lu %lu",
                     &ut, &st) != 2)
        return 0;
    return (double)(ut + st) / (double)sysconf(_SC_CLK_TCK);
}

/* ------------------------------------------------------------ 1. overhead */

/* One `mcf smooth in out FLAGS`: wall time from fork to exit. */
static double run_mcf(const char *in, const char *out, const char *errlog)
{
    static const char *const vars[] = {"OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS",
                                       "OMP_THREAD_LIMIT", "GOTO_NUM_THREADS",
                                       "MKL_NUM_THREADS"};
    const char *argv[16];
    int n = 0, st = 0;
    double t0 = mcf_now(), t;
    pid_t pid;

    argv[n++] = g_mcf;
    argv[n++] = "smooth";
    argv[n++] = in;
    argv[n++] = out;
    for (int i = 0; MCF_FLAGS[i]; i++)
        argv[n++] = MCF_FLAGS[i];
    argv[n] = NULL;
    pid = fork();
    if (pid < 0) {
        perror("bench_server: fork");
        exit(1);
    }
    if (pid == 0) {
        int fd = open(errlog, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        /* the thread counts mcfd gives itself (server/main.c) */
        for (size_t i = 0; i < sizeof vars / sizeof vars[0]; i++)
            setenv(vars[i], "1", 0);
        if (fd >= 0) {
            dup2(fd, 1);
            dup2(fd, 2);
        }
        execv(g_mcf, (char *const *)(uintptr_t)argv);
        _exit(127);
    }
    if (!wait_exit(pid, 600, &st) || !WIFEXITED(st) || WEXITSTATUS(st) != 0) {
        char *buf = NULL;
        size_t len = 0;
        kill(pid, SIGKILL);
        waitpid(pid, NULL, 0);
        fprintf(stderr, "bench_server: %s smooth %s failed (status 0x%x)\n", g_mcf, in, st);
        if (bench_read_file(errlog, &buf, &len) == 0)
            fprintf(stderr, "%s\n", buf);
        free(buf);
        exit(1);
    }
    t = mcf_now() - t0;
    return t;
}

typedef struct {
    const char *mesh;
    int nv;
    double mcf, srv;                      /* medians, seconds */
    double decode, flow, encode, job;     /* the job's own split, medians */
    int same_bytes;
    double rel;                           /* position difference if not */
} overhead_row;

/* POST /smooth with a fresh handle (a new connection, like `curl -F`);
 * keeps the body; exits on anything but 200. Returns the wall time. */
static double post_once(int port, const char *mesh, size_t len,
                        const char *fname, reply_t *r, const daemon_t *d)
{
    CURL *c = xcurl();
    double t0 = mcf_now(), t;
    request(c, port, "/smooth?" QUERY, mesh, len, fname, 600, r);
    t = mcf_now() - t0;
    curl_easy_cleanup(c);
    if (r->code != 200) {
        fprintf(stderr, "bench_server: POST /smooth %s: HTTP %ld (%s) %.500s\n",
                fname, r->code, r->err, r->body.data ? r->body.data : "");
        print_log_tail(d);
        exit(1);
    }
    return t;
}

/* The job's decode, flow, encode and total seconds (-1 when missing). */
static void job_split(int port, const char *id, double out[4])
{
    char path[128];
    reply_t r = {.keep = 1};
    CURL *c = xcurl();
    cJSON *j;

    out[0] = out[1] = out[2] = out[3] = -1;
    api_buf_init(&r.body, 0);
    snprintf(path, sizeof path, "/v1/jobs/%s/metrics", id);
    if (request(c, port, path, NULL, 0, NULL, 30, &r) == 200 &&
        (j = cJSON_ParseWithLength(r.body.data, r.body.len)) != NULL) {
        out[0] = jnum(j, "timing", "decode_s");
        out[1] = jnum(j, "timing", "flow_s");
        out[2] = jnum(j, "timing", "encode_s");
        out[3] = jnum(j, "timing", "total_s");
        cJSON_Delete(j);
    }
    curl_easy_cleanup(c);
    api_buf_free(&r.body);
}

/* Decodes a mesh from bytes (NULL on failure). */
static mcf_mesh *decode(const void *buf, size_t len)
{
    api_limits lim;
    mcf_mesh *m = NULL;
    api_limits_default(&lim);
    if (api_mesh_decode(buf, len, &lim, &m, NULL, NULL) != MCF_OK)
        return NULL;
    return m;
}

static void overhead(const daemon_t *d, const char *name, overhead_row *row)
{
    const char *ext = strrchr(name, '.');
    char in[4096], out[512], errlog[512], *mesh, *mcfout = NULL;
    size_t len, mcflen = 0;
    double tm[MAXREPS], ts[MAXREPS], sp[4][MAXREPS], split[4];
    reply_t r = {.keep = 1};
    int R = g_reps, ns = 0;
    mcf_mesh *a, *b;

    api_buf_init(&r.body, 0);
    load(name, &mesh, &len);
    a = decode(mesh, len);
    row->mesh = name;
    row->nv = a ? mcf_mesh_nvertices(a) : -1;
    mcf_mesh_free(a);
    snprintf(in, sizeof in, "%s/%s", g_meshes, name);
    snprintf(out, sizeof out, "%s/mcf_out%s", g_tmp, ext ? ext : ".obj");
    snprintf(errlog, sizeof errlog, "%s/mcf.err", g_tmp);

    /* warm-up: page cache, the daemon's first job, lazy library set-up */
    run_mcf(in, out, errlog);
    post_once(d->port, mesh, len, name, &r, d);
    for (int k = 0; k < R; k++) {
        if (k % 2 == 0) {
            tm[k] = run_mcf(in, out, errlog);
            ts[k] = post_once(d->port, mesh, len, name, &r, d);
        } else {
            ts[k] = post_once(d->port, mesh, len, name, &r, d);
            tm[k] = run_mcf(in, out, errlog);
        }
        job_split(d->port, r.job, split);
        if (split[0] >= 0 && split[1] >= 0 && split[2] >= 0 && split[3] >= 0) {
            for (int i = 0; i < 4; i++)
                sp[i][ns] = split[i];
            ns++;
        }
    }
    row->mcf = bench_median(tm, R);
    row->srv = bench_median(ts, R);
    row->decode = ns ? bench_median(sp[0], ns) : -1;
    row->flow = ns ? bench_median(sp[1], ns) : -1;
    row->encode = ns ? bench_median(sp[2], ns) : -1;
    row->job = ns ? bench_median(sp[3], ns) : -1;

    /* the last response against mcf's last output file */
    if (bench_read_file(out, &mcfout, &mcflen) != 0) {
        fprintf(stderr, "bench_server: cannot read %s\n", out);
        exit(1);
    }
    row->same_bytes = mcflen == r.body.len && memcmp(mcfout, r.body.data, mcflen) == 0;
    row->rel = row->same_bytes ? 0 : -1;
    if (!row->same_bytes) {
        a = decode(mcfout, mcflen);
        b = decode(r.body.data, r.body.len);
        if (a && b && mcf_mesh_nvertices(a) == mcf_mesh_nvertices(b)) {
            const double *x = mcf_mesh_positions(a), *y = mcf_mesh_positions(b);
            double num = 0, den = 0;
            for (size_t i = 0; i < 3 * (size_t)mcf_mesh_nvertices(a); i++) {
                num += (x[i] - y[i]) * (x[i] - y[i]);
                den += x[i] * x[i];
            }
            row->rel = den > 0 ? sqrt(num / den) : -1;
        }
        mcf_mesh_free(a);
        mcf_mesh_free(b);
    }
    free(mcfout);
    free(mesh);
    api_buf_free(&r.body);
}

/* ------------------------------------------------------------ 2. throughput */

typedef struct {
    /* in */
    int port;
    const char *mesh;
    size_t len;
    pthread_barrier_t *go;
    const double *deadline;   /* written by main before the barrier */
    /* out */
    double lat[MAXLAT];       /* latencies of the 200s, seconds */
    double lat503[MAXLAT];    /* latencies of the 503s */
    int n200, n503, n503_bare, nerr, nv_first;
    double ra_min, ra_max;    /* Retry-After seen, seconds */
    char first_err[CURL_ERROR_SIZE + 64];
} client_t;

static void *client_main(void *arg)
{
    client_t *cl = arg;
    CURL *c = xcurl();
    reply_t r = {.keep = 1};
    double deadline;

    api_buf_init(&r.body, 0);
    cl->nv_first = -1;
    cl->ra_min = 1e30;
    cl->ra_max = -1;
    pthread_barrier_wait(cl->go);
    deadline = *cl->deadline;
    while (mcf_now() < deadline && cl->n200 < MAXLAT && cl->n503 < MAXLAT) {
        double t0 = mcf_now(), t;
        long code = request(c, cl->port, "/smooth?" QUERY, cl->mesh, cl->len,
                            "sphere_cgal.obj", 60, &r);
        t = mcf_now() - t0;
        if (code == 200) {
            if (cl->n200 == 0) {
                mcf_mesh *m = decode(r.body.data, r.body.len);
                cl->nv_first = m ? mcf_mesh_nvertices(m) : -1;
                mcf_mesh_free(m);
            }
            cl->lat[cl->n200++] = t;
        } else if (code == 503) {
            cl->lat503[cl->n503++] = t;
            if (r.retry_after < 0) {
                cl->n503_bare++;
                sleep_s(0.1);
                continue;
            }
            if (r.retry_after < cl->ra_min)
                cl->ra_min = r.retry_after;
            if (r.retry_after > cl->ra_max)
                cl->ra_max = r.retry_after;
            /* a polite client: wait as told, but not past the deadline */
            t = deadline - mcf_now();
            sleep_s(r.retry_after < t ? r.retry_after : t);
        } else {
            if (cl->nerr++ == 0)
                snprintf(cl->first_err, sizeof cl->first_err, "HTTP %ld (%s)",
                         code, r.err);
            sleep_s(0.05);
        }
    }
    curl_easy_cleanup(c);
    api_buf_free(&r.body);
    return NULL;
}

typedef struct {
    int workers, queue, clients;
    double seconds, jobs_s, p50, p99, p50_503;
    double cpu_clients, cpu_mcfd;  /* CPU seconds during the run */
    double cpu_other;              /* the machine's busy CPU s minus both */
    int n200, n503, n503_bare, nerr, bad_mesh;
    double ra_min, ra_max;
} tp_row;

static client_t g_cl[MAXCLIENTS]; /* big (latency arrays): not on a stack */

/* N clients against d for g_duration seconds. Exits when a client
 * thread cannot start. */
static void throughput(const daemon_t *d, int workers, int queue, int N,
                       const char *mesh, size_t len, tp_row *row)
{
    pthread_t th[MAXCLIENTS];
    pthread_barrier_t go;
    double deadline = 0, t0, *all;
    int n = 0, n5 = 0;

    memset(row, 0, sizeof *row);
    row->workers = workers;
    row->queue = queue;
    row->clients = N;
    row->ra_min = 1e30;
    row->ra_max = -1;
    pthread_barrier_init(&go, NULL, (unsigned)N + 1);
    for (int i = 0; i < N; i++) {
        memset(&g_cl[i], 0, sizeof g_cl[i]);
        g_cl[i].port = d->port;
        g_cl[i].mesh = mesh;
        g_cl[i].len = len;
        g_cl[i].go = &go;
        g_cl[i].deadline = &deadline;
        if (pthread_create(&th[i], NULL, client_main, &g_cl[i]) != 0) {
            fprintf(stderr, "bench_server: pthread_create failed\n");
            exit(1);
        }
    }
    row->cpu_clients = -self_cpu();
    row->cpu_mcfd = -proc_cpu(d->pid);
    row->cpu_other = -machine_cpu();
    t0 = mcf_now();
    deadline = t0 + g_duration;
    pthread_barrier_wait(&go);
    for (int i = 0; i < N; i++)
        pthread_join(th[i], NULL);
    row->seconds = mcf_now() - t0;
    row->cpu_clients += self_cpu();
    row->cpu_mcfd += proc_cpu(d->pid);
    row->cpu_other += machine_cpu() - row->cpu_clients - row->cpu_mcfd;
    if (row->cpu_other < 0) /* tick granularity */
        row->cpu_other = 0;
    pthread_barrier_destroy(&go);

    for (int i = 0; i < N; i++) {
        row->n200 += g_cl[i].n200;
        row->n503 += g_cl[i].n503;
        row->n503_bare += g_cl[i].n503_bare;
        row->nerr += g_cl[i].nerr;
        row->bad_mesh += g_cl[i].n200 > 0 && g_cl[i].nv_first != 812;
        if (g_cl[i].ra_min < row->ra_min)
            row->ra_min = g_cl[i].ra_min;
        if (g_cl[i].ra_max > row->ra_max)
            row->ra_max = g_cl[i].ra_max;
        if (g_cl[i].nerr && row->nerr == g_cl[i].nerr)
            fprintf(stderr, "bench_server: %d clients: %s\n", N, g_cl[i].first_err);
    }
    all = xmalloc(((size_t)row->n200 + (size_t)row->n503 + 1) * sizeof *all);
    for (int i = 0; i < N; i++)
        for (int k = 0; k < g_cl[i].n200; k++)
            all[n++] = g_cl[i].lat[k];
    row->jobs_s = row->n200 / row->seconds;
    row->p50 = n ? bench_percentile(all, n, 50) : -1;
    row->p99 = n ? bench_percentile(all, n, 99) : -1;
    for (int i = 0; i < N; i++)
        for (int k = 0; k < g_cl[i].n503; k++)
            all[n5++] = g_cl[i].lat503[k];
    row->p50_503 = n5 ? bench_percentile(all, n5, 50) : -1;
    free(all);
}

/* GET /metrics: do mcfd's counts of /smooth 200s and 503s match? */
static int metrics_agree(const daemon_t *d, int n200, int n503)
{
    CURL *c = xcurl();
    reply_t r = {.keep = 1};
    double m200 = -1, m503 = -1;
    int ok;

    api_buf_init(&r.body, 0);
    if (request(c, d->port, "/metrics", NULL, 0, NULL, 30, &r) == 200) {
        m200 = prom(r.body.data, "mcfd_http_requests_total{route=\"smooth\",code=\"200\"}");
        m503 = prom(r.body.data, "mcfd_http_requests_total{route=\"smooth\",code=\"503\"}");
    }
    ok = m200 == n200 && m503 == n503;
    printf(" mcfd /metrics: %.0f x 200, %.0f x 503 on /smooth; the clients saw "
           "%d and %d: %s\n", m200, m503, n200, n503, ok ? "agree" : "DISAGREE");
    curl_easy_cleanup(c);
    api_buf_free(&r.body);
    return ok;
}

static void print_tp_head(void)
{
    printf("  %7s %5s %7s | %5s %5s %3s %4s | %6s %7s %7s | %-26s | %s\n", "workers",
           "queue", "clients", "200", "503", "err", "s", "jobs/s", "p50 ms",
           "p99 ms", "CPU s: cl mcfd other, /job", "503: p50 ms, Retry-After s");
}

static void print_tp(const tp_row *t)
{
    printf("  %7d %5d %7d | %5d %5d %3d %4.1f | %6.1f %7.1f %7.1f | %4.1f %4.1f %4.1f %5.1fms/job |",
           t->workers, t->queue, t->clients, t->n200, t->n503, t->nerr, t->seconds,
           t->jobs_s, t->p50 * 1e3, t->p99 * 1e3, t->cpu_clients, t->cpu_mcfd,
           t->cpu_other, t->n200 ? 1e3 * t->cpu_mcfd / t->n200 : 0.0);
    if (t->n503)
        printf(" %.2f, %g-%g%s", t->p50_503 * 1e3, t->ra_min, t->ra_max,
               t->n503_bare ? " (some without Retry-After)" : "");
    else
        printf(" -");
    printf("\n");
}

/* ------------------------------------------------------------ main */

static void usage(void)
{
    fprintf(stderr,
            "usage: bench_server --mcf PATH --mcfd PATH --meshes DIR [--reps N]\n"
            "                    [--duration S] [--no-overhead] [--no-throughput]\n"
            "  --reps N      runs per figure of the overhead part, median (default 5, max %d)\n"
            "  --duration S  seconds per throughput run (default 5)\n",
            MAXREPS);
    exit(2);
}

int main(int argc, char **argv)
{
    /* the goal's two meshes, then a small job for its fixed costs */
    static const char *const meshes[] = {"bunny.drc", "armadillo.obj",
                                         "sphere_cgal.obj"};
    static const int nclients[] = {1, 2, 8, 32};
    enum { NM = 3, NGOAL = 2, NN = 4 };
    overhead_row ov[NM];
    tp_row tp[2][NN], tq[2];
    int do_ov = 1, do_tp = 1, sane = 1, goal = 1;
    double t_begin = mcf_now();
    daemon_t d;
    char *sphere = NULL;
    size_t sphere_len = 0;

    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--mcf") && v)
            g_mcf = argv[++i];
        else if (!strcmp(a, "--mcfd") && v)
            g_mcfd = argv[++i];
        else if (!strcmp(a, "--meshes") && v)
            g_meshes = argv[++i];
        else if (!strcmp(a, "--reps") && v)
            g_reps = atoi(argv[++i]);
        else if (!strcmp(a, "--duration") && v)
            g_duration = atof(argv[++i]);
        else if (!strcmp(a, "--no-overhead"))
            do_ov = 0;
        else if (!strcmp(a, "--no-throughput"))
            do_tp = 0;
        else
            usage();
    }
    if (!g_mcf || !g_mcfd || !g_meshes || g_reps < 1 || g_reps > MAXREPS ||
        !(g_duration > 0 && g_duration <= 60))
        usage();
    if (access(g_mcf, X_OK) != 0 || access(g_mcfd, X_OK) != 0) {
        fprintf(stderr, "bench_server: %s or %s is missing: run `make` first\n",
                g_mcf, g_mcfd);
        return 1;
    }
    snprintf(g_tmp, sizeof g_tmp, "%s/bench_server.XXXXXX",
             getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp");
    if (!mkdtemp(g_tmp)) {
        perror("bench_server: mkdtemp");
        return 1;
    }
    atexit(cleanup);
    signal(SIGPIPE, SIG_IGN);
    /* REST only here (bench_grpc.py measures the gRPC door): two daemons
     * run at once, and neither may take port 50051 */
    setenv("MCFD_GRPC_PORT", "off", 1);
    if (curl_global_init(CURL_GLOBAL_DEFAULT) != CURLE_OK) {
        fprintf(stderr, "bench_server: curl_global_init failed\n");
        return 1;
    }

    printf("bench_server: mcfd over HTTP (loopback, libcurl) against mcf smooth\n");
    bench_print_machine();
    printf("libs:    libcurl %s, compiler %s\n", curl_version_info(CURLVERSION_NOW)->version,
           __VERSION__);
    printf("flow:    %s (default dt), BLAS/OpenMP threads as mcfd sets them (1 unless set)\n",
           QUERY);

    if (do_ov) {
        printf("\n1. service overhead: POST /smooth (multipart, new connection) vs "
               "`mcf smooth IN OUT`, median of %d (mcfd --workers 1)\n", g_reps);
        start_daemon(&d, "overhead", 1, 64);
        for (int i = 0; i < NM; i++)
            overhead(&d, meshes[i], &ov[i]);
        sane &= stop_daemon(&d);
        printf("  %-14s %6s | %8s | %8s %6s %8s | %8s %8s %8s %8s %8s | %s\n", "mesh",
               "nv", "mcf ms", "/smooth", "ratio", "goal ms", "decode", "flow",
               "encode", "job", "rest", "same output");
        for (int i = 0; i < NM; i++) {
            const overhead_row *o = &ov[i];
            double lim = GOAL_FACTOR * o->mcf + GOAL_ADD;
            printf("  %-14s %6d | %8.1f | %8.1f %5.2fx %8.1f | %8.1f %8.1f %8.1f %8.1f %8.1f | ",
                   o->mesh, o->nv, o->mcf * 1e3, o->srv * 1e3, o->srv / o->mcf,
                   lim * 1e3, o->decode * 1e3, o->flow * 1e3, o->encode * 1e3,
                   o->job * 1e3, (o->srv - o->job) * 1e3);
            if (o->same_bytes)
                printf("bytes identical\n");
            else
                printf("bytes differ, positions rel %.1e\n", o->rel);
            /* identical bytes: the same code on the same input with the
             * same single-threaded BLAS is deterministic; a different
             * parameter would move positions by far more than 1e-12 */
            sane &= o->same_bytes || (o->rel >= 0 && o->rel <= 1e-12);
        }
        printf("  (decode/flow/encode/job: the job's own timings from "
               "/v1/jobs/ID/metrics; rest = /smooth - job: HTTP, multipart,\n"
               "  spool, queue hand-off; %s is not in the goal, it shows the fixed "
               "costs of a small job)\n", meshes[NGOAL]);
    }

    if (do_tp) {
        load("sphere_cgal.obj", &sphere, &sphere_len);
        printf("\n2. throughput of small jobs: sphere_cgal.obj, %s, %.0f s per run, "
               "keep-alive, each client a thread with its own curl handle\n",
               QUERY, g_duration);
        print_tp_head();
        {
            /* both daemons up at once (the idle one sleeps), runs alternate
             * between them so both see the same load from other jobs */
            daemon_t dw[2];
            int n200[2] = {0, 0}, n503[2] = {0, 0};
            for (int w = 0; w < 2; w++) {
                reply_t r = {.keep = 1};
                CURL *c = xcurl();
                char name[32];
                snprintf(name, sizeof name, "tp-w%d", w + 1);
                start_daemon(&dw[w], name, w + 1, 64);
                api_buf_init(&r.body, 0);
                /* warm-up job, counted by mcfd too */
                if (request(c, dw[w].port, "/smooth?" QUERY, sphere, sphere_len,
                            "sphere_cgal.obj", 60, &r) == 200)
                    n200[w]++;
                curl_easy_cleanup(c);
                api_buf_free(&r.body);
            }
            for (int k = 0; k < NN; k++)
                for (int w = 0; w < 2; w++) {
                    tp_row *t = &tp[w][k];
                    throughput(&dw[w], w + 1, 64, nclients[k], sphere, sphere_len, t);
                    print_tp(t);
                    fflush(stdout);
                    n200[w] += t->n200;
                    n503[w] += t->n503;
                    sane &= t->nerr == 0 && t->n503 == 0 && t->bad_mesh == 0 &&
                            t->n200 > 0;
                }
            for (int w = 0; w < 2; w++) {
                printf("  --workers %d:", w + 1);
                sane &= metrics_agree(&dw[w], n200[w], n503[w]);
                sane &= stop_daemon(&dw[w]);
            }
        }
        printf("  scaling, jobs/s with --workers 2 over --workers 1:");
        for (int k = 0; k < NN; k++)
            printf(" %d clients %.2fx%s", nclients[k], tp[1][k].jobs_s / tp[0][k].jobs_s,
                   k + 1 < NN ? "," : "\n");

        printf("\n   short queue: 32 clients against --queue 2; a refused client "
               "sleeps Retry-After (to the deadline at most), then retries\n");
        print_tp_head();
        for (int w = 0; w < 2; w++) {
            char name[32];
            snprintf(name, sizeof name, "short-w%d", w + 1);
            start_daemon(&d, name, w + 1, 2);
            throughput(&d, w + 1, 2, 32, sphere, sphere_len, &tq[w]);
            print_tp(&tq[w]);
            printf("  --workers %d:", w + 1);
            sane &= tq[w].nerr == 0 && tq[w].n503_bare == 0 && tq[w].bad_mesh == 0 &&
                    tq[w].n200 > 0;
            sane &= metrics_agree(&d, tq[w].n200, tq[w].n503);
            sane &= stop_daemon(&d);
        }
        free(sphere);
    }

    printf("\n");
    if (do_ov) {
        char s[512] = "";
        for (int i = 0; i < NGOAL; i++) {
            double lim = GOAL_FACTOR * ov[i].mcf + GOAL_ADD;
            goal &= ov[i].srv <= lim;
            snprintf(s + strlen(s), sizeof s - strlen(s),
                     "%s%s %.0f ms vs %.0f ms allowed (%.2fx)", i ? ", " : "",
                     ov[i].mesh, ov[i].srv * 1e3, lim * 1e3, ov[i].srv / ov[i].mcf);
        }
        printf("%s goal /smooth <= %.2fx mcf smooth + %.0f ms: %s\n",
               goal ? "PASS" : "FAIL", GOAL_FACTOR, GOAL_ADD * 1e3, s);
    }
    printf("%s sanity:%s%s mcfd exits 0 on SIGTERM\n", sane ? "PASS" : "FAIL",
           do_ov ? " /smooth answers the bytes mcf smooth writes;" : "",
           do_tp ? " no transport errors, no 503 with a long queue, every 503 with "
                   "Retry-After, results decode, /metrics counts agree;" : "");
    printf("bench_server: %.0f s\n", mcf_now() - t_begin);
    curl_global_cleanup();
    return sane ? 0 : 1;
}
