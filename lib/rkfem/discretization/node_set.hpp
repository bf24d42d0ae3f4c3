#pragma once
/// @file node_set.hpp
/// All kinematic carriers (FE nodes now, RK particles later) as flat arrays.
/// Vector arrays are n_nodes x 3, node-major: component d of node i is at [3 i + d].
#include <vector>

#include "rkfem/core/huge_pages.hpp"
#include "rkfem/core/types.hpp"

namespace rkfem
{
struct NodeSet
{
    std::vector<real_t> x0;    ///< reference coordinates [m]
    std::vector<real_t> x;     ///< current coordinates x0 + u [m]
    std::vector<real_t> u;     ///< displacement [m]
    std::vector<real_t> v;     ///< velocity [m/s] (full step, or half step inside a step)
    std::vector<real_t> a;     ///< acceleration [m/s^2]
    std::vector<real_t> f_int; ///< internal force incl. hourglass and bulk viscosity [N]
    std::vector<real_t> f_ext; ///< external force [N]
    std::vector<real_t> mass;  ///< lumped mass [kg], n_nodes
    std::vector<index_t> part; ///< owning part, n_nodes

    index_t size() const { return static_cast<index_t>(mass.size()); }

    void resize(index_t n)
    {
        const std::size_t n3 = 3 * static_cast<std::size_t>(n);
        for (auto* arr : {&x0, &x, &u, &v, &a, &f_int, &f_ext})
        {
            arr->assign(n3, 0.0);
            use_huge_pages(*arr);
        }
        mass.assign(static_cast<std::size_t>(n), 0.0);
        part.assign(static_cast<std::size_t>(n), 0);
    }
};
} // namespace rkfem
