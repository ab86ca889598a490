/* SPDX-License-Identifier: MIT */
/*
 * cli_files.c - the files of `mcf`: reading IN (or stdin) up to the input
 * bound, decoding it (Draco under the daemon's CPU and memory bound, in
 * this process), encoding and writing OUT (or stdout) through a temporary
 * file renamed over it, so a failed run never leaves a half-written OUT.
 */
#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <unistd.h>

#include "api.h"
#include "cli.h"

/* ------------------------------------------------------------------ files */

/* Reads path ("-": stdin) into a malloc'ed buffer of at most max bytes.
 * Returns 0, or an exit status after printing the error line; cancel (may
 * be NULL) set meanwhile (a signal, which also ends a read waiting on a
 * pipe): EXIT_SIGNAL, no line printed (the caller's to say). */
int read_all(const char *path, size_t max, const mcf_cancel_flag *cancel, char **buf,
             size_t *len)
{
    FILE *f = strcmp(path, "-") == 0 ? stdin : fopen(path, "rb");
    char *data = NULL;
    size_t n = 0, cap = 0;
    int rc = 1;

    if (!f)
        return fail(1, "cannot read '%s': %s", path, strerror(errno));
    for (;;) {
        size_t got;
        if (cap - n < 65536) {
            size_t ncap = cap ? cap * 2 : 1 << 20;
            char *p = realloc(data, ncap + 1);
            if (!p) {
                fail(1, "'%s': out of memory", path);
                goto done;
            }
            data = p;
            cap = ncap;
        }
        got = fread(data + n, 1, cap - n, f);
        n += got;
        if (cancel && atomic_load(cancel)) {
            rc = EXIT_SIGNAL;
            goto done;
        }
        if (n > max) {
            fail(1, "'%s': larger than max_input_bytes (%zu)", path, max);
            goto done;
        }
        if (got == 0) {
            if (ferror(f) && errno == EINTR && cancel) {
                clearerr(f); /* a signal other than the cancel's */
                continue;
            }
            if (ferror(f)) {
                fail(1, "cannot read '%s': %s", path, strerror(errno));
                goto done;
            }
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
    if (f != stdin)
        fclose(f);
    return rc;
}

/* Writes len bytes to path ("-": stdout) through a temporary file renamed
 * over path, so readers never see a partial file; cancel (may be NULL)
 * set by then: the temporary file removed, path untouched, ECANCELED.
 * 0, or -1 with the error line's text in err. */
int write_file(const char *path, const void *buf, size_t len,
               const mcf_cancel_flag *cancel, mcf_error *err)
{
    char *tmp;
    FILE *f;
    int ok;

    if (strcmp(path, "-") == 0) {
        if (fwrite(buf, 1, len, stdout) != len || fflush(stdout) != 0) {
            mcf_error_set(err, MCF_EIO, "cannot write to stdout: %s", strerror(errno));
            return -1;
        }
        return 0;
    }
    tmp = malloc(strlen(path) + 32);
    if (!tmp) {
        mcf_error_set(err, MCF_ENOMEM, "out of memory");
        return -1;
    }
    sprintf(tmp, "%s.tmp%ld", path, (long)getpid());
    f = fopen(tmp, "wb");
    ok = f != NULL;
    if (f) {
        ok = fwrite(buf, 1, len, f) == len;
        ok = (fclose(f) == 0) && ok;
        if (ok && cancel && atomic_load(cancel)) {
            remove(tmp);
            free(tmp);
            mcf_error_set(err, MCF_ECANCELED, "canceled before '%s' was in place", path);
            return -1;
        }
        ok = ok && rename(tmp, path) == 0;
    }
    if (!ok) {
        int e = errno;
        if (f)
            remove(tmp);
        mcf_error_set(err, MCF_EIO, "cannot write '%s': %s", path, strerror(e));
    }
    free(tmp);
    return ok ? 0 : -1;
}

/* write_file, or the error line and exit status 1. */
int write_all(const char *path, const void *buf, size_t len)
{
    mcf_error err;
    return write_file(path, buf, len, NULL, &err) == 0 ? 0 : fail(1, "%s", err.msg);
}

/* Draco decodes under the daemon's bound (api_decode_bounds with the
 * daemon's default floors; the daemon's is a child process, here it is
 * this one: the CLI's files are its user's): libdraco 1.5.5 trusts counts
 * inside a stream that no header check sees (210 bytes cost 256 MiB and
 * 8.8 s of CPU). While it decodes, the soft RLIMIT_AS is the process's
 * size plus the memory bound (a failed allocation is an ENOMEM), and the
 * soft RLIMIT_CPU the CPU bound beyond what it used (SIGXCPU: the message
 * below, exit 1); both are put back after. No RLIMIT_AS under ASan/TSan
 * (API_SANITIZED). */

static void on_decode_cpu(int sig)
{
    static const char msg[] = "mcf: the Draco stream needs more than its "
                              "decode CPU limit (2 s + 1 us per declared face): refused\n";
    (void)sig;
    if (write(2, msg, sizeof msg - 1) < 0) {
        /* nothing more to say */
    }
    _exit(1);
}

mcf_status decode_bounded(const char *buf, size_t len,
                          const api_limits *lim, mcf_mesh **m,
                          api_attrs **attrs, api_format *fmt,
                          mcf_error *err)
{
    struct rlimit as0, cpu0, rl;
    struct rusage ru;
    api_mem_estimate est;
    double cpu;
    size_t mem;
    int bound_as = 0, bound_cpu = 0;
    mcf_status st;
    void (*old)(int);

    api_estimate_memory(buf, len, NULL, &est);
    if (!est.draco) /* libdraco is not reached (the daemon's rule too) */
        return api_mesh_decode_attrs(buf, len, lim, m, attrs, fmt, err);
    api_decode_bounds(&est, API_DECODE_CPU_S, API_DECODE_MEMORY, &cpu, &mem);
    if (!API_SANITIZED && getrlimit(RLIMIT_AS, &as0) == 0) {
        rl = as0;
        rl.rlim_cur = (rlim_t)(api_vm_size() + mem);
        bound_as = (as0.rlim_max == RLIM_INFINITY || rl.rlim_cur < as0.rlim_max) &&
                   setrlimit(RLIMIT_AS, &rl) == 0;
    }
    old = signal(SIGXCPU, on_decode_cpu);
    if (getrlimit(RLIMIT_CPU, &cpu0) == 0 && getrusage(RUSAGE_SELF, &ru) == 0) {
        rl = cpu0;
        rl.rlim_cur = (rlim_t)(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec + cpu + 1);
        bound_cpu = (cpu0.rlim_max == RLIM_INFINITY || rl.rlim_cur < cpu0.rlim_max) &&
                    setrlimit(RLIMIT_CPU, &rl) == 0;
    }
    st = api_mesh_decode_attrs(buf, len, lim, m, attrs, fmt, err);
    if (bound_cpu)
        setrlimit(RLIMIT_CPU, &cpu0);
    signal(SIGXCPU, old);
    if (bound_as)
        setrlimit(RLIMIT_AS, &as0);
    if (st == MCF_ENOMEM && bound_as)
        mcf_error_set(err, MCF_ELIMIT, "the Draco stream needs more than %.0f "
                      "MiB to decode: refused", (double)mem / 1048576.0);
    return st;
}

/* Reads and decodes a mesh file; *attrs (the input's texture coordinates,
 * colours, normals and precision, for the output), *fmt and the timings
 * are optional. */
int load_mesh_attrs(const char *path, const api_limits *lim,
                    mcf_mesh **m, api_attrs **attrs, api_format *fmt,
                    size_t *bytes, double *read_s, double *decode_s)
{
    char *buf = NULL;
    size_t len = 0;
    mcf_error err = {MCF_OK, ""};
    mcf_status st;
    double t0 = now(), t1;
    int rc;

    if ((rc = read_all(path, lim->max_input_bytes, NULL, &buf, &len)) != 0)
        return rc;
    t1 = now();
    st = decode_bounded(buf, len, lim, m, attrs, fmt, &err);
    free(buf);
    if (st != MCF_OK)
        return fail(1, "%s: %s", path, err.msg);
    if (bytes)
        *bytes = len;
    if (read_s)
        *read_s = t1 - t0;
    if (decode_s)
        *decode_s = now() - t1;
    return 0;
}

int load_mesh(const char *path, const api_limits *lim, mcf_mesh **m,
              api_format *fmt, size_t *bytes, double *read_s,
              double *decode_s)
{
    return load_mesh_attrs(path, lim, m, NULL, fmt, bytes, read_s, decode_s);
}

/* Encodes (measuring Draco's quantization error) and writes OUT, with the
 * input's attributes when opts->attrs has them. PLY curvature properties
 * are opt-in (--ply-curvature), as in the daemon (ply_curvature). */
int save_mesh(const mcf_mesh *m, const api_encode_opts *opts,
              const char *path, size_t *bytes, double *encode_s,
              double *write_s, double *qerr)
{
    api_buf b;
    api_encode_opts o = *opts;
    mcf_error err = {MCF_OK, ""};
    mcf_status st;
    double t0 = now(), t1;
    int rc;

    api_buf_init(&b, 0);
    if (o.format == API_FMT_DRACO)
        st = api_draco_encode(m, &o, &b, qerr, &err);
    else
        st = api_mesh_encode(m, &o, &b, &err);
    if (st != MCF_OK) {
        api_buf_free(&b);
        return fail(1, "%s: %s", path, err.msg);
    }
    t1 = now();
    rc = write_all(path, b.data ? b.data : "", b.len);
    if (bytes)
        *bytes = b.len;
    if (encode_s)
        *encode_s = t1 - t0;
    if (write_s)
        *write_s = now() - t1;
    api_buf_free(&b);
    return rc;
}
