/* SPDX-License-Identifier: MIT */
/*
 * bench_common.c - the machine header, medians, percentiles, file reading
 * and mesh loading shared by the lab/bench/ programs (contracts in
 * bench_common.h).
 * Linux only: /proc/cpuinfo, /proc/meminfo, /proc/loadavg and
 * sched_getaffinity (hence -D_GNU_SOURCE in lab/Makefile).
 */
#include "bench_common.h"

#include <errno.h>
#include <math.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/utsname.h>
#include <time.h>

#include "api.h"
#include "lab.h"

void bench_print_machine(void)
{
    char model[256] = "unknown", line[512], load[128] = "?", date[64];
    long memkb = 0;
    FILE *f = fopen("/proc/cpuinfo", "r");
    cpu_set_t set;
    struct utsname u;
    time_t now = time(NULL);
    int nproc;

    while (f && fgets(line, sizeof line, f))
        if (strncmp(line, "model name", 10) == 0) {
            char *c = strchr(line, ':');
            if (c && c[1]) {
                snprintf(model, sizeof model, "%s", c + 2);
                model[strcspn(model, "\n")] = 0;
            }
            break;
        }
    if (f)
        fclose(f);
    f = fopen("/proc/meminfo", "r");
    while (f && fgets(line, sizeof line, f))
        if (sscanf(line, "MemTotal: %ld kB", &memkb) == 1)
            break;
    if (f)
        fclose(f);
    f = fopen("/proc/loadavg", "r");
    if (f && fgets(load, sizeof load, f))
        load[strcspn(load, "\n")] = 0;
    if (f)
        fclose(f);
    nproc = sched_getaffinity(0, sizeof set, &set) == 0 ? CPU_COUNT(&set) : -1;
    strftime(date, sizeof date, "%Y-%m-%d %H:%M:%S UTC", gmtime(&now));
    if (uname(&u) != 0)
        strcpy(u.release, "?");
    printf("machine: %s, nproc %d, %.1f GiB RAM, Linux %s\n", model, nproc,
           (double)memkb / (1024.0 * 1024.0), u.release);
    printf("date:    %s, load average %s\n", date, load);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

double bench_median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double bench_percentile(double *v, int n, double p)
{
    int k;

    qsort(v, (size_t)n, sizeof *v, cmp_double);
    k = (int)ceil(p / 100.0 * n) - 1; /* nearest rank, 0-based */
    if (k < 0)
        k = 0;
    if (k > n - 1)
        k = n - 1;
    return v[k];
}

int bench_read_file(const char *path, char **buf, size_t *len)
{
    FILE *f = fopen(path, "rb");
    char *b = NULL;
    long n;
    int saved;

    if (!f)
        return -1;
    if (fseek(f, 0, SEEK_END) != 0 || (n = ftell(f)) < 0 ||
        fseek(f, 0, SEEK_SET) != 0)
        goto fail;
    b = malloc((size_t)n + 1);
    if (!b) {
        errno = ENOMEM;
        goto fail;
    }
    if (fread(b, 1, (size_t)n, f) != (size_t)n) {
        errno = EIO;
        goto fail;
    }
    fclose(f);
    b[n] = 0;
    *buf = b;
    *len = (size_t)n;
    return 0;
fail:
    saved = errno;
    free(b);
    fclose(f);
    errno = saved;
    return -1;
}

mcf_mesh *bench_load_mesh(const char *prog, const char *dir, const char *name)
{
    char path[4096], *buf = NULL;
    size_t len = 0;
    mcf_error e = {0};
    mcf_mesh *m = NULL;
    snprintf(path, sizeof path, "%s/%s", dir, name);
    if (bench_read_file(path, &buf, &len) != 0) {
        fprintf(stderr, "%s: cannot read %s: %s\n", prog, path, strerror(errno));
        exit(1);
    }
    if (api_mesh_decode(buf, len, NULL, &m, NULL, &e) != MCF_OK) {
        fprintf(stderr, "%s: %s: %s\n", prog, path, e.msg);
        exit(1);
    }
    free(buf);
    return m;
}

mcf_mesh *bench_dup_mesh(const char *prog, const mcf_mesh *m)
{
    mcf_error e = {0};
    mcf_mesh *d = mcf_mesh_dup(m, &e);
    if (!d) {
        fprintf(stderr, "%s: mcf_mesh_dup: %s\n", prog, e.msg);
        exit(1);
    }
    return d;
}

FILE *bench_open_out(const char *dir, const char *name)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "w");
    if (!f) {
        lab_fail(1, "cannot write %s: %s", path, strerror(errno));
        exit(1);
    }
    return f;
}
