#include "rkfem/operators/nodal_step_estimate.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include <Eigen/Eigenvalues>

#include "rkfem/operators/nodal_force.hpp"

namespace rkfem
{
HighestFrequency nodal_highest_frequency(NodalBlock& blk, const std::vector<real_t>& mass, int max_passes,
                                         real_t tolerance)
{
    HighestFrequency out;
    const std::size_t b = 3 * static_cast<std::size_t>(blk.node_begin), e = 3 * static_cast<std::size_t>(blk.node_end);
    real_t l0_min = std::numeric_limits<real_t>::max();
    for (const real_t l : blk.length0)
        l0_min = std::min(l0_min, l);
    if (e <= b || blk.n_points() == 0 || !(l0_min > 0.0))
        return out;
    auto m_of = [&](std::size_t dof) { return mass[dof / 3]; };
    // w0: a fixed pseudo-random sign per dof (a hash of its index), M-normalized; a start with
    // a share of every mode, the highest included
    // the probe's nodes: only the arrays the pass reads (u, v) and the assembly writes (f_int),
    // up to the block's last node (global numbering)
    NodeSet probe;
    for (auto* a : {&probe.u, &probe.v, &probe.f_int})
        a->assign(e, 0.0);
    std::vector<real_t> w(e - b);
    for (std::size_t k = 0; k < w.size(); ++k)
    {
        std::uint64_t h = (k + 1) * 0x9E3779B97F4A7C15ull;
        h ^= h >> 31;
        h *= 0xBF58476D1CE4E5B9ull;
        h ^= h >> 29;
        w[k] = (h & 1) ? 1.0 : -1.0;
    }
    auto normalize = [&]()
    {
        real_t n2 = 0.0;
        for (std::size_t k = 0; k < w.size(); ++k)
            n2 += m_of(b + k) * w[k] * w[k];
        const real_t s = n2 > 0.0 ? 1.0 / std::sqrt(n2) : 0.0;
        for (real_t& x : w)
            x *= s;
        return n2 > 0.0;
    };
    if (!normalize())
        return out;
    // Lanczos in the M inner product (M^-1 K is self-adjoint there): q_j M-orthonormal,
    // M^-1 K q_j = beta_{j-1} q_{j-1} + alpha_j q_j + beta_j q_{j+1}; the largest eigenvalue
    // of the tridiagonal (alpha, beta) approaches omega_max^2 from below, much faster than the
    // power iteration's quotient (which took 20-60 passes to come within 1-2 % on the test
    // blocks). Stops when the Ritz value's residual bound beta_j |s_j| is under `tolerance` of it.
    // The probe's step: a strain increment of about 1e-9 (|q| l0 / l0_min at most), elastic for
    // every material; from zero stress the pass's forces are dt K q, exactly linear in dt.
    const BulkViscositySpec saved_q = blk.bulk_viscosity;
    blk.bulk_viscosity = {0.0, 0.0};
    std::vector<real_t> q_prev(w.size(), 0.0), z(w.size());
    std::vector<real_t> alpha, beta;
    real_t lambda = 0.0, beta_prev = 0.0;
    for (int pass = 0; pass < max_passes; ++pass)
    {
        real_t w_max = 0.0;
        for (const real_t x : w)
            w_max = std::max(w_max, std::abs(x));
        const real_t dt = 1e-9 * l0_min / w_max;
        std::copy(w.begin(), w.end(), probe.v.begin() + static_cast<std::ptrdiff_t>(b));
        nodal_internal_force(blk, probe, dt);
        assemble_nodal_forces(blk, probe);
        ++out.passes;
        real_t a = 0.0;
        for (std::size_t k = 0; k < w.size(); ++k)
        {
            const real_t kw = probe.f_int[b + k] / dt;
            a += w[k] * kw;
            z[k] = kw / m_of(b + k);
        }
        if (!std::isfinite(a))
        {
            lambda = 0.0;
            break;
        }
        real_t n2 = 0.0;
        for (std::size_t k = 0; k < w.size(); ++k)
        {
            z[k] -= a * w[k] + beta_prev * q_prev[k];
            n2 += m_of(b + k) * z[k] * z[k];
        }
        const real_t bj = std::sqrt(n2);
        alpha.push_back(a);
        beta.push_back(bj);
        // the tridiagonal's largest eigenvalue and its eigenvector's last component
        const int n = static_cast<int>(alpha.size());
        const Eigen::VectorXd diag = Eigen::Map<const Eigen::VectorXd>(alpha.data(), n);
        const Eigen::VectorXd sub = Eigen::Map<const Eigen::VectorXd>(beta.data(), n - 1);
        Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es;
        es.computeFromTridiagonal(diag, sub, Eigen::ComputeEigenvectors);
        lambda = es.eigenvalues()(n - 1);
        const real_t residual = bj * std::abs(es.eigenvectors()(n - 1, n - 1));
        if (residual <= tolerance * lambda || !(bj > 1e-14 * lambda))
            break;
        q_prev.swap(w);
        for (std::size_t k = 0; k < w.size(); ++k)
            w[k] = z[k] / bj;
        beta_prev = bj;
    }
    blk.bulk_viscosity = saved_q;
    if (lambda > 0.0)
    {
        out.omega_max = std::sqrt(lambda);
        out.alpha_crit = 2.0 / out.omega_max * blk.material.wave_speed() / l0_min;
    }
    return out;
}

bool nodal_step_calibrated(Formulation formulation, const NodalIntegrationSpec& nodal, const RkSpec& rk,
                           bool jittered_cloud)
{
    const RkSpec defaults;
    const bool coefficient =
        nodal.stabilization_coefficient == (nodal.stabilization == "nsni" ? kNsniCoefficient : 1.0);
    if (formulation == Formulation::FemNodal)
        return coefficient && nodal.scheme != "dni";
    return formulation == Formulation::Rkpm && coefficient && nodal.scheme != "dni" && rk.order == defaults.order &&
           rk.kernel == defaults.kernel && rk.support == defaults.support &&
           (rk.normalized_support == defaults.normalized_support ||
            (jittered_cloud && rk.normalized_support == kCloudNormalizedSupport));
}
} // namespace rkfem
