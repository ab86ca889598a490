/* SPDX-License-Identifier: MIT */
/*
 * eigen_peer.cpp - the Eigen peer of `make bench`: a straightforward mean
 * curvature flow step as libigl's tutorial (cotmatrix + massmatrix +
 * SimplicialLLT on M - dt L) and pmp-library (cotan weights from
 * dot/|cross|, Eigen sparse matrices) write it.
 *
 * Per step, from scratch, nothing cached between calls:
 *   1. cotan weights and barycentric areas per face;
 *   2. L (12 triplets per face: -w on (i,j),(j,i), +w on (i,i),(j,j)) and
 *      M (3 triplets per face) by SparseMatrix::setFromTriplets;
 *   3. implicit: A = M + dt L, SimplicialLDLT::compute(A) (symbolic AMD
 *      analysis + numeric factorization), solve A Xout = M X for the three
 *      columns at once. explicit: Xout = X - dt M^-1 (L X).
 * That is what a user of those libraries gets; libmcf instead analyzes once
 * per job and refills a fixed pattern, which is the difference measured.
 *
 * Degenerate triangles. A zero-area triangle makes the plain cotangent
 * dot/|cross| infinite (or 0/0 when all three points coincide), and the
 * dragon (dragon_vrip.drc) has 4,770 of them, so the plain peer would put
 * inf/NaN into L and fail. Choice made here: CLAMP the doubled area
 * |e1 x e2| of every triangle from below at 1e-8 * (longest edge)^2 (and at
 * DBL_MIN when all three points coincide). The numerators stay exact, so a
 * clamped triangle's 3x3 stiffness block keeps the sign pattern of a very
 * thin real triangle (PSD: the quadratic form is a limit of Dirichlet
 * energies) with finite, large weights; its barycentric mass uses the same
 * clamped area, so no vertex gets zero mass. Triangles with
 * |e1 x e2| >= 1e-8 lmax^2 (every triangle of a sane mesh, all of
 * sphere_cgal.obj and the icospheres) are untouched, so there the peer is
 * plain cotan and solves exactly libmcf's system. libmcf mollifies instead
 * (intrinsic mollification, core/mcf_laplacian.c); both only differ from
 * plain cotan on near-degenerate triangles, and the cost per face is the
 * same, which is all the timing needs.
 */
#include "eigen_peer.h"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <cfloat>
#include <chrono>
#include <cmath>
#include <vector>

namespace {

using SpMat = Eigen::SparseMatrix<double>;
using Trip = Eigen::Triplet<double>;
using RowMat = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

/* Relative floor on the doubled area: see the file comment. */
constexpr double kAreaFloor = 1e-8;

double now()
{
    using clk = std::chrono::steady_clock;
    return std::chrono::duration<double>(clk::now().time_since_epoch()).count();
}

/* Builds L (PSD cotan stiffness) and M (barycentric lumped mass) of the
 * mesh by triplets, libigl-style. */
void build_LM(int nv, const double *X, int nf, const int32_t *F, SpMat &L,
              SpMat &M)
{
    std::vector<Trip> tl, tm;
    tl.reserve(12 * static_cast<size_t>(nf));
    tm.reserve(3 * static_cast<size_t>(nf));
    for (int f = 0; f < nf; f++) {
        const int32_t *t = F + 3 * static_cast<size_t>(f);
        Eigen::Vector3d p[3];
        for (int k = 0; k < 3; k++)
            p[k] = Eigen::Map<const Eigen::Vector3d>(X + 3 * static_cast<size_t>(t[k]));
        /* e[k]: edge opposite corner k, from corner k+1 to corner k+2 */
        Eigen::Vector3d e[3] = {p[2] - p[1], p[0] - p[2], p[1] - p[0]};
        double lmax2 = std::max({e[0].squaredNorm(), e[1].squaredNorm(),
                                 e[2].squaredNorm()});
        double dbl_area = e[2].cross(-e[1]).norm(); /* |(p1-p0) x (p2-p0)| */
        dbl_area = std::max({dbl_area, kAreaFloor * lmax2, DBL_MIN});
        for (int k = 0; k < 3; k++) {
            /* angle at corner k between edges to k+1 and k+2:
             * cot = <p_{k+1}-p_k, p_{k+2}-p_k> / |cross| = -<e[k+2], e[k+1]>/|cross| */
            double cot = -e[(k + 2) % 3].dot(e[(k + 1) % 3]) / dbl_area;
            double w = 0.5 * cot;
            int i = t[(k + 1) % 3], j = t[(k + 2) % 3];
            tl.emplace_back(i, j, -w);
            tl.emplace_back(j, i, -w);
            tl.emplace_back(i, i, w);
            tl.emplace_back(j, j, w);
        }
        double a3 = dbl_area / 6.0; /* area / 3 */
        for (int k = 0; k < 3; k++)
            tm.emplace_back(t[k], t[k], a3);
    }
    L.resize(nv, nv);
    L.setFromTriplets(tl.begin(), tl.end());
    M.resize(nv, nv);
    M.setFromTriplets(tm.begin(), tm.end());
}

bool all_finite(const RowMat &Y)
{
    return Y.allFinite();
}

} // namespace

extern "C" int peer_desbrun_step(int nv, const double *X, int nf,
                                 const int32_t *F, double dt, double *Xout,
                                 peer_times *times)
{
    try {
        double t0 = now();
        SpMat L, M;
        build_LM(nv, X, nf, F, L, M);
        SpMat A = M + dt * L;
        double t1 = now();
        Eigen::SimplicialLDLT<SpMat> solver;
        solver.compute(A);
        if (solver.info() != Eigen::Success)
            return -1;
        double t2 = now();
        Eigen::Map<const RowMat> Xin(X, nv, 3);
        RowMat B = M * Xin;
        RowMat Y = solver.solve(B);
        if (solver.info() != Eigen::Success || !all_finite(Y))
            return -1;
        double t3 = now();
        std::copy(Y.data(), Y.data() + 3 * static_cast<size_t>(nv), Xout);
        if (times) {
            times->assemble = t1 - t0;
            times->factorize = t2 - t1;
            times->solve = t3 - t2;
            times->total = now() - t0;
        }
        return 0;
    } catch (...) {
        return -1;
    }
}

extern "C" int peer_euler_step(int nv, const double *X, int nf,
                               const int32_t *F, double dt, double *Xout,
                               peer_times *times)
{
    try {
        double t0 = now();
        SpMat L, M;
        build_LM(nv, X, nf, F, L, M);
        double t1 = now();
        Eigen::Map<const RowMat> Xin(X, nv, 3);
        RowMat LX = L * Xin;
        Eigen::VectorXd m = M.diagonal();
        RowMat Y = Xin - dt * (LX.array().colwise() / m.array()).matrix();
        if (!all_finite(Y))
            return -1;
        double t2 = now();
        std::copy(Y.data(), Y.data() + 3 * static_cast<size_t>(nv), Xout);
        if (times) {
            times->assemble = t1 - t0;
            times->factorize = 0.0;
            times->solve = t2 - t1;
            times->total = now() - t0;
        }
        return 0;
    } catch (...) {
        return -1;
    }
}

#define PEER_STR2(x) #x
#define PEER_STR(x) PEER_STR2(x)

extern "C" const char *peer_eigen_version(void)
{
    return PEER_STR(EIGEN_WORLD_VERSION) "." PEER_STR(EIGEN_MAJOR_VERSION) "." PEER_STR(
        EIGEN_MINOR_VERSION);
}
