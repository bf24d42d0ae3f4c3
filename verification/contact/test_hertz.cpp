// Hertz contact: an elastic sphere pressed slowly onto an elastic half-space of the same steel,
// through mortar contact, against Hertz's theory (Johnson, Contact Mechanics, 1985, ch. 3-4).
//
// Hertz: a = (3 F R / (4 E*))^(1/3), p(r) = p0 sqrt(1 - r^2 / a^2), p0 = 3 F / (2 pi a^2), and
// the approach of distant points delta = a^2 / R, 1 / E* = 2 (1 - nu^2) / E for two equal
// materials. A finite model has no distant points: the approach of the sphere's centre and of a
// point deep in a finite block differs from delta by terms of order a / R (the bodies' own
// compression). So the indentation measured here is the approach of two points on the axis at
// distance L from the contact, one in each body, and Hertz's half-space solution gives it exactly:
//   delta_L = delta - 2 w(L),  w(z) = int_0^a p(r) u_B(r, z) 2 pi r dr,
//   u_B(r, z) = (2 (1 - nu) / rho + z^2 / rho^3) / (4 pi G),  rho^2 = r^2 + z^2
// (Boussinesq's displacement at depth z under a unit point force; w(0) = delta / 2).
//
// Model: a quarter (symmetry rollers on x = 0 and y = 0). The sphere is its cap: a 10.9 mm block
// whose bottom is the sphere of radius R = 50 mm touching the half-space at the origin; the
// half-space a 10.9 mm block with its bottom fixed. Both meshes are graded towards the contact
// (0.125 mm elements there, ratio 1.2, 16 per edge; fully integrated hexes, so that no hourglass
// control stands between the bodies' elasticity and Hertz's: with 1-point hexes and the stiffness
// form at QM 0.15 the force at full load is 5.8 % low) and written as an LS-DYNA keyword file, which
// the deck reads (generator type keyword). The cap's top is pushed down 24 um along a smooth
// ramp in 60 us (about 35 wave transits of the bodies: quasi-static).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "../support.hpp"
#include "rkfem/run/simulation.hpp"

using namespace rkfem;

