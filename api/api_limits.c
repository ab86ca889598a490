/* SPDX-License-Identifier: MIT */
/*
 * api_limits.c - the default limits on untrusted input (api_limits).
 *
 * One place for every bound, so the daemon, the CLI and the fuzzers all
 * enforce the same numbers; the daemon and the CLI may change them
 * (mcfd's --max-vertices, mcf's --max-vertices...).
 *
 * No size wall below memory (issue 27): the vertex and face counts are
 * bounded only by what core's int indices hold with room to spare (the
 * vertex graph's 2 x edges ~ 6 nv adjacency entries and 3 nf corner
 * indices stay below 2^31 up to 300M vertices and 700M faces); what a
 * machine can hold is the daemon's memory admission's (api_estimate.c,
 * --max-memory), where a 10M-vertex scan's explicit passes are charged
 * about 6.4 GB. max_input_bytes stays the daemon's upload bound
 * (--max-upload: a request body is held in memory and on the spool); the
 * CLI reads local files and sets its own (cli/mcf.c: none).
 */
#include "api_internal.h"

void api_limits_default(api_limits *lim)
{
    lim->max_input_bytes = (size_t)256 << 20;
    lim->max_vertices = 100000000;
    lim->max_faces = 200000000;
#ifdef FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION
    /* a few hundred fuzzed bytes may declare counts a decoder reserves
     * memory for before reading them (libdraco: 12 bytes per face); the
     * daemon's sandbox bounds that by the estimate, libFuzzer by its 2 GB
     * RSS limit: the fuzzers keep the old 5M/10M counts */
    lim->max_vertices = 5000000;
    lim->max_faces = 10000000;
#endif
    lim->max_iterations = 100000;
    lim->max_work = 2e10;
    lim->max_json_bytes = (size_t)64 << 10;
    lim->max_json_depth = 16;
    lim->max_fixed = lim->max_vertices;
}
