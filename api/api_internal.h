/*
 * api_internal.h - helpers shared by the files of the api layer, not
 * public (the server and the CLI use api.h only).
 *
 * Internal non-static functions carry the api__ prefix, as core's carry
 * mcf__.
 */
#ifndef API_INTERNAL_H
#define API_INTERNAL_H

#include "api.h"

/* Fills err (if non-NULL) with a formatted one-line message and returns
 * code: return api__fail(err, MCF_EDECODE, "line %d: ...", line);
 * the core's public mcf_error_set, so both layers format errors alike. */
#define api__fail mcf_error_set

/* Parses a decimal or scientific number from the n bytes at s (which need
 * not be NUL-terminated and are never read past s + n): the whole span
 * must be the number. Returns 0 and *out on success, -1 when the text is
 * not a number or too long (> 63 bytes). Non-finite values ("nan", "inf",
 * overflow to infinity) are returned as such: the caller decides. */
int api__parse_double(const char *s, size_t n, double *out);

#endif /* API_INTERNAL_H */
