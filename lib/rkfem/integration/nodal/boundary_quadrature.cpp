/// @file boundary_quadrature.cpp
/// The boundary quadrature of a hex mesh: points on its boundary faces with their area normals.
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

std::vector<BoundaryPoint> boundary_quadrature(const HexMesh& mesh)
{
    const std::vector<index_t> nb = face_neighbours(mesh);
    std::vector<BoundaryPoint> out;
    SubHex sh;
    real_t xe[8][3];
    for (index_t e = 0; e < mesh.n_elements(); ++e)
    {
        bool any = false;
        for (int f = 0; f < 6; ++f)
            any = any || nb[6 * e + f] < 0;
        if (!any)
            continue;
        element_coordinates(mesh, e, xe);
        for (int a = 0; a < 8; ++a)
        {
            build_sub_hex(xe, a, sh);
            for (int f = 1; f < 6; f += 2) // external facets
                if (nb[6 * e + sh.element_face[f]] < 0)
                    for (const FacetPoint& fp : sh.facets[f])
                        out.push_back({e, mesh.conn[8 * e + a], fp});
        }
    }
    return out;
}
} // namespace rkfem
