// The nodal force pass's batch kernel (nodal_fast.hpp) for blocks of material kind None, in a
// translation unit of its own: with the four kinds in one unit GCC inlined less into each (P3 as
// rkpm, J2, stepped 19 % slower than with a per-point branch on the kind).
#include "rkfem/operators/kernels/nodal_fast.hpp"

namespace rkfem::nodal_kernels
{
RKFEM_NODAL_POINTS_BATCHES(, None);
} // namespace rkfem::nodal_kernels
