/* SPDX-License-Identifier: MIT */
/*
 * api.h - the public interface of mcfd's api layer: bytes <-> meshes and
 * JSON parameters/metrics.
 *
 * Codecs work on memory buffers only, never on paths: (const void *buf,
 * size_t len) in, an mcf_mesh out; an mcf_mesh in, an api_buf out. Every
 * decoder checks the api_limits before data reaches core/ and names the
 * offending line, element or key in the mcf_error message. The Draco codec
 * and the glTF reader are C++ (api_draco.cc, api_gltf.cc over tinygltf);
 * they export plain C through this header.
 *
 * Dependencies run one way: server -> api -> core. This header may include
 * mcf.h and cJSON, never microhttpd.h.
 */
#ifndef API_H
#define API_H

#include <stddef.h>
#include <stdint.h>

#include <cjson/cJSON.h>

#include "mcf.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------ byte buffer */

/* A growable byte buffer with a hard maximum (curl's dynbuf). Appending
 * past max fails with ELIMIT and leaves the buffer unchanged. The data is
 * always NUL-terminated (not counted in len). init cannot fail. */
typedef struct {
    char *data;
    size_t len, cap, max;
} api_buf;

void api_buf_init(api_buf *b, size_t max);
void api_buf_free(api_buf *b);                   /* accepts zeroed */
mcf_status api_buf_append(api_buf *b, const void *p, size_t n);
mcf_status api_buf_printf(api_buf *b, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
/* Hands the data to the caller (free() it) and resets the buffer. */
char *api_buf_detach(api_buf *b, size_t *len);

/* ----------------------------------------------------------------- limits */

/* Every limit on untrusted input, in one place. 0 means "no limit" for
 * the size_t/double fields only where documented. */
typedef struct {
    size_t max_input_bytes;    /* one mesh upload (default 256 MiB) */
    int max_vertices;          /* default 100,000,000 (api_limits.c) */
    int max_faces;             /* default 200,000,000 */
    int max_iterations;        /* steps of one job (default 100,000) */
    double max_work;           /* iterations x vertices (default 2e10) */
    size_t max_json_bytes;     /* parameters document (default 64 KiB) */
    int max_json_depth;        /* nesting (default 16) */
    int max_fixed;             /* fixed-vertex list length (default = max_vertices) */
} api_limits;

void api_limits_default(api_limits *lim);

/* ---------------------------------------------------------------- formats */

typedef enum {
    API_FMT_UNKNOWN = 0,
    API_FMT_OBJ,
    API_FMT_DRACO,
    API_FMT_PLY,
    API_FMT_STL,
    API_FMT_OFF,
    API_FMT_GLB,               /* glTF 2.0 binary (model/gltf-binary) */
    API_FMT_GLTF               /* glTF 2.0 JSON, buffers embedded (model/gltf+json) */
} api_format;

/* From the bytes: "DRACO" magic, "ply\n", "OFF", binary STL size rule or
 * "solid ... facet", else OBJ-looking text ("v ", "f ", "#"). */
api_format api_format_detect(const void *buf, size_t len);
/* From a name, extension or file name: "obj", ".drc", "out.ply", "draco". */
api_format api_format_from_name(const char *name);
const char *api_format_name(api_format f);       /* "obj", "draco", ... */
const char *api_format_ext(api_format f);        /* ".obj", ".drc", ... */
const char *api_format_mime(api_format f);       /* "model/obj", ... */

/* ------------------------------------------------------------- attributes */

/* What a mesh file carries besides the geometry that core smooths: texture
 * coordinates, colours and normals, plus how the input stored its
 * positions. core/ stays pure geometry; this side channel travels next to
 * the mcf_mesh from a decoder to an encoder (api_encode_opts.attrs). The
 * smoothing changes positions only, never the connectivity, so texture
 * coordinates and colours are written back unchanged, and normals are
 * recomputed from the smoothed surface (area-weighted face normals summed
 * over the corners that shared a normal in the input, so hard edges stay
 * hard). An attribute is a table of values (ncomp doubles each) and, per
 * face corner (3 per triangle, in the mesh's face order), the index of its
 * value; a per-vertex attribute has corner index == vertex index.
 *
 * Formats: Draco NORMAL, TEX_COORD and COLOR (the first of each), with
 * their quantization; OBJ vt and vn (per corner) and `v x y z r g b`; PLY
 * vertex nx ny nz, s t (also u v, texture_u texture_v), red green blue
 * [alpha], and the face `texcoord` list (6 floats) draco_decoder writes;
 * PLY's other vertex scalars pass through to a PLY output as they came
 * (api_attrs_not_kept names what an output does not keep).
 * STL and OFF carry none. The connectivity as it came: the polygons of
 * an OBJ, PLY or OFF (smoothed as their fan triangles) are written back
 * as those polygons by the same three formats, and OBJ's g, o, s, usemtl
 * and mtllib statements in their place. Colours are held in [0, 1] (8-bit sources
 * divided by 255, and written back as bytes exactly). */
typedef struct api_attrs api_attrs;

typedef enum {
    API_ATTR_NORMAL = 0,
    API_ATTR_TEXCOORD,
    API_ATTR_COLOR
} api_attr_kind;
#define API_ATTR_KINDS 3

/* An empty handle for a mesh of nv vertices and nf triangles (what the
 * decoders fill); NULL on allocation failure. Free with api_attrs_free,
 * which accepts NULL. A handle belongs to the mesh it was decoded with or
 * made for: encoders refuse one whose counts differ (EINVAL). */
api_attrs *api_attrs_new(int nv, int nf);
void api_attrs_free(api_attrs *a);

/* Sets attribute k (replacing any): nvalues values of ncomp components
 * (normal 3, texcoord 2, colour 3 or 4) and 3*nf corner indices into
 * them (for a per-vertex attribute, the mesh's face array). Both are
 * copied. EINVAL (named) for a bad count, a non-finite value or an index
 * out of range; ENOMEM. The handle is unchanged on failure. */
mcf_status api_attrs_set(api_attrs *a, api_attr_kind k, int ncomp,
                         int nvalues, const double *values,
                         const int32_t *corners, mcf_error *err);
/* Lends attribute k (valid until the handle changes or is freed): returns
 * 0 when absent, else 1 with *ncomp, *nvalues, *values and *corners (3*nf
 * indices, never NULL) filled; any out-pointer may be NULL. */
int api_attrs_get(const api_attrs *a, api_attr_kind k, int *ncomp,
                  int *nvalues, const double **values,
                  const int32_t **corners);
/* How the input stored its positions: 1 when single precision (Draco,
 * binary STL, PLY `float`, OBJ text of at most 7 significant digits), 0
 * otherwise (and for a NULL handle). */
int api_attrs_float32(const api_attrs *a);
/* For a Draco input, the quantization bits of the positions (k =
 * API_ATTR_POSITION) or of attribute kind k: 0 = stored raw; -1 = not
 * from Draco, or absent. */
#define API_ATTR_POSITION API_ATTR_KINDS
int api_attrs_draco_bits(const api_attrs *a, int k);
/* What an output in format `out` will not keep of the input, for the user
 * to be told: PLY vertex properties the attributes do not model (quality,
 * confidence, intensity, ...; a PLY output writes them back, as they came,
 * with their types, the first 16 of them), PLY list properties and
 * elements other than the vertices and faces. Writes "vertex quality,
 * element edge" (truncated with "..." to n bytes) into buf and returns how
 * many items; 0 and "" when everything is kept (and for NULL). */
int api_attrs_not_kept(const api_attrs *a, api_format out, char *buf, size_t n);

/* Encoder options; api_encode_opts_init sets the defaults. */
typedef struct {
    api_format format;        /* UNKNOWN: same as the input */
    /* Draco: -1 = auto (default): the input's quantization when attrs says
     * it came from Draco (raw stays raw), else 16 bits for positions
     * (API_DRACO_DEFAULT_BITS); 0 = lossless (float32 when every
     * coordinate is a float, else float64, which libdraco reads but
     * draco_decoder's PLY writer does not); 1..30 = that many bits. */
    int quantization_bits;
    int compression_level;    /* Draco: 0..10 (default 7) */
    int preserve_order;       /* Draco: sequential method, order kept */
    int ply_binary;           /* PLY: binary little-endian (default 1) */
    /* PLY: per-vertex mean_curvature and gaussian_curvature properties,
     * computed by the encoder from the mesh (default 0: opt-in). */
    int ply_curvature;
    const double *ply_mean_curvature;     /* PLY: these instead when given */
    const double *ply_gaussian_curvature; /* (borrowed, nv each) */
    int stl_binary;           /* STL: default 1 */
    /* Attributes to write with the mesh (borrowed, may be NULL): texture
     * coordinates and colours as they are, normals recomputed; and the
     * input's precision (PLY float vs double) and Draco quantization. */
    const api_attrs *attrs;
} api_encode_opts;

/* Position quantization of Draco output when quantization_bits is auto and
 * the input was not Draco: a step of 1/65535 of the bounding box's largest
 * side, so an error (half a step) under 2% of the mean edge h even on a
 * 5-million-vertex scan (h ~ side/2200), well below the 0.1-0.5 h of noise
 * the flow removes. draco_encoder's own default, 11 bits, is 32 times
 * coarser: half a mean edge there. Every bit costs about 3 bits per vertex
 * in the output. */
#define API_DRACO_DEFAULT_BITS 16
/* Texture coordinates and normals from a non-Draco input, auto mode. */
#define API_DRACO_DEFAULT_TEXCOORD_BITS 16
#define API_DRACO_DEFAULT_NORMAL_BITS 10

void api_encode_opts_init(api_encode_opts *o);

/* Decodes any supported format (detected from the bytes). *out is a new
 * mesh owned by the caller; *fmt (may be NULL) the detected format.
 * Errors: EFORMAT (unknown format), EDECODE (malformed, with the line or
 * element), ELIMIT (a limit, naming it), EMESH (core refused), ENOMEM. */
mcf_status api_mesh_decode(const void *buf, size_t len, const api_limits *lim,
                           mcf_mesh **out, api_format *fmt, mcf_error *err);
/* The same, also returning the input's attributes: *attrs (may be NULL:
 * not wanted) a new handle owned by the caller (api_attrs_free), set only
 * on success, empty for formats without attributes. */
mcf_status api_mesh_decode_attrs(const void *buf, size_t len,
                                 const api_limits *lim, mcf_mesh **out,
                                 api_attrs **attrs, api_format *fmt,
                                 mcf_error *err);
/* Encodes in o->format (which must not be UNKNOWN) into out (appended). */
mcf_status api_mesh_encode(const mcf_mesh *m, const api_encode_opts *o,
                           api_buf *out, mcf_error *err);

/* Per-format codecs, same contracts. The *_decode_attrs forms also
 * return the attributes (attrs may be NULL); encoders take them from
 * o->attrs (OBJ and OFF, which have no options, write none through
 * api_obj_encode and api_off_encode: use api_mesh_encode or the _opts
 * forms). */
mcf_status api_obj_decode(const void *buf, size_t len, const api_limits *lim,
                          mcf_mesh **out, mcf_error *err);
mcf_status api_obj_encode(const mcf_mesh *m, api_buf *out, mcf_error *err);
mcf_status api_obj_decode_attrs(const void *buf, size_t len,
                                const api_limits *lim, mcf_mesh **out,
                                api_attrs **attrs, mcf_error *err);
mcf_status api_obj_encode_opts(const mcf_mesh *m, const api_encode_opts *o,
                               api_buf *out, mcf_error *err);
mcf_status api_ply_decode(const void *buf, size_t len, const api_limits *lim,
                          mcf_mesh **out, mcf_error *err);
mcf_status api_ply_encode(const mcf_mesh *m, const api_encode_opts *o,
                          api_buf *out, mcf_error *err);
mcf_status api_ply_decode_attrs(const void *buf, size_t len,
                                const api_limits *lim, mcf_mesh **out,
                                api_attrs **attrs, mcf_error *err);
mcf_status api_stl_decode(const void *buf, size_t len, const api_limits *lim,
                          mcf_mesh **out, mcf_error *err);
mcf_status api_stl_encode(const mcf_mesh *m, const api_encode_opts *o,
                          api_buf *out, mcf_error *err);
mcf_status api_off_decode(const void *buf, size_t len, const api_limits *lim,
                          mcf_mesh **out, mcf_error *err);
mcf_status api_off_encode(const mcf_mesh *m, api_buf *out, mcf_error *err);
mcf_status api_off_decode_attrs(const void *buf, size_t len,
                                const api_limits *lim, mcf_mesh **out,
                                api_attrs **attrs, mcf_error *err);
mcf_status api_off_encode_opts(const mcf_mesh *m, const api_encode_opts *o,
                               api_buf *out, mcf_error *err);
mcf_status api_draco_decode(const void *buf, size_t len, const api_limits *lim,
                            mcf_mesh **out, mcf_error *err);
mcf_status api_draco_decode_attrs(const void *buf, size_t len,
                                  const api_limits *lim, mcf_mesh **out,
                                  api_attrs **attrs, mcf_error *err);
/* glTF 2.0, GLB or .gltf with embedded buffers (api_gltf_decode.c says what is
 * read, refused and welded). Encoding a mesh decoded from glTF (o->attrs
 * holds its document) rewrites that document: positions and normals
 * changed, everything else as it came, each primitive compressed as it
 * was; o->format (GLB or GLTF) picks the container. Any other mesh is
 * written as a new document of one mesh and one primitive. */
mcf_status api_gltf_decode_attrs(const void *buf, size_t len,
                                 const api_limits *lim, mcf_mesh **out,
                                 api_attrs **attrs, mcf_error *err);
mcf_status api_gltf_encode(const mcf_mesh *m, const api_encode_opts *o,
                           api_buf *out, mcf_error *err);
/* *max_quant_err (may be NULL): largest |decoded - input| coordinate error
 * of the encoded result (0 when lossless). */
mcf_status api_draco_encode(const mcf_mesh *m, const api_encode_opts *o,
                            api_buf *out, double *max_quant_err,
                            mcf_error *err);

/* The version of mcf, mcfd and their API (openapi.yaml info.version, the
 * Python client's; tests/test_contract.py holds them equal). */
#define API_VERSION "1.0.0"

/* ------------------------------------------------------------- parameters */

/* Job parameters: the core flow parameters plus what the api layer needs.
 * Owns the fixed-vertex array (params.flow.fixed points into it). */
typedef struct {
    mcf_flow_params flow;
    api_encode_opts encode;       /* output format and encoder options */
    int32_t *fixed_owned;         /* backing store of flow.fixed */
    int time_set, iterations_set; /* which of the two was given */
    int dt_set;                   /* dt given (a number or auto) */
    int tol_set;                  /* tol given (needs adaptive) */
    int scheme_set;               /* scheme given */
    int scheme_chosen;            /* not given: api_params_finish chose it
                                     (again at every call) */
    int strength_set;             /* strength given (a number or auto) */
    int flow_keys_set;            /* time, dt, adaptive, laplacian, mass or
                                     rescale given: without a scheme, the
                                     job is desbrun2's flow */
    unsigned given;               /* a bit per parameter given (the table's
                                     order): api_params_given_json */
} api_params;

/* The scheme of a request that names none, on a mesh of nv vertices: the
 * fairing filter, `fairing` (implicit, one CHOLMOD factorization of a
 * 2-ring matrix: about 2 KB per vertex) up to API_FAIRING_IMPLICIT_MAX
 * vertices, `fairing_explicit` (no factorization, a few hundred bytes per
 * vertex) above: api_estimate.c has the measured memory and times. The
 * bound keeps the default's charge (2,900 B per vertex, 415 MiB at
 * 150,000, plus 3x the input: an OBJ of that size is about 11 MB) within
 * the image's job budget (--max-memory, half its 1 GiB: 512 MiB), where
 * 200,000 (566 MiB) had the default request refused (422 ELIMIT) on
 * meshes the explicit filter runs in 130 MiB, at nearly the same quality
 * (make quality, 2026-11-25: its error 1.03x the implicit's on the median
 * case, worst 1.88x on the regular sphere_cgal). */
#define API_FAIRING_IMPLICIT_MAX 150000
mcf_scheme api_default_scheme(long long nv);
/* The scheme a job with parameters p runs on a mesh of nv vertices: the
 * one named, else api_default_scheme(nv), or desbrun2 when p sets a
 * flow's keys (flow_keys_set). p may be NULL (no parameters). */
mcf_scheme api_params_scheme(const api_params *p, long long nv);
/* 1 when the job's amount is automatic (mcf_auto.c): strength=auto, or
 * a request that names no amount (none of time, iterations, dt and
 * strength). api_params_finish then sets flow.strength_auto. Every
 * scheme's default: an MCF scheme's time, Taubin's pass count. */
int api_params_auto_amount(const api_params *p);

void api_params_init(api_params *p);   /* core defaults, format UNKNOWN */
void api_params_free(api_params *p);   /* frees fixed_owned, keeps defaults */
/* dst (uninitialized) becomes a copy of src with its own fixed-vertex
 * array. MCF_OK or MCF_ENOMEM (dst untouched). */
mcf_status api_params_copy(api_params *dst, const api_params *src);

/* One validation path for every source (JSON, query string, CLI flags):
 * sets key to the textual value, EINVAL naming the key and the accepted
 * range when it is unknown, of the wrong type or out of range. */
mcf_status api_params_set(api_params *p, const char *key, const char *value,
                          const api_limits *lim, mcf_error *err);
/* A JSON object of keys (cJSON_ParseWithLengthOpts, depth/size limited);
 * numbers, strings, booleans and (for fixed_vertices) arrays of integers. */
mcf_status api_params_parse_json(api_params *p, const char *buf, size_t len,
                                 const api_limits *lim, mcf_error *err);
/* A parsed JSON object of keys, as api_params_parse_json applies them
 * (without its size and depth checks: obj is already a tree). */
mcf_status api_params_set_json(api_params *p, const cJSON *obj,
                               const api_limits *lim, mcf_error *err);
/* A URL query string "scheme=desbrun2&dt=1e-3" (percent-decoded). Keys the
 * daemon handles itself (listed in `ignore`, NULL-terminated) are skipped. */
mcf_status api_params_parse_query(api_params *p, const char *qs,
                                  const char *const *ignore,
                                  const api_limits *lim, mcf_error *err);
/* A request's parameters from the sources a daemon's request (REST's
 * body and URL, and the record a job keeps of them) carries, later ones
 * overriding earlier: a JSON object (params_json, a C string), then form
 * fields [[key, value], ...] in order (api_params_set each), then a URL
 * query string (api_params_parse_query, `ignore` skipped). Each may be
 * NULL. */
mcf_status api_params_parse_request(api_params *p, const char *params_json,
                                    const cJSON *fields, const char *query,
                                    const char *const *ignore,
                                    const api_limits *lim, mcf_error *err);
/* The steps a run takes as far as its parameters decide (mcf.h, "The
 * amount of smoothing"): its iterations (MCF_DEFAULT_STEPS when 0; a
 * filter's passes), or ceil(time / dt) (not capped: over max_iterations
 * it is refused). *by_mesh (may be NULL) is set when the mesh decides
 * instead (adaptive, dt=auto, a fixed dt with the amount from strength, a
 * fairing filter's automatic amount): then the most it may take
 * (max_steps within lim's max_iterations, or the filter's cap). Before
 * the mesh, an unnamed scheme is api_params_scheme's (a fairing filter
 * counted at the larger of the two caps). */
double api_params_steps(const api_params *p, const api_limits *lim,
                        int *by_mesh);
/* Final checks once the mesh is known: the default scheme when none was
 * named (api_default_scheme; desbrun2 when flow_keys_set), a fairing
 * filter's strength as its noise level (mcf_flow_params.noise_sigma;
 * unset or auto: estimated), mcf_flow_params_check, fixed indices in
 * range, iterations x vertices within max_work; and amounts that
 * contradict each other (EINVAL naming them): time, dt and iterations
 * all given and ceil(time / dt) != iterations (or dt=auto), or a dt
 * larger than the time. The automatic amount (api_params_auto_amount)
 * becomes flow.strength_auto. */
mcf_status api_params_finish(api_params *p, int nv, const api_limits *lim,
                             mcf_error *err);
/* The parameters as a JSON object (for job records and metrics). */
cJSON *api_params_to_json(const api_params *p);
/* Only the parameters that were given, with their values: a JSON object
 * that api_params_set_json turns back into the same parameters (the
 * record a job keeps of its request). NULL when out of memory. */
cJSON *api_params_given_json(const api_params *p);
/* Every parameter as the one table in api_params.c defines it, a JSON
 * array of {name, type (number, integer, boolean, string, array), auto
 * (accepts "auto"), format (uint64 for an unsigned 64-bit integer),
 * minimum or exclusiveMinimum, maximum (or
 * maximum_limit: the name of the api_limits field that bounds it), enum,
 * default (a value) or default_text (how it is derived), accepts (the
 * range in the words of the errors), unit, help, output (an encoder option
 * `mcf convert` takes too)}, under lim (NULL: the defaults). For `mcf
 * smooth --help`, `mcf params` and the test that keeps api/openapi.yaml
 * and api/mcfd.proto in step with the table. NULL when out of memory. */
cJSON *api_params_describe(const api_limits *lim);
/* The name of names (n of them, NULLs skipped) nearest to word, for "did
 * you mean" in errors: the smallest edit distance (insert, delete,
 * substitute, swap two neighbours), at most 2 and less than half of
 * word's length (a tie: the first of word's length, else the first);
 * NULL when none is that near (or word is longer than 63 characters).
 * Case and '-'/'_' are not told apart. */
const char *api_nearest_name(const char *word, const char *const *names, size_t n);

/* ----------------------------------------------------------- memory estimate */

/* A job's peak memory as the input declares it (api_estimate.c: how the
 * counts are found and the fitted model with its margin). */
typedef struct {
    api_format format;         /* detected from the bytes */
    long long vertices, faces; /* declared or counted (faces: triangles) */
    double decode_bytes;       /* decoding it (sizes the Draco sandbox) */
    int draco;                 /* decoding it runs libdraco (a Draco stream, or a
                                * glTF with KHR_draco_mesh_compression) */
    double job_bytes;          /* the whole job, decode to encode */
} api_mem_estimate;

/* Fills *out from the bytes and the parameters (p may be NULL: the
 * default scheme). Never fails; unreadable counts give 0 (the input's
 * size term remains, and decoding will refuse it). */
void api_estimate_memory(const void *buf, size_t len, const api_params *p,
                         api_mem_estimate *out);
/* The model alone: peak bytes of a job on a mesh of nv vertices and nf
 * triangles from an input of input_bytes (the daemon re-estimates with
 * the decoded counts before the flow). */
double api_estimate_job_bytes(long long nv, long long nf, size_t input_bytes,
                              const api_params *p);

/* ------------------------------------------------------------------ pack */

/* The mesh and its attributes (attrs may be NULL) appended to out as one
 * exact binary record (api_pack.c), for the decode sandbox's pipe. */
mcf_status api_mesh_pack(const mcf_mesh *m, const api_attrs *attrs,
                         api_buf *out, mcf_error *err);
/* The largest record api_mesh_pack writes for a mesh decoded within lim. */
size_t api_mesh_pack_max(const api_limits *lim);
/* The record back: a new mesh and attributes (attrs may be NULL), every
 * count checked against the bytes and lim. EDECODE for a bad record. */
mcf_status api_mesh_unpack(const void *buf, size_t len, const api_limits *lim,
                           mcf_mesh **out, api_attrs **attrs, mcf_error *err);

/* ---------------------------------------------------------------- process */

/* The bounds a Draco decode runs under (api_bounds.c says why): the
 * daemon's in a child process (server/sandbox/sandbox.c, floors --decode-cpu and
 * --decode-memory), the CLI's in its own (these defaults). */
#define API_DECODE_CPU_S 2.0                  /* CPU seconds, floor */
#define API_DECODE_MEMORY ((size_t)64 << 20)  /* address space, floor */
/* For an input the estimator sized (api_estimate_memory): CPU seconds
 * cpu_floor plus 1 us per declared face, and bytes of address space
 * twice the estimated decode peak, at least mem_floor. */
void api_decode_bounds(const api_mem_estimate *est, double cpu_floor,
                       size_t mem_floor, double *cpu_s, size_t *mem_bytes);
/* Bytes of address space this process maps now (VmSize), 0 when /proc
 * cannot say: what an RLIMIT_AS adds a budget to. */
size_t api_vm_size(void);
/* 1 in a build under AddressSanitizer or ThreadSanitizer, whose shadow
 * (terabytes reserved at start) cannot live under an RLIMIT_AS and which
 * die rather than fail an allocation: no address-space bound there (the
 * CPU bound still holds). */
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define API_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
#define API_SANITIZED 1
#endif
#endif
#ifndef API_SANITIZED
#define API_SANITIZED 0
#endif

/* ------------------------------------------------------------------- JSON */

/* Each returns a new cJSON object (caller cJSON_Delete's) or NULL on
 * allocation failure. */
cJSON *api_json_mesh_info(const mcf_mesh_info *info,
                          const mcf_curvature_summary *curv);
cJSON *api_json_curvature(const mcf_curvature_summary *curv);
/* Its "log" holds at most API_LOG_MAX entries: the first and last steps
 * and evenly spaced ones between, each with its "step". */
#define API_LOG_MAX 1000
cJSON *api_json_flow_stats(const mcf_flow_stats *st);
cJSON *api_json_compare(const mcf_compare_result *cmp);
cJSON *api_json_schemes(void);
/* Serializes (pretty when pretty != 0) into a malloc'ed string. */
char *api_json_print(const cJSON *j, int pretty);

/* ---------------------------------------------------------------- metrics */

/* The one metrics document of a smoothing run (api_metrics.c), which every
 * door returns: `mcf smooth --metrics FILE` and the daemon's job metrics.
 * The same request gives the same keys; a value a door does not have is
 * null, never a missing key. Members: command ("smooth"), job (the
 * daemon's id, else null), scheme, params, warnings (the names of the
 * core's warnings: folds, edge_collapse, area_loss, little_smoothing; []
 * when none), input {path, format, bytes, info, mesh (= info)}, output
 * {path, format, bytes, vertices, faces, area, volume,
 * quantization_max_error, info}, curvature {before, after}, flow (the
 * flow statistics, with the step log when one was kept), compare (only
 * with a target: the after members, target, before, after), timings and
 * timing (the same: queue_s, read_s, decode_s, flow_s,
 * encode_s, write_s, metrics_s, total_s), peak_rss_bytes, measured
 * (whether the meshes were measured: without the measures, the light
 * document of a request that did not ask for them, input.info,
 * input.mesh, output.info and curvature's before and after are null,
 * output's counts, area and volume come from the flow, metrics_s is null
 * and flow has no step log).
 * api/openapi.yaml (Metrics) describes each member. Every volume in it is
 * mcf_mesh_volume's: signed, about the input's coordinate origin, in
 * input units. */

/* What a run measured, in two calls around the flow (which changes the
 * mesh in place). Plain data; api_metrics_init zeroes it. */
typedef struct {
    int measured;                  /* bit 0: before the flow, bit 1: after */
    int target;                    /* same bits: compared with a target */
    mcf_mesh_info info[2];         /* [0] before the flow, [1] after */
    mcf_curvature_summary curv[2];
    mcf_compare_result cmp[2];
} api_metrics;

void api_metrics_init(api_metrics *mt);
/* Measures m as the flow receives it, resp. as
 * the flow returned it: validation, curvature summary and, when target is
 * not NULL, the comparison with it (same connectivity, else EINVAL).
 * ENOMEM; mt is unchanged on failure. Linear in the mesh (radix sorts):
 * about 0.06 s per call on the 35k-vertex bunny, a fraction of a flow
 * step. */
mcf_status api_metrics_before(api_metrics *mt, const mcf_mesh *m,
                              const mcf_mesh *target, mcf_error *err);
mcf_status api_metrics_after(api_metrics *mt, const mcf_mesh *m,
                             const mcf_mesh *target, mcf_error *err);

/* What only the door knows. Names and the job id are borrowed (NULL:
 * null); a time or size the door does not have is NaN (null). */
typedef struct {
    const char *job;               /* the daemon's job id; NULL in the CLI */
    const char *input_name;        /* CLI: IN; daemon: the upload's file name */
    const char *output_name;       /* CLI: OUT; daemon: the result's name */
    const char *target_name;       /* with a target */
    api_format input_format, output_format;
    size_t input_bytes, output_bytes;
    double quantization_max_error; /* Draco output (api_draco_encode) */
    const char *not_kept;          /* api_attrs_not_kept's list; NULL: all
                                      kept (output.not_kept null) */
    double queue_s, read_s, decode_s, flow_s, encode_s, write_s,
           total_s;                /* seconds per phase */
    double metrics_s;              /* in api_metrics_before and _after */
    double peak_rss_bytes;         /* the process's peak resident size */
    int nv, nf;                    /* the mesh's counts (output.vertices
                                      and faces when nothing was measured) */
} api_metrics_run;

/* Unknown formats, zero bytes, NULL names, NaN numbers. */
void api_metrics_run_init(api_metrics_run *r);

/* The document (a new cJSON object, cJSON_Delete it) from the measures
 * (both api_metrics_before and api_metrics_after done, or neither: the
 * light document, measured false), the parameters as run (after
 * api_params_finish), the flow statistics and the door's facts. NULL when
 * an argument is missing, one measure of the two was taken, or an
 * allocation failed (never a half-built document). */
cJSON *api_metrics_json(const api_metrics *mt, const api_params *p,
                        const mcf_flow_stats *st, const api_metrics_run *r);

/* ----------------------------------------------------------------- fields */

/* The per-vertex fields of a run for viewers (api_fields.c): positions of
 * before (the mesh as the flow received it) and after (as it returned it),
 * their shared faces, mean and Gaussian curvature of each (mcf_curvature)
 * and each vertex's displacement |after - before|. One binary document,
 * appended to out: API_FIELDS_MAGIC, u32 API_FIELDS_VERSION, u32 header
 * length, a JSON header (space-padded to a multiple of 4: vertices,
 * faces, arrays [{name, type "uint32"|"float32", components, count,
 * offset from the end of the header, stats {min, max, p02, p98} of the
 * scalar ones}]), then the arrays, all little-endian. EINVAL when after
 * does not share before's faces, ENOMEM (ELIMIT over out's maximum). */
#define API_FIELDS_MAGIC "MCFF"
#define API_FIELDS_VERSION 1
mcf_status api_fields_encode(const mcf_mesh *before, const mcf_mesh *after,
                             api_buf *out, mcf_error *err);

/* -------------------------------------------------------------------- jobs */

/* One smoothing job from the input's bytes to the result's and the metrics
 * document (api_job.c), for every door: `mcf smooth` and the daemon's
 * workers both call api_job_run, so the same request runs the same steps
 * and gives the same metrics keys and timings. Their own code is file I/O
 * on one side, the spool, retries and locking on the other; what differs
 * (the Draco sandbox, memory admission, progress, cancel, where the bytes
 * go) comes in through hooks.
 *
 * The steps: decode the input (hook), finish the parameters for its
 * vertex count (api_params_finish: the default scheme), decode the target
 * and check it shares the mesh's connectivity, measure (api_metrics_before), run the flow (progress and cancel),
 * encode (unless a hook withholds the output), store it (hook), measure
 * again, and build the metrics document and the fields document.
 *
 * Timings in the document (seconds, the same keys through every door):
 * read_s and queue_s are the door's (request); decode_s the input's and
 * the target's decode; flow_s, encode_s; write_s the store hook (null without one); metrics_s both
 * measures; total_s read_s plus everything api_job_run did. */

/* Where a failure came from (it decides a door's status: a parameter, the
 * request's bytes, or this mesh with these parameters). */
typedef enum {
    API_JOB_OK = 0,
    API_JOB_PARAMS,            /* api_params_finish: the parameters */
    API_JOB_DECODE,            /* the bytes: malformed, unknown format,
                                  over a size limit */
    API_JOB_RUN                /* the mesh with these parameters: target,
                                  noise, flow, encode, measures, a budget
                                  the input's cost exceeds */
} api_job_stage;

/* One step of the flow, as the progress hook sees it. */
typedef struct {
    int step;
    double t, dt;
    double energy;             /* the step log's area (input units; the
                                  core's mcf_progress_fn), and */
    double volume;             /* its volume (mcf_mesh_volume, input
                                  units): NaN both without a log (no
                                  metrics, or the light document), so
                                  a step costs no pass of its own */
    double t_target;           /* the run's total time once the core knows
                                  it (0: the run counts steps) */
    double threads_cpu_s;      /* CPU seconds of the threads the flow
                                  started besides the caller's so far
                                  (mcf_flow_stats.threads_cpu_s) */
} api_job_step;

/* The door's hooks; any may be NULL. ctx is passed to each. */
typedef struct {
    void *ctx;
    /* Decodes part ("mesh", or "target": then attrs is NULL). NULL:
     * api_mesh_decode_attrs in this thread. A failure's stage is
     * API_JOB_DECODE unless the hook sets *stage (API_JOB_RUN: a budget of
     * the decoder, such as the daemon's sandbox limits). */
    mcf_status (*decode)(void *ctx, const char *part, const void *buf,
                         size_t len, const api_limits *lim, mcf_mesh **out,
                         api_attrs **attrs, api_format *fmt,
                         api_job_stage *stage, mcf_error *err);
    /* The input decoded (nv vertices, nf triangles), before anything is
     * sized by it (the daemon's memory admission). Not OK stops the job
     * (stage API_JOB_RUN, part "mesh"). */
    mcf_status (*decoded)(void *ctx, int nv, int nf, const api_params *p,
                          mcf_error *err);
    /* The flow's threads, asked as it starts (nv: the mesh's vertices):
     * the door's share of the cores for this mesh (the daemon's budget).
     * NULL, or a value below 1: rq->threads. */
    int (*threads)(void *ctx, int nv);
    /* Checked and measured: the flow starts (p finished: its scheme is
     * the one that runs). */
    void (*ready)(void *ctx, const api_params *p, api_format in_fmt);
    /* Every step of the flow; nonzero cancels the job (MCF_ECANCELED). */
    int (*progress)(void *ctx, const api_job_step *s);
    /* The flow's share of work done, 0..1, at its milestones (the core's
     * mcf_work_fn: every step, the fairing filters' phases and passes). */
    void (*work)(void *ctx, const char *phase, double done);
    /* The flow is done: nonzero withholds the output (not encoded, not
     * stored; output.path null in the document): the CLI's --strict. */
    int (*flowed)(void *ctx, const mcf_flow_stats *st);
    /* The encoded output (name: api_job_result.output_name): keep it
     * (write the file, the spool). Not OK fails the job with err as the
     * hook set it (part "output"). Timed as write_s. */
    mcf_status (*store)(void *ctx, const api_buf *out, const char *name,
                        mcf_error *err);
    /* As mcf_flow_params.cancel (may be NULL): loaded before every step
     * and between the phases of the fairing filters' set-up, and by the
     * job once its input is decoded (ECANCELED, part "mesh", stage
     * API_JOB_RUN) and before the output is stored (part "output"). */
    const mcf_cancel_flag *cancel;
} api_job_hooks;

typedef struct {
    char *input;               /* the mesh's bytes */
    size_t input_len;
    char *target;              /* a clean mesh to compare with, or NULL */
    size_t target_len;
    int free_bytes;            /* input and target are malloc'ed: free()d
                                  (and set NULL) as soon as decoded, so the
                                  flow does not hold them */
    const api_limits *lim;     /* NULL: the defaults */
    int metrics;               /* build the metrics document (and keep the
                                  flow's step log) */
    int light;                 /* with metrics: the light document, no
                                  measures and no step log (their cost
                                  is the meshes' size times a few passes;
                                  a fifth of the flow's wall on a 7M
                                  scan): what the daemon builds for a
                                  request that did not ask for them */
    int fields;                /* build the fields document
                                  (api_fields_encode) */
    size_t max_output;         /* the encoded output's cap (ELIMIT), 0:
                                  none */
    /* The door's facts in the document (borrowed; NULL: null). */
    const char *job;           /* the daemon's job id */
    const char *input_name, *target_name;
    const char *output_name;   /* NULL: output_stem and the format's
                                  extension ("result" -> "result.obj") */
    const char *output_stem;
    double queue_s, read_s;    /* NaN: the door has none */
    int process_rss;           /* peak_rss_bytes: the process's peak
                                  resident size (a process of one job) */
    int threads;               /* mcf_flow_params.threads: the job's share
                                  of the cores (0: one), unless the
                                  threads hook says otherwise */
} api_job_request;

/* api_job_request_init: no input, no target, no document, NaN times. */
void api_job_request_init(api_job_request *rq);

typedef struct {
    api_buf output;            /* the encoded mesh (empty when withheld) */
    api_buf fields;            /* the fields document (request.fields) */
    cJSON *metrics;            /* the metrics document (request.metrics) */
    mcf_flow_stats stats;      /* the flow's (warnings, steps, strength) */
    api_format input_format, output_format;
    const char *output_name;   /* as named in the document: the request's,
                                  or name_buf */
    char name_buf[64];         /* output_stem and the extension */
    int nv, nf;                /* the input's counts once decoded */
    int withheld;              /* the flowed hook withheld the output */
    double quantization_max_error;  /* Draco output; NaN otherwise */
    /* What the output does not keep of the input (api_attrs_not_kept):
     * not_kept_n items named in not_kept ("" when none). */
    char not_kept[256];
    int not_kept_n;
    double flow_s;
    /* a failure: where, which part ("mesh", "target", "params",
     * "flow", "encode", "output", "metrics", "fields") and the core's or
     * codec's message, unprefixed (each door prefixes it its way) */
    api_job_stage stage;
    const char *part;
    mcf_error err;
} api_job_result;

void api_job_result_init(api_job_result *r);
void api_job_result_free(api_job_result *r);   /* keeps it reusable */

/* Runs the job rq with parameters p (parsed by the door; finished here
 * for the mesh: p->flow.scheme, p->encode.format, p->encode.attrs change)
 * and hooks h (may be NULL); rq changes only by free_bytes. MCF_OK, or the failure's status with its
 * stage, part and message in *res. *res holds what was done either way;
 * api_job_result_free it. */
mcf_status api_job_run(api_job_request *rq, api_params *p,
                       const api_job_hooks *h, api_job_result *res);

#ifdef __cplusplus
}
#endif
#endif /* API_H */
