/* SPDX-License-Identifier: MIT */
/*
 * api_draco_measure.cc - the encoder's *max_quant_err, measured.
 *
 * *max_quant_err is measured, not predicted: the encoded bytes are decoded
 * again and every input face is compared with its decoded counterpart
 * corner by corner (faces are looked up by centroid in a grid, cyclic
 * rotations tried), since edgebreaker changes vertex and face order.
 */
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "api_draco_internal.h"

namespace api_draco {

/* The decoded faces binned by the cell of their centroid: a hash table
 * (open addressing, linear probing) from a cell to its faces, built in two
 * passes (count, then place), looked up in O(1). It replaced a sort and
 * 27 binary searches per input face, 1.4 s of CPU on the 871k-face dragon. */
class cell_index {
public:
    /* b: 3 cell coordinates per face, nfaces faces */
    explicit cell_index(const std::vector<int64_t> &b)
    {
        const size_t n = b.size() / 3;
        size_t cap = 16;
        while (cap < 2 * n)
            cap *= 2;
        mask_ = cap - 1;
        slot_.assign(cap, UINT32_MAX);
        std::vector<uint32_t> cell_of(n);
        for (size_t f = 0; f < n; f++) {
            const int64_t *k = &b[3 * f];
            size_t h = hash(k) & mask_;
            while (slot_[h] != UINT32_MAX && !same(slot_[h], k))
                h = (h + 1) & mask_;
            if (slot_[h] == UINT32_MAX) {
                slot_[h] = static_cast<uint32_t>(key_.size() / 3);
                key_.insert(key_.end(), k, k + 3);
                start_.push_back(0);
            }
            cell_of[f] = slot_[h];
            start_[slot_[h]]++;
        }
        /* counts -> starts (one more entry: the end of the last cell) */
        uint32_t sum = 0;
        for (uint32_t &c : start_) {
            const uint32_t cnt = c;
            c = sum;
            sum += cnt;
        }
        start_.push_back(sum);
        std::vector<uint32_t> next(start_.begin(), start_.end() - 1);
        face_.resize(n);
        for (size_t f = 0; f < n; f++)
            face_[next[cell_of[f]]++] = static_cast<uint32_t>(f);
    }
    /* The faces in cell k: [*begin, *end) of faces(); false when none. */
    bool find(const int64_t k[3], const uint32_t **begin, const uint32_t **end) const
    {
        for (size_t h = hash(k) & mask_; slot_[h] != UINT32_MAX; h = (h + 1) & mask_)
            if (same(slot_[h], k)) {
                *begin = face_.data() + start_[slot_[h]];
                *end = face_.data() + start_[slot_[h] + 1];
                return true;
            }
        return false;
    }

private:
    static size_t hash(const int64_t k[3])
    {
        /* the three coordinates spread by odd constants, then MurmurHash3's
         * 64-bit finalizer: neighbouring cells land far apart */
        uint64_t h = static_cast<uint64_t>(k[0]) * 0x9E3779B97F4A7C15ull ^
                     static_cast<uint64_t>(k[1]) * 0xC2B2AE3D27D4EB4Full ^
                     static_cast<uint64_t>(k[2]) * 0x165667B19E3779F9ull;
        h ^= h >> 33;
        h *= 0xff51afd7ed558ccdull;
        h ^= h >> 33;
        h *= 0xc4ceb9fe1a85ec53ull;
        h ^= h >> 33;
        return static_cast<size_t>(h);
    }
    bool same(uint32_t c, const int64_t k[3]) const
    {
        const int64_t *q = &key_[3 * static_cast<size_t>(c)];
        return q[0] == k[0] && q[1] == k[1] && q[2] == k[2];
    }
    size_t mask_ = 0;
    std::vector<uint32_t> slot_;   /* cell number or UINT32_MAX */
    std::vector<int64_t> key_;     /* 3 per cell */
    std::vector<uint32_t> start_;  /* cell -> first of its faces in face_ */
    std::vector<uint32_t> face_;   /* faces grouped by cell */
};

/* The decoded mesh's positions (3 per value) in Y and its faces in G as
 * position indices (mapped_index: by value, as the encoder's input had
 * them); false when it has no 3-component position or a face points
 * outside. */
static bool decoded_geometry(const draco::Mesh &dm, std::vector<double> *Y,
                             std::vector<uint32_t> *G)
{
    const draco::PointAttribute *pos =
        dm.GetNamedAttribute(draco::GeometryAttribute::POSITION);
    if (!pos || pos->num_components() != 3)
        return false;
    const size_t ny = pos->size();
    const size_t ng = dm.num_faces();
    Y->resize(3 * ny);
    for (size_t v = 0; v < ny; v++)
        if (!read_position(pos, static_cast<uint32_t>(v), &(*Y)[3 * v]))
            return false;
    G->resize(3 * ng);
    for (size_t f = 0; f < ng; f++) {
        const draco::Mesh::Face &face =
            dm.face(draco::FaceIndex(static_cast<uint32_t>(f)));
        for (int k = 0; k < 3; k++) {
            if (face[k].value() >= dm.num_points())
                return false;
            uint32_t a = pos->mapped_index(face[k]).value();
            if (a >= ny)
                return false;
            (*G)[3 * f + k] = a;
        }
    }
    return true;
}

/* The grid of centroid cells: side h from the low corner lo of the box
 * around both meshes, whose largest extent is ext. */
struct grid {
    double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, ext = 0.0, h = 1.0;

