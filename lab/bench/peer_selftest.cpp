/* SPDX-License-Identifier: MIT */
/*
 * peer_selftest.cpp - checks the Eigen peer (eigen_peer.cpp) against a
 * trivially correct dense reference before `make bench` trusts its times.
 *
 * The reference builds L and M densely by a different route (angles from
 * the law of cosines, cot = cos/sin, area by Heron's formula) and solves
 * (M + dt L) Y = M X with a dense LU, so a sign, index or factor-of-two
 * slip in the peer's triplets shows up. Meshes: a perturbed icosahedron
 * (closed, some obtuse angles), the same with 5 faces removed (boundary
 * edges: one cotangent per edge), and one with a vertex moved onto its
 * neighbour (two zero-area triangles: the peer's clamp must keep the step
 * finite and the two coincident points together). Exit status 0 on pass.
 */
#include "eigen_peer.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

namespace {

using Dense = Eigen::MatrixXd;

struct Mesh {
    std::vector<double> X;
    std::vector<int32_t> F;
    int nv() const { return static_cast<int>(X.size() / 3); }
    int nf() const { return static_cast<int>(F.size() / 3); }
};

Mesh icosahedron()
{
    const double p = (1.0 + std::sqrt(5.0)) / 2.0;
    Mesh m;
    m.X = {-1, p, 0, 1, p, 0, -1, -p, 0, 1, -p, 0, 0, -1, p, 0, 1, p,
           0, -1, -p, 0, 1, -p, p, 0, -1, p, 0, 1, -p, 0, -1, -p, 0, 1};
    m.F = {0, 11, 5, 0, 5, 1, 0, 1, 7, 0, 7, 10, 0, 10, 11, 1, 5, 9, 5, 11, 4,
           11, 10, 2, 10, 7, 6, 7, 1, 8, 3, 9, 4, 3, 4, 2, 3, 2, 6, 3, 6, 8,
           3, 8, 9, 4, 9, 5, 2, 4, 11, 6, 2, 10, 8, 6, 7, 9, 8, 1};
    /* deterministic perturbation up to +-0.3 per coordinate (edge length 2),
     * enough to make several angles obtuse */
    uint32_t s = 12345u;
    for (double &x : m.X) {
        s = s * 1664525u + 1013904223u;
        x += 0.6 * (static_cast<double>(s >> 8) / 16777216.0 - 0.5);
    }
    return m;
}

/* Dense reference L (PSD) and diagonal mass m, via the law of cosines. */
void dense_LM(const Mesh &m, Dense &L, Eigen::VectorXd &mass)
{
    int n = m.nv();
    L = Dense::Zero(n, n);
    mass = Eigen::VectorXd::Zero(n);
    for (int f = 0; f < m.nf(); f++) {
        int v[3] = {m.F[3 * f], m.F[3 * f + 1], m.F[3 * f + 2]};
        double l[3]; /* l[k]: side opposite corner k */
        for (int k = 0; k < 3; k++) {
            int a = v[(k + 1) % 3], b = v[(k + 2) % 3];
            double d2 = 0;
            for (int c = 0; c < 3; c++) {
                double d = m.X[3 * a + c] - m.X[3 * b + c];
                d2 += d * d;
            }
            l[k] = std::sqrt(d2);
        }
        double s = 0.5 * (l[0] + l[1] + l[2]);
        double area = std::sqrt(s * (s - l[0]) * (s - l[1]) * (s - l[2]));
        for (int k = 0; k < 3; k++) {
            double a = l[(k + 1) % 3], b = l[(k + 2) % 3], c = l[k];
            double cosk = (a * a + b * b - c * c) / (2 * a * b);
            double cotk = cosk / std::sqrt(1 - cosk * cosk);
            int i = v[(k + 1) % 3], j = v[(k + 2) % 3];
            L(i, j) -= 0.5 * cotk;
            L(j, i) -= 0.5 * cotk;
            L(i, i) += 0.5 * cotk;
            L(j, j) += 0.5 * cotk;
            mass(v[k]) += area / 3;
        }
    }
}

double rel_diff(const std::vector<double> &a, const Dense &b)
{
    double num = 0, den = 0;
    for (size_t i = 0; i < a.size(); i++) {
        double r = b(static_cast<Eigen::Index>(i / 3), static_cast<Eigen::Index>(i % 3));
        num += (a[i] - r) * (a[i] - r);
        den += r * r;
    }
    return std::sqrt(num / den);
}

int failures = 0;

void check(bool ok, const char *what, double value)
{
    std::printf("  %-58s %.3g  %s\n", what, value, ok ? "ok" : "FAIL");
    if (!ok)
        failures++;
}

void compare_with_dense(const char *name, const Mesh &m, double dt)
{
    Dense L;
    Eigen::VectorXd mass;
    dense_LM(m, L, mass);
    Dense X(m.nv(), 3);
    for (int i = 0; i < m.nv(); i++)
        for (int c = 0; c < 3; c++)
            X(i, c) = m.X[3 * i + c];
    Dense Mx = mass.asDiagonal() * X;
    Dense Yimp = (Dense(mass.asDiagonal()) + dt * L).partialPivLu().solve(Mx);
    Dense Yexp = X - dt * (mass.cwiseInverse().asDiagonal() * (L * X));

    std::vector<double> out(m.X.size());
    char what[128];
    /* Both sides solve a 12x12 system with condition number below ~1e3 in
     * double precision: 1e-12 relative leaves a wide margin over roundoff
     * yet catches any wrong weight (errors of order 1e-2 and up). */
    int rc = peer_desbrun_step(m.nv(), m.X.data(), m.nf(), m.F.data(), dt,
                               out.data(), nullptr);
    std::snprintf(what, sizeof what, "%s: implicit step vs dense LU (dt %g)", name, dt);
    check(rc == 0 && rel_diff(out, Yimp) < 1e-12, what, rc == 0 ? rel_diff(out, Yimp) : -1.0);
    rc = peer_euler_step(m.nv(), m.X.data(), m.nf(), m.F.data(), dt, out.data(),
                         nullptr);
    std::snprintf(what, sizeof what, "%s: explicit step vs dense (dt %g)", name, dt);
    check(rc == 0 && rel_diff(out, Yexp) < 1e-12, what, rc == 0 ? rel_diff(out, Yexp) : -1.0);
}

} // namespace

