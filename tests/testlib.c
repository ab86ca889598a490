/* SPDX-License-Identifier: MIT */
/*
 * testlib.c - the helpers of testlib.h: locating the test meshes (in the
 * repository, else in $MCF_MESHES, else skipping the test), reading files,
 * decoding a mesh or failing the test, tolerance checks, running the mcf
 * tool as a child process in a scratch directory, and making sure no child
 * daemon outlives the test binary.
 *
 * Plain stdio on purpose: tests may run from any directory, and a missing
 * file must fail (or skip) loudly with the path it tried, not crash.
 */
#define _XOPEN_SOURCE 700 /* realpath, mkdtemp */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include "testlib.h"
#include "../api/api.h"

/* stdout line by line even into a pipe or file (make test tees every
 * binary's output): cmocka's [ RUN ]/[ OK ] lines go to stdout, its errors
 * to stderr, and a block-buffered stdout would print a failure's message
 * far from the test it belongs to. Runs before main in every test binary. */
__attribute__((constructor)) static void tl_line_buffered(void)
{
    setvbuf(stdout, NULL, _IOLBF, 0);
}

const char *tl_meshes_dir(void)
{
    const char *d = getenv("MCF_MESHES");
    return d ? d : "";
}

const char *tl_testdata_dir(void)
{
    const char *d = getenv("MCF_TESTDATA");
    return (d && *d) ? d : "tests/data";
}

const char *tl_mesh_path(const char *name)
{
    /* per thread: test_concurrent_clients' clients call this at once */
    static _Thread_local char p[4][4096];
    static _Thread_local int k;
    const char *big = tl_meshes_dir();

    k = (k + 1) % 4;
    snprintf(p[k], sizeof p[k], "%s/meshes/%s", tl_testdata_dir(), name);
    if (access(p[k], R_OK) == 0)
        return p[k];
    if (*big) {
        snprintf(p[k], sizeof p[k], "%s/%s", big, name);
        if (access(p[k], R_OK) == 0)
            return p[k];
    }
    return NULL;
}

int tl_mesh_in_repo(const char *name)
{
    char p[4096];
    snprintf(p, sizeof p, "%s/meshes/%s", tl_testdata_dir(), name);
    return access(p, R_OK) == 0;
}

void tl_skip(const char *tag, const char *why)
{
    const char *log = getenv("MCF_SKIP_LOG");
    FILE *f;

    print_message("[  SKIP    ] %s\n", why);
    if (log && *log && (f = fopen(log, "a")) != NULL) {
        fprintf(f, "%s\t%s\n", tag, why);
        fclose(f);
    }
    skip();
}

