#pragma once
// Elastic steel cantilevers against beam theory.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <gtest/gtest.h>

#include "../support.hpp"
#include "rkfem/run/simulation.hpp"

namespace rkfem::test
{
/// First cantilever period (Euler-Bernoulli): omega = (1.875104)^2 sqrt(E I / (rho A L^4)).
inline real_t euler_bernoulli_period(real_t E, real_t rho, real_t L, real_t h)
{
    const real_t beta = 1.875104068711961;
    return 2 * M_PI / (beta * beta * std::sqrt(E * h * h / (12 * rho * std::pow(L, 4))));
}

/// Static tip deflection with shear (Timoshenko, Cowper's kappa for a rectangle).
inline real_t timoshenko_tip_deflection(real_t P, real_t E, real_t nu, real_t L, real_t b, real_t h)
{
    const real_t I = b * h * h * h / 12, G = E / (2 * (1 + nu));
    const real_t kappa = 10 * (1 + nu) / (12 + 11 * nu);
    return P * L * L * L / (3 * E * I) + P * L / (kappa * G * b * h);
}

inline std::string cantilever_deck(const std::string& formulation, int nx, int ny, int nz, real_t h_mm,
                                   const std::string& time_block, const std::string& loads)
{
    return "title: cantilever\n" + time_block + "parts:\n  beam:\n    generator: {type: box, size: [1000 mm, " +
           std::to_string(h_mm) + " mm, " + std::to_string(h_mm) + " mm], divisions: [" + std::to_string(nx) + ", " +
           std::to_string(ny) + ", " + std::to_string(nz) +
           "]}\n    material: {model: elastic, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3}\n" + formulation +
           "    bulk_viscosity: {linear: 0, quadratic: 0}\n"
           "node_sets:\n  root: {select: {type: named, name: xmin}}\n  tip: {select: {type: named, name: xmax}}\n"
           "boundary_conditions:\n  - {node_set: root, fixed: all}\n" +
           loads + "probes:\n  tip: {point: [1000 mm, " + std::to_string(h_mm / 2) + " mm, " +
           std::to_string(h_mm / 2) + " mm]}\n";
}

/// Static tip deflection by dynamic relaxation (mass damping near critical for mode 1).
inline real_t relaxed_tip_deflection(const std::string& formulation, int nx, int ny, int nz)
{
    const std::string deck =
        cantilever_deck(formulation, nx, ny, nz, 100.0, "time: {end: 30 ms, mass_damping: 1000}\n",
                        "loads:\n  - {type: nodal_force, node_set: tip, force: {z: -10 kN}, total: true}\n");
    Model m = model_from(deck);
    RunOptions opt;
    opt.progress = false;
    const RunSummary s = run_simulation(m, opt);
    EXPECT_EQ(s.status, "completed") << s.message;
    // residual velocity must be negligible for a converged relaxation
    real_t vmax = 0;
    for (real_t v : m.nodes.v)
        vmax = std::max(vmax, std::abs(v));
    EXPECT_LT(vmax, 1e-5);
    return -m.nodes.u[3 * m.probe_nodes[0] + 2];
}
struct Vibration
{
    real_t period = 0, drift = 0, balance = 0;
};

/// Slender steel cantilever 1000 x 50 x 50 mm released in its first Euler-Bernoulli mode shape
/// (initial velocity), run for ten periods without damping.
inline Vibration free_vibration(const std::string& formulation, int nx, int n)
{
    const real_t L = 1.0, h = 0.05;
    const real_t T = euler_bernoulli_period(200e9, 7850, L, h);
    const std::string deck =
        cantilever_deck(formulation, nx, n, n, 50.0, "time: {end: " + std::to_string(10.5 * T) + "}\n", "");
    Model m = model_from(deck);
    const real_t bl = 1.875104068711961;
    const real_t sig = (std::cosh(bl) + std::cos(bl)) / (std::sinh(bl) + std::sin(bl));
    auto phi = [&](real_t x)
    {
        const real_t b = bl * x / L;
        return std::cosh(b) - std::cos(b) - sig * (std::sinh(b) - std::sin(b));
    };
    for (index_t i = 0; i < m.nodes.size(); ++i)
        m.nodes.v[3 * i + 2] = 0.1 * phi(m.nodes.x0[3 * i]) / phi(L); // 0.1 m/s at the tip
    std::vector<real_t> times, uz, totals;
    RunOptions opt;
    opt.progress = false;
    const RunSummary s = run_simulation(m, opt,
                                        [&](const Model& mm, real_t t, real_t, std::int64_t)
                                        {
                                            times.push_back(t);
                                            uz.push_back(mm.nodes.u[3 * mm.probe_nodes[0] + 2]);
                                            totals.push_back(mm.energy.total());
                                        });
    EXPECT_EQ(s.status, "completed") << s.message;
    // period from upward zero crossings of the tip displacement (linear interpolation)
    std::vector<real_t> crossings;
    for (std::size_t i = 1; i < uz.size(); ++i)
        if (uz[i - 1] < 0 && uz[i] >= 0)
            crossings.push_back(times[i - 1] + (times[i] - times[i - 1]) * (-uz[i - 1]) / (uz[i] - uz[i - 1]));
    Vibration v;
    EXPECT_GE(crossings.size(), 9u);
    if (crossings.size() >= 2)
        v.period = (crossings.back() - crossings.front()) / (crossings.size() - 1);
    const auto [lo, hi] = std::minmax_element(totals.begin(), totals.end());
    v.drift = (*hi - *lo) / totals.front();
    v.balance = s.max_balance_error;
    std::printf("%s %dx%dx%d: period %.4f ms vs Euler-Bernoulli %.4f ms (%+.2f%%), energy drift %.2e\n",
                formulation.c_str(), nx, n, n, v.period * 1e3, T * 1e3, 100 * (v.period / T - 1), v.drift);
    return v;
}
} // namespace rkfem::test
