// GCC 12 reports a false "may be used uninitialized" inside Eigen's AVX-512 packet code for the
// fixed-size LDL^T below; every value is initialised.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"

#include "rkfem/approximation/rk/rk_shape.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <utility>

#include "rkfem/approximation/rk/rk_basis.hpp"
#include "rkfem/core/mark_set.hpp"
#include "rkfem/core/simd.hpp"

namespace rkfem
{
namespace
{
using rk_detail::basis;

/// Moment matrix, its LDL^T, and Psi (and direct gradients) for every sample entry. With
/// `others` (values only), the right-hand side is H(0) - sum_k w_k H(dy_k / s): the RK functions
/// complete other functions' reproduction (RkShapeFunctions::evaluate_completing).
template <int m, class OnSingular>
void solve_and_fill(RkSample& out, real_t s, bool gradients, OnSingular&& singular, const RkOthers* others = nullptr,
                    real_t pivot = 1e-12)
{
    using MatM = Eigen::Matrix<real_t, m, m>;
    using VecM = Eigen::Matrix<real_t, m, 1>;
    const index_t n = out.size();
    const real_t inv_s = 1.0 / s;

    MatM M = MatM::Zero();
    MatM dM[3];
    if (gradients)
        for (auto& d : dM)
            d.setZero();
    VecM H, dH[3];
    for (index_t k = 0; k < n; ++k)
    {
        basis<m>(out.dx[k] * inv_s, H, dH);
        const real_t phi = out.phi[k];
        M.noalias() += phi * H * H.transpose();
        if (gradients)
            for (int i = 0; i < 3; ++i)
            {
                const VecM Hi = dH[i] * inv_s;
                dM[i].noalias() += phi * (Hi * H.transpose() + H * Hi.transpose()) + out.dphi[k][i] * H * H.transpose();
            }
    }
    VecM H0 = VecM::Zero();
    H0[0] = 1.0;
    if (others != nullptr)
    {
        for (std::size_t k = 0; k < others->weight.size(); ++k)
        {
            basis<m>(others->dx[k] * inv_s, H, dH);
            H0.noalias() -= others->weight[k] * H;
        }
        // the other functions reproduce the basis here by themselves: every Psi is 0, whatever M
        if (H0.cwiseAbs().maxCoeff() < 1e-13)
        {
            out.psi.assign(static_cast<std::size_t>(n), 0.0);
            return;
        }
    }
    Eigen::LDLT<MatM> ldlt(M);
    const auto D = ldlt.vectorD();
    const real_t dmax = D.cwiseAbs().maxCoeff();
    if (ldlt.info() != Eigen::Success || !(D.minCoeff() > pivot * dmax))
    {
        singular("pivot ratio below 1e-12");
        return;
    }
    const VecM b = ldlt.solve(H0);
    VecM db[3];
    if (gradients)
        for (int i = 0; i < 3; ++i)
            db[i] = -ldlt.solve(dM[i] * b);

    out.psi.resize(static_cast<std::size_t>(n));
    if (gradients)
        out.grad.resize(static_cast<std::size_t>(n));
    for (index_t k = 0; k < n; ++k)
    {
        basis<m>(out.dx[k] * inv_s, H, dH);
        const real_t bH = b.dot(H);
        out.psi[k] = bH * out.phi[k];
        if (gradients)
            for (int i = 0; i < 3; ++i)
                out.grad[k][i] = out.phi[k] * (db[i].dot(H) + inv_s * b.dot(dH[i])) + out.dphi[k][i] * bH;
    }
}
} // namespace

RkShapeFunctions::RkShapeFunctions(std::vector<real_t> x, std::vector<real_t> radius, RkParams params)
    : x_(std::move(x)), a_(std::move(radius)), p_(params)
{
    RKFEM_REQUIRE(p_.order == 1 || p_.order == 2, "RK basis order must be 1 or 2, got " << p_.order);
    RKFEM_REQUIRE(x_.size() == 3 * a_.size(),
                  "RK shape functions: " << x_.size() / 3 << " positions but " << a_.size() << " support radii");
    a_max_ = 0.0;
    for (real_t a : a_)
    {
        RKFEM_REQUIRE(a > 0.0, "RK shape functions: support radius must be positive, got " << a);
        a_max_ = std::max(a_max_, a);
    }
    // box support reaches a * sqrt(3) along a diagonal but each axis only a: bins of side a_max
    // cover every axis-aligned offset below a_max
    cells_ = CellList(x_, a_.empty() ? 1.0 : a_max_);
    const std::vector<index_t>& ids = cells_.ids();
    const std::size_t n = ids.size();
    binned_.resize(4 * n);
    for (std::size_t q = 0; q < n; ++q)
    {
        const std::size_t j = static_cast<std::size_t>(ids[q]);
        for (int d = 0; d < 3; ++d)
            binned_[d * n + q] = x_[3 * j + static_cast<std::size_t>(d)];
        binned_[3 * n + q] = a_[j] * (1.0 + 1e-12);
    }
}

bool rk_solve_sample(RkSample& sample, real_t s, int order, bool gradients, real_t pivot)
{
    bool ok = sample.size() >= (order == 1 ? 4 : 10);
    auto singular = [&](const char*) { ok = false; };
    if (ok && order == 1)
        solve_and_fill<4>(sample, s, gradients, singular, nullptr, pivot);
    else if (ok)
        solve_and_fill<10>(sample, s, gradients, singular, nullptr, pivot);
    return ok;
}

void RkShapeFunctions::evaluate(const Vec3& x, bool gradients, RkSample& out) const
{
    evaluate_impl(x, gradients, out, nullptr);
}

void RkShapeFunctions::evaluate_completing(const Vec3& x, const RkOthers& others, RkSample& out) const
{
    evaluate_impl(x, false, out, &others);
}

void RkShapeFunctions::evaluate_impl(const Vec3& x, bool gradients, RkSample& out, const RkOthers* others) const
{
    out.clear();
    real_t s = kNoLimit;
    const bool box = p_.support == SupportShape::Box;
    cells_.for_each_candidate(x,
                              [&](index_t j)
                              {
                                  const Vec3 dx = x - position(j);
                                  // most candidates of the cell list lie outside the box: one
                                  // comparison per axis, with a margin that leaves to kernel_3d
                                  // every point it could find inside (the same samples, bit for bit)
                                  const real_t reach = a_[j] * (1.0 + 1e-12);
                                  if (box &&
                                      (std::abs(dx[0]) > reach || std::abs(dx[1]) > reach || std::abs(dx[2]) > reach))
                                      return;
                                  real_t phi = 0.0;
                                  Vec3 g;
                                  if (kernel_3d(p_.kernel, p_.support, dx, a_[j], phi, g) && phi > 0.0)
                                  {
                                      out.nodes.push_back(j);
                                      out.phi.push_back(phi);
                                      out.dphi.push_back(g);
                                      out.dx.push_back(dx);
                                      s = std::min(s, a_[j]);
                                  }
                              });
    const index_t n = out.size();
    const int m = p_.basis_size();
    auto singular = [&](const char* why) { throw_singular(x, n, why); };
    if (n < m && others == nullptr)
        singular("too few neighbours");
    if (m == 4)
        solve_and_fill<4>(out, s, gradients, singular, others);
    else
        solve_and_fill<10>(out, s, gradients, singular, others);
}

void RkShapeFunctions::throw_singular(const Vec3& x, index_t n, const char* why) const
{
    std::ostringstream os;
    os << "RK moment matrix is singular at x = (" << x[0] << ", " << x[1] << ", " << x[2] << ") m: " << n
       << " particle(s) cover the point (" << why << "); a basis of order " << p_.order << " needs at least "
       << p_.basis_size() << " covering particles not all in one " << (p_.order == 1 ? "plane" : "quadric")
       << "; increase rk.normalized_support or refine the particle cloud there";
    throw SingularMomentError(os.str());
}

namespace
{
/// The hits of a search (one set per thread, empty between calls), read back ascending.
MarkSet& search_hits(std::size_t n)
{
    thread_local MarkSet hits;
    hits.reserve(n);
    return hits;
}
} // namespace

void RkShapeFunctions::particles_near_box_plain(const Vec3& lo, const Vec3& hi, std::vector<index_t>& out) const
{
    MarkSet& hits = search_hits(a_.size());
    cells_.for_each_near_box(lo, hi,
                             [&](index_t j)
                             {
                                 // the margin of evaluate_impl's box test: every particle it could keep
                                 const real_t reach = a_[j] * (1.0 + 1e-12);
                                 bool in = true;
                                 for (int d = 0; d < 3; ++d)
                                 {
                                     const real_t xj = x_[3 * static_cast<std::size_t>(j) + d];
                                     in &= !(xj + reach < lo[d]) & !(xj - reach > hi[d]);
                                 }
                                 if (in)
                                     hits.insert(j);
                             });
    out.clear();
    hits.drain([&](index_t j) { out.push_back(j); });
}

void RkShapeFunctions::particles_near_box(const Vec3& lo, const Vec3& hi, std::vector<index_t>& out) const
{
    MarkSet& hits = search_hits(a_.size());
    const std::size_t n = a_.size();
    const real_t *bx = binned_.data(), *by = bx + n, *bz = by + n, *br = bz + n;
    const index_t* ids = cells_.ids().data();
#if defined(__AVX512F__) && defined(__AVX512VL__)
    // the hits' smallest and largest particle per lane, out of the loop's dependency chain
    simd::IdRange8 range;
    const double lo3[3] = {lo[0], lo[1], lo[2]}, hi3[3] = {hi[0], hi[1], hi[2]};
#endif
    cells_.for_each_run_near_box(lo, hi,
                                 [&](index_t q0, index_t q1)
                                 {
                                     index_t q = q0;
#if defined(__AVX512F__) && defined(__AVX512VL__)
                                     // !(x + r < lo) and !(x - r > hi) per axis, as the plain
                                     // test (unordered compares: a NaN is in, as there)
                                     for (; q + 8 <= q1; q += 8)
                                     {
                                         const auto in =
                                             simd::boxes_reach(simd::load(bx + q), simd::load(by + q),
                                                               simd::load(bz + q), simd::load(br + q), lo3, hi3);
                                         range.take(in, ids + q);
                                         for (unsigned bits = in; bits != 0; bits &= bits - 1)
                                             hits.set(ids[q + __builtin_ctz(bits)]);
                                     }
#endif
                                     for (; q < q1; ++q)
                                     {
                                         const real_t r = br[q];
                                         if (!(bx[q] + r < lo[0]) & !(bx[q] - r > hi[0]) & !(by[q] + r < lo[1]) &
                                             !(by[q] - r > hi[1]) & !(bz[q] + r < lo[2]) & !(bz[q] - r > hi[2]))
                                             hits.insert(ids[q]);
                                     }
                                 });
#if defined(__AVX512F__) && defined(__AVX512VL__)
    index_t first, last;
    range.bounds(first, last);
    hits.cover(first, last);
#endif
    out.clear();
    hits.drain([&](index_t j) { out.push_back(j); });
}

void RkShapeFunctions::hessians(const Vec3& x, std::vector<index_t>& nodes, std::vector<Mat3>& H) const
{
    thread_local RkSample at, plus, minus;
    evaluate(x, false, at);
    real_t a = std::numeric_limits<real_t>::max();
    for (index_t n : at.nodes)
        a = std::min(a, radius(n));
    const real_t delta = 1e-3 * a;
    // column j of H_I is (grad Psi_I(x + delta e_j) - grad Psi_I(x - delta e_j)) / (2 delta);
    // the nodes are the union over the six samples, in ascending order
    std::vector<std::pair<index_t, Mat3>> rows;
    for (int j = 0; j < 3; ++j)
    {
        Vec3 d = Vec3::Zero();
        d[j] = delta;
        evaluate(x + d, true, plus);
        evaluate(x - d, true, minus);
        for (int side = 0; side < 2; ++side)
        {
            const RkSample& s = side == 0 ? plus : minus;
            const real_t sign = side == 0 ? 1.0 : -1.0;
            for (index_t k = 0; k < s.size(); ++k)
            {
                Mat3 m = Mat3::Zero();
                m.col(j) = sign / (2.0 * delta) * s.grad[k];
                rows.emplace_back(s.nodes[k], m);
            }
        }
    }
    std::stable_sort(rows.begin(), rows.end(), [](const auto& p, const auto& q) { return p.first < q.first; });
    nodes.clear();
    H.clear();
    for (const auto& [n, m] : rows)
    {
        if (!nodes.empty() && nodes.back() == n)
            H.back() += m;
        else
        {
            nodes.push_back(n);
            H.push_back(m);
        }
    }
    // the exact Hessian is symmetric; the differences are to O(delta^2)
    for (Mat3& m : H)
        m = 0.5 * (m + m.transpose()).eval();
}

namespace
{
/// The drop both prune_rk_* share: keeps the entries whose magnitude is at least tau times the
/// largest (nodes and values compacted in place) and, when any went, gives for the kept ones
/// their magnitudes w_k, the linear basis B_k = (1, (x_k - x) / s) (s: the farthest kept offset
/// along an axis) and M = sum_k w_k B_k B_k^T, which the callers' corrections solve with.
/// Returns false when nothing was dropped.
template <class T, class Magnitude>
bool drop_small(const RkShapeFunctions& rk, const Vec3& x, real_t tau, std::vector<index_t>& nodes,
                std::vector<T>& values, Magnitude magnitude, std::vector<real_t>& weight,
                std::vector<Eigen::Vector4d>& B, Eigen::Matrix4d& M)
{
    real_t big = 0.0;
    for (const T& v : values)
        big = std::max(big, magnitude(v));
    std::size_t w = 0;
    real_t s = 0.0;
    for (std::size_t k = 0; k < values.size(); ++k)
        if (magnitude(values[k]) >= tau * big)
        {
            s = std::max(s, (rk.position(nodes[k]) - x).cwiseAbs().maxCoeff());
            nodes[w] = nodes[k];
            values[w++] = values[k];
        }
    if (w == values.size())
        return false;
    nodes.resize(w);
    values.resize(w);
    weight.resize(w);
    B.resize(w);
    M.setZero();
    for (std::size_t k = 0; k < w; ++k)
    {
        const Vec3 d = (rk.position(nodes[k]) - x) / s;
        B[k] = Eigen::Vector4d(1.0, d[0], d[1], d[2]);
        weight[k] = magnitude(values[k]);
        M += weight[k] * B[k] * B[k].transpose();
    }
    return true;
}
} // namespace

void prune_rk_values(const RkShapeFunctions& rk, const Vec3& x, real_t tau, std::vector<index_t>& nodes,
                     std::vector<real_t>& psi)
{
    std::vector<real_t> weight;
    std::vector<Eigen::Vector4d> H;
    Eigen::Matrix4d M;
    if (!drop_small(
            rk, x, tau, nodes, psi, [](real_t v) { return std::abs(v); }, weight, H, M))
        return;
    // residual of the reproducing conditions, then the weighted correction
    Eigen::Vector4d r(1.0, 0.0, 0.0, 0.0);
    for (std::size_t k = 0; k < psi.size(); ++k)
        r -= psi[k] * H[k];
    const Eigen::Vector4d c = M.ldlt().solve(r);
    RKFEM_REQUIRE(c.allFinite(),
                  "RK drop tolerance: the functions left at (" << x.transpose() << ") do not span a linear field");
    for (std::size_t k = 0; k < psi.size(); ++k)
        psi[k] += weight[k] * H[k].dot(c);
}

void prune_rk_hessians(const RkShapeFunctions& rk, const Vec3& x, real_t tau, std::vector<index_t>& nodes,
                       std::vector<Mat3>& H)
{
    std::vector<real_t> weight;
    std::vector<Eigen::Vector4d> B;
    Eigen::Matrix4d M;
    if (!drop_small(
            rk, x, tau, nodes, H, [](const Mat3& m) { return m.cwiseAbs().maxCoeff(); }, weight, B, M))
        return;
    // residuals of sum H = 0 and sum H (x_k - x) = 0, per component, and the weighted correction
    Mat3 r[4] = {Mat3::Zero(), Mat3::Zero(), Mat3::Zero(), Mat3::Zero()};
    for (std::size_t k = 0; k < H.size(); ++k)
        for (int a = 0; a < 4; ++a)
            r[a] -= B[k][a] * H[k];
    const Eigen::Matrix4d Mi = M.inverse();
    RKFEM_REQUIRE(Mi.allFinite(), "RK drop tolerance: the second derivatives left at ("
                                      << x.transpose() << ") do not span a linear field");
    Mat3 c[4];
    for (int a = 0; a < 4; ++a)
        c[a] = Mi(a, 0) * r[0] + Mi(a, 1) * r[1] + Mi(a, 2) * r[2] + Mi(a, 3) * r[3];
    for (std::size_t k = 0; k < H.size(); ++k)
        H[k] += weight[k] * (B[k][0] * c[0] + B[k][1] * c[1] + B[k][2] * c[2] + B[k][3] * c[3]);
    for (Mat3& m : H)
        m = 0.5 * (m + m.transpose()).eval(); // exactly symmetric again
}

RkShapeFunctions rk_on_mesh(const HexMesh& mesh, const RkParams& params)
{
    std::vector<real_t> a = nodal_spacing(mesh);
    for (auto& v : a)
        v *= params.normalized_support;
    return RkShapeFunctions(mesh.x, std::move(a), params);
}

std::vector<real_t> nodal_spacing(const HexMesh& mesh, bool longest)
{
    static constexpr int edges[12][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6},
                                         {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
    std::vector<real_t> h(static_cast<std::size_t>(mesh.n_nodes()), longest ? 0.0 : kNoLimit);
    for (index_t e = 0; e < mesh.n_elements(); ++e)
        for (const auto& ed : edges)
        {
            const index_t i = mesh.conn[8 * e + ed[0]], j = mesh.conn[8 * e + ed[1]];
            if (i == j)
                continue; // a degenerate solid's collapsed edge is no edge
            const real_t len = (mesh.node(i) - mesh.node(j)).norm();
            h[i] = longest ? std::max(h[i], len) : std::min(h[i], len);
            h[j] = longest ? std::max(h[j], len) : std::min(h[j], len);
        }
    return h;
}
} // namespace rkfem