double tl_uniform01(uint64_t *r)
{
    uint64_t z = (*r += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    z ^= z >> 31;
    return (double)(z >> 11) * (1.0 / 9007199254740992.0);
}

double tl_gauss01(uint64_t *r)
{
    double a = tl_uniform01(r);
    return sqrt(-2.0 * log(1.0 - a)) * cos(2.0 * 3.14159265358979323846 * tl_uniform01(r));
}

void tl_long(const char *what)
{
    const char *quick = getenv("MCF_QUICK");
    char why[512];

    if (!quick || !*quick)
        return;
    snprintf(why, sizeof why, "a long study (%s): `make test` runs it", what);
    tl_skip("long", why);
}

const char *tl_need_mesh(const char *name)
{
    const char *p = tl_mesh_path(name), *big = tl_meshes_dir();
    char why[4200];

    if (p)
        return p;
    if (*big)
        snprintf(why, sizeof why, "%s is not in MESHES=%s", name, big);
    else
        snprintf(why, sizeof why,
                 "%s is not in the repository (tests/data/meshes) and MESHES is unset "
                 "(make test MESHES=/path/to/meshes runs it)", name);
    tl_skip(name, why);
    return NULL; /* not reached */
}

int tl_read_file(const char *path, char **buf, size_t *len)
{
    FILE *f = fopen(path, "rb");
    char *data = NULL;
    size_t n = 0, cap = 0;
    int rc = -1;

    if (!f)
        return -1;
    for (;;) {
        size_t got;
        if (cap - n < 65536) {
            size_t ncap = cap ? cap * 2 : 131072;
            char *p = realloc(data, ncap + 1);
            if (!p) {
                errno = ENOMEM;
                goto done;
            }
            data = p;
            cap = ncap;
        }
        got = fread(data + n, 1, cap - n, f);
        n += got;
        if (got == 0) {
            if (ferror(f))
                goto done;
            break;
        }
    }
    data[n] = '\0';
    *buf = data;
    *len = n;
    data = NULL;
    rc = 0;
done:
    free(data);
    fclose(f);
    return rc;
}

mcf_mesh *tl_load(const char *name)
{
    char path[4096];
    char *buf = NULL;
    size_t len = 0;
    api_limits lim;
    mcf_error err = {MCF_OK, ""};
    mcf_mesh *m = NULL;
    mcf_status rc;

    snprintf(path, sizeof path, "%s", tl_need_mesh(name));
    if (tl_read_file(path, &buf, &len) != 0)
        fail_msg("tl_load: cannot read %s: %s", path, strerror(errno));
    api_limits_default(&lim);
    rc = api_mesh_decode(buf, len, &lim, &m, NULL, &err);
    free(buf);
    if (rc != MCF_OK || !m)
        fail_msg("tl_load: %s: %s: %s", path, mcf_status_name(rc), err.msg);
    return m;
}

const char *tl_write_noisy(const char *name, double rho, uint64_t seed, const char *out_path)
{
    mcf_mesh *m = tl_load(name);
    mcf_error err = {MCF_OK, ""};
    api_encode_opts o;
    api_buf b;
    FILE *f;

    api_buf_init(&b, SIZE_MAX);
    api_encode_opts_init(&o);
    o.format = API_FMT_OBJ;
    if (mcf_mesh_add_noise(m, rho, seed, &err) != MCF_OK || api_mesh_encode(m, &o, &b, &err) != MCF_OK)
        fail_msg("tl_write_noisy: %s: %s", name, err.msg);
    mcf_mesh_free(m);
    if (!(f = fopen(out_path, "wb")) || fwrite(b.data, 1, b.len, f) != b.len || fclose(f) != 0)
        fail_msg("tl_write_noisy: cannot write %s: %s", out_path, strerror(errno));
    api_buf_free(&b);
    return out_path;
}

void tl_assert_near(double a, double b, double tol, const char *what)
{
    if (a == b) /* also equal infinities */
        return;
    if (!isfinite(a) || !isfinite(b) || !(fabs(a - b) <= tol))
        fail_msg("%s: %.17g vs %.17g differ by %.3g (tolerance %.3g)",
                 what ? what : "value", a, b, fabs(a - b), tol);
}

/* ------------------------------------------------------------ mcf runs */

static char scratch[64];      /* scratch directory of this test binary */
static char mcf_path[4096];
static char prog_prefix[64];  /* "mcf: ", the error lines' start */
static char sphere[4096];

int tl_mcf_setup(const char *who, const char *tmpl)
{
    return tl_prog_setup(who, tmpl, "mcf");
}

int tl_prog_setup(const char *who, const char *tmpl, const char *prog)
{
    const char *b = getenv("MCF_BUILD"), *base = strrchr(prog, '/');
    char rel[4096];
    snprintf(prog_prefix, sizeof prog_prefix, "%s: ", base ? base + 1 : prog);
    /* Absolute paths: the children run inside the scratch directory. */
    snprintf(rel, sizeof rel, "%s/%s", b && *b ? b : "build", prog);
    if (!realpath(rel, mcf_path)) {
        fprintf(stderr, "%s: no %s (build it, or set MCF_BUILD)\n", who, rel);
        return -1;
    }
    if (!tl_mesh_path("sphere_cgal.obj") || !realpath(tl_mesh_path("sphere_cgal.obj"), sphere)) {
        fprintf(stderr, "%s: no %s/meshes/sphere_cgal.obj (set MCF_TESTDATA)\n", who,
                tl_testdata_dir());
        return -1;
    }
    if (strlen(tmpl) >= sizeof scratch)
        return -1;
    strcpy(scratch, tmpl);
    return mkdtemp(scratch) ? 0 : -1;
}

int tl_mcf_teardown(void)
{
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", scratch);
    return system(cmd) == 0 ? 0 : -1;
}

const char *tl_prog(void)
{
    return mcf_path;
}

const char *tl_scratch(void)
{
    return scratch;
}

const char *tl_sphere(void)
{
    return sphere;
}

const char *tl_in_scratch(const char *name)
{
    /* per thread, as tl_mesh_path */
    static _Thread_local char p[4][4096];
    static _Thread_local int k;
    k = (k + 1) % 4;
    snprintf(p[k], sizeof p[k], "%s/%s", scratch, name);
    return p[k];
}

tl_run_result tl_run_env(const char *path_env, const char *a0, ...)
{
    const char *argv[64];
    char opath[128], epath[128];
    tl_run_result r = {0, NULL, NULL, 0, 0};
    va_list ap;
    int n = 0, st;
    pid_t pid;

    argv[n++] = mcf_path;
    va_start(ap, a0);
    for (const char *a = a0; a && n < 63; a = va_arg(ap, const char *))
        argv[n++] = a;
    va_end(ap);
    argv[n] = NULL;
    snprintf(opath, sizeof opath, "%s/stdout", scratch);
    snprintf(epath, sizeof epath, "%s/stderr", scratch);
    pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        int fo = open(opath, O_WRONLY | O_CREAT | O_TRUNC, 0600);
        int fe = open(epath, O_WRONLY | O_CREAT | O_TRUNC, 0600);
        if (fo < 0 || fe < 0 || chdir(scratch) != 0)
            _exit(127);
        dup2(fo, 1);
        dup2(fe, 2);
        if (path_env)
            setenv("PATH", path_env, 1);
        execv(mcf_path, (char *const *)(void *)argv);
        _exit(127);
    }
    assert_int_equal(waitpid(pid, &st, 0), pid);
    r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
    if (r.status == 127)
        fail_msg("cannot run %s (set MCF_BUILD)", mcf_path);
    assert_int_equal(tl_read_file(opath, &r.out, &r.outlen), 0);
    assert_int_equal(tl_read_file(epath, &r.err, &r.errlen), 0);
    return r;
}

