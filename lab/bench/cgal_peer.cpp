/* SPDX-License-Identifier: MIT */
/*
 * cgal_peer.cpp - the CGAL peer of the benchmark: smooth_shape on a
 * CGAL::Surface_mesh<Simple_cartesian<double>::Point_3>, called the way the
 * CGAL manual's example does, with the default solver. See cgal_peer.h for
 * what one iteration solves and how its `time` maps to mcfd's dt.
 *
 * The only thing added to a plain call is a timing wrapper around CGAL's
 * default solver: Timed_solver forwards factor() and linear_solver() to the
 * very solver type smooth_shape would pick by itself (Eigen_solver_traits of
 * BiCGSTAB + IncompleteLUT, whose factor() and linear_solver() are the
 * generic compute() and solve()), and records the seconds, BiCGSTAB's
 * iteration counts and residuals. smooth_shape copies the solver object it
 * is given; the copies share the Eigen solver and the statistics through
 * shared_ptr, so the caller's copy sees everything.
 */
#include "cgal_peer.h"

#include <CGAL/Eigen_solver_traits.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/smooth_shape.h>
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/boost/graph/helpers.h>
#include <CGAL/version.h>

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/Sparse>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <memory>
#include <vector>

namespace {

using Kernel = CGAL::Simple_cartesian<double>;
using Point = Kernel::Point_3;
using Mesh = CGAL::Surface_mesh<Point>;
using VI = Mesh::Vertex_index;
namespace PMP = CGAL::Polygon_mesh_processing;

double now()
{
    using clk = std::chrono::steady_clock;
    return std::chrono::duration<double>(clk::now().time_since_epoch()).count();
}

/* smooth_shape's default solver (smooth_shape.h, CGAL 5.5.1). */
using Eigen_sp = CGAL::Eigen_sparse_matrix<double>::EigenType;
using Default_solver =
    CGAL::Eigen_solver_traits<Eigen::BiCGSTAB<Eigen_sp, Eigen::IncompleteLUT<double>>>;

struct Solver_stats {
    double factor = 0.0, solve = 0.0;
    int factors = 0, solves = 0, failed = 0;
    long fail_iters = 0;
    double fail_residual = 0.0;
    long iters = 0;
    int iters_max = 0;
    double residual_max = 0.0;
};

/* A model of SparseLinearAlgebraWithFactorTraits_d that forwards to
 * Default_solver and times it. */
class Timed_solver {
public:
    using Matrix = Default_solver::Matrix;
    using Vector = Default_solver::Vector;
    using NT = Default_solver::NT;

    explicit Timed_solver(long max_iters) : st_(std::make_shared<Solver_stats>())
    {
        if (max_iters > 0)
            base_.solver().setMaxIterations(static_cast<Eigen::Index>(max_iters));
    }

    bool factor(const Matrix &A, NT &D)
    {
        double t0 = now();
        bool ok = base_.factor(A, D);
        st_->factor += now() - t0;
        st_->factors++;
        st_->failed += !ok;
        return ok;
    }

    bool linear_solver(const Vector &B, Vector &X)
    {
        double t0 = now();
        bool ok = base_.linear_solver(B, X);
        st_->solve += now() - t0;
        st_->solves++;
        long it = static_cast<long>(base_.solver().iterations());
        double res = base_.solver().error();
        st_->iters += it;
        st_->iters_max = std::max(st_->iters_max, static_cast<int>(it));
        if (ok)
            st_->residual_max = std::max(st_->residual_max, res);
        else {
            st_->failed++;
            st_->fail_iters = it;
            st_->fail_residual = res;
        }
        return ok;
    }

    Solver_stats &stats() { return *st_; }

private:
    Default_solver base_;
    std::shared_ptr<Solver_stats> st_;
};

__attribute__((format(printf, 3, 4))) void set_msg(char *msg, size_t len, const char *fmt, ...)
{
    if (!msg || !len)
        return;
    va_list ap;
    va_start(ap, fmt);
    std::vsnprintf(msg, len, fmt, ap);
    va_end(ap);
}

} // namespace

struct cgal_peer {
    Mesh mesh;
    std::vector<VI> v; /* v[i] = vertex of input index i */
    bool closed = false;
};

