/* SPDX-License-Identifier: MIT */
/*
 * mcf_error.c - status codes and warnings, their texts, the error-buffer
 * helper and the overflow-checked allocators every file of libmcf uses.
 *
 * The texts come from the one MCF_ERRORS table in mcf.h, so the enum, the
 * messages and the server's HTTP map cannot drift apart.
 */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "mcf_internal.h"

const char *mcf_strerror(mcf_status s)
{
    switch (s) {
#define MCF_X_(name, code, text) case MCF_##name: return text;
        MCF_ERRORS(MCF_X_)
#undef MCF_X_
    }
    return "unknown error";
}

const char *mcf_status_name(mcf_status s)
{
    switch (s) {
#define MCF_X_(name, code, text) case MCF_##name: return #name;
        MCF_ERRORS(MCF_X_)
#undef MCF_X_
    }
    return "EUNKNOWN";
}

const char *mcf_warning_name(unsigned bit)
{
    switch (bit) {
#define MCF_X_(name, b, id, text) case MCF_WARN_##name: return id;
        MCF_WARNINGS(MCF_X_)
#undef MCF_X_
    }
    return NULL;
}

const char *mcf_warning_text(unsigned bit)
{
    switch (bit) {
#define MCF_X_(name, b, id, text) case MCF_WARN_##name: return text;
        MCF_WARNINGS(MCF_X_)
#undef MCF_X_
    }
    return NULL;
}

mcf_status mcf_error_set(mcf_error *err, mcf_status code, const char *fmt, ...)
{
    if (err) {
        va_list ap;
        err->status = code;
        va_start(ap, fmt);
        vsnprintf(err->msg, sizeof err->msg, fmt, ap);
        va_end(ap);
    }
    return code;
}

void *mcf__calloc(size_t n, size_t size)
{
    if (n == 0 || size == 0)
        return calloc(1, 1);
    if (n > (size_t)-1 / size)
        return NULL;
    return calloc(n, size);
}

void *mcf__malloc(size_t n, size_t size)
{
    if (n == 0 || size == 0)
        return malloc(1);
    if (n > (size_t)-1 / size)
        return NULL;
    return malloc(n * size);
}

/* C11's timespec_get keeps core free of POSIX; TIME_UTC is a wall clock,
 * good enough for phase timings (a clock step shows as one odd figure). */
double mcf_now(void)
{
    struct timespec ts;
    if (timespec_get(&ts, TIME_UTC) != TIME_UTC)
        return 0.0;
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}