void tl_run_free(tl_run_result *r)
{
    free(r->out);
    free(r->err);
    r->out = r->err = NULL;
}

void tl_expect_error(tl_run_result *r, int code, const char *want)
{
    const char *nl = strchr(r->err, '\n');
    if (r->status != code || strncmp(r->err, prog_prefix, strlen(prog_prefix)) != 0 || !nl
        || nl[1] != '\0' || !strstr(r->err, want))
        fail_msg("status %d, stderr \"%s\"; want status %d and one line with \"%s\"",
                 r->status, r->err, code, want);
    tl_run_free(r);
}

void tl_assert_same_mesh(const mcf_mesh *a, const mcf_mesh *b)
{
    assert_int_equal(mcf_mesh_nvertices(b), mcf_mesh_nvertices(a));
    assert_int_equal(mcf_mesh_nfaces(b), mcf_mesh_nfaces(a));
    assert_memory_equal(mcf_mesh_positions(b), mcf_mesh_positions(a),
                        sizeof(double) * 3 * (size_t)mcf_mesh_nvertices(a));
    assert_memory_equal(mcf_mesh_faces(b), mcf_mesh_faces(a),
                        sizeof(int32_t) * 3 * (size_t)mcf_mesh_nfaces(a));
}

mcf_status tl_decode_copy(tl_decoder fn, const void *buf, size_t len,
                          const api_limits *lim, mcf_mesh **m, mcf_error *err)
{
    void *copy = malloc(len ? len : 1);
    mcf_status rc;
    assert_non_null(copy);
    if (len)
        memcpy(copy, buf, len);
    *m = NULL;
    err->status = MCF_OK;
    err->msg[0] = '\0';
    rc = fn(copy, len, lim, m, err);
    free(copy);
    return rc;
}

/* ------------------------------------------------------ child processes */

/* Plain arrays and no locks: the signal handler reads them, and only the
 * test's main thread adds to them. */
#define TL_MAX_CHILDREN 64
static volatile pid_t children[TL_MAX_CHILDREN];
static volatile sig_atomic_t nchildren;

void tl_child_own_group(void)
{
    setpgid(0, 0);
}

/* 1 while pid runs, 0 once it exited (a zombie: its pid and the group it
 * leads stay reserved until it is reaped), -1 when it was reaped (or is no
 * child of ours). Reaps nothing (WNOWAIT): the tests wait for their
 * daemons themselves. */
