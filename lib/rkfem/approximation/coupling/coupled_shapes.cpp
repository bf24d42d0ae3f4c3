#include "rkfem/approximation/coupling/coupled_shapes.hpp"

#include <algorithm>

#include <omp.h>

#include "rkfem/core/error.hpp"

namespace rkfem
{
CoupledLayout coupled_layout(const HexMesh& mesh, const std::vector<char>& rk_element, const RkParams& params)
{
    const index_t ne = mesh.n_elements(), nn = mesh.n_nodes();
    RKFEM_REQUIRE(static_cast<index_t>(rk_element.size()) == ne,
                  "coupled shapes: " << rk_element.size() << " element flags for " << ne << " elements");
    CoupledLayout L;
    L.kind.assign(static_cast<std::size_t>(ne), CoupledShapes::Kind::Fe);
    std::vector<char> particle(static_cast<std::size_t>(nn), 0);
    for (index_t e = 0; e < ne; ++e)
        if (rk_element[e])
        {
            L.kind[e] = CoupledShapes::Kind::Rk;
            for (int a = 0; a < 8; ++a)
                particle[mesh.conn[8 * e + a]] = 1;
        }
    // interface elements, and the nodes they touch
    std::vector<char> touches_interface(static_cast<std::size_t>(nn), 0);
    for (index_t e = 0; e < ne; ++e)
    {
        if (L.kind[e] == CoupledShapes::Kind::Rk)
            continue;
        bool any = false;
        for (int a = 0; a < 8; ++a)
            any = any || particle[mesh.conn[8 * e + a]];
        if (!any)
            continue;
        L.kind[e] = CoupledShapes::Kind::Interface;
        for (int a = 0; a < 8; ++a)
            touches_interface[mesh.conn[8 * e + a]] = 1;
    }
    // supports: normalized_support x the longest edge at the node; at least kInterfaceSupport x
    // for every node of an RK element that shares a node with an interface element (two particle
    // layers reach across each interface element)
    const std::vector<real_t> h = nodal_spacing(mesh);
    std::vector<real_t> c(static_cast<std::size_t>(nn), params.normalized_support);
    for (index_t e = 0; e < ne; ++e)
    {
        if (L.kind[e] != CoupledShapes::Kind::Rk)
            continue;
        bool near = false;
        for (int a = 0; a < 8; ++a)
            near = near || touches_interface[mesh.conn[8 * e + a]];
        if (near)
            for (int a = 0; a < 8; ++a)
            {
                real_t& ca = c[mesh.conn[8 * e + a]];
                ca = std::max(ca, CoupledShapes::kInterfaceSupport);
            }
    }
    L.radius.assign(static_cast<std::size_t>(nn), 0.0);
    for (index_t i = 0; i < nn; ++i)
        if (particle[i])
            L.radius[i] = c[i] * h[i];
    return L;
}

CoupledShapes::CoupledShapes(const HexMesh& mesh, const std::vector<char>& rk_element, const RkParams& params,
                             Transition transition)
    : mesh_(mesh), transition_(transition)
{
    CoupledLayout L = coupled_layout(mesh, rk_element, params);
    index_t n_rk = 0;
    for (Kind k : L.kind)
        n_rk += k == Kind::Rk;
    RKFEM_REQUIRE(n_rk > 0, "coupled shapes: no element of " << mesh.n_elements() << " is RK");
    kind_ = std::move(L.kind);
    radius_ = std::move(L.radius);
    particle_of_.assign(radius_.size(), -1);
    std::vector<real_t> x, radius;
    for (index_t i = 0; i < mesh.n_nodes(); ++i)
        if (radius_[i] > 0.0)
        {
            particle_of_[i] = static_cast<index_t>(particle_node_.size());
            particle_node_.push_back(i);
            for (int d = 0; d < 3; ++d)
                x.push_back(mesh.x[3 * i + d]);
            radius.push_back(radius_[i]);
        }
    rk_ = RkShapeFunctions(std::move(x), std::move(radius), params);
    regions_.resize(static_cast<std::size_t>(omp_get_max_threads()));
}

void CoupledShapes::fe_functions(index_t e, const real_t (&N)[8], const Vec3& x, std::vector<index_t>& nodes,
                                 std::vector<real_t>& psi, RkOthers& others) const
{
    others.clear();
    const index_t* en = &mesh_.conn[8 * static_cast<std::size_t>(e)];
    for (int a = 0; a < 8; ++a)
        if (particle_of_[en[a]] < 0)
        {
            nodes.push_back(en[a]);
            psi.push_back(N[a]);
            others.weight.push_back(N[a]);
            others.dx.push_back(x - mesh_.node(en[a]));
        }
}

CoupledShapes::Region* CoupledShapes::region(index_t e) const
{
    const std::size_t thread = static_cast<std::size_t>(omp_get_thread_num());
    if (thread >= regions_.size())
        return nullptr;
    Region& r = regions_[thread];
    if (!r.values)
        r.values = std::make_unique<RkRegionValues>(rk_, 0.0);
    if (r.element != e)
    {
        // the particles whose supports reach the element's box (a trilinear element lies in it)
        const index_t* en = &mesh_.conn[8 * static_cast<std::size_t>(e)];
        Vec3 lo = mesh_.node(en[0]), hi = lo;
        for (int a = 1; a < 8; ++a)
        {
            lo = lo.cwiseMin(mesh_.node(en[a]));
            hi = hi.cwiseMax(mesh_.node(en[a]));
        }
        r.values->gather(lo, hi);
        r.element = e;
        r.focused = false;
    }
    return &r;
}

bool CoupledShapes::fast(index_t e) const
{
    const Kind k = kind_[static_cast<std::size_t>(e)];
    // interface elements of the mixed transition at order 1 (RkRegionValues completes order 1 only)
    return k == Kind::Rk ||
           (k == Kind::Interface && transition_ == Transition::Mixed && rk_.params().basis_size() == 4);
}

void CoupledShapes::focus(index_t e, const Vec3& lo, const Vec3& hi) const
{
    if (!fast(e))
        return;
    Region* r = region(e);
    if (!r)
        return;
    r->values->focus(lo, hi);
    r->focused = true;
    r->lo = lo;
    r->hi = hi;
}

void CoupledShapes::values(index_t e, const Vec3& xi, const Vec3& x, std::vector<index_t>& nodes,
                           std::vector<real_t>& psi) const
{
    Region* r = fast(e) ? region(e) : nullptr;
    if (!r)
    {
        values_plain(e, xi, x, nodes, psi);
        return;
    }
    if (r->focused && !(((r->lo.array() <= x.array()) && (x.array() <= r->hi.array())).all()))
    {
        // outside the focus: the whole element's candidates again
        r->element = -1;
        r = region(e);
    }
    nodes.clear();
    psi.clear();
    if (kind_[static_cast<std::size_t>(e)] == Kind::Rk)
        r->values->evaluate(x);
    else
    {
        // the FE nodes' functions, and the particles' that complete them
        thread_local RkOthers others;
        real_t N[8];
        const real_t z[3] = {xi[0], xi[1], xi[2]};
        hex8_shape(z, N);
        fe_functions(e, N, x, nodes, psi, others);
        r->values->evaluate_completing(x, others);
    }
    const std::vector<index_t>& ids = r->values->candidates();
    const real_t *value = r->values->psi(), *kept = r->values->kept();
    for (std::size_t k = 0; k < ids.size(); ++k)
        if (kept[k] != 0.0)
        {
            nodes.push_back(particle_node_[static_cast<std::size_t>(ids[k])]);
            psi.push_back(value[k]);
        }
}

void CoupledShapes::values_plain(index_t e, const Vec3& xi, const Vec3& x, std::vector<index_t>& nodes,
                                 std::vector<real_t>& psi) const
{
    thread_local RkSample s;
    thread_local RkOthers others;
    nodes.clear();
    psi.clear();
    const index_t* en = &mesh_.conn[8 * static_cast<std::size_t>(e)];
    real_t N[8];
    const real_t z[3] = {xi[0], xi[1], xi[2]};
    hex8_shape(z, N);
    // particles are never among the FE nodes listed before them, so only the ramp (which lists
    // every node of the element first) can meet a node twice
    auto add_distinct = [&]()
    {
        for (index_t k = 0; k < s.size(); ++k)
        {
            nodes.push_back(particle_node_[s.nodes[k]]);
            psi.push_back(s.psi[k]);
        }
    };
    auto add_particles = [&](real_t scale)
    {
        for (index_t k = 0; k < s.size(); ++k)
        {
            const index_t node = particle_node_[s.nodes[k]];
            auto it = std::find(nodes.begin(), nodes.end(), node);
            if (it == nodes.end())
            {
                nodes.push_back(node);
                psi.push_back(scale * s.psi[k]);
            }
            else
                psi[it - nodes.begin()] += scale * s.psi[k];
        }
    };
    switch (kind_[static_cast<std::size_t>(e)])
    {
    case Kind::Fe:
        nodes.assign(en, en + 8);
        psi.assign(N, N + 8);
        return;
    case Kind::Rk:
        rk_.evaluate(x, false, s);
        add_distinct();
        return;
    case Kind::Interface:
        break;
    }
    if (transition_ == Transition::Mixed)
    {
        fe_functions(e, N, x, nodes, psi, others);
        rk_.evaluate_completing(x, others, s);
        add_distinct();
        return;
    }
    // ramp: (1 - R) N_k for every node of the element, R Psi_J for every covering particle
    real_t R = 0.0;
    for (int a = 0; a < 8; ++a)
        if (particle_of_[en[a]] >= 0)
            R += N[a];
    for (int a = 0; a < 8; ++a)
    {
        nodes.push_back(en[a]);
        psi.push_back((1.0 - R) * N[a]);
    }
    if (R > 0.0)
    {
        rk_.evaluate(x, false, s);
        add_particles(R);
    }
}

void CoupledShapes::gradients_at_node(index_t, std::vector<index_t>&, std::vector<Vec3>&) const
{
    throw Error("direct nodal integration is not available on coupled FE-RK parts");
}

void CoupledShapes::node_row(index_t node, std::vector<index_t>& nodes, std::vector<real_t>& values) const
{
    const index_t p = particle_of_[static_cast<std::size_t>(node)];
    if (p < 0)
    {
        nodes.push_back(node);
        values.push_back(1.0);
        return;
    }
    // N_i(X_J) = 0 for every FE node i: the RK interpolant alone, in either treatment
    thread_local RkSample s;
    rk_.evaluate(mesh_.node(node), false, s);
    for (index_t k = 0; k < s.size(); ++k)
    {
        nodes.push_back(particle_node_[s.nodes[k]]);
        values.push_back(s.psi[k]);
    }
}
} // namespace rkfem
