#include "rkfem/integration/integration_operator.hpp"

namespace rkfem
{
void IntegrationOperator::append(const IntegrationOperator& o)
{
    const index_t p0 = n_points(), k0 = n_entries();
    weight.insert(weight.end(), o.weight.begin(), o.weight.end());
    position.insert(position.end(), o.position.begin(), o.position.end());
    owner.insert(owner.end(), o.owner.begin(), o.owner.end());
    for (index_t q : o.parent)
        parent.push_back(q + p0);
    for (std::size_t p = 1; p < o.offsets.size(); ++p)
        offsets.push_back(o.offsets[p] + k0);
    nodes.insert(nodes.end(), o.nodes.begin(), o.nodes.end());
    grad.insert(grad.end(), o.grad.begin(), o.grad.end());
}
} // namespace rkfem