static int child_state(pid_t pid)
{
    siginfo_t si;
    memset(&si, 0, sizeof si);
    if (waitid(P_PID, (id_t)pid, &si, WEXITED | WNOHANG | WNOWAIT) != 0)
        return -1;
    return si.si_pid == 0 ? 1 : 0;
}

/* SIGKILLs the group of every tracked child that still runs, other than
 * keep; with reap, also reaps it (and any tracked zombie). Only system
 * calls, so the signal handler can use it too. */
static int kill_tracked(pid_t keep, int reap)
{
    int i, killed = 0;
    for (i = 0; i < nchildren; i++) {
        pid_t pid = children[i];
        int st;
        if (pid <= 0 || pid == keep)
            continue;
        st = child_state(pid);
        if (st < 0) {
            children[i] = 0;
            continue;
        }
        if (st == 1) {
            kill(-pid, SIGKILL);
            kill(pid, SIGKILL); /* should it not have reached its own group yet */
            killed++;
        }
        if (reap) {
            waitpid(pid, NULL, 0);
            children[i] = 0;
        }
    }
    return killed;
}

static void kill_at_exit(void)
{
    kill_tracked(0, 1);
}

static void kill_on_signal(int sig)
{
    kill_tracked(0, 0);
    signal(sig, SIG_DFL);
    raise(sig);
}

void tl_track_child(pid_t pid)
{
    static int installed;
    int i;

    if (pid <= 0)
        return;
    if (!installed) {
        static const int sigs[] = {SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGABRT};
        struct sigaction sa;
        memset(&sa, 0, sizeof sa);
        sa.sa_handler = kill_on_signal;
        sigemptyset(&sa.sa_mask);
        for (i = 0; i < (int)(sizeof sigs / sizeof sigs[0]); i++)
            sigaction(sigs[i], &sa, NULL);
        atexit(kill_at_exit);
        installed = 1;
    }
    setpgid(pid, pid); /* fails harmlessly once the child has exec'd */
    for (i = 0; i < nchildren; i++)
        if (children[i] == 0 || child_state(children[i]) < 0) {
            children[i] = pid;
            return;
        }
    if (nchildren < TL_MAX_CHILDREN) {
        children[nchildren] = pid;
        nchildren++;
    } else {
        fprintf(stderr, "tl_track_child: more than %d children\n", TL_MAX_CHILDREN);
    }
}

int tl_kill_children(pid_t keep)
{
    return kill_tracked(keep, 1);
}

void tl_assimp_reads(const void *bytes, size_t len, const char *name, int nv, int nf)
{
    char path[4096], cmd[8400], line[512];
    FILE *f, *p;
    int got_v = -1, got_f = -1;
    snprintf(path, sizeof path, "%s/%s", getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp", name);
    f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(bytes, 1, len, f), len);
    fclose(f);
    snprintf(cmd, sizeof cmd, "assimp info '%s' 2>&1", path);
    p = popen(cmd, "r");
    assert_non_null(p);
    while (fgets(line, sizeof line, p)) {
        sscanf(line, "Vertices: %d", &got_v);
        sscanf(line, "Faces: %d", &got_f);
        if (strstr(line, "ERROR"))
            fail_msg("assimp on %s: %s", name, line);
    }
    if (pclose(p) != 0)
        fail_msg("assimp info %s failed (is assimp-utils installed? make deps)", name);
    remove(path);
    if ((nv && got_v != nv) || (nf && got_f != nf))
        fail_msg("assimp reads %s as %d vertices, %d faces; expected %d, %d", name, got_v,
                 got_f, nv, nf);
}

void tl_quad_grid(double X[147], int Q[144])
{
    int i, j;
    for (j = 0; j < 7; j++)
        for (i = 0; i < 7; i++) {
            X[3 * (7 * j + i)] = i / 6.0;
            X[3 * (7 * j + i) + 1] = j / 6.0;
            X[3 * (7 * j + i) + 2] = 0.05 * ((i * 3 + j * 5) % 4);
        }
    for (j = 0; j < 6; j++)
        for (i = 0; i < 6; i++) {
            int *q = Q + 4 * (6 * j + i);
            q[0] = 7 * j + i;
            q[1] = 7 * j + i + 1;
            q[2] = 7 * (j + 1) + i + 1;
            q[3] = 7 * (j + 1) + i;
        }
}

