#include "rkfem/approximation/shape_evaluator.hpp"

namespace rkfem
{
void FemShapes::gradients_at_node(index_t i, std::vector<index_t>&, std::vector<Vec3>&) const
{
    throw Error("direct nodal integration of trilinear FE functions is undefined: their gradient "
                "jumps at node " +
                std::to_string(i) + "; use scheme scni or sd-scni with fem-nodal");
}
} // namespace rkfem