namespace
{
constexpr real_t E = 200e9, nu = 0.3, R = 0.05;

/// Hertz's approach of two axis points at distance L from the contact, one in each body, under F
/// (the whole sphere's force).
real_t hertz_delta_L(real_t F, real_t L)
{
    const real_t Es = E / (2.0 * (1.0 - nu * nu));
    const real_t a = std::cbrt(3.0 * F * R / (4.0 * Es));
    const real_t p0 = 3.0 * F / (2.0 * M_PI * a * a);
    const real_t G = E / (2.0 * (1.0 + nu));
    // w(L): r = a sin(t), the midpoint rule on t in [0, pi/2] (smooth integrand)
    const int n = 4000;
    real_t w = 0.0;
    for (int k = 0; k < n; ++k)
    {
        const real_t t = (k + 0.5) * (0.5 * M_PI / n);
        const real_t r = a * std::sin(t), dr = a * std::cos(t) * (0.5 * M_PI / n);
        const real_t rho = std::sqrt(r * r + L * L);
        const real_t p = p0 * std::cos(t);
        w += p * (2.0 * (1.0 - nu) / rho + L * L / (rho * rho * rho)) / (4.0 * M_PI * G) * 2.0 * M_PI * r * dr;
    }
    return a * a / R - 2.0 * w;
}

/// The force Hertz gives for an approach delta_L of the axis points at distance L (bisection).
real_t hertz_force(real_t delta_L, real_t L)
{
    real_t lo = 0.0, hi = 1.0;
    while (hertz_delta_L(hi, L) < delta_L)
        hi *= 2.0;
    for (int it = 0; it < 100; ++it)
    {
        const real_t mid = 0.5 * (lo + hi);
        (hertz_delta_L(mid, L) < delta_L ? lo : hi) = mid;
    }
    return 0.5 * (lo + hi);
}

std::string num(real_t v)
{
    char b[32];
    std::snprintf(b, sizeof b, "%.17g", v);
    return b;
}

/// Graded 1-D coordinates 0, h0, h0 + h0 q, ... (n intervals).
std::vector<real_t> graded(real_t h0, real_t q, int n)
{
    std::vector<real_t> s{0.0};
    real_t h = h0;
    for (int k = 0; k < n; ++k, h *= q)
        s.push_back(s.back() + h);
    return s;
}

/// The two bodies as an LS-DYNA keyword file: PID 1 the half-space block (z from -D to 0), PID 2
/// the sphere's cap (z from the sphere's surface to H).
std::string write_mesh(const std::vector<real_t>& s)
{
    const int n = static_cast<int>(s.size()) - 1;
    const real_t H = s.back();
    std::vector<real_t> x;
    std::vector<index_t> conn;
    std::vector<int> pid;
    auto node = [&](int body, int i, int j, int l)
    { return static_cast<index_t>(body * (n + 1) * (n + 1) * (n + 1) + (l * (n + 1) + j) * (n + 1) + i); };
    for (int body = 0; body < 2; ++body)
        for (int l = 0; l <= n; ++l)
            for (int j = 0; j <= n; ++j)
                for (int i = 0; i <= n; ++i)
                {
                    const real_t xx = s[i], y = s[j];
                    real_t z = -s[n - l]; // block: l = n at the contact plane
                    if (body == 1)
                    {
                        const real_t zs = R - std::sqrt(R * R - xx * xx - y * y); // the sphere's surface
                        z = s[l] + zs * (1.0 - s[l] / H);
                    }
                    x.insert(x.end(), {xx, y, z});
                }
    for (int body = 0; body < 2; ++body)
        for (int l = 0; l < n; ++l)
            for (int j = 0; j < n; ++j)
                for (int i = 0; i < n; ++i)
                {
                    conn.insert(conn.end(),
                                {node(body, i, j, l), node(body, i + 1, j, l), node(body, i + 1, j + 1, l),
                                 node(body, i, j + 1, l), node(body, i, j, l + 1), node(body, i + 1, j, l + 1),
                                 node(body, i + 1, j + 1, l + 1), node(body, i, j + 1, l + 1)});
                    pid.push_back(body + 1);
                }
    return test::write_keyword_mesh("rkfem_hertz.k", x, conn, pid);
}
} // namespace

TEST(Hertz, SphereOnHalfSpaceForceFollowsHertzWithinFivePercent)
{
    const std::vector<real_t> s = graded(1.5e-4, 1.25, 13);
    const real_t H = s.back();
    const std::string mesh = write_mesh(s);
    // the top's displacement: a smooth ramp (zero velocity at both ends) to U in T
    const real_t U = 24e-6, T = 40e-6;
    std::ostringstream ramp;
    ramp << "[";
    for (int k = 0; k <= 60; ++k)
    {
        const real_t t = T * k / 60.0;
        ramp << (k ? ", " : "") << "[" << t << ", " << -U * (t / T - std::sin(2 * M_PI * t / T) / (2 * M_PI)) << "]";
    }
    ramp << "]";
    const std::string deck = R"(
title: Hertz, sphere on half-space
time: {end: 40 us, stepper: central-difference, energy_error_limit: 1}
parts:
  block:
    generator: {type: keyword, file: )" +
                             mesh + R"(, pid: 1}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: fem-2x2x2
  cap:
    generator: {type: keyword, file: )" +
                             mesh + R"(, pid: 2}
    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}
    formulation: fem-2x2x2
