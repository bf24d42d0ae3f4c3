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
    // sub-cell s: its own row minus its parent's, each node's terms in that order (sub-cells in
    // parallel, each row summed as it comes)
    IntegrationOperator op = assemble(
        sd.n_points(),
        [&](index_t s, Entries& out, real_t& w, Vec3& pos, index_t& owner, std::vector<index_t>&, std::vector<real_t>&)
        {
            thread_local RowSum row;
            row.clear();
            const index_t L = sd.owner[s];
            for (index_t k = sd.offsets[s]; k < sd.offsets[s + 1]; ++k)
                row.add(sd.nodes[k], sd.gradient(k));
            for (index_t k = scni.offsets[L]; k < scni.offsets[L + 1]; ++k)
                row.add(scni.nodes[k], -scni.gradient(k));
            row.take(out, 1.0);
            w = sd.weight[s];
            pos = Vec3(sd.position[3 * s], sd.position[3 * s + 1], sd.position[3 * s + 2]);
            owner = L;
        },
        false);
    op.parent = sd.owner; // SCNI point index = node index
    return op;
}
} // namespace rkfem
