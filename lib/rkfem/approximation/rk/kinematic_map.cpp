#include "rkfem/approximation/rk/kinematic_map.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>

#include "rkfem/core/error.hpp"
#include "rkfem/core/offsets_hash.hpp"
#include "rkfem/core/parallel.hpp"

namespace rkfem
{
void KinematicMap::reset(index_t n_nodes)
{
    coefficient_.assign(static_cast<std::size_t>(n_nodes), 0);
    row_.assign(static_cast<std::size_t>(n_nodes), -1);
    base_.assign(static_cast<std::size_t>(n_nodes), 0);
    row_offsets_.assign(1, 0);
    row_columns_.clear();
    row_values_.clear();
    n_row_entries_ = 0;
    n_coefficient_nodes_ = 0;
}

void KinematicMap::set_rows(index_t begin, index_t end, const std::vector<index_t>& offsets,
                            const std::vector<index_t>& columns, const std::vector<real_t>& values,
                            const std::vector<char>* coefficient)
{
    RKFEM_REQUIRE(begin >= 0 && end <= size() && begin <= end,
                  "kinematic map: rows [" << begin << ", " << end << ") outside " << size() << " nodes");
    RKFEM_REQUIRE(static_cast<index_t>(offsets.size()) == end - begin + 1,
                  "kinematic map: " << offsets.size() << " row offsets for " << end - begin << " rows");
    // every node's row (the new ones for [begin, end) read in place, the others as stored,
    // written out with their columns into a scratch row), in node order: the rows are not copied
    // whole (at P6's target as rkpm that copy was a noticeable share of the set-up, most of it
    // fresh pages; measurements: docs/performance.md)
    const index_t n = size();
    std::vector<index_t> scratch_columns;
    std::vector<real_t> scratch_values;
    // node i's row: whether it carries coefficients, and then its columns, values and count
    auto row_of = [&](index_t i, const index_t*& c, const real_t*& v, index_t& m)
    {
        if (i >= begin && i < end)
        {
            const index_t r = i - begin;
            const index_t k0 = offsets[r], k1 = offsets[r + 1];
            const bool identity_row = k1 - k0 == 1 && columns[k0] == i && values[k0] == 1.0;
            coefficient_[i] = coefficient != nullptr ? (*coefficient)[r] != 0 : !identity_row;
            c = columns.data() + k0;
            v = values.data() + k0;
            m = k1 - k0;
            return static_cast<bool>(coefficient_[i]);
        }
        if (!coefficient_[i])
            return false;
        scratch_columns.clear();
        scratch_values.clear();
        for_row(i,
                [&](index_t j, real_t w)
                {
                    scratch_columns.push_back(j);
                    scratch_values.push_back(w);
                });
        c = scratch_columns.data();
        v = scratch_values.data();
        m = static_cast<index_t>(scratch_columns.size());
        return true;
    };
    // shared rows: the same column offsets, values within the tolerance of the stored row's
    // largest; the first of each kind in node order is stored, the others read it
    constexpr real_t tolerance = 1e-11;
    constexpr int max_candidates = 16;
    std::vector<index_t> new_offsets{0}, new_columns;
    std::vector<real_t> new_values, scale;
    std::unordered_map<std::uint64_t, std::vector<index_t>> by_offsets;
    n_coefficient_nodes_ = 0;
    std::size_t row_entries = 0;
    for (index_t i = 0; i < n; ++i)
    {
        const index_t* c = nullptr;
        const real_t* v = nullptr;
        index_t m = 0;
        const bool carries = row_of(i, c, v, m); // (reads a stored row before it is replaced)
        row_[i] = -1;
        base_[i] = 0;
        if (!carries)
            continue;
        ++n_coefficient_nodes_;
        row_entries += static_cast<std::size_t>(m);
        base_[i] = m > 0 ? c[0] : 0;
        std::vector<index_t>& candidates = by_offsets[offsets_hash(c, m)];
        auto matches = [&](index_t s)
        {
            const index_t j0 = new_offsets[static_cast<std::size_t>(s)];
            if (new_offsets[static_cast<std::size_t>(s) + 1] - j0 != m)
                return false;
            for (index_t k = 0; k < m; ++k)
                if (new_columns[static_cast<std::size_t>(j0 + k)] != c[k] - c[0])
                    return false;
            const real_t bound = tolerance * scale[static_cast<std::size_t>(s)];
            for (index_t k = 0; k < m; ++k)
                if (!(std::abs(new_values[static_cast<std::size_t>(j0 + k)] - v[k]) <= bound))
                    return false;
            return true;
        };
        index_t found = -1;
        const int searched = std::min<int>(static_cast<int>(candidates.size()), max_candidates);
        for (int q = 0; q < searched && found < 0; ++q)
            if (matches(candidates[static_cast<std::size_t>(q)]))
                found = candidates[static_cast<std::size_t>(q)];
        if (found < 0)
        {
            found = static_cast<index_t>(new_offsets.size()) - 1;
            real_t largest = 0.0;
            for (index_t k = 0; k < m; ++k)
            {
                new_columns.push_back(c[k] - c[0]);
                new_values.push_back(v[k]);
                largest = std::max(largest, std::abs(v[k]));
            }
            new_offsets.push_back(static_cast<index_t>(new_columns.size()));
            scale.push_back(largest);
            candidates.push_back(found);
        }
        row_[i] = found;
    }
    n_row_entries_ = row_entries;
    row_offsets_ = std::move(new_offsets);
    row_columns_ = std::move(new_columns);
    row_values_ = std::move(new_values);
    row_columns_.shrink_to_fit();
    row_values_.shrink_to_fit();
}

Vec3 KinematicMap::physical(const real_t* field, index_t node) const
{
    Vec3 s = Vec3::Zero();
    for_row(node, [&](index_t j, real_t w) { s += w * Vec3(field[3 * j], field[3 * j + 1], field[3 * j + 2]); });
    return s;
}

void KinematicMap::physical_field(const std::vector<real_t>& field, std::vector<real_t>& out) const
{
    if (identity())
    {
        out = field; // no node carries coefficients
        return;
    }
    out.resize(field.size());
    parallel_for("rkfem::kinematic_map", size(),
                 [&](index_t i)
                 {
                     const Vec3 s = physical(field.data(), i);
                     for (int a = 0; a < 3; ++a)
                         out[3 * static_cast<std::size_t>(i) + a] = s[a];
                 });
}

Vec3 KinematicMap::position(const std::vector<real_t>& x0, const std::vector<real_t>& u, index_t node) const
{
    return Vec3(x0[3 * node], x0[3 * node + 1], x0[3 * node + 2]) + physical(u.data(), node);
}

void KinematicMap::spread(index_t node, const Vec3& f, real_t* force) const
{
    for_row(node,
            [&](index_t j, real_t w)
            {
                for (int a = 0; a < 3; ++a)
                    force[3 * static_cast<std::size_t>(j) + a] += w * f[a];
            });
}
} // namespace rkfem