extern "C" cgal_peer *cgal_peer_new(int nv, const double *X, int nf,
                                    const int32_t *F, char *msg, size_t msglen)
{
    try {
        std::unique_ptr<cgal_peer> p(new cgal_peer);
        if (nv <= 0 || nf <= 0) {
            set_msg(msg, msglen, "cgal_peer: empty mesh (nv %d, nf %d)", nv, nf);
            return nullptr;
        }
        p->mesh.reserve(static_cast<Mesh::size_type>(nv), static_cast<Mesh::size_type>(3 * nf / 2 + 3),
                        static_cast<Mesh::size_type>(nf));
        p->v.resize(static_cast<size_t>(nv));
        for (int i = 0; i < nv; i++) {
            const double *x = X + 3 * static_cast<size_t>(i);
            p->v[static_cast<size_t>(i)] = p->mesh.add_vertex(Point(x[0], x[1], x[2]));
        }
        for (int f = 0; f < nf; f++) {
            const int32_t *t = F + 3 * static_cast<size_t>(f);
            for (int k = 0; k < 3; k++)
                if (t[k] < 0 || t[k] >= nv) {
                    set_msg(msg, msglen, "cgal_peer: face %d has an index out of range", f);
                    return nullptr;
                }
            if (p->mesh.add_face(p->v[static_cast<size_t>(t[0])], p->v[static_cast<size_t>(t[1])],
                                 p->v[static_cast<size_t>(t[2])]) == Mesh::null_face()) {
                set_msg(msg, msglen,
                        "cgal_peer: Surface_mesh refused face %d (non-manifold or repeated)", f);
                return nullptr;
            }
        }
        for (VI vi : p->mesh.vertices())
            if (p->mesh.is_isolated(vi)) {
                set_msg(msg, msglen,
                        "cgal_peer: vertex %ld is used by no face (smooth_shape's system would "
                        "be singular)",
                        static_cast<long>(vi.idx()));
                return nullptr;
            }
        p->closed = CGAL::is_closed(p->mesh);
        return p.release();
    } catch (...) {
        set_msg(msg, msglen, "cgal_peer: exception while building the mesh");
        return nullptr;
    }
}

extern "C" void cgal_peer_free(cgal_peer *p)
{
    delete p;
}

extern "C" int cgal_peer_closed(const cgal_peer *p)
{
    return p->closed ? 1 : 0;
}

extern "C" void cgal_peer_get(const cgal_peer *p, double *X)
{
    for (size_t i = 0; i < p->v.size(); i++) {
        const Point &q = p->mesh.point(p->v[i]);
        X[3 * i] = q.x();
        X[3 * i + 1] = q.y();
        X[3 * i + 2] = q.z();
    }
}

extern "C" void cgal_peer_set(cgal_peer *p, const double *X)
{
    for (size_t i = 0; i < p->v.size(); i++)
        p->mesh.point(p->v[i]) = Point(X[3 * i], X[3 * i + 1], X[3 * i + 2]);
}

extern "C" int cgal_peer_smooth(cgal_peer *p, double time, int iterations, long max_iters,
                                cgal_peer_times *t)
{
    try {
        Timed_solver solver(max_iters);
        double t0 = now();
        PMP::smooth_shape(p->mesh, time,
                          CGAL::parameters::number_of_iterations(static_cast<unsigned>(iterations))
                              .sparse_linear_solver(solver));
        double wall = now() - t0;
        const Solver_stats &s = solver.stats();
        if (t) {
            t->total += wall;
            t->factor += s.factor;
            t->solve += s.solve;
            t->calls++;
            t->iterations += s.factors;
            t->solves += s.solves;
            t->bicgstab_iters += s.iters;
            t->bicgstab_iters_max = std::max(t->bicgstab_iters_max, s.iters_max);
            t->residual_max = std::max(t->residual_max, s.residual_max);
            if (s.failed || s.factors != iterations) {
                t->failures++;
                t->fail_iters = s.fail_iters;
                t->fail_residual = s.fail_residual;
            }
        }
        /* smooth_shape stops silently on a solver failure: the wrapper
         * knows (a failed solve, or fewer factorizations than asked) */
        return s.failed || s.factors != iterations ? -1 : 0;
    } catch (...) {
        return -1;
    }
}

extern "C" void cgal_peer_rescale_like_smooth_shape(cgal_peer *p, const double *Xold,
                                                    const double *Y, double *Xout)
{
    /* the same calls as Shape_smoother::update_mesh (curvature_flow_impl.h) */
    cgal_peer_set(p, Xold);
    const double old_vol = PMP::volume(p->mesh);
    const Point pre = PMP::centroid(p->mesh);
    cgal_peer_set(p, Y);
    const Point post = PMP::centroid(p->mesh);
    const double new_vol = PMP::volume(p->mesh);
    const double s = std::cbrt(std::abs(old_vol / new_vol));
    const double a[3] = {pre.x(), pre.y(), pre.z()}, b[3] = {post.x(), post.y(), post.z()};
    for (size_t i = 0; i < 3 * p->v.size(); i++)
        Xout[i] = a[i % 3] + s * (Y[i] - b[i % 3]);
    cgal_peer_set(p, Xout);
}

extern "C" void cgal_peer_times_reset(cgal_peer_times *t)
{
    *t = cgal_peer_times();
}

#define CGAL_PEER_STR2(x) #x
#define CGAL_PEER_STR(x) CGAL_PEER_STR2(x)

extern "C" const char *cgal_peer_version(void)
{
    return CGAL_VERSION_STR;
}

extern "C" const char *cgal_peer_eigen_version(void)
{
    return CGAL_PEER_STR(EIGEN_WORLD_VERSION) "." CGAL_PEER_STR(
        EIGEN_MAJOR_VERSION) "." CGAL_PEER_STR(EIGEN_MINOR_VERSION);
}
