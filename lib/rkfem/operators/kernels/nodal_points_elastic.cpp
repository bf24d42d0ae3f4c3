// The nodal force pass's batch kernel (nodal_fast.hpp) for blocks of material kind None, in a
// translation unit of its own: with the four kinds in one unit GCC inlined less into each (P3 as
// rkpm, J2, stepped 19 % slower than with a per-point branch on the kind).
#include "rkfem/operators/kernels/nodal_fast.hpp"

namespace rkfem::nodal_kernels
{
template void nodal_points_batch<PlasticPoints::Kind::None, true>(NodalBlock&, const real_t*, const real_t*, index_t,
                                                                  real_t, real_t*, index_t);
template void nodal_points_batch<PlasticPoints::Kind::None, false>(NodalBlock&, const real_t*, const real_t*, index_t,
                                                                   real_t, real_t*, index_t);
} // namespace rkfem::nodal_kernels
