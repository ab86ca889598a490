/* SPDX-License-Identifier: MIT */
/*
 * sandbox.c - untrusted Draco streams are decoded in a child process with
 * a CPU limit, an address-space limit and a wall-clock deadline.
 *
 * Why: libdraco 1.5.5 trusts counts inside the stream that no header check
 * can see. A 210-byte edgebreaker file whose texcoord predictor declares
 * 2^31-1 orientations (tests/data/draco_texcoord_orientations.drc) makes
 * MeshPredictionSchemeTexCoordsPortableDecoder allocate 256 MiB and loop
 * for 8.8 s of CPU, then decode "successfully"; fuzzers found more such
 * inputs. Run in a worker thread, that is a worker and a quarter of a GB
 * per 210-byte request. In a child, the kernel enforces the bounds.
 *
 * How: the worker posix_spawn()s the daemon's own executable
 * (/proc/self/exe) in its hidden decode mode (`mcfd --sandbox-decode CPU
 * MEM MAXBYTES MAXV MAXF`, sandbox_child), writes the bytes to its
 * stdin and reads back a status, the detected format, a message and, on
 * success, the mesh and its attributes as api_mesh_pack's exact record.
 * The child closes every inherited descriptor above 2, sets RLIMIT_CPU
 * (soft: SIGXCPU; hard one second later: SIGKILL) and RLIMIT_AS (its
 * address space at start plus the memory budget) before it reads a byte,
 * and dies with its parent (PR_SET_PDEATHSIG). The parent polls both pipes
 * (non-blocking, 50 ms ticks) so it notices the job's cancel flag (DELETE,
 * client hang-up, shutdown checkpoint) and the wall-clock deadline, kills
 * the child with SIGKILL on every early exit, and always reaps it with
 * wait4 (whose rusage tells which limit it met). Both pipes are O_CLOEXEC
 * in the parent, so no other child inherits them.
 *
 * Limits per decode (sandbox_limits_for, the CLI's rule too:
 * api_decode_bounds): CPU = --decode-cpu (2 s) plus 1 us per declared
 * face: libdraco decodes the 871k-face dragon in 0.19 s (0.22 us/face), so
 * a legitimate 10M-face stream needs about 2.2 s, under half of its
 * 2 + 10 s. Memory = the estimator's decode peak for the declared counts
 * (api_estimate_memory) times 2, at least --decode-memory (64 MiB). Wall
 * clock = 10 x CPU + 5 s (waiting for a
 * core on a loaded machine is not the input's fault; a child that sleeps
 * is). A child stopped by a limit is a 422 ELIMIT naming the limit.
 *
 * Cost: one process start per Draco decode, measured in the README
 * (reliability section). Under AddressSanitizer the address-space limit
 * is left out (ASan reserves terabytes of shadow at start); CPU and wall
 * clock still hold.
 */
#define _GNU_SOURCE 1
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/time.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "sandbox.h"
#include "srv.h"

extern char **environ;

#define MIB (1024.0 * 1024.0)

/* The child's answer before the packed mesh. */
typedef struct {
    int32_t status;            /* mcf_status of the decode */
    int32_t format;            /* api_format detected */
    int32_t msglen;            /* bytes of message that follow */
} child_head;

/* ------------------------------------------------------------------ child */

