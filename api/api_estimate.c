/* SPDX-License-Identifier: MIT */
/*
 * api_estimate.c - a job's peak memory, estimated from what its input
 * declares before a byte of it is decoded: the daemon refuses a job whose
 * estimate exceeds the per-job bound and starts jobs only while their
 * estimates fit its memory budget (server/service/svc_admit.c).
 *
 * Counts. Draco, PLY and OFF declare their vertex and face counts in a
 * header (Draco's are the ones check_counts bounds; a stream that needs
 * more than its header admits is stopped by the decode sandbox's memory
 * limit, which is sized from this same estimate); a binary STL declares
 * its triangles (vertices are not stored: counted as one per triangle,
 * twice the n/2 of a closed surface). OBJ and ASCII STL declare nothing,
 * so they are counted: one pass over the lines (`v` lines; `f` lines give
 * tokens - 2 triangles; `endfacet` for STL), about 1 GB/s. PLY and OFF
 * faces may be polygons: a face counts as one triangle here, and the
 * daemon estimates again from the decoded mesh before the flow. A glTF
 * declares its accessors' counts: the POSITION and indices counts of its
 * triangle primitives (api__gltf_declared), and the copies of its
 * buffers are charged per input byte (below).
 *
 * The model, fitted to the peak resident size of `mcf smooth` (which runs
 * the daemon's job: decode, metrics, flow, encode, the input and output
 * bytes held) minus the 8.3 MiB of the process at rest, over 10 meshes of
 * 114 to 435,545 vertices (test_nm, sphere_cgal, bunny.drc, knot1, spot,
 * fertility, stanford-bunny, armadillo, dragon_vrip.drc, dragon_vrip_res2)
 * and the settings desbrun2, euler, ros2, richardson, implicit, cmcf,
 * taubin, strength=auto and adaptive: 88 runs (implicit on the two
 * dragons did not end within 300 s), 2026-11-23, /usr/bin/time's maxrss;
 * lab/results/memory/peak_rss.csv and the script that made it, lab/peak_rss.sh:
 *
 *   bytes = 3 x input bytes + per_vertex(scheme) x nv + 4 MiB
 *
 * per_vertex = 640 B for the explicit schemes that factorize nothing
 * (euler, taylor2 with an amount given, taubin: measured at most 354 B
 * beyond the other terms, dragon_vrip), 1,600 B for every other (the
 * automatic amount factorizes) (measured at most 1,246 B:
 * strength=auto on stanford-bunny, whose six-column solve is the largest;
 * 1,215 B on the dragon; desbrun2 738-1,041 B, implicit 1,060 B, adaptive
 * 1,220 B). CHOLMOD's fill grows a little faster than nv on scans
 * (desbrun2 1.00 -> 1.04 KB/vertex from 35k to 435k vertices), which the
 * 1,600 B covers well past the dragon. The face term is folded into the
 * vertex one (nf ~ 2 nv on every scan; a mesh with more than 2 faces per
 * vertex is charged nf / 2 vertices). Measured / estimated is at most
 * 0.80 over the 88 runs (a margin of 20 %: strength=auto on bunny.drc and
 * stanford-bunny; 0.76 on the dragon), 0.44-0.79 on the meshes above
 * 2,000 vertices; small meshes are dominated by the constant 4 MiB
 * (ratios 0-0.4). An estimate of a peak, not a bound: the tested figure
 * of the daemon (README, reliability) adds its size at rest.
 *
 * The fairing filters (issue 16; the default when a request names no
 * scheme: api_params_scheme), measured the same way on 2026-11-24 with
 * noise 0.25 (their automatic amount, 6 probe columns): `fairing`
 * factors a 2-ring matrix once, 1,525-2,330 B per vertex (armadillo
 * 1,525, fertility 1,843, stanford-bunny 1,946, dragon_vrip 2,014,
 * bunny.drc 2,330), charged 2,900 (the same 0.8 margin);
 * `fairing_explicit` 185-491 B (dragon_vrip 432), charged 640 with the
 * other explicit schemes. The combination of iterates (2026-11-25) keeps
 * four single-precision displacements: 48 B more per vertex, within both
 * margins (2,378 of 2,900; 539 of 640).
 */