node_sets:
  x0: {select: {type: plane, point: [0, 0, 0], normal: [1, 0, 0]}}
  y0: {select: {type: plane, point: [0, 0, 0], normal: [0, 1, 0]}}
  base: {part: block, select: {type: plane, point: [0, 0, )" +
                             num(-H) + R"(], normal: [0, 0, 1]}}
  top: {part: cap, select: {type: plane, point: [0, 0, )" +
                             num(H) + R"(], normal: [0, 0, 1]}}
boundary_conditions:
  - {node_set: x0, fixed: [x]}
  - {node_set: y0, fixed: [y]}
  - {node_set: base, fixed: [z]}
  - {node_set: top, displacement: {z: {curve: )" +
                             ramp.str() + R"(}}}
contacts:
  - {type: surface-to-surface, surfaces: [cap, block], formulation: mortar, stiffness: segment, penalty_scale: 10}
)";
    Model m = test::model_from(deck);
    // the axis nodes at distance L from the contact in each body
    auto axis_node = [&](real_t z, index_t part)
    {
        index_t best = -1;
        real_t d = 1e300;
        for (index_t i = 0; i < m.nodes.size(); ++i)
        {
            if (m.nodes.part[i] != part)
                continue;
            const Vec3 x(m.nodes.x0[3 * i], m.nodes.x0[3 * i + 1], m.nodes.x0[3 * i + 2]);
            const real_t e = (x - Vec3(0, 0, z)).norm();
            if (e < d)
                d = e, best = i;
        }
        EXPECT_LT(d, 1e-12);
        return best;
    };
    struct Sample
    {
        real_t t, F, delta[2];
    };
    const int Ls[2] = {6, 8}; // L = s[6] = 1.24 mm, s[8] = 2.07 mm
    index_t cap_node[2], block_node[2];
    for (int k = 0; k < 2; ++k)
    {
        cap_node[k] = axis_node(s[Ls[k]], 1);
        block_node[k] = axis_node(-s[Ls[k]], 0);
    }
    std::vector<Sample> samples;
    RunOptions opt;
    opt.progress = false;
    const RunSummary sum =
        run_simulation(m, opt,
                       [&](const Model& mm, real_t t, real_t, std::int64_t)
                       {
                           Sample a;
                           a.t = t;
                           a.F = 4.0 * mm.contacts[0]->resultant()[2]; // the whole sphere
                           for (int k = 0; k < 2; ++k)
                               a.delta[k] = -mm.nodes.u[3 * cap_node[k] + 2] + mm.nodes.u[3 * block_node[k] + 2];
                           samples.push_back(a);
                       });
    ASSERT_EQ(sum.status, "completed") << sum.message;
    std::printf("Hertz: %lld steps, %.1f s\n", static_cast<long long>(sum.steps), sum.stepping_seconds);
    // at 50 %, 75 % and 100 % of the ramp: the force Hertz gives for the measured approach,
    // averaged over 2 us (the elastic ringing)
    for (real_t frac : {0.5, 0.75, 1.0})
    {
        for (int k = 0; k < 2; ++k)
        {
            real_t F = 0.0, d = 0.0;
            int cnt = 0;
            for (const Sample& a : samples)
                if (a.t > frac * T - 2e-6 && a.t <= frac * T)
                {
                    F += a.F, d += a.delta[k];
                    ++cnt;
                }
            F /= cnt, d /= cnt;
            const real_t L = s[Ls[k]];
            const real_t Fh = hertz_force(d, L);
            const real_t a = std::cbrt(3.0 * F * R / (4.0 * E / (2.0 * (1.0 - nu * nu))));
            std::printf("Hertz at %3.0f %% of the ramp, L = %.2f mm: F %.1f N, approach %.3f um, Hertz's force for it "
                        "%.1f N (%+.2f %%), contact radius %.3f mm (a / R %.3f)\n",
                        100 * frac, 1e3 * L, F, 1e6 * d, Fh, 100 * (F / Fh - 1), 1e3 * a, a / R);
            EXPECT_NEAR(F / Fh, 1.0, 0.05);
        }
    }
}