int sandbox_child(int argc, char **argv)
{
    double cpu;
    size_t mem, max_in, len = 0, cap;
    api_limits lim;
    struct rlimit rl;
    char *buf;
    mcf_mesh *m = NULL;
    api_attrs *attrs = NULL;
    api_format fmt = API_FMT_UNKNOWN;
    mcf_error err = {MCF_OK, ""};
    api_buf out;
    child_head h;

    if (argc != 7)
        return 2;
    /* Nothing but the two pipes and stderr: a descriptor of the daemon
     * (a socket, a spool file) must not live on in here. */
    closefrom(3);
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    cpu = strtod(argv[2], NULL);
    mem = strtoull(argv[3], NULL, 10);
    api_limits_default(&lim);
    max_in = lim.max_input_bytes = strtoull(argv[4], NULL, 10);
    lim.max_vertices = atoi(argv[5]);
    lim.max_faces = atoi(argv[6]);
    rl.rlim_cur = (rlim_t)(cpu + 0.999);
    rl.rlim_max = rl.rlim_cur + 1;
    if (setrlimit(RLIMIT_CPU, &rl) != 0)
        return 3;
    if (!API_SANITIZED) { /* api.h: none under ASan or TSan */
        rl.rlim_cur = rl.rlim_max = api_vm_size() + mem;
        if (setrlimit(RLIMIT_AS, &rl) != 0)
            return 3;
    }
    cap = 1 << 16;
    buf = malloc(cap);
    for (;;) {
        ssize_t r;
        if (!buf)
            return 4;
        if (len == cap) {
            char *nb;
            if (cap > max_in) {
                free(buf);
                return 5;     /* the parent sends at most max_in bytes */
            }
            nb = realloc(buf, cap * 2);
            if (!nb) {
                free(buf);
                return 4;
            }
            buf = nb;
            cap *= 2;
        }
        r = read(0, buf + len, cap - len);
        if (r < 0 && errno == EINTR)
            continue;
        if (r < 0) {
            free(buf);
            return 5;
        }
        if (r == 0)
            break;
        len += (size_t)r;
    }
    h.status = api_mesh_decode_attrs(buf, len, &lim, &m, &attrs, &fmt, &err);
    free(buf);
    api_buf_init(&out, (size_t)-1);
    if (h.status == MCF_OK)
        h.status = api_mesh_pack(m, attrs, &out, &err);
    h.format = fmt;
    h.msglen = h.status == MCF_OK ? 0 : (int32_t)strlen(err.msg);
    mcf_mesh_free(m);
    api_attrs_free(attrs);
    /* everything freed: a leak checker (the ASan build) exits clean */
    if (srv_write_all(1, &h, sizeof h) != 0 ||
        srv_write_all(1, err.msg, (size_t)h.msglen) != 0 ||
        srv_write_all(1, out.data, out.len) != 0) {
        api_buf_free(&out);
        return 6;
    }
    api_buf_free(&out);
    return 0;
}

/* ----------------------------------------------------------------- parent */

void sandbox_limits_for(const api_mem_estimate *est, double cpu_floor,
                        size_t mem_floor, sandbox_limits *out)
{
    api_decode_bounds(est, cpu_floor, mem_floor, &out->cpu_s, &out->mem_bytes);
    out->wall_s = 10.0 * out->cpu_s + 5.0;
}

int sandbox_wanted(const api_mem_estimate *est)
{
    return est->draco;
}

