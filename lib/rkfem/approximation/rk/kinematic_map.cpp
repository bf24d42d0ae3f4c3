#include "rkfem/approximation/rk/kinematic_map.hpp"

#include <algorithm>

#include "rkfem/core/error.hpp"
#include "rkfem/core/parallel.hpp"

namespace rkfem
{
void KinematicMap::reset(index_t n_nodes)
{
    coefficient_.assign(static_cast<std::size_t>(n_nodes), 0);
    offsets_.assign(static_cast<std::size_t>(n_nodes) + 1, 0);
    columns_.clear();
    values_.clear();
    n_coefficient_nodes_ = 0;
}

void KinematicMap::set_rows(index_t begin, index_t end, const std::vector<index_t>& offsets,
                            const std::vector<index_t>& columns, const std::vector<real_t>& values,
                            const std::vector<char>* coefficient)
{
    RKFEM_REQUIRE(begin >= 0 && end <= size() && begin <= end, "kinematic map: rows [" << begin << ", " << end
                                                                                        << ") outside " << size()
                                                                                        << " nodes");
    RKFEM_REQUIRE(static_cast<index_t>(offsets.size()) == end - begin + 1, "kinematic map: " << offsets.size()
                                                                                              << " row offsets for "
                                                                                              << end - begin << " rows");
    // rebuild the CSR with the new rows in place of the old ones for [begin, end)
    std::vector<index_t> new_offsets(offsets_.size(), 0);
    std::vector<index_t> new_columns;
    std::vector<real_t> new_values;
    new_columns.reserve(columns_.size() + columns.size());
    new_values.reserve(values_.size() + values.size());
    const index_t n = size();
    n_coefficient_nodes_ = 0;
    for (index_t i = 0; i < n; ++i)
    {
        if (i >= begin && i < end)
        {
            const index_t r = i - begin;
            const index_t k0 = offsets[r], k1 = offsets[r + 1];
            const bool identity_row = k1 - k0 == 1 && columns[k0] == i && values[k0] == 1.0;
            const bool coef = coefficient != nullptr ? (*coefficient)[r] != 0 : !identity_row;
            coefficient_[i] = coef;
            if (coef)
                for (index_t k = k0; k < k1; ++k)
                {
                    new_columns.push_back(columns[k]);
                    new_values.push_back(values[k]);
                }
        }
        else if (coefficient_[i])
            for (index_t k = offsets_[i]; k < offsets_[i + 1]; ++k)
            {
                new_columns.push_back(columns_[k]);
                new_values.push_back(values_[k]);
            }
        n_coefficient_nodes_ += coefficient_[i];
        new_offsets[i + 1] = static_cast<index_t>(new_columns.size());
    }
    offsets_ = std::move(new_offsets);
    columns_ = std::move(new_columns);
    values_ = std::move(new_values);
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
