/* SPDX-License-Identifier: MIT */
/*
 * api_ply_internal.h - what the PLY reader's files share (api_ply_header.c
 * parses the header, api_ply.c reads the body): the property types, the
 * roles of the properties read, and the parsed header (elements and their
 * properties, names pointing into the input buffer).
 */
#ifndef API_PLY_INTERNAL_H
#define API_PLY_INTERNAL_H

#include "api_internal.h"

typedef enum { T_NONE = 0, T_I8, T_U8, T_I16, T_U16, T_I32, T_U32, T_F32, T_F64 } ptype;

/* Bytes of one value of each ptype (T_NONE: 0), and its header name. */
extern const size_t api__ply_type_size[T_F64 + 1];
const char *api__ply_type_name(ptype t);

static inline int is_int_type(ptype t)
{
    return t != T_NONE && t != T_F32 && t != T_F64;
}

enum {
    ROLE_NONE = 0, ROLE_X, ROLE_Y, ROLE_Z, ROLE_INDICES,
    /* vertex attributes (read only for api_ply_decode_attrs) */
    ROLE_NX, ROLE_NY, ROLE_NZ, ROLE_S, ROLE_T, ROLE_R, ROLE_G, ROLE_B, ROLE_A,
    ROLE_FTC,       /* the face's `texcoord` list (u v per corner) */
    ROLE_EXTRA,     /* any other vertex scalar (quality, confidence, ...):
                       passed through (api__attrs_scalar), the first
                       API__PLY_EXTRA_MAX of them */
    ROLE_COUNT
};
#define NVROLES (ROLE_A - ROLE_NX + 1)

enum { FMT_ASCII = 0, FMT_LE, FMT_BE };

typedef struct {
    const char *name;       /* into the input buffer */
    size_t nlen;
    int is_list;
    ptype type;             /* scalar type, or the list's item type */
    ptype count_type;       /* list only */
    int role;
    int extra;              /* ROLE_EXTRA: its rank among the element's */
} prop;

typedef struct {
    const char *name;
    size_t nlen;
    unsigned long long count;
    prop *props;
    int nprops, cap;
    int nextra;             /* ROLE_EXTRA properties */
    int is_vertex, is_face;
} element;

typedef struct {
    int format;
    element *el;
    int nel, cap;
    size_t body;            /* offset of the first body byte */
    long body_line;         /* ASCII: number of the first body line */
} header;

/* Parses the header up to and including the end_header line into h
 * (api__ply_header_free frees it, also after an error). */
mcf_status api__ply_parse_header(const char *buf, size_t len, header *h, mcf_error *err);
void api__ply_header_free(header *h);

/* Smallest number of bytes one instance of e can take in the body. */
unsigned long long api__ply_min_size(const element *e, int format);

#endif
