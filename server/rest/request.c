/* SPDX-License-Identifier: MIT */
/*
 * request.c - what a REST request says, for every file of the door: its
 * route's label and its query string, raw or one value decoded. A leaf of
 * the door: it reads a rest_request and calls no other file of it, so the
 * router (http.c) and the files it calls (upload.c, reply.c, ...) all
 * reach it without calling back into the router.
 */
#include <ctype.h>
#include <stdlib.h>
#include <string.h>

#include "rest_internal.h"

static const char *const route_names[] = {
    "healthz", "readyz", "metrics", "openapi", "schemes", "smooth", "jobs",
    "job", "job_result", "job_metrics", "job_events", "job_fields", "ui",
    "other"};

const char *rest_route_name(rest_route rt)
{
    return route_names[rt];
}

const char *rest_query_of(const rest_request *r)
{
    const char *q = strchr(r->uri, '?');
    return q ? q + 1 : NULL;
}

const char *rest_query_value(const rest_request *r, const char *key,
                             char *out, size_t size)
{
    const char *p = rest_query_of(r), *found = NULL;
    size_t klen = strlen(key);

    while (p && *p) {
        size_t n = strcspn(p, "&");
        if (n > klen && strncmp(p, key, klen) == 0 && p[klen] == '=')
            found = p + klen + 1;
        else if (n == klen && strncmp(p, key, klen) == 0)
            found = p + klen;
        p += n;
        if (*p == '&')
            p++;
    }
    if (!found)
        return NULL;
    {
        size_t i = 0;
        for (; *found && *found != '&' && i + 1 < size; found++) {
            if (*found == '%' && isxdigit((unsigned char)found[1]) &&
                isxdigit((unsigned char)found[2])) {
                char hex[3] = {found[1], found[2], 0};
                out[i++] = (char)strtol(hex, NULL, 16);
                found += 2;
            } else {
                out[i++] = *found == '+' ? ' ' : *found;
            }
        }
        out[i] = '\0';
    }
    return out;
}
