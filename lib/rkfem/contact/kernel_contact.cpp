#include "rkfem/contact/kernel_contact.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "rkfem/core/error.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/state_archive.hpp"
#include "rkfem/operators/semi_lagrangian_block.hpp"

namespace rkfem
{
KernelContact::KernelContact(std::vector<const SemiLagrangianForceBlock*> bodies, const KernelContactParameters& p)
    : p_(p)
{
    set_bodies(std::move(bodies));
}

void KernelContact::set_bodies(std::vector<const SemiLagrangianForceBlock*> bodies)
{
    RKFEM_REQUIRE(bodies.size() == 1 || bodies.size() == 2, "kernel contact: one body (self-contact) or two");
    bodies_ = std::move(bodies);
    node_.clear();
    body_.clear();
    for (std::size_t b = 0; b < bodies_.size(); ++b)
    {
        const NodalBlock& s = *bodies_[b]->nodal_points();
        for (index_t p = 0; p < s.n_points(); ++p)
        {
            node_.push_back(s.node_begin + p);
            body_.push_back(static_cast<int>(b));
        }
    }
    const std::size_t n = node_.size();
    x_.assign(3 * n, 0.0);
    v_.assign(3 * n, 0.0);
    m_.assign(n, 0.0);
    cell_.assign(12 * n, 0.0);
    size_.assign(n, 0.0);
    reach_.assign(n, 0.0);
    wsum_.assign(n, 0.0);
    normal_.assign(3 * n, 0.0);
    near_.assign(n, 0);
    separated_.assign(n, 0);
    dormant_.assign(n, 0);
    dp_.assign(3 * n, 0.0);
    built_ = false;
}

void KernelContact::gather(const PhysicalNodes& nodes, const ContactClock& clock, const ContactChannel& channel)
{
    const NodeSet& ns = nodes.nodes();
    const real_t dt = clock.dt;
    index_t k0 = 0;
    for (const SemiLagrangianForceBlock* b : bodies_)
    {
        const NodalBlock& s = *b->nodal_points();
        const index_t np = s.n_points();
        parallel_for("rkfem::kernel_contact::gather", np,
                     [&](index_t p)
                     {
                         const index_t k = k0 + p, i = node_[k];
                         const std::size_t k3 = 3 * static_cast<std::size_t>(k), i3 = 3 * static_cast<std::size_t>(i);
                         const real_t m = ns.mass[i];
                         m_[k] = m;
                         for (int d = 0; d < 3; ++d)
                         {
                             x_[k3 + d] = ns.x[i3 + d];
                             v_[k3 + d] =
                                 ns.v[i3 + d] + dt * (ns.f_ext[i3 + d] - ns.f_int[i3 + d] + channel.force(i3 + d)) / m;
                         }
                         real_t* c = &cell_[12 * static_cast<std::size_t>(k)];
                         separated_[k] = b->separated(p);
                         dormant_[k] = b->dormant(p);
                         real_t reach = 0.0;
                         if (s.jacobian[p] == 0.0) // an empty cell: separated (or dormant, in no pair)
                         {
                             // the cube of the particle's starting volume about it
                             const real_t half = 0.5 * std::cbrt(s.points.weight[p]);
                             std::fill(c, c + 12, 0.0);
                             c[3] = c[7] = c[11] = half;
                             size_[k] = 2.0 * half;
                             reach = std::sqrt(3.0) * half;
                         }
                         else
                         {
                             std::copy_n(&s.cells[12 * static_cast<std::size_t>(p)], 12, c);
                             size_[k] = std::cbrt(b->volume(p));
                             reach = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
                             for (int a = 1; a <= 3; ++a)
                                 reach += std::sqrt(c[3 * a] * c[3 * a] + c[3 * a + 1] * c[3 * a + 1] +
                                                    c[3 * a + 2] * c[3 * a + 2]);
                         }
                         reach_[k] = reach;
                     });
        k0 += np;
    }
}

void KernelContact::update_candidates()
{
    const index_t n = static_cast<index_t>(node_.size());
    const real_t reach = n > 0 ? *std::max_element(reach_.begin(), reach_.end()) : 0.0;
    const bool self = bodies_.size() == 1;
    // self-contact: the pairs with a separated particle, so the lists go stale when one separates
    const index_t n_separated =
        self ? static_cast<index_t>(std::count(separated_.begin(), separated_.end(), char{1})) : 0;
    // conversion: particles that stop being dormant join the pairs
    const index_t n_dormant = static_cast<index_t>(std::count(dormant_.begin(), dormant_.end(), char{1}));
    if (built_ && n_separated == separated_built_ && n_dormant == dormant_built_)
    {
        // two particles approach by at most twice the largest motion since the build, and the
        // cells' reaches grow by at most reach - reach_built_ each
        real_t moved2 = 0.0;
        for (index_t k = 0; k < n; ++k)
        {
            const std::size_t k3 = 3 * static_cast<std::size_t>(k);
            const real_t dx = x_[k3] - x_built_[k3], dy = x_[k3 + 1] - x_built_[k3 + 1],
                         dz = x_[k3 + 2] - x_built_[k3 + 2];
            moved2 = std::max(moved2, dx * dx + dy * dy + dz * dz);
        }
        if (2.0 * std::sqrt(moved2) + 2.0 * std::max(0.0, reach - reach_built_) <= skin_)
            return;
    }
    reach_built_ = reach;
    skin_ = reach; // a cell's reach of motion between searches
    const real_t cutoff = 2.0 * reach + p_.thickness + skin_;
    const CellList cells(x_, std::max(cutoff, 1e-300));
    build_neighbour_rows(
        cells, x_, n,
        [&](index_t i, index_t j)
        {
            if (j <= i || dormant_[i] || dormant_[j] ||
                (self ? !(separated_[i] || separated_[j]) : body_[i] == body_[j]))
                return false;
            const std::size_t i3 = 3 * static_cast<std::size_t>(i), j3 = 3 * static_cast<std::size_t>(j);
            const real_t dx = x_[j3] - x_[i3], dy = x_[j3 + 1] - x_[i3 + 1], dz = x_[j3 + 2] - x_[i3 + 2];
            return dx * dx + dy * dy + dz * dz <= cutoff * cutoff;
        },
        offsets_, ids_);
    std::fill(near_.begin(), near_.end(), 0);
    for (index_t k = 0; k < n; ++k)
        for (index_t e = offsets_[k]; e < offsets_[k + 1]; ++e)
            near_[k] = near_[ids_[e]] = 1;
    x_built_ = x_;
    separated_built_ = n_separated;
    dormant_built_ = n_dormant;
    built_ = true;
    ++rebuilds_;
}

void KernelContact::add_forces(const PhysicalNodes& nodes, const ContactClock& clock, ContactChannel& channel)
{
    resultant_ = Vec3::Zero();
    active_ = n_pairs_ = 0;
    dt_bound_ = kNoLimit;
    const index_t n = static_cast<index_t>(node_.size());
    if (n == 0)
        return;
    gather(nodes, clock, channel);
    update_candidates();
    w_.resize(ids_.size());
    // the bodies' outward normals at the particles that may meet
    std::fill(normal_.begin(), normal_.end(), 0.0);
    parallel_for("rkfem::kernel_contact::normals", n,
                 [&](index_t k)
                 {
                     if (!near_[k])
                         return;
                     const SemiLagrangianForceBlock& b = *bodies_[body_[k]];
                     const Vec3 nk = b.outward_normal(node_[k] - b.nodal_points()->node_begin, nodes.nodes().x);
                     for (int d = 0; d < 3; ++d)
                         normal_[3 * static_cast<std::size_t>(k) + d] = nk[d];
                 });
    // the pairs' overlaps (each row's own entries), and the step bound of the pairs that can meet
    dt_bound_ =
        parallel_reduce_min("rkfem::kernel_contact::pairs", n,
                            [&](index_t k)
                            {
                                const std::size_t k3 = 3 * static_cast<std::size_t>(k);
                                const Vec3 xk(x_[k3], x_[k3 + 1], x_[k3 + 2]);
                                const Vec3 vk(v_[k3], v_[k3 + 1], v_[k3 + 2]);
                                real_t bound = kNoLimit;
                                for (index_t e = offsets_[k]; e < offsets_[k + 1]; ++e)
                                {
                                    const index_t j = ids_[e];
                                    const std::size_t j3 = 3 * static_cast<std::size_t>(j);
                                    const Vec3 r = Vec3(x_[j3], x_[j3 + 1], x_[j3 + 2]) - xk;
                                    const real_t d = r.norm();
                                    w_[static_cast<std::size_t>(e)] = overlap(k, j);
                                    // a closing pair may not come from apart to deeper than half a
                                    // cell in one step
                                    const real_t apart = std::max(0.0, d - reach_[k] - reach_[j] - p_.thickness);
                                    const real_t closing =
                                        d > 0.0 ? (vk - Vec3(v_[j3], v_[j3 + 1], v_[j3 + 2])).dot(r) / d : 0.0;
                                    if (closing > 0.0)
                                        bound = std::min(bound, (apart + 0.5 * std::min(size_[k], size_[j])) / closing);
                                }
                                return bound;
                            });
    if (!(clock.dt > 0.0))
        return; // the start: no step to share velocities over
    std::fill(wsum_.begin(), wsum_.end(), 0.0);
    std::fill(dp_.begin(), dp_.end(), 0.0);
    // each particle's mass is shared over its pairs by weight
    for (index_t k = 0; k < n; ++k)
        for (index_t e = offsets_[k]; e < offsets_[k + 1]; ++e)
        {
            const real_t w = w_[static_cast<std::size_t>(e)];
            wsum_[k] += w;
            wsum_[ids_[e]] += w;
        }
    // the pairs in contact, in particle order: normal and reduced mass of their shares
    pk_.clear(), pj_.clear(), pn_.clear(), pmu_.clear(), pP_.clear();
    for (index_t k = 0; k < n; ++k)
        for (index_t e = offsets_[k]; e < offsets_[k + 1]; ++e)
        {
            const real_t w = w_[static_cast<std::size_t>(e)];
            if (!(w > 0.0))
                continue;
            const index_t j = ids_[e];
            const Vec3 nrm = pair_normal(k, j);
            const real_t mk = m_[k] * w / wsum_[k], mj = m_[j] * w / wsum_[j];
            pk_.push_back(k), pj_.push_back(j);
            pn_.insert(pn_.end(), {nrm[0], nrm[1], nrm[2]});
            pmu_.push_back(mk * mj / (mk + mj));
            pP_.push_back(0.0);
        }
    const std::size_t np = pk_.size();
    auto closing = [&](std::size_t q)
    {
        const std::size_t k3 = 3 * static_cast<std::size_t>(pk_[q]), j3 = 3 * static_cast<std::size_t>(pj_[q]);
        const real_t ik = 1.0 / m_[pk_[q]], ij = 1.0 / m_[pj_[q]];
        real_t vn = 0.0;
        for (int d = 0; d < 3; ++d)
            vn += (v_[k3 + d] + ik * dp_[k3 + d] - v_[j3 + d] - ij * dp_[j3 + d]) * pn_[3 * q + d];
        return vn;
    };
    // normal impulses: each pair in turn brings its shares to their common normal velocity from
    // the velocities the pairs before it left (Gauss-Seidel, in the fixed pair order), sweeps
    // repeated until the impulses settle; a pair's total stays compressive (projected: P >= 0,
    // a pair pulled apart lets go)
    iterations_ = 0;
    for (int it = 0; it < kMaxIterations && np > 0; ++it)
    {
        real_t change = 0.0, total = 0.0;
        for (std::size_t q = 0; q < np; ++q)
        {
            const real_t dP = std::max(0.0, pP_[q] + pmu_[q] * closing(q)) - pP_[q];
            pP_[q] += dP;
            change = std::max(change, std::abs(dP));
            total = std::max(total, pP_[q]);
            const std::size_t k3 = 3 * static_cast<std::size_t>(pk_[q]), j3 = 3 * static_cast<std::size_t>(pj_[q]);
            for (int d = 0; d < 3; ++d)
            {
                dp_[k3 + d] -= dP * pn_[3 * q + d];
                dp_[j3 + d] += dP * pn_[3 * q + d];
            }
        }
        ++iterations_;
        if (!(change > kTolerance * total))
            break;
    }
    // friction on the settled velocities: at most mu P, and at most what stops the sliding
    if (p_.friction.active())
    {
        ft_.assign(3 * np, 0.0);
        for (std::size_t q = 0; q < np; ++q)
        {
            if (!(pP_[q] > 0.0))
                continue;
            const std::size_t k3 = 3 * static_cast<std::size_t>(pk_[q]), j3 = 3 * static_cast<std::size_t>(pj_[q]);
            const real_t ik = 1.0 / m_[pk_[q]], ij = 1.0 / m_[pj_[q]];
            Vec3 rel, nrm(pn_[3 * q], pn_[3 * q + 1], pn_[3 * q + 2]);
            for (int d = 0; d < 3; ++d)
                rel[d] = v_[k3 + d] + ik * dp_[k3 + d] - v_[j3 + d] - ij * dp_[j3 + d];
            const Vec3 vt = rel - rel.dot(nrm) * nrm;
            const real_t slip = vt.norm();
            if (slip > 0.0)
            {
                const Vec3 t = (std::min(p_.friction.coefficient(slip) * pP_[q], pmu_[q] * slip) / slip) * vt;
                for (int d = 0; d < 3; ++d)
                    ft_[3 * q + d] = t[d];
            }
        }
        for (std::size_t q = 0; q < np; ++q)
        {
            const std::size_t k3 = 3 * static_cast<std::size_t>(pk_[q]), j3 = 3 * static_cast<std::size_t>(pj_[q]);
            for (int d = 0; d < 3; ++d)
            {
                dp_[k3 + d] -= ft_[3 * q + d];
                dp_[j3 + d] += ft_[3 * q + d];
            }
        }
    }
    for (std::size_t q = 0; q < np; ++q)
        n_pairs_ += pP_[q] > 0.0;
    const real_t inv_dt = 1.0 / clock.dt;
    for (index_t k = 0; k < n; ++k)
    {
        const std::size_t k3 = 3 * static_cast<std::size_t>(k);
        const Vec3 f = inv_dt * Vec3(dp_[k3], dp_[k3 + 1], dp_[k3 + 2]);
        if (f == Vec3::Zero())
            continue;
        channel.add(node_[k], f);
        if (body_[k] == 0)
            resultant_ += f;
        ++active_;
    }
}

Vec3 KernelContact::pair_normal(index_t k, index_t j) const
{
    const std::size_t k3 = 3 * static_cast<std::size_t>(k), j3 = 3 * static_cast<std::size_t>(j);
    const Vec3 nk(normal_[k3], normal_[k3 + 1], normal_[k3 + 2]), nj(normal_[j3], normal_[j3 + 1], normal_[j3 + 2]);
    // bodies facing each other (normals within 60 degrees of opposite): their normals
    if (-nk.dot(nj) > 0.5)
        return (nk - nj).normalized();
    // a fragment (no normal) against a body: the body's
    if (nk == Vec3::Zero() && nj != Vec3::Zero())
        return -nj;
    if (nj == Vec3::Zero() && nk != Vec3::Zero())
        return nk;
    // otherwise (edges, two fragments) the line between the cells' centres
    const real_t* ck = &cell_[12 * static_cast<std::size_t>(k)];
    const real_t* cj = &cell_[12 * static_cast<std::size_t>(j)];
    const Vec3 r(x_[j3] + cj[0] - x_[k3] - ck[0], x_[j3 + 1] + cj[1] - x_[k3 + 1] - ck[1],
                 x_[j3 + 2] + cj[2] - x_[k3 + 2] - ck[2]);
    const real_t d = r.norm();
    return d > 0.0 ? Vec3(r / d) : Vec3::Zero();
}

real_t KernelContact::overlap(index_t k, index_t j) const
{
    // separating axes: the faces' normals of both parallelepipeds and the pair's normal (the
    // edge-edge axes left out: a pair may count a little before its cells meet at an edge)
    const real_t* ck = &cell_[12 * static_cast<std::size_t>(k)];
    const real_t* cj = &cell_[12 * static_cast<std::size_t>(j)];
    const std::size_t k3 = 3 * static_cast<std::size_t>(k), j3 = 3 * static_cast<std::size_t>(j);
    const Vec3 r(x_[j3] + cj[0] - x_[k3] - ck[0], x_[j3 + 1] + cj[1] - x_[k3 + 1] - ck[1],
                 x_[j3 + 2] + cj[2] - x_[k3 + 2] - ck[2]);
    auto edge = [](const real_t* c, int a) { return Vec3(c[3 * a], c[3 * a + 1], c[3 * a + 2]); };
    auto radius = [&](const real_t* c, const Vec3& u)
    { return std::abs(edge(c, 1).dot(u)) + std::abs(edge(c, 2).dot(u)) + std::abs(edge(c, 3).dot(u)); };
    real_t w = 1.0;
    auto axis = [&](Vec3 u)
    {
        const real_t a = u.norm();
        if (!(a > 0.0))
            return true;
        u /= a;
        const real_t room = radius(ck, u) + radius(cj, u) + p_.thickness;
        const real_t depth = room - std::abs(r.dot(u));
        if (!(depth > 0.0))
            return false;
        w = std::min(w, depth / room);
        return true;
    };
    for (const real_t* c : {ck, cj})
        for (int a = 0; a < 3; ++a)
            if (!axis(edge(c, 1 + (a + 1) % 3).cross(edge(c, 1 + (a + 2) % 3))))
                return 0.0;
    return axis(pair_normal(k, j)) ? w : 0.0;
}

void KernelContact::save_state(StateArchive& a, const std::string& prefix) const
{
    a.put_value(prefix + "dt_bound", dt_bound_);
    a.put_value(prefix + "resultant", std::array<real_t, 3>{resultant_[0], resultant_[1], resultant_[2]});
    a.put_value(prefix + "active", active_);
    a.put_value(prefix + "pairs", n_pairs_);
}

void KernelContact::load_state(const StateArchive& a, const std::string& prefix)
{
    dt_bound_ = a.value<real_t>(prefix + "dt_bound");
    const auto r = a.value<std::array<real_t, 3>>(prefix + "resultant");
    resultant_ = Vec3(r[0], r[1], r[2]);
    active_ = a.value<index_t>(prefix + "active");
    n_pairs_ = a.value<index_t>(prefix + "pairs");
}
} // namespace rkfem