#include <string.h>

#include "api_internal.h"

#define MIB (1024.0 * 1024.0)
/* `fairing`: see the model above */
#define FAIRING_PER_VERTEX 2900.0

/* The first occurrence of word in s[0, len), or NULL (memmem is GNU). */
static const char *find(const char *s, size_t len, const char *word)
{
    size_t k = strlen(word), i;
    for (i = 0; i + k <= len; i++)
        if (s[i] == word[0] && memcmp(s + i, word, k) == 0)
            return s + i;
    return NULL;
}

/* Counts `v` lines and the triangles of `f` lines (OBJ); endfacet (STL). */
static void scan_text(const char *s, size_t len, int stl, long long *nv,
                      long long *nf)
{
    const char *e = s + len, *p = s;
    *nv = *nf = 0;
    while (p < e) {
        const char *nl = memchr(p, '\n', (size_t)(e - p));
        const char *q = p;
        if (!nl)
            nl = e;
        while (q < nl && (*q == ' ' || *q == '\t'))
            q++;
        if (stl) {
            if (nl - q >= 8 && memcmp(q, "endfacet", 8) == 0)
                (*nf)++;
        } else if (nl - q >= 2 && (q[1] == ' ' || q[1] == '\t')) {
            if (q[0] == 'v') {
                (*nv)++;
            } else if (q[0] == 'f') {
                long long tok = 0;
                int in = 0;
                for (q++; q < nl; q++) {
                    int sp = *q == ' ' || *q == '\t' || *q == '\r';
                    if (!sp && !in)
                        tok++;
                    in = !sp;
                }
                if (tok >= 3)
                    *nf += tok - 2;
            }
        }
        p = nl + 1;
    }
    if (stl)
        *nv = *nf;
}

/* The first two integers after the word `key` at the start of a line of
 * the header text (PLY "element vertex N"); 0 when absent. */
static long long header_count(const char *h, size_t len, const char *key)
{
    size_t k = strlen(key), i;
    for (i = 0; i + k < len; i++)
        if ((i == 0 || h[i - 1] == '\n') && memcmp(h + i, key, k) == 0) {
            long long v = 0;
            const char *p = h + i + k;
            while (p < h + len && *p == ' ')
                p++;
            while (p < h + len && *p >= '0' && *p <= '9' && v < (1LL << 40))
                v = v * 10 + (*p++ - '0');
            return v;
        }
    return 0;
}

/* OFF: the vertex and face counts after the keyword and comments. */
static void off_counts(const char *s, size_t len, long long *nv, long long *nf)
{
    long long v[2] = {0, 0};
    int n = 0, seen_kw = 0;
    const char *p = s, *e = s + len;
    while (p < e && n < 2) {
        if (*p == '#') {
            while (p < e && *p != '\n')
                p++;
        } else if (*p >= '0' && *p <= '9' && seen_kw) {
            long long x = 0;
            while (p < e && *p >= '0' && *p <= '9' && x < (1LL << 40))
                x = x * 10 + (*p++ - '0');
            v[n++] = x;
        } else if (*p > ' ') {
            seen_kw = 1;
            while (p < e && *p > ' ')
                p++;
        } else {
            p++;
        }
    }
    *nv = v[0];
    *nf = v[1];
}