static double mono(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* The largest record a decode within lim can send back: head, message,
 * and api_mesh_pack's record at its largest. */
static size_t reply_max(const api_limits *lim)
{
    return sizeof(child_head) + MCF_ERRMSG_SIZE + api_mesh_pack_max(lim);
}

/* The decoder process: this program again in its hidden mode, with its
 * stdin from in[0] and its stdout to res[1], signals as a fresh process
 * has them. 0 and *pid, or -1 (err set). */
static int spawn_child(char *const argv[], const int in[2], const int res[2],
                       pid_t *pid, mcf_error *err)
{
    posix_spawn_file_actions_t fa;
    posix_spawnattr_t at;
    sigset_t none, deflt;
    int e;

    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_adddup2(&fa, in[0], 0);
    posix_spawn_file_actions_adddup2(&fa, res[1], 1);
    posix_spawnattr_init(&at);
    sigemptyset(&none);
    sigemptyset(&deflt);
    sigaddset(&deflt, SIGPIPE);
    sigaddset(&deflt, SIGTERM);
    sigaddset(&deflt, SIGINT);
    sigaddset(&deflt, SIGXCPU);
    posix_spawnattr_setsigmask(&at, &none);
    posix_spawnattr_setsigdefault(&at, &deflt);
    posix_spawnattr_setflags(&at, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);
    e = posix_spawn(pid, "/proc/self/exe", &fa, &at, argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    posix_spawnattr_destroy(&at);
    if (e == 0)
        return 0;
    *pid = -1;
    mcf_error_set(err, MCF_ENOMEM, "sandbox: cannot start a decoder process: %s",
                  strerror(e));
    return -1;
}

/* Feeds buf to the child (fd_in, closed at the end: its EOF) while its
 * answer comes into rep (fd_res, closed at its EOF), until it is all in,
 * the job is canceled or the wall-clock deadline passes. Returns why it
 * stopped early (SANDBOX_OK: it did not); the descriptors still open
 * are the caller's. */
static sandbox_why exchange(int *fd_in, int *fd_res, const void *buf,
                            size_t len, const mcf_cancel_flag *cancel,
                            double deadline, api_buf *rep)
{
    size_t sent = 0;

    fcntl(*fd_in, F_SETFL, O_NONBLOCK);
    fcntl(*fd_res, F_SETFL, O_NONBLOCK);
    while (*fd_res >= 0) {
        struct pollfd p[2];
        int n = 0, r;
        p[n].fd = *fd_res;
        p[n++].events = POLLIN;
        if (*fd_in >= 0) {
            p[n].fd = *fd_in;
            p[n++].events = POLLOUT;
        }
        r = poll(p, (nfds_t)n, 50);
        if (r < 0 && errno != EINTR)
            return SANDBOX_PROTOCOL;
        if (cancel && atomic_load_explicit(cancel, memory_order_acquire))
            return SANDBOX_CANCELED;
        if (mono() > deadline)
            return SANDBOX_WALL;
        if (r <= 0)
            continue;
        if (n == 2 && (p[1].revents & (POLLOUT | POLLERR | POLLHUP))) {
            ssize_t w = write(*fd_in, (const char *)buf + sent, len - sent);
            if (w > 0)
                sent += (size_t)w;
            if ((w < 0 && errno != EAGAIN && errno != EINTR) || sent == len) {
                close(*fd_in); /* EOF: the child decodes now (or it died) */
                *fd_in = -1;
            }
        }
        if (p[0].revents & (POLLIN | POLLERR | POLLHUP)) {
            char chunk[1 << 16];
            ssize_t got = read(*fd_res, chunk, sizeof chunk);
            if (got > 0 && api_buf_append(rep, chunk, (size_t)got) != MCF_OK)
                return SANDBOX_PROTOCOL; /* more than any mesh needs */
            if (got == 0 || (got < 0 && errno != EAGAIN && errno != EINTR)) {
                close(*fd_res);
                *fd_res = -1;
            }
        }
    }
    return SANDBOX_OK;
}

/* What the child's end says, once it was reaped (status, ru; killed: by
 * us, after it stopped early): the mesh from its answer (rep), or why
 * not. */
static mcf_status verdict(int status, const struct rusage *ru, int killed,
                          const api_buf *rep, const api_limits *lim,
                          const sandbox_limits *sl, mcf_mesh **out,
                          api_attrs **attrs, api_format *fmt,
                          sandbox_why *why, mcf_error *err)
{
    double cpu = (double)ru->ru_utime.tv_sec + 1e-6 * ru->ru_utime.tv_usec +
                 (double)ru->ru_stime.tv_sec + 1e-6 * ru->ru_stime.tv_usec;
    double rss = (double)ru->ru_maxrss * 1024.0;
    int sig = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
    child_head h;

    if (!killed && (sig == SIGXCPU || (sig == SIGKILL && cpu >= sl->cpu_s))) {
        *why = SANDBOX_CPU;
        return mcf_error_set(err, MCF_ELIMIT, "the Draco stream needs more "
                             "than %.3g s of CPU to decode: refused", sl->cpu_s);
    }
    if (rep->len >= sizeof h && WIFEXITED(status) && WEXITSTATUS(status) == 0) {
        memcpy(&h, rep->data, sizeof h);
        if (h.msglen >= 0 && h.msglen < MCF_ERRMSG_SIZE &&
            rep->len >= sizeof h + (size_t)h.msglen) {
            if (fmt)
                *fmt = (api_format)h.format;
            if (h.status == MCF_ENOMEM) {
                *why = SANDBOX_MEMORY;
                return mcf_error_set(err, MCF_ELIMIT, "the Draco stream needs "
                                     "more than %.0f MiB to decode: refused",
                                     sl->mem_bytes / MIB);
            }
            if (h.status != MCF_OK)
                return mcf_error_set(err, (mcf_status)h.status, "%.*s",
                                     (int)h.msglen, rep->data + sizeof h);
            return api_mesh_unpack(rep->data + sizeof h + h.msglen,
                                   rep->len - sizeof h - (size_t)h.msglen, lim,
                                   out, attrs, err);
        }
    }
    /* Died another way: an abort or a fault inside libdraco (a failed
     * allocation in code that cannot throw ends like this too). */
    if (sig && !killed && !API_SANITIZED && rss > 0.75 * (double)sl->mem_bytes) {
        *why = SANDBOX_MEMORY;
        return mcf_error_set(err, MCF_ELIMIT, "the Draco stream needs more "
                             "than %.0f MiB to decode: refused",
                             sl->mem_bytes / MIB);
    }
    *why = SANDBOX_PROTOCOL;
    if (sig)
        return mcf_error_set(err, MCF_EDECODE, "draco: the decoder process "
                             "died of signal %d (%s): refused", sig,
                             strsignal(sig));
    return mcf_error_set(err, MCF_EDECODE, "draco: the decoder process exited "
                         "with status %d and %zu bytes of answer",
                         WIFEXITED(status) ? WEXITSTATUS(status) : -1, rep->len);
}

static void close_fd(int *fd)
{
    if (*fd >= 0)
        close(*fd);
    *fd = -1;
}

mcf_status sandbox_decode(const void *buf, size_t len,
                          const api_limits *lim,
                          const sandbox_limits *sl,
                          const mcf_cancel_flag *cancel, mcf_mesh **out,
                          api_attrs **attrs, api_format *fmt,
                          sandbox_why *why, mcf_error *err)
{
    int in[2] = {-1, -1}, res[2] = {-1, -1}, status = 0, killed = 0;
    char a_cpu[32], a_mem[32], a_in[32], a_v[16], a_f[16];
    char *argv[] = {"mcfd", SANDBOX_ARG, a_cpu, a_mem, a_in, a_v, a_f, NULL};
    pid_t pid = -1;
    api_buf rep;
    struct rusage ru;
    mcf_status rc;

    *why = SANDBOX_OK;
    api_buf_init(&rep, reply_max(lim));
    snprintf(a_cpu, sizeof a_cpu, "%.3f", sl->cpu_s);
    snprintf(a_mem, sizeof a_mem, "%zu", sl->mem_bytes);
    snprintf(a_in, sizeof a_in, "%zu", lim->max_input_bytes);
    snprintf(a_v, sizeof a_v, "%d", lim->max_vertices);
    snprintf(a_f, sizeof a_f, "%d", lim->max_faces);
    if (pipe2(in, O_CLOEXEC) != 0 || pipe2(res, O_CLOEXEC) != 0) {
        rc = mcf_error_set(err, MCF_ENOMEM, "sandbox: pipe: %s", strerror(errno));
        goto out;
    }
    status = spawn_child(argv, in, res, &pid, err);
    close_fd(&in[0]);
    close_fd(&res[1]);
    if (status != 0) {
        rc = err->status;
        goto out;
    }
    *why = exchange(&in[1], &res[0], buf, len, cancel, mono() + sl->wall_s,
                    &rep);
    if (res[0] >= 0) {         /* left early: the child dies now */
        kill(pid, SIGKILL);
        killed = 1;
    }
    while (wait4(pid, &status, 0, &ru) < 0 && errno == EINTR)
        ;
    pid = -1;
    if (*why == SANDBOX_CANCELED)
        rc = mcf_error_set(err, MCF_ECANCELED, "canceled while decoding");
    else if (*why == SANDBOX_WALL)
        rc = mcf_error_set(err, MCF_ELIMIT, "the Draco stream took more than "
                           "%.3g s of wall-clock time to decode: refused",
                           sl->wall_s);
    else
        rc = verdict(status, &ru, killed, &rep, lim, sl, out, attrs, fmt, why,
                     err);
out:
    if (pid > 0) {
        kill(pid, SIGKILL);
        while (waitpid(pid, NULL, 0) < 0 && errno == EINTR)
            ;
    }
    close_fd(&in[0]);
    close_fd(&in[1]);
    close_fd(&res[0]);
    close_fd(&res[1]);
    api_buf_free(&rep);
    return rc;
}

/* -------------------------------------------------------------- job runner */

mcf_status sandbox_decode_upload(const void *buf, size_t len,
                                 const svc_config *cfg,
                                 const mcf_cancel_flag *cancel, mcf_mesh **out,
                                 api_attrs **attrs, api_format *fmt,
                                 api_job_stage *stage, mcf_error *err)
{
    api_mem_estimate est;
    sandbox_limits sl;
    sandbox_why why;
    mcf_status rc;

    api_estimate_memory(buf, len, NULL, &est);
    if (!sandbox_wanted(&est))
        return api_mesh_decode_attrs(buf, len, &cfg->lim, out, attrs, fmt, err);
    sandbox_limits_for(&est, cfg->decode_cpu, cfg->decode_memory, &sl);
    rc = sandbox_decode(buf, len, &cfg->lim, &sl, cancel, out, attrs, fmt,
                        &why, err);
    /* A limit met is the input's cost, not its size: 422, not 413. */
    if (why == SANDBOX_CPU || why == SANDBOX_MEMORY ||
        why == SANDBOX_WALL)
        *stage = API_JOB_RUN;
    return rc;
}