    grid(const std::vector<double> &Y, int nv, const double *X, size_t ng, double tol)
    {
        for (size_t i = 0; i < Y.size(); i++)
            lo[i % 3] = std::min(lo[i % 3], Y[i]);
        for (int i = 0; i < 3 * nv; i++)
            lo[i % 3] = std::min(lo[i % 3], X[i]);
        for (size_t i = 0; i < Y.size(); i++)
            ext = std::max(ext, Y[i] - lo[i % 3]);
        for (int i = 0; i < 3 * nv; i++)
            ext = std::max(ext, X[i] - lo[i % 3]);
        /* Cells of about a face's size (the extent over sqrt(faces): a few
         * centroids per cell on a surface), at least 2 tol so that a search
         * box mostly lies in one cell, and at most ~2^40 per axis so indices
         * fit. */
        h = std::max({2.0 * tol, ext / std::sqrt(static_cast<double>(ng) + 1.0), ext * 0x1p-40});
        if (!(h > 0.0))
            h = 1.0;
    }
    void bin(const double c[3], int64_t b[3]) const
    {
        for (int a = 0; a < 3; a++)
            b[a] = static_cast<int64_t>(std::floor((c[a] - lo[a]) / h));
    }
};

static void centroid(const double *P, const double *Q, const double *R, double c[3])
{
    for (int a = 0; a < 3; a++)
        c[a] = (P[a] + Q[a] + R[a]) / 3.0;
}

/* The smallest distance (the largest coordinate difference over the
 * corners, each of the three rotations tried) from input face t to a
 * decoded face binned in the cells [b0, b1]; HUGE_VAL when there is none. */
static double nearest_face(const int32_t *t, const double *X, const std::vector<double> &Y,
                           const std::vector<uint32_t> &G, const cell_index &cells,
                           const int64_t b0[3], const int64_t b1[3])
{
    double best = HUGE_VAL;
    int64_t key[3];
    for (key[0] = b0[0]; key[0] <= b1[0]; key[0]++)
        for (key[1] = b0[1]; key[1] <= b1[1]; key[1]++)
            for (key[2] = b0[2]; key[2] <= b1[2]; key[2]++) {
                const uint32_t *it, *end;
                if (!cells.find(key, &it, &end))
                    continue;
                for (; it != end; ++it) {
                    const uint32_t *g = &G[3 * (size_t)*it];
                    for (int r3 = 0; r3 < 3; r3++) {
                        double d = 0.0;
                        for (int q = 0; q < 3; q++) {
                            const double *x = &X[3 * t[q]];
                            const double *y = &Y[3 * g[(q + r3) % 3]];
                            for (int a = 0; a < 3; a++)
                                d = std::max(d, std::fabs(y[a] - x[a]));
                        }
                        best = std::min(best, d);
                    }
                }
            }
    return best;
}

/* Largest coordinate error between the input (X, F) and the decoded mesh
 * dm, through face corners. Every input face whose three indices differ
 * must have a decoded face, up to a cyclic rotation, whose corners lie
 * within tol of its own (tol >= the quantization bound, so a missing one
 * is a real mismatch); *worst_face names it otherwise and false is
 * returned. Decoded faces are binned by centroid in cells of side h >= 2 tol;
 * a counterpart's centroid lies within tol of the input face's (each
 * corner does), so only the cells that box of half-side tol touches are
 * searched: one, or two along an axis where it straddles a cell wall. */
bool measure(int nv, const double *X, int nf, const int32_t *F,
             const draco::Mesh &dm, double tol, double *maxerr,
             int *worst_face)
{
    std::vector<double> Y;
    std::vector<uint32_t> G;
    if (!decoded_geometry(dm, &Y, &G))
        return false;
    const size_t ny = Y.size() / 3, ng = G.size() / 3;

    /* Sequential streams keep everything in place: compare all vertices
     * (unreferenced ones included) index by index. */
    if (ny == static_cast<size_t>(nv) && ng == static_cast<size_t>(nf) &&
        std::equal(G.begin(), G.end(), F,
                   [](uint32_t a, int32_t b) { return a == static_cast<uint32_t>(b); })) {
        double e = 0.0;
        for (size_t i = 0; i < 3 * ny; i++)
            e = std::max(e, std::fabs(Y[i] - X[i]));
        *maxerr = e;
        return true;
    }

    const grid cg(Y, nv, X, ng, tol);
    std::vector<int64_t> fb(3 * ng);
    for (size_t f = 0; f < ng; f++) {
        double c[3];
        centroid(&Y[3 * G[3 * f]], &Y[3 * G[3 * f + 1]], &Y[3 * G[3 * f + 2]], c);
        cg.bin(c, &fb[3 * f]);
    }
    const cell_index cells(fb);
    /* the search box's half-side: tol, plus the centroids' rounding (a few
     * ulps of the extent), generously */
    const double r = tol + cg.ext * 0x1p-40;

    double e = 0.0;
    for (int f = 0; f < nf; f++) {
        const int32_t *t = F + 3 * (size_t)f;
        if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2])
            continue;
        double c[3], clo[3], chi[3];
        int64_t b0[3], b1[3];
        centroid(&X[3 * t[0]], &X[3 * t[1]], &X[3 * t[2]], c);
        for (int a = 0; a < 3; a++) {
            clo[a] = c[a] - r;
            chi[a] = c[a] + r;
        }
        cg.bin(clo, b0);
        cg.bin(chi, b1);
        const double best = nearest_face(t, X, Y, G, cells, b0, b1);
        if (!(best <= tol)) {
            *worst_face = f;
            return false;
        }
        e = std::max(e, best);
    }
    *maxerr = e;
    return true;
}

} // namespace api_draco
