/* SPDX-License-Identifier: MIT */
/*
 * bench_common.h - helpers shared by the lab/bench/ programs: the machine and
 * date header every benchmark prints first (so runs of different programs
 * can be told apart and compared), medians and percentiles, reading a
 * whole file, loading a mesh. Compiled with -D_GNU_SOURCE (sched_getaffinity).
 */
#ifndef BENCH_COMMON_H
#define BENCH_COMMON_H

#include <stddef.h>
#include <stdio.h>

#include "mcf.h"

/* Prints two lines to stdout:
 *   machine: <CPU model>, nproc <usable CPUs>, <RAM> GiB RAM, Linux <release>
 *   date:    <UTC date and time>, load average <the /proc/loadavg fields>
 * Fields that cannot be read print as "unknown" or "?". */
void bench_print_machine(void);

/* Median of n >= 1 values; v is sorted in place. */
double bench_median(double *v, int n);

/* The p-th percentile (0 <= p <= 100) of n >= 1 values by nearest rank
 * (the smallest value with at least p% of the values <= it); v is sorted
 * in place. p = 50 is the lower median for even n. */
double bench_percentile(double *v, int n, double p);

/* Reads the whole file into a malloc'ed buffer (one extra NUL byte after
 * the data, not counted in *len). Returns 0, or -1 with errno set (*buf
 * untouched). The caller frees *buf. */
int bench_read_file(const char *path, char **buf, size_t *len);

/* Reads dir/name and decodes it (default limits); mcf_mesh_dup. Both exit
 * with status 1 and a line "<prog>: ..." on stderr on failure. */
mcf_mesh *bench_load_mesh(const char *prog, const char *dir, const char *name);
mcf_mesh *bench_dup_mesh(const char *prog, const mcf_mesh *m);

/* Opens dir/name for writing; on failure exits with status 1 and a line
 * "<lab_prog>: cannot write PATH: reason" on stderr. */
FILE *bench_open_out(const char *dir, const char *name);

#endif
