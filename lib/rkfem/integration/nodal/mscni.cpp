/// @file mscni.cpp
/// Modified stabilized conforming nodal integration (MSCNI): each SCNI cell's sub-cells, as
/// operators of their own, from SCNI and its sub-cell (SD-SCNI) operator.
#include "rkfem/integration/nodal/nodal_common.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <exception>
#include <limits>
#include <utility>

#include <omp.h>

#include "rkfem/approximation/rk/rk_region_values.hpp"
#include "rkfem/approximation/rk/rk_translates.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/core/mark_set.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/setup_progress.hpp"
#include "rkfem/integration/stencil_table.hpp"

namespace rkfem
{
using namespace nodal_detail;

IntegrationOperator build_mscni_stabilization(const IntegrationOperator& scni, const IntegrationOperator& sd)
{
    IntegrationOperator op;
    op.weight = sd.weight;
    op.position = sd.position;
    op.owner = sd.owner;
    op.parent = sd.owner; // SCNI point index = node index
    for (index_t s = 0; s < sd.n_points(); ++s)
    {
        const index_t L = sd.owner[s];
        Entries e;
        for (index_t k = sd.offsets[s]; k < sd.offsets[s + 1]; ++k)
            e.emplace_back(sd.nodes[k], sd.gradient(k));
        for (index_t k = scni.offsets[L]; k < scni.offsets[L + 1]; ++k)
            e.emplace_back(scni.nodes[k], -scni.gradient(k));
        merge(e, 1.0);
        for (const auto& [n, g] : e)
        {
            op.nodes.push_back(n);
            op.grad.insert(op.grad.end(), {g[0], g[1], g[2]});
        }
        op.offsets.push_back(op.n_entries());
    }
    return op;
}
} // namespace rkfem
