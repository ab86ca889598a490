/* SPDX-License-Identifier: MIT */
/*
 * api_params_internal.h - the parameter table's types, shared by the three
 * files of the job parameters, not public: api_params.c (the table, its
 * description and its JSON form), api_params_parse.c (values from text,
 * JSON and query strings) and api_params_finish.c (the rules applied once
 * the mesh is known).
 */
#ifndef API_PARAMS_INTERNAL_H
#define API_PARAMS_INTERNAL_H

#include <stddef.h>

#include "api_internal.h"

typedef enum {
    K_NUM,      /* finite double, lo < x <= hi (or lo <= x with LO_INCL) */
    K_INT,      /* integer lo..hi (hi from the limits with HI_ITER) */
    K_BOOL,     /* true/false/1/0/yes/no */
    K_ENUM,     /* one of names[] (value = index) */
    K_SCHEME,   /* a scheme name (mcf_scheme_from_name) */
    K_FORMAT,   /* obj|draco|ply|stl|off */
    K_LIST      /* vertex indices: JSON array or comma/space separated */
} kind;

enum { LO_INCL = 1, AUTO = 2, HI_ITER = 4 };

typedef union {
    double d;
    long long i;
    int e;              /* bool, enum index, scheme, format */
} value;

typedef struct {
    const char *name;
    kind kind;
    double lo, hi;
    int flags;
    const char *const *names;
    void (*apply)(api_params *p, value v);
} keydef;

/* The one table (api_params.c), its length, and the names of K_FORMAT. */
extern const keydef api__param_keys[];
extern const size_t api__param_nkeys;
extern const char *const api__format_names[];

/* The key named name, or NULL. */
const keydef *api__param_find(const char *name);

/* What key k accepts, in words ("a number > 0 and <= 1000 or \"auto\"");
 * the error messages and api_params_describe share it. */
void api__param_accepts(const keydef *k, const api_limits *lim, char *out,
                        size_t size);

/* 1 for the fairing filters (api_params_finish.c). */
int api__is_fairing(mcf_scheme s);

#endif
