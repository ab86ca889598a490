/* SPDX-License-Identifier: MIT */
/*
 * srvlib.c - the helpers of the daemon's integration tests (srvlib.h).
 */
#include "srvlib.h"

char g_tmp[256];
char g_bin[512];
/* Every daemon started, so that a test failing half-way (cmocka jumps out
 * of it) leaves no process behind: the group teardown kills the rest. */
pid_t g_started[64];
int g_nstarted;
daemon_t g_main;   /* shared by the tests that need no special flags */

void sleep_ms(int ms)
{
    struct timespec ts = {ms / 1000, (long)(ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

void print_log_tail(const daemon_t *d)
{
    char *buf = NULL;
    size_t len = 0;

    if (tl_read_file(d->log, &buf, &len) == 0) {
        const char *p = len > 4000 ? buf + len - 4000 : buf;
        fprintf(stderr, "---- tail of %s\n%s\n----\n", d->log, p);
        free(buf);
    }
}

/* Starts mcfd with the given extra flags on spool <tmp>/<name>. Returns 0
 * and fills d, or -1 (after printing why). */
int start_daemon(daemon_t *d, const char *name, const char *spool,
                 const char *const *extra)
{
    const char *argv[40];
    int pfd[2], n = 0, i;
    char line[256];
    size_t got = 0;
    double end;

    memset(d, 0, sizeof *d);
    snprintf(d->log, sizeof d->log, "%s/%s.log", g_tmp, name);
    snprintf(d->spool, sizeof d->spool, "%s", spool);
    argv[n++] = g_bin;
    argv[n++] = "--bind";
    argv[n++] = "127.0.0.1";
    argv[n++] = "--port";
    argv[n++] = "0";
    argv[n++] = "--spool";
    argv[n++] = spool;
    for (i = 0; extra && extra[i] && n < 38; i++)
        argv[n++] = extra[i];
    argv[n] = NULL;
    if (pipe(pfd) != 0)
        return -1;
    d->pid = fork();
    if (d->pid < 0)
        return -1;
    if (d->pid == 0) {
        int lf = open(d->log, O_WRONLY | O_CREAT | O_APPEND, 0644);
        dup2(pfd[1], 1);
        if (lf >= 0)
            dup2(lf, 2);
        close(pfd[0]);
        close(pfd[1]);
        tl_child_own_group();
        execv(g_bin, (char *const *)(uintptr_t)argv);
        _exit(127);
    }
    close(pfd[1]);
    tl_track_child(d->pid); /* killed at teardown, exit or a fatal signal */
    if (g_nstarted < (int)(sizeof g_started / sizeof g_started[0]))
        g_started[g_nstarted++] = d->pid;
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
        line[got] = '\0';
    }
    close(pfd[0]);
    line[got] = '\0';
    if (sscanf(line, "mcfd listening on http://127.0.0.1:%d", &d->port) != 1) {
        fprintf(stderr, "mcfd did not start (stdout: \"%s\")\n", line);
        print_log_tail(d);
        kill(d->pid, SIGKILL);
        waitpid(d->pid, NULL, 0);
        d->pid = 0;
        return -1;
    }
    return 0;
}

/* Waits for the process to exit; 1 and *status when it did in time. */
int wait_exit(pid_t pid, double seconds, int *status)
{
    double end = mcf_now() + seconds;
    do {
        pid_t r = waitpid(pid, status, WNOHANG);
        if (r == pid)
            return 1;
        if (r < 0)
            return 0;
        sleep_ms(20);
    } while (mcf_now() < end);
    return 0;
}

/* SIGKILL its process group and reap (teardown, or a test that already
 * failed). */
void reap(daemon_t *d)
{
    if (d->pid > 0) {
        kill(-d->pid, SIGKILL);
        kill(d->pid, SIGKILL);
        waitpid(d->pid, NULL, 0);
        d->pid = 0;
    }
}

/* SIGTERM; the daemon must exit 0 within the bound. */
void stop_daemon(daemon_t *d)
{
    int st = 0;
    kill(d->pid, SIGTERM);
    if (!wait_exit(d->pid, 40, &st)) {
        print_log_tail(d);
        reap(d);
        fail_msg("mcfd did not exit within 40 s of SIGTERM");
    }
    d->pid = 0;
    if (!WIFEXITED(st) || WEXITSTATUS(st) != 0) {
        print_log_tail(d);
        fail_msg("mcfd exited with status 0x%x after SIGTERM", st);
    }
}

void rm_rf(const char *path)
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

void resp_init(resp_t *r)
{
    memset(r, 0, sizeof *r);
    api_buf_init(&r->body, 0);
    api_buf_init(&r->hdr, 0);
}

void resp_free(resp_t *r)
{
    api_buf_free(&r->body);
    api_buf_free(&r->hdr);
}

size_t on_body(char *p, size_t s, size_t n, void *ud)
{
    resp_t *r = ud;
    double now = mcf_now();
    if (r->chunks++ == 0)
        r->t_first = now;
    r->t_last = now;
    if (api_buf_append(&r->body, p, s * n) != MCF_OK)
        return 0;
    if (r->watch && !r->seen && strstr(r->body.data, r->watch))
        __atomic_store_n(&r->seen, 1, __ATOMIC_RELEASE);
    return s * n;
}

size_t on_hdr(char *p, size_t s, size_t n, void *ud)
{
    resp_t *r = ud;
    return api_buf_append(&r->hdr, p, s * n) == MCF_OK ? s * n : 0;
}

/* A test mesh by name (tl_need_mesh: the test is skipped when it is not
 * available), or an absolute path as it is. */
void mesh_path(char *buf, size_t size, const char *name)
{
    snprintf(buf, size, "%s", name[0] == '/' ? name : tl_need_mesh(name));
}

/* One request; returns the HTTP status, 0 on a transport error. With
 * watch, r->seen turns 1 (atomically: another thread may wait for it with
 * watch_seen) as soon as the body received so far contains that string;
 * the headers are complete by then. */
long http_watch(const daemon_t *d, const char *method, const char *path,
                const char *const *headers, const upload_t *up,
                resp_t *r, const char *watch)
{
    CURL *c = curl_easy_init();
    curl_mime *mime = NULL;
    struct curl_slist *hl = NULL;
    char url[1024], file[1024];
    int i;

    resp_init(r);
    r->watch = watch;
    if (!c)
        return 0;
    snprintf(url, sizeof url, "http://127.0.0.1:%d%s", d->port, path);
    curl_easy_setopt(c, CURLOPT_URL, url);
    curl_easy_setopt(c, CURLOPT_PATH_AS_IS, 1L); /* "/../" reaches the daemon */
    curl_easy_setopt(c, CURLOPT_NOSIGNAL, 1L);
    curl_easy_setopt(c, CURLOPT_CONNECTTIMEOUT, 5L);
    curl_easy_setopt(c, CURLOPT_TIMEOUT, 60L);
    curl_easy_setopt(c, CURLOPT_WRITEFUNCTION, on_body);
    curl_easy_setopt(c, CURLOPT_WRITEDATA, r);
    curl_easy_setopt(c, CURLOPT_HEADERFUNCTION, on_hdr);
    curl_easy_setopt(c, CURLOPT_HEADERDATA, r);
    curl_easy_setopt(c, CURLOPT_ERRORBUFFER, r->err);
    for (i = 0; headers && headers[i]; i++)
        hl = curl_slist_append(hl, headers[i]);
    if (up && up->raw) {
        curl_easy_setopt(c, CURLOPT_POSTFIELDS, up->raw);
        curl_easy_setopt(c, CURLOPT_POSTFIELDSIZE_LARGE, (curl_off_t)up->raw_len);
    } else if (up) {
        curl_mimepart *part;
        mime = curl_mime_init(c);
        if (up->mesh) {
            part = curl_mime_addpart(mime);
            curl_mime_name(part, "mesh");
            mesh_path(file, sizeof file, up->mesh);
            curl_mime_filedata(part, file);
        }
        if (up->target) {
            part = curl_mime_addpart(mime);
            curl_mime_name(part, "target");
            mesh_path(file, sizeof file, up->target);
            curl_mime_filedata(part, file);
        }
        if (up->params) {
            part = curl_mime_addpart(mime);
            curl_mime_name(part, "params");
            curl_mime_data(part, up->params, CURL_ZERO_TERMINATED);
            curl_mime_type(part, "application/json");
        }
        if (up->field) {
            part = curl_mime_addpart(mime);
            curl_mime_name(part, up->field);
            curl_mime_data(part, up->value, CURL_ZERO_TERMINATED);
        }
        curl_easy_setopt(c, CURLOPT_MIMEPOST, mime);
    }
    curl_easy_setopt(c, CURLOPT_CUSTOMREQUEST, method);
    if (strcmp(method, "HEAD") == 0)
        curl_easy_setopt(c, CURLOPT_NOBODY, 1L);
    curl_easy_setopt(c, CURLOPT_HTTPHEADER, hl);
    if (curl_easy_perform(c) == CURLE_OK)
        curl_easy_getinfo(c, CURLINFO_RESPONSE_CODE, &r->code);
    else
        r->code = 0;
    curl_easy_cleanup(c);
    curl_mime_free(mime);
    curl_slist_free_all(hl);
    return r->code;
}

long http(const daemon_t *d, const char *method, const char *path,
          const char *const *headers, const upload_t *up, resp_t *r)
{
    return http_watch(d, method, path, headers, up, r, NULL);
}

/* Waits until the body that another thread is receiving into r (with
 * http_watch) holds the watched string; fails after `seconds`. */
void watch_seen(const daemon_t *d, resp_t *r, double seconds,
                const char *what)
{
    double end = mcf_now() + seconds;
    while (!__atomic_load_n(&r->seen, __ATOMIC_ACQUIRE)) {
        if (mcf_now() > end) {
            print_log_tail(d);
            fail_msg("%s: nothing within %g s", what, seconds);
        }
        sleep_ms(5);
    }
}

void *live_client(void *arg)
{
    live_client_t *lc = arg;
    upload_t up = {.mesh = "sphere_cgal.obj"};
    http_watch(lc->d, lc->method, lc->path, NULL, lc->mesh ? &up : NULL,
               &lc->r, lc->watch);
    return NULL;
}

/* The last value of a response header (the final response's), or NULL. */
const char *header(const resp_t *r, const char *name, char *out,
                   size_t size)
{
    const char *p = r->hdr.data, *found = NULL;
    size_t n = strlen(name);

    while (p && *p) {
        const char *eol = strchr(p, '\n');
        if (strncasecmp(p, name, n) == 0 && p[n] == ':')
            found = p + n + 1;
        p = eol ? eol + 1 : NULL;
    }
    if (!found)
        return NULL;
    while (*found == ' ')
        found++;
    n = strcspn(found, "\r\n");
    if (n >= size)
        n = size - 1;
    memcpy(out, found, n);
    out[n] = '\0';
    return out;
}

void expect_status(const daemon_t *d, const resp_t *r, long want,
                   const char *what)
{
    if (r->code != want) {
        fprintf(stderr, "%s: HTTP %ld (curl: %s), body:\n%.2000s\n", what,
                r->code, r->err, r->body.data ? r->body.data : "");
        print_log_tail(d);
        fail_msg("%s: expected HTTP %ld, got %ld", what, want, r->code);
    }
}

cJSON *body_json(const resp_t *r, const char *what)
{
    cJSON *j = cJSON_ParseWithLength(r->body.data ? r->body.data : "",
                                     r->body.len);
    if (!j)
        fail_msg("%s: the body is not JSON: %.500s", what,
                 r->body.data ? r->body.data : "");
    return j;
}

double jnum(const cJSON *o, const char *path)
{
    char key[128];
    const char *dot;
    const cJSON *x = o;

    while ((dot = strchr(path, '.')) != NULL) {
        snprintf(key, sizeof key, "%.*s", (int)(dot - path), path);
        x = cJSON_GetObjectItemCaseSensitive(x, key);
        path = dot + 1;
    }
    x = cJSON_GetObjectItemCaseSensitive(x, path);
    if (!cJSON_IsNumber(x))
        fail_msg("JSON number '%s' missing", path);
    return x->valuedouble;
}

const char *jstr(const cJSON *o, const char *key)
{
    const char *s = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(o, key));
    if (!s)
        fail_msg("JSON string '%s' missing", key);
    return s;
}

/* An RFC 9457 problem with the given status, code and a detail holding
 * `needle` (when given). */
void expect_problem(const daemon_t *d, const resp_t *r, long status,
                    const char *code, const char *needle,
                    const char *what)
{
    char ct[128];
    cJSON *j;

    expect_status(d, r, status, what);
    if (!header(r, "Content-Type", ct, sizeof ct) ||
        strcmp(ct, "application/problem+json") != 0)
        fail_msg("%s: Content-Type '%s', want application/problem+json", what,
                 header(r, "Content-Type", ct, sizeof ct) ? ct : "(none)");
    j = body_json(r, what);
    assert_int_equal((long)jnum(j, "status"), status);
    assert_string_equal(jstr(j, "code"), code);
    assert_true(strncmp(jstr(j, "type"), "urn:mcfd:problem:", 17) == 0);
    assert_true(strlen(jstr(j, "title")) > 0);
    if (needle && !strstr(jstr(j, "detail"), needle))
        fail_msg("%s: detail \"%s\" does not mention \"%s\"", what,
                 jstr(j, "detail"), needle);
    if (status == 503) {
        char ra[32];
        if (!header(r, "Retry-After", ra, sizeof ra) || atoi(ra) < 1)
            fail_msg("%s: 503 without a Retry-After", what);
    }
    cJSON_Delete(j);
}

mcf_mesh *decode_body(const resp_t *r, api_format *fmt)
{
    api_limits lim;
    mcf_mesh *m = NULL;
    mcf_error err = {MCF_OK, ""};

    api_limits_default(&lim);
    if (api_mesh_decode(r->body.data, r->body.len, &lim, &m, fmt, &err) !=
        MCF_OK)
        fail_msg("the response body is no mesh: %s", err.msg);
    return m;
}

/* Polls GET /v1/jobs/ID until the status is `want` (or, with want NULL,
 * any final status); returns the job JSON. */
cJSON *poll_job(const daemon_t *d, const char *id, const char *want,
                double seconds)
{
    char path[128];
    double end = mcf_now() + seconds;
    resp_t r;

    snprintf(path, sizeof path, "/v1/jobs/%s", id);
    for (;;) {
        cJSON *j;
        const char *st;
        http(d, "GET", path, NULL, NULL, &r);
        expect_status(d, &r, 200, "GET job");
        j = body_json(&r, "GET job");
        resp_free(&r);
        st = jstr(j, "status");
        if (want ? strcmp(st, want) == 0
                 : (!strcmp(st, "succeeded") || !strcmp(st, "failed") ||
                    !strcmp(st, "canceled")))
            return j;
        if (want && (!strcmp(st, "succeeded") || !strcmp(st, "failed") ||
                     !strcmp(st, "canceled")))
            fail_msg("job %s ended %s while waiting for %s", id, st, want);
        cJSON_Delete(j);
        if (mcf_now() > end) {
            print_log_tail(d);
            fail_msg("job %s: not %s within %g s", id, want ? want : "done",
                     seconds);
        }
        sleep_ms(30);
    }
}

/* Waits until the job runs and has done at least one step. */
void wait_running(const daemon_t *d, const char *id)
{
    double end = mcf_now() + 20;
    for (;;) {
        cJSON *j = poll_job(d, id, "running", 20);
        int step = (int)jnum(j, "progress.step");
        cJSON_Delete(j);
        if (step >= 1)
            return;
        if (mcf_now() > end)
            fail_msg("job %s made no step within 20 s", id);
        sleep_ms(20);
    }
}

/* POST /v1/jobs; returns the new ID (static buffer per call site). */
void submit(const daemon_t *d, const char *query, char *id)
{
    char path[256], loc[128];
    upload_t up = {.mesh = "sphere_cgal.obj"};
    resp_t r;
    cJSON *j;

    snprintf(path, sizeof path, "/v1/jobs%s", query);
    http(d, "POST", path, NULL, &up, &r);
    expect_status(d, &r, 202, "POST /v1/jobs");
    j = body_json(&r, "POST /v1/jobs");
    snprintf(id, SRV_ID_BUF, "%s", jstr(j, "id"));
    assert_int_equal(strlen(id), 32);
    assert_non_null(header(&r, "Location", loc, sizeof loc));
    snprintf(path, sizeof path, "/v1/jobs/%s", id);
    assert_string_equal(loc, path);
    /* a free worker may have taken it before the answer was written */
    assert_true(!strcmp(jstr(j, "status"), "queued") ||
                !strcmp(jstr(j, "status"), "running") ||
                !strcmp(jstr(j, "status"), "succeeded"));
    cJSON_Delete(j);
    resp_free(&r);
}

/* The value of a Prometheus sample line "name{labels} value": 1 and *v
 * when the series is there, else 0. */
int metric_find(const char *text, const char *series, double *v)
{
    const char *p = text;
    size_t n = strlen(series);
    while (p && *p) {
        if (strncmp(p, series, n) == 0 && p[n] == ' ') {
            *v = strtod(p + n + 1, NULL);
            return 1;
        }
        p = strchr(p, '\n');
        if (p)
            p++;
    }
    return 0;
}

/* metric_find, or the test fails: a series that is not there (a renamed
 * metric, a label that changed, a counter that never counted) must not
 * pass for 0. */
double metric(const char *text, const char *series)
{
    double v = 0;
    if (!metric_find(text ? text : "", series, &v))
        fail_msg("metric series %s is missing from /metrics", series);
    return v;
}

/* Polls /metrics until the gauge has the value (bounded). */
void wait_gauge(const daemon_t *d, const char *name, double want)
{
    double end = mcf_now() + 20;
    resp_t r;
    for (;;) {
        double v = NAN;
        int found;
        http(d, "GET", "/metrics", NULL, NULL, &r);
        found = metric_find(r.body.data ? r.body.data : "", name, &v);
        resp_free(&r);
        if (found && v == want)
            return;
        if (mcf_now() > end)
            fail_msg("%s stayed %g, not %g%s", name, v, want,
                     found ? "" : " (the series is missing)");
        sleep_ms(10);
    }
}

/* ------------------------------------------------------------ fixtures */

int group_setup(void **state)
{
    static const char *const flags[] = {"--workers", "2", "--queue", "8",
                                        "--max-upload", "3M", NULL};
    const char *b = getenv("MCF_BUILD");
    char spool[512];

    (void)state;
    signal(SIGPIPE, SIG_IGN);
    curl_global_init(CURL_GLOBAL_DEFAULT);
    /* The REST door's tests: no gRPC door (tests/test_grpc.py has it), so
     * no daemon here takes port 50051 and the thread count is REST's. */
    setenv("MCFD_GRPC_PORT", "off", 1);
    snprintf(g_bin, sizeof g_bin, "%s/mcfd", b && *b ? b : "build");
    if (access(g_bin, X_OK) != 0) {
        fprintf(stderr, "no executable %s (set MCF_BUILD)\n", g_bin);
        return -1;
    }
    snprintf(g_tmp, sizeof g_tmp, "/tmp/mcfd-test-XXXXXX");
    if (!mkdtemp(g_tmp))
        return -1;
    snprintf(spool, sizeof spool, "%s/main", g_tmp);
    return start_daemon(&g_main, "main", spool, flags);
}

/* The shared daemon must also stop cleanly (under ASan: without leaks,
 * which would turn its exit status non-zero). */
int group_teardown(void **state)
{
    int st = 0, rc = 0;
    (void)state;
    if (g_main.pid > 0) {
        kill(g_main.pid, SIGTERM);
        if (!wait_exit(g_main.pid, 40, &st)) {
            fprintf(stderr, "the main mcfd did not exit within 40 s\n");
            reap(&g_main);
            rc = -1;
        } else if (!WIFEXITED(st) || WEXITSTATUS(st) != 0) {
            fprintf(stderr, "the main mcfd exited with status 0x%x\n", st);
            print_log_tail(&g_main);
            rc = -1;
        }
    }
    for (int i = 0; i < g_nstarted; i++)
        if (g_started[i] > 0 && waitpid(g_started[i], NULL, WNOHANG) == 0) {
            /* still running: a test failed before stopping it */
            kill(g_started[i], SIGKILL);
            waitpid(g_started[i], NULL, 0);
        }
    tl_kill_children(0);
    unmount_all();
    unlock_dirs();
    rm_rf(g_tmp);
    curl_global_cleanup();
    return rc;
}

/* After every test: a daemon of its own that a failing test left running
 * is killed with its process group (testlib also does so at exit and on
 * SIGINT, SIGTERM, SIGHUP, SIGQUIT and SIGABRT). */
int kill_strays(void **state)
{
    (void)state;
    tl_kill_children(g_main.pid);
    unmount_all();
    return 0;
}

/* How many times needle occurs in hay. */
int count_of(const char *hay, const char *needle)
{
    int n = 0;
    while (hay && (hay = strstr(hay, needle)) != NULL) {
        n++;
        hay += strlen(needle);
    }
    return n;
}

/* Directories made unwritable by a test (root: the immutable flag, which
 * root's writes respect; others: mode 0555), restored by unlock_dirs. */
char g_locked[4][800];
int g_nlocked;

int set_writable(const char *path, int writable)
{
    int rc = -1;
    if (geteuid() == 0) {
        int fd = open(path, O_RDONLY | O_NONBLOCK), flags = 0;
        if (fd < 0)
            return -1;
        if (ioctl(fd, FS_IOC_GETFLAGS, &flags) == 0) {
            flags = writable ? (flags & ~FS_IMMUTABLE_FL) : (flags | FS_IMMUTABLE_FL);
            rc = ioctl(fd, FS_IOC_SETFLAGS, &flags);
        }
        close(fd);
    } else {
        rc = chmod(path, writable ? 0750 : 0555);
    }
    return rc;
}

void unlock_dirs(void)
{
    while (g_nlocked > 0)
        set_writable(g_locked[--g_nlocked], 1);
}

/* A connection from source address `from` (127.0.0.x) to d, the request
 * `req` sent; returns the socket. */
int connect_from(const daemon_t *d, const char *from, const char *req)
{
    struct sockaddr_in sa, src;
    struct timeval tv = {5, 0};
    int fd = socket(AF_INET, SOCK_STREAM, 0);

    assert_true(fd >= 0);
    memset(&src, 0, sizeof src);
    src.sin_family = AF_INET;
    inet_pton(AF_INET, from, &src.sin_addr);
    assert_int_equal(bind(fd, (struct sockaddr *)&src, sizeof src), 0);
    memset(&sa, 0, sizeof sa);
    sa.sin_family = AF_INET;
    sa.sin_port = htons((uint16_t)d->port);
    sa.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    assert_int_equal(connect(fd, (struct sockaddr *)&sa, sizeof sa), 0);
    if (write(fd, req, strlen(req)) < 0) {
        /* refused at once: the caller reads the outcome */
    }
    return fd;
}

/* A size field of a process's status ("VmRSS", "VmHWM": its peak) in
 * KiB, -1 when /proc cannot say. */
long status_kib(pid_t pid, const char *field)
{
    char path[64], line[256];
    size_t n = strlen(field);
    long kib = -1;
    FILE *f;
    snprintf(path, sizeof path, "/proc/%d/status", (int)pid);
    if (!(f = fopen(path, "r")))
        return -1;
    while (fgets(line, sizeof line, f))
        if (strncmp(line, field, n) == 0 && line[n] == ':' &&
            sscanf(line + n + 1, "%ld", &kib) == 1)
            break;
    fclose(f);
    return kib;
}

/* ------------------------------------------------------------ a full spool */

/* Small filesystems mounted by a test (tmpfs with size=), unmounted by
 * unmount_all at the end of the test or the group. */
char g_mounted[2][800];
int g_nmounted;

void unmount_all(void)
{
    char cmd[900];
    while (g_nmounted > 0) {
        snprintf(cmd, sizeof cmd, "umount -l '%s' 2>/dev/null",
                 g_mounted[--g_nmounted]);
        if (system(cmd) != 0)
            fprintf(stderr, "could not unmount %s\n", g_mounted[g_nmounted]);
    }
}

/* POSTs a file of tests/data as the raw body of path. */
long post_file(const daemon_t *d, const char *path, const char *name,
               resp_t *r)
{
    char file[1024];
    char *data = NULL;
    size_t len = 0;
    long code;
    static const char *const h[] = {"Content-Type: application/octet-stream",
                                    "Expect:", NULL};
    upload_t up;

    if (name[0] == '/')
        snprintf(file, sizeof file, "%s", name);
    else
        snprintf(file, sizeof file, "%s/%s", getenv("MCF_TESTDATA"), name);
    assert_int_equal(tl_read_file(file, &data, &len), 0);
    memset(&up, 0, sizeof up);
    up.raw = data;
    up.raw_len = len;
    code = http(d, "POST", path, h, &up, r);
    free(data);
    return code;
}

/* Polls /metrics until the gauge has the value, at most `seconds`. */
void wait_gauge_within(const daemon_t *d, const char *name, double want,
                       double seconds, const char *what)
{
    double end = mcf_now() + seconds;
    resp_t r;
    for (;;) {
        double v = NAN; /* NAN: the series is not there (yet) */
        http(d, "GET", "/metrics", NULL, NULL, &r);
        metric_find(r.body.data ? r.body.data : "", name, &v);
        resp_free(&r);
        if (v == want)
            return;
        if (mcf_now() > end) {
            print_log_tail(d);
            fail_msg("%s: %s stayed %g, not %g within %g s", what, name, v,
                     want, seconds);
        }
        sleep_ms(20);
    }
}