int main()
{
    std::printf("peer self-test (Eigen %s) against a dense reference:\n",
                peer_eigen_version());
    Mesh ico = icosahedron();
    compare_with_dense("icosahedron", ico, 0.05);
    compare_with_dense("icosahedron", ico, 2.0);

    Mesh open = ico;
    open.F.resize(open.F.size() - 15); /* drop 5 faces: a boundary loop */
    compare_with_dense("open icosahedron", open, 0.05);

    /* vertex 1 moved onto vertex 0: faces (0,5,1) and (0,1,7) get zero
     * area; without the clamp their cotangents are inf and the solve NaN */
    Mesh deg = ico;
    for (int c = 0; c < 3; c++)
        deg.X[3 + c] = deg.X[c];
    std::vector<double> out(deg.X.size());
    int rc = peer_desbrun_step(deg.nv(), deg.X.data(), deg.nf(), deg.F.data(),
                               0.05, out.data(), nullptr);
    bool finite = rc == 0 && std::all_of(out.begin(), out.end(),
                                         [](double v) { return std::isfinite(v); });
    double gap = finite ? std::hypot(out[0] - out[3], std::hypot(out[1] - out[4], out[2] - out[5]))
                        : -1.0;
    /* The clamped weight of the collapsed edge is ~5e7 against O(1)
     * others, so the two points may drift apart by ~1e-8 of the edge
     * length at most; 1e-6 is a safe bound that still fails if the
     * collapsed edge got no stiffness at all (gap would be O(0.1)). */
    check(finite && gap < 1e-6, "zero-area triangles: finite step, coincident pair kept", gap);
    rc = peer_euler_step(deg.nv(), deg.X.data(), deg.nf(), deg.F.data(), 1e-9,
                         out.data(), nullptr);
    finite = rc == 0 && std::all_of(out.begin(), out.end(),
                                    [](double v) { return std::isfinite(v); });
    check(finite, "zero-area triangles: explicit step finite", finite ? 0.0 : 1.0);

    std::printf("peer self-test: %s\n", failures ? "FAIL" : "PASS");
    return failures ? 1 : 0;
}