void tl_smooth_a_little(mcf_mesh *m)
{
    mcf_flow_params p;
    mcf_error err;
    mcf_flow_params_init(&p);
    p.scheme = MCF_DESBRUN2;
    p.dt = 1e-4;
    p.iterations = 2;
    if (mcf_flow_run(m, &p, NULL, &err) != MCF_OK)
        fail_msg("flow: %s", err.msg);
}

static void tl_face_normal(const double *X, const int32_t *t, double *n)
{
    const double *a = X + 3 * (size_t)t[0], *b = X + 3 * (size_t)t[1], *c = X + 3 * (size_t)t[2];
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    n[0] = u[1] * v[2] - u[2] * v[1];
    n[1] = u[2] * v[0] - u[0] * v[2];
    n[2] = u[0] * v[1] - u[1] * v[0];
}

int tl_flips_against(const mcf_mesh *x, const mcf_mesh *clean)
{
    const double *X = mcf_mesh_positions(x), *C = mcf_mesh_positions(clean);
    const int32_t *F = mcf_mesh_faces(x);
    int n = 0;
    for (int f = 0; f < mcf_mesh_nfaces(x); f++) {
        double a[3], b[3];
        tl_face_normal(X, F + 3 * (size_t)f, a);
        tl_face_normal(C, F + 3 * (size_t)f, b);
        n += a[0] * b[0] + a[1] * b[1] + a[2] * b[2] < 0.0;
    }
    return n;
}

int tl_folds_against(const double *X, const double *X0, const int32_t *F, int nf, int nv,
                     unsigned char *mask)
{
    /* per vertex: the summed face normals, and the summed squared edges
     * (from the first corner) of those faces, the scale of the sum's
     * rounding */
    double *N = calloc(3 * (size_t)nv + 1, sizeof *N), *E = calloc((size_t)nv + 1, sizeof *E);
    int bad = 0;
    if (!N || !E)
        fail_msg("tl_folds_against: out of memory");
    for (int f = 0; f < nf; f++) {
        const int32_t *t = F + 3 * (size_t)f;
        double a[3], e = 0.0;
        tl_face_normal(X, t, a);
        for (int k = 1; k < 3; k++)
            for (int d = 0; d < 3; d++)
                e += (X[3 * (size_t)t[k] + d] - X[3 * (size_t)t[0] + d]) * (X[3 * (size_t)t[k] + d] - X[3 * (size_t)t[0] + d]);
        for (int k = 0; k < 3; k++) {
            for (int d = 0; d < 3; d++)
                N[3 * (size_t)t[k] + d] += a[d];
            E[t[k]] += e;
        }
    }
    for (int f = 0; f < nf; f++) {
        const int32_t *t = F + 3 * (size_t)f;
        double a[3], b[3], s[3] = {0, 0, 0}, e = 0.0, es = 0.0;
        tl_face_normal(X, t, a);
        tl_face_normal(X0, t, b);
        for (int k = 1; k < 3; k++)
            for (int d = 0; d < 3; d++) {
                double q = X[3 * (size_t)t[k] + d] - X[3 * (size_t)t[0] + d];
                e += q * q;
            }
        for (int k = 0; k < 3; k++) {
            for (int d = 0; d < 3; d++)
                s[d] += N[3 * (size_t)t[k] + d];
            es += E[t[k]];
        }
        double aa = a[0] * a[0] + a[1] * a[1] + a[2] * a[2], bb = b[0] * b[0] + b[1] * b[1] + b[2] * b[2];
        /* lying backwards: against s, or within rounding (1e-10 of |a| and
         * the squared edges summed) of perpendicular to it (a two-sided
         * fin's s is 0 but for rounding) */
        int fold = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] < 0.0 && aa > 1e-20 * e * e && bb > 1e-20 * e * e &&
                   a[0] * s[0] + a[1] * s[1] + a[2] * s[2] <= 1e-10 * sqrt(aa) * es;
        if (mask)
            mask[f] = (unsigned char)fold;
        bad += fold;
    }
    free(N);
    free(E);
    return bad;
}
