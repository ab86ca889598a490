/* SPDX-License-Identifier: MIT */
/*
 * api_limits.c - the default limits on untrusted input (api_limits).
 *
 * One place for every bound, so the daemon, the CLI and the fuzzers all
 * enforce the same numbers; the daemon may lower them from its config.
 */
#include "api_internal.h"

void api_limits_default(api_limits *lim)
{
    lim->max_input_bytes = (size_t)256 << 20;
    lim->max_vertices = 5000000;
    lim->max_faces = 10000000;
    lim->max_iterations = 100000;
    lim->max_work = 2e10;
    lim->max_json_bytes = (size_t)64 << 10;
    lim->max_json_depth = 16;
    lim->max_fixed = lim->max_vertices;
}
