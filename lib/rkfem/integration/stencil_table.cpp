#include "rkfem/integration/stencil_table.hpp"

#include "rkfem/core/error.hpp"
#include "rkfem/core/offsets_hash.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <unordered_map>

namespace rkfem
{
namespace
{
/// Every |a[k] - b[k]| <= bound for k < n (written so that a NaN on either side differs).
bool within(const real_t* a, const real_t* b, index_t n, real_t bound)
{
    for (index_t k = 0; k < n; ++k)
        if (!(std::abs(a[k] - b[k]) <= bound))
            return false;
    return true;
}

real_t largest_magnitude(const real_t* a, index_t n)
{
    real_t largest = 0.0;
    for (index_t k = 0; k < n; ++k)
        largest = std::max(largest, std::abs(a[k]));
    return largest;
}

/// The newest of the last opts.max_candidates stored classes that matches, or -1: the newest
/// are a lattice row's neighbours (share_stencils).
template <class Matches>
index_t newest_match(const std::vector<index_t>& candidates, const StencilSharing& opts, Matches&& matches)
{
    const int nc = static_cast<int>(candidates.size());
    for (int c = nc - 1; c >= std::max(0, nc - opts.max_candidates); --c)
        if (matches(candidates[static_cast<std::size_t>(c)]))
            return candidates[static_cast<std::size_t>(c)];
    return -1;
}
} // namespace

StencilSharer::StencilSharer(index_t n_points, std::size_t n_entries, const StencilSharing& opts)
    : opts_(opts), budget_(static_cast<std::size_t>(opts.max_entry_fraction * static_cast<real_t>(n_entries)))
{
    t_.point_stencil.resize(static_cast<std::size_t>(n_points));
    t_.point_base.resize(static_cast<std::size_t>(n_points));
    // room for the budget at once: memory reserved and never written costs no page, and the
    // stencils are never copied as the table grows
    t_.node_offset.reserve(budget_ + 1);
    t_.grad.reserve(3 * (budget_ + 1));
}

bool StencilSharer::add(const index_t* nodes, const real_t* g, index_t n)
{
    const std::size_t p = static_cast<std::size_t>(next_++);
    t_.point_base[p] = n > 0 ? nodes[0] : 0;
    std::vector<index_t>& candidates = by_offsets_[offsets_hash(nodes, n)];
    // does stencil s have this point's node offsets and, within the tolerance of its largest
    // gradient, its gradients? (written so that a NaN on either side differs)
    auto matches = [&](index_t s)
    {
        const index_t j0 = t_.offsets[static_cast<std::size_t>(s)];
        if (t_.offsets[static_cast<std::size_t>(s) + 1] - j0 != n)
            return false;
        const index_t* offset = t_.node_offset.data() + j0;
        for (index_t k = 1; k < n; ++k)
            if (offset[k] != nodes[k] - nodes[0])
                return false;
        return within(t_.grad.data() + 3 * static_cast<std::size_t>(j0), g, 3 * n,
                      opts_.relative_tolerance * scale_[static_cast<std::size_t>(s)]);
    };
    index_t found = newest_match(candidates, opts_, matches);
    if (found < 0)
    {
        stored_ += static_cast<std::size_t>(n);
        if (stored_ > budget_)
            return false; // sharing does not pay
        found = t_.n_stencils();
        scale_.push_back(largest_magnitude(g, 3 * n));
        candidates.push_back(found);
        for (index_t k = 0; k < n; ++k)
            t_.node_offset.push_back(nodes[k] - nodes[0]);
        t_.grad.insert(t_.grad.end(), g, g + 3 * n);
        t_.offsets.push_back(t_.n_entries());
    }
    t_.point_stencil[p] = found;
    return true;
}

StencilTable StencilSharer::take()
{
    RKFEM_REQUIRE(next_ == static_cast<index_t>(t_.point_stencil.size()) && stored_ <= budget_,
                  "StencilSharer: " << next_ << " of " << t_.point_stencil.size() << " points offered, " << stored_
                                    << " entries stored for a budget of " << budget_);
    // the table lives as long as its block: the budget's spare room is returned
    t_.node_offset.shrink_to_fit();
    t_.grad.shrink_to_fit();
    return std::move(t_);
}

StencilTable share_stencils(IntegrationOperator& op, const StencilSharing& opts)
{
    const index_t np = op.n_points();
    if (np == 0)
        return {};
    StencilSharer sharer(np, static_cast<std::size_t>(op.n_entries()), opts);
    for (index_t p = 0; p < np; ++p)
    {
        const index_t k0 = op.offsets[static_cast<std::size_t>(p)];
        if (!sharer.add(op.nodes.data() + k0, op.grad.data() + 3 * static_cast<std::size_t>(k0),
                        op.offsets[static_cast<std::size_t>(p) + 1] - k0))
            return {}; // sharing does not pay: the operator stays as it was
    }
    StencilTable t = sharer.take();
    // snap: every point takes its stencil's gradients
    for (index_t p = 0; p < np; ++p)
    {
        const StencilView s = t.view(p);
        std::copy(s.grad, s.grad + 3 * s.size, op.grad.begin() + 3 * static_cast<std::ptrdiff_t>(op.offsets[p]));
    }
    return t;
}

TripletTable build_triplets(const IntegrationOperator& stab, const StencilTable& shared)
{
    TripletTable t;
    const index_t ns = stab.n_points();
    if (ns == 0 || ns % 3 != 0)
        return t;
    const index_t np = ns / 3;
    // Row i of entry k's matrix is sub-point i's gradient. The operator's are symmetric bit for
    // bit (RkShapeFunctions::hessians); shared stencils snapped each sub-point to its own class,
    // which moves the lower triangle by up to the sharing's tolerance. The table keeps the upper
    // triangle (the values the force pass reads); more asymmetry than that: no table.
    auto symmetric = [](const real_t* g0, const real_t* g1, const real_t* g2, real_t tol)
    { return std::abs(g0[1] - g1[0]) <= tol && std::abs(g0[2] - g2[0]) <= tol && std::abs(g1[2] - g2[1]) <= tol; };
    auto add_triplet = [&](const StencilView(&v)[3], real_t relative) -> bool
    {
        real_t scale = 0.0;
        for (int i = 0; i < 3; ++i)
            for (index_t k = 0; k < 3 * v[i].size; ++k)
                scale = std::max(scale, std::abs(v[i].grad[k]));
        for (index_t k = 0; k < v[0].size; ++k)
        {
            const real_t *g0 = v[0].grad + 3 * k, *g1 = v[1].grad + 3 * k, *g2 = v[2].grad + 3 * k;
            if (v[1].size != v[0].size || v[2].size != v[0].size || v[1].offset[k] != v[0].offset[k] ||
                v[2].offset[k] != v[0].offset[k] || !symmetric(g0, g1, g2, relative * scale))
                return false;
            t.node_offset.push_back(v[0].offset[k]);
            t.hess.insert(t.hess.end(), {g0[0], g0[1], g0[2], g1[1], g1[2], g2[2]});
        }
        t.offsets.push_back(t.n_entries());
        return true;
    };
    t.point_triplet.resize(static_cast<std::size_t>(np));
    t.point_base.resize(static_cast<std::size_t>(np));
    if (shared.empty())
    {
        t.node_offset.reserve(static_cast<std::size_t>(stab.n_entries() / 3));
        t.hess.reserve(2 * static_cast<std::size_t>(stab.n_entries()));
        for (index_t p = 0; p < np; ++p)
        {
            const StencilView v[3] = {stencil_view(stab, 3 * p), stencil_view(stab, 3 * p + 1),
                                      stencil_view(stab, 3 * p + 2)};
            if (!add_triplet(v, 0.0))
                return TripletTable{};
            t.point_triplet[static_cast<std::size_t>(p)] = p;
            t.point_base[static_cast<std::size_t>(p)] = 0;
        }
        return t;
    }
    // one triplet stencil per distinct triple of shared stencils
    const real_t relative = 10 * StencilSharing{}.relative_tolerance;
    std::unordered_map<std::uint64_t, std::vector<index_t>> by_triple; // hash -> triplet stencils
    std::vector<std::array<index_t, 3>> triple_of;                     // per triplet stencil
    for (index_t p = 0; p < np; ++p)
    {
        const std::size_t s0 = 3 * static_cast<std::size_t>(p);
        const std::array<index_t, 3> key = {shared.point_stencil[s0], shared.point_stencil[s0 + 1],
                                            shared.point_stencil[s0 + 2]};
        const std::uint64_t h =
            (static_cast<std::uint64_t>(key[0]) * 1000003u + static_cast<std::uint64_t>(key[1])) * 1000003u +
            static_cast<std::uint64_t>(key[2]);
        index_t found = -1;
        for (const index_t c : by_triple[h])
            if (triple_of[static_cast<std::size_t>(c)] == key)
                found = c;
        if (found < 0)
        {
            found = static_cast<index_t>(triple_of.size());
            const StencilView v[3] = {shared.view(3 * p), shared.view(3 * p + 1), shared.view(3 * p + 2)};
            if (!add_triplet(v, relative))
                return TripletTable{};
            triple_of.push_back(key);
            by_triple[h].push_back(found);
        }
        t.point_triplet[static_cast<std::size_t>(p)] = found;
        t.point_base[static_cast<std::size_t>(p)] = shared.point_base[s0];
    }
    // the distinct triples were not known in advance: growth left up to half the capacity
    // unused (1 MB of 3.4 on the P1 cylinder at 0.5 in), and the table lives as long as the block
    t.offsets.shrink_to_fit();
    t.node_offset.shrink_to_fit();
    t.hess.shrink_to_fit();
    return t;
}

TripletTable share_triplets(TripletTable t, const StencilSharing& opts)
{
    // in place: the kept stencils move down over the merged ones (a kept stencil's new place is
    // never past its old one, and each is compared before it moves)
    const index_t nt = t.n_triplets();
    std::vector<index_t> kept(static_cast<std::size_t>(nt));            // per stencil: the stencil it becomes
    std::vector<index_t> offsets{0};                                    // of the kept stencils
    std::unordered_map<std::uint64_t, std::vector<index_t>> by_offsets; // hash -> kept stencils
    std::vector<real_t> scale;                                          // per kept stencil: its largest value
    for (index_t c = 0; c < nt; ++c)
    {
        const index_t k0 = t.offsets[static_cast<std::size_t>(c)];
        const index_t n = t.offsets[static_cast<std::size_t>(c) + 1] - k0;
        const index_t* offset = t.node_offset.data() + k0;
        const real_t* h = t.hess.data() + 6 * static_cast<std::size_t>(k0);
        std::vector<index_t>& candidates = by_offsets[offsets_hash(offset, n)];
        auto matches = [&](index_t s)
        {
            const index_t j0 = offsets[static_cast<std::size_t>(s)];
            return offsets[static_cast<std::size_t>(s) + 1] - j0 == n &&
                   std::equal(offset, offset + n, t.node_offset.data() + j0) &&
                   within(t.hess.data() + 6 * static_cast<std::size_t>(j0), h, 6 * n,
                          opts.relative_tolerance * scale[static_cast<std::size_t>(s)]);
        };
        index_t found = newest_match(candidates, opts, matches);
        if (found < 0)
        {
            found = static_cast<index_t>(offsets.size()) - 1;
            scale.push_back(largest_magnitude(h, 6 * n));
            const index_t w = offsets.back();
            std::copy(offset, offset + n, t.node_offset.begin() + w);
            std::copy(h, h + 6 * n, t.hess.begin() + 6 * static_cast<std::ptrdiff_t>(w));
            offsets.push_back(w + n);
            candidates.push_back(found);
        }
        kept[static_cast<std::size_t>(c)] = found;
    }
    for (index_t& c : t.point_triplet)
        c = kept[static_cast<std::size_t>(c)];
    t.offsets = std::move(offsets);
    t.node_offset.resize(static_cast<std::size_t>(t.offsets.back()));
    t.hess.resize(6 * t.node_offset.size());
    return_spare_room(t.node_offset, t.hess); // (build_nsni_triplets reserves about the margin)
    return t;
}

void expand_triplets(IntegrationOperator& stab, const TripletTable& table)
{
    const index_t ns = stab.n_points();
    stab.nodes.resize(static_cast<std::size_t>(stab.offsets[static_cast<std::size_t>(ns)]));
    stab.grad.resize(3 * stab.nodes.size());
    constexpr int row[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};
    for (index_t s = 0; s < ns; ++s)
    {
        const TripletView v = table.view(s / 3);
        const int i = static_cast<int>(s % 3);
        const index_t k0 = stab.offsets[static_cast<std::size_t>(s)];
        RKFEM_REQUIRE(stab.offsets[static_cast<std::size_t>(s) + 1] - k0 == v.size,
                      "expand_triplets: sub-point " << s << " has "
                                                    << stab.offsets[static_cast<std::size_t>(s) + 1] - k0
                                                    << " entries, its triplet " << v.size);
        for (index_t k = 0; k < v.size; ++k)
        {
            stab.nodes[static_cast<std::size_t>(k0 + k)] = v.base + v.offset[k];
            for (int d = 0; d < 3; ++d)
                stab.grad[3 * static_cast<std::size_t>(k0 + k) + d] =
                    v.hess[6 * static_cast<std::size_t>(k) + row[i][d]];
        }
    }
}

std::vector<char> uniform_batches(const std::vector<index_t>& point_class, const std::vector<index_t>& point_base,
                                  index_t lanes)
{
    const std::size_t w = static_cast<std::size_t>(lanes);
    std::vector<char> uniform(point_class.size() / w, 0);
    for (std::size_t b = 0; b < uniform.size(); ++b)
    {
        const std::size_t p0 = w * b;
        bool same = true;
        for (std::size_t l = 1; l < w && same; ++l)
            same = point_class[p0 + l] == point_class[p0] &&
                   point_base[p0 + l] == point_base[p0] + static_cast<index_t>(l);
        uniform[b] = same;
    }
    return uniform;
}

std::vector<char> uniform_batch_stencils(const std::vector<char>& uniform, const std::vector<index_t>& point_class,
                                         index_t n_stencils, index_t lanes)
{
    std::vector<char> used(static_cast<std::size_t>(n_stencils), 0);
    for (std::size_t b = 0; b < uniform.size(); ++b)
        if (uniform[b])
            used[static_cast<std::size_t>(point_class[static_cast<std::size_t>(lanes) * b])] = 1;
    return used;
}

AddOrder uniform_add_order(const std::vector<index_t>& offsets, const std::vector<index_t>& node_offset, index_t lanes,
                           const std::vector<char>& wanted)
{
    AddOrder ao;
    const std::size_t n_stencils = offsets.empty() ? 0 : offsets.size() - 1;
    ao.start.assign(n_stencils, -1);
    std::size_t room = 0;
    auto ordered = [&](std::size_t s)
    { return (wanted.empty() || wanted[s]) && offsets[s + 1] - offsets[s] <= index_t{65535}; };
    for (std::size_t s = 0; s < n_stencils; ++s)
        if (ordered(s))
            room += static_cast<std::size_t>(offsets[s + 1] - offsets[s]);
    ao.order.reserve(room);
    std::vector<index_t> waits; // per entry: later entries with an overlapping window not yet added
    std::vector<char> done;
    for (std::size_t s = 0; s < n_stencils; ++s)
    {
        if (!ordered(s))
            continue;
        const index_t k0 = offsets[s], n = offsets[s + 1] - k0;
        ao.start[s] = static_cast<index_t>(ao.order.size());
        const index_t* o = node_offset.data() + k0;
        auto overlap = [&](index_t a, index_t b) { return std::abs(o[a] - o[b]) < lanes; };
        waits.assign(static_cast<std::size_t>(n), 0);
        done.assign(static_cast<std::size_t>(n), 0);
        for (index_t k = 0; k < n; ++k)
            for (index_t j = k + 1; j < n; ++j)
                waits[static_cast<std::size_t>(k)] += overlap(j, k);
        index_t last[2] = {-1, -1};
        for (index_t step = 0; step < n; ++step)
        {
            // of the ready entries (waiting on none), the latest apart from the last two added,
            // else the latest apart from the last one, else the latest
            index_t pick[3] = {-1, -1, -1};
            for (index_t k = n - 1; k >= 0; --k)
            {
                if (done[static_cast<std::size_t>(k)] || waits[static_cast<std::size_t>(k)] > 0)
                    continue;
                const bool apart0 = last[0] < 0 || !overlap(k, last[0]);
                const bool apart1 = last[1] < 0 || !overlap(k, last[1]);
                const int rank = apart0 && apart1 ? 0 : apart0 ? 1 : 2;
                if (pick[rank] < 0)
                    pick[rank] = k;
            }
            const index_t k = pick[0] >= 0 ? pick[0] : pick[1] >= 0 ? pick[1] : pick[2];
            done[static_cast<std::size_t>(k)] = 1;
            for (index_t i = 0; i < k; ++i)
                waits[static_cast<std::size_t>(i)] -= overlap(k, i);
            ao.order.push_back(static_cast<std::uint16_t>(k));
            last[1] = last[0];
            last[0] = k;
        }
    }
    return ao;
}
} // namespace rkfem
