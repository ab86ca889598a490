/* SPDX-License-Identifier: MIT */
/*
 * api_bounds.c - the CPU and memory a Draco decode may take, one rule for
 * the daemon (which decodes in a child process under them:
 * server/sandbox/sandbox.c) and the CLI (in its own process, cli/mcf.c).
 *
 * Why: libdraco 1.5.5 trusts counts inside a stream that no header check
 * sees: a 210-byte edgebreaker file costs 8.8 s of CPU and 256 MiB, then
 * decodes. CPU: libdraco decodes the 871k-face dragon in 0.19 s
 * (0.22 us/face), so 1 us per declared face above the floor leaves a
 * legitimate 10M-face stream more than twice what it needs. Memory: the
 * estimator's decode peak for the declared counts, twice, above a floor
 * that covers the decoder's own start.
 */
#include <stdio.h>
#include <unistd.h>

#include "api_internal.h"

void api_decode_bounds(const api_mem_estimate *est, double cpu_floor,
                       size_t mem_floor, double *cpu_s, size_t *mem_bytes)
{
    double mem = 2.0 * est->decode_bytes;
    *cpu_s = cpu_floor + 1e-6 * (double)est->faces;
    *mem_bytes = mem > (double)mem_floor ? (size_t)mem : mem_floor;
}

size_t api_vm_size(void)
{
    FILE *f = fopen("/proc/self/statm", "r");
    unsigned long pages = 0;
    if (!f)
        return 0;
    if (fscanf(f, "%lu", &pages) != 1)
        pages = 0;
    fclose(f);
    return (size_t)pages * (size_t)sysconf(_SC_PAGESIZE);
}