double api_estimate_job_bytes(long long nv, long long nf, size_t input_bytes,
                              const api_params *p)
{
    double per_vertex = 1600.0;
    /* the scheme the job will run (api_params_finish's choice when the
     * request names none); an automatic amount factorizes for every MCF
     * scheme, taubin's frozen passes and probes add about 150 B
     * (dragon_vrip_res2: 55 MB peak against 40 MB for 10 passes) */
    mcf_scheme s = api_params_scheme(p, nv);
    int auto_amount = p && api_params_auto_amount(p);
    if (((s == MCF_EULER || s == MCF_TAYLOR2) && !auto_amount) || s == MCF_TAUBIN ||
        s == MCF_FAIRING_EXPLICIT)
        per_vertex = 640.0;
    else if (s == MCF_FAIRING || s == MCF_FAIRING_FEATURE)
        per_vertex = FAIRING_PER_VERTEX;
    /* Charged per face as well when a mesh has more than 2 faces per
     * vertex (a triangle soup, an STL counted as one vertex per face). */
    if (nf > 2 * nv)
        nv = (nf + 1) / 2;
    double bytes = per_vertex * (double)nv;
    /* The decoder welds: a binary STL declares a vertex per face, a glTF
     * its seams twice, so the mesh the job runs on can have as few as
     * about nf / 2 vertices (a closed surface), and below
     * API_FAIRING_IMPLICIT_MAX the default picks the implicit filter:
     * charged for it on that many vertices (at most the bound) when that
     * costs more (a 300,000-facet STL of a closed scan: 150,000 vertices
     * at 2,900 B, not 300,000 at 640). */
    long long weld = (nf + 1) / 2;
    if (nf > 0 && weld < nv && weld <= API_FAIRING_IMPLICIT_MAX &&
        api_params_scheme(p, weld) == MCF_FAIRING && s != MCF_FAIRING) {
        long long n = nv < API_FAIRING_IMPLICIT_MAX ? nv : API_FAIRING_IMPLICIT_MAX;
        if (FAIRING_PER_VERTEX * (double)n > bytes)
            bytes = FAIRING_PER_VERTEX * (double)n;
    }
    return 3.0 * (double)input_bytes + bytes + 4.0 * MIB;
}

void api_estimate_memory(const void *buf, size_t len, const api_params *p,
                         api_mem_estimate *out)
{
    const char *s = buf;
    long long nv = 0, nf = 0;
    uint32_t dv, df;

    memset(out, 0, sizeof *out);
    out->format = api_format_detect(buf, len);
    switch (out->format) {
    case API_FMT_DRACO:
        out->draco = 1;
        if (api__draco_declared(buf, len, &dv, &df)) {
            nv = dv;
            nf = df;
        }
        break;
    case API_FMT_GLB:
    case API_FMT_GLTF:
        api__gltf_declared(buf, len, &nv, &nf, &out->draco);
        break;
    case API_FMT_PLY: {
        const char *end = find(s, len < 65536 ? len : 65536, "end_header");
        size_t hl = end ? (size_t)(end - s) : len;
        nv = header_count(s, hl, "element vertex");
        nf = header_count(s, hl, "element face");
        break;
    }
    case API_FMT_OFF:
        off_counts(s, len, &nv, &nf);
        break;
    case API_FMT_STL:
        if (len >= 84 && len == 84 + 50 * (size_t)((const unsigned char *)s)[80]
                                   + 50 * ((size_t)((const unsigned char *)s)[81] << 8)
                                   + 50 * ((size_t)((const unsigned char *)s)[82] << 16)
                                   + 50 * ((size_t)((const unsigned char *)s)[83] << 24))
            nv = nf = (long long)(len - 84) / 50;
        else
            scan_text(s, len, 1, &nv, &nf);
        break;
    default:
        scan_text(s, len, 0, &nv, &nf);
        break;
    }
    out->vertices = nv;
    out->faces = nf;
    /* libdraco's decode, our copy and the packed answer: the decoder
     * process's peak beyond its 12 MiB at start was 121 B per face on
     * bunny.drc and 136 B on dragon_vrip.drc (113 MiB for 871k faces);
     * charged 170 B per face, 64 per vertex and twice the stream (the
     * estimate is 1.6-1.7x those peaks). */
    out->decode_bytes = 170.0 * (double)nf + 64.0 * (double)nv +
                        2.0 * (double)len;
    out->job_bytes = api_estimate_job_bytes(nv, nf, len, p);
    if (out->format == API_FMT_GLB || out->format == API_FMT_GLTF) {
        /* A glTF's buffers (textures too) are copied by tinygltf, into the
         * document and into its record, which the job keeps to the end:
         * charged 4 and 2 more times the input (not measured yet). */
        out->decode_bytes += 4.0 * (double)len;
        out->job_bytes += 2.0 * (double)len;
    }
}
