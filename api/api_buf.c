/* SPDX-License-Identifier: MIT */
/*
 * api_buf.c - the api layer's growable byte buffer with a hard maximum
 * (curl's dynbuf).
 *
 * Encoders append millions of short lines, so api_buf_printf formats
 * straight into the spare capacity and only measures first when the text
 * does not fit. Capacity doubles; an append that would pass max fails with
 * ELIMIT and leaves the buffer exactly as it was.
 */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "api_internal.h"

/* max == 0 means no maximum beyond what size_t and malloc allow. */
void api_buf_init(api_buf *b, size_t max)
{
    b->data = NULL;
    b->len = 0;
    b->cap = 0;
    b->max = max;
}

void api_buf_free(api_buf *b)
{
    if (!b)
        return;
    free(b->data);
    b->data = NULL;
    b->len = 0;
    b->cap = 0;
}

/* Makes room for n more bytes plus the NUL. */
static mcf_status reserve(api_buf *b, size_t n)
{
    size_t need, ncap;
    char *p;

    if (n > (size_t)-1 - b->len - 1)
        return MCF_ELIMIT;
    need = b->len + n;
    if (b->max && need > b->max)
        return MCF_ELIMIT;
    if (need + 1 <= b->cap)
        return MCF_OK;
    ncap = b->cap ? b->cap : 256;
    while (ncap < need + 1) {
        if (ncap > (size_t)-1 / 2) {
            ncap = need + 1;
            break;
        }
        ncap *= 2;
    }
    /* Never reserve far beyond max: the NUL needs one byte past it (and
     * max + 1 must not wrap: max = SIZE_MAX is a legal "no limit"). */
    if (b->max && b->max < (size_t)-1 && ncap > b->max + 1)
        ncap = b->max + 1;
    p = realloc(b->data, ncap);
    if (!p)
        return MCF_ENOMEM;
    b->data = p;
    b->cap = ncap;
    return MCF_OK;
}

mcf_status api_buf_append(api_buf *b, const void *p, size_t n)
{
    mcf_status rc = reserve(b, n);
    if (rc != MCF_OK)
        return rc;
    if (n)
        memcpy(b->data + b->len, p, n);
    b->len += n;
    b->data[b->len] = '\0';
    return MCF_OK;
}

mcf_status api_buf_printf(api_buf *b, const char *fmt, ...)
{
    va_list ap;
    int n;
    size_t room = b->cap > b->len ? b->cap - b->len : 0;
    mcf_status rc;

    if (room) {
        va_start(ap, fmt);
        n = vsnprintf(b->data + b->len, room, fmt, ap);
        va_end(ap);
        if (n < 0) {
            b->data[b->len] = '\0';
            return MCF_EINVAL;
        }
        if ((size_t)n < room) {
            if (b->max && b->len + (size_t)n > b->max) {
                b->data[b->len] = '\0';
                return MCF_ELIMIT;
            }
            b->len += (size_t)n;
            return MCF_OK;
        }
        b->data[b->len] = '\0'; /* the partial text is not kept */
    } else {
        va_start(ap, fmt);
        n = vsnprintf(NULL, 0, fmt, ap);
        va_end(ap);
        if (n < 0)
            return MCF_EINVAL;
    }
    if ((rc = reserve(b, (size_t)n)) != MCF_OK)
        return rc;
    va_start(ap, fmt);
    vsnprintf(b->data + b->len, (size_t)n + 1, fmt, ap);
    va_end(ap);
    b->len += (size_t)n;
    return MCF_OK;
}

char *api_buf_detach(api_buf *b, size_t *len)
{
    char *p = b->data;
    if (!p) {
        p = malloc(1);
        if (p)
            p[0] = '\0';
    }
    if (len)
        *len = p ? b->len : 0;
    b->data = NULL;
    b->len = 0;
    b->cap = 0;
    return p;
}
