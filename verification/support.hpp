#pragma once
// Helpers shared by verification tests: a block built straight from a generated mesh, and a
// model built from deck text.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <random>
#include <string>

#include "rkfem/config/deck.hpp"
#include "rkfem/discretization/generators.hpp"
#include "rkfem/model/model.hpp"
#include "rkfem/operators/hex_block.hpp"
#include "rkfem/operators/semi_lagrangian_block.hpp"
#include "rkfem/run/simulation.hpp"

namespace rkfem::test
{
/// A fast operator builder's result against its plain twin's: the same points (positions,
/// owners) and stencils (offsets, nodes) are expected; returns the largest gradient difference
/// over the largest gradient (infinity when the stencils differ).
inline real_t gradient_difference(const IntegrationOperator& fast, const IntegrationOperator& plain)
{
    EXPECT_EQ(fast.position, plain.position);
    EXPECT_EQ(fast.owner, plain.owner);
    EXPECT_EQ(fast.offsets, plain.offsets);
    EXPECT_EQ(fast.nodes, plain.nodes);
    if (fast.offsets != plain.offsets || fast.nodes != plain.nodes)
        return std::numeric_limits<real_t>::infinity();
    real_t worst = 0.0, big = 0.0;
    for (std::size_t k = 0; k < plain.grad.size(); ++k)
    {
        worst = std::max(worst, std::abs(fast.grad[k] - plain.grad[k]));
        big = std::max(big, std::abs(plain.grad[k]));
    }
    return worst / big;
}

/// Box mesh of n^3 unit-ish hexes with interior nodes jittered by up to `jitter` x element size.
inline HexMesh distorted_box(int n, real_t h, real_t jitter, unsigned seed = 7)
{
    HexMesh m = generate_box(Vec3::Zero(), Vec3::Constant(n * h), {n, n, n});
    std::mt19937 gen(seed);
    std::uniform_real_distribution<real_t> u(-jitter * h, jitter * h);
    for (index_t i = 0; i < m.n_nodes(); ++i)
    {
        bool interior = true;
        for (int d = 0; d < 3; ++d)
        {
            const real_t x = m.x[3 * i + d];
            interior = interior && x > 1e-9 * h && x < n * h - 1e-9 * h;
        }
        if (interior)
            for (int d = 0; d < 3; ++d)
                m.x[3 * i + d] += u(gen);
    }
    return m;
}

/// Each hex of m split into two wedges written as degenerate hexes, as pre-processors write them for
/// LS-DYNA (a node repeated: N1 N2 N3 N3 N4 N5 N6 N6): the prisms (0 1 3, 4 5 7) and (1 2 3, 5 6 7),
/// whose triangles lie in the hex's bottom and top faces. The nodes stay; faces are not rebuilt.
inline HexMesh split_into_wedges(const HexMesh& m)
{
    HexMesh w = m;
    w.conn.clear();
    for (index_t e = 0; e < m.n_elements(); ++e)
    {
        const index_t* c = m.conn.data() + 8 * static_cast<std::size_t>(e);
        w.conn.insert(w.conn.end(), {c[0], c[1], c[3], c[3], c[4], c[5], c[7], c[7]});
        w.conn.insert(w.conn.end(), {c[1], c[2], c[3], c[3], c[5], c[6], c[7], c[7]});
    }
    return w;
}

/// Each hex of m split into the six tetrahedra about its diagonal from node 0 to node 6 (Kuhn's
/// split, conforming on a structured box), written as degenerate hexes in the form Gmsh meshes
/// take here (gmsh_mesh.cpp: N1 N2 N3 N3 N4 N4 N4 N4), each right-handed; boundary faces rebuilt.
inline HexMesh split_into_tets(const HexMesh& m)
{
    static constexpr int kuhn[6][4] = {{0, 1, 2, 6}, {0, 1, 5, 6}, {0, 3, 2, 6},
                                       {0, 3, 7, 6}, {0, 4, 5, 6}, {0, 4, 7, 6}};
    HexMesh t = m;
    t.conn.clear();
    for (index_t e = 0; e < m.n_elements(); ++e)
    {
        const index_t* c = m.conn.data() + 8 * static_cast<std::size_t>(e);
        for (const auto& k : kuhn)
        {
            index_t a = c[k[0]], b = c[k[1]], d = c[k[2]], top = c[k[3]];
            if ((m.node(b) - m.node(a)).cross(m.node(d) - m.node(a)).dot(m.node(top) - m.node(a)) < 0.0)
                std::swap(b, d);
            t.conn.insert(t.conn.end(), {a, b, d, d, top, top, top, top});
        }
    }
    t.faces = extract_boundary_faces(t.conn);
    return t;
}

/// Each hex of m split into the six pyramids on its faces with their apex at a new node at the
/// hex's centre, written as LS-DYNA writes pyramids (N1 N2 N3 N4 N5 N5 N5 N5), each right-handed;
/// boundary faces rebuilt (the hexes' own).
inline HexMesh split_into_pyramids(const HexMesh& m)
{
    HexMesh p = m;
    p.conn.clear();
    for (index_t e = 0; e < m.n_elements(); ++e)
    {
        const index_t* c = m.conn.data() + 8 * static_cast<std::size_t>(e);
        Vec3 centre = Vec3::Zero();
        for (int a = 0; a < 8; ++a)
            centre += m.node(c[a]) / 8.0;
        const index_t apex = p.n_nodes();
        p.x.insert(p.x.end(), {centre[0], centre[1], centre[2]});
        for (const auto& f : hex_faces) // outward: the base is written inward, towards the apex
            p.conn.insert(p.conn.end(), {c[f[3]], c[f[2]], c[f[1]], c[f[0]], apex, apex, apex, apex});
    }
    p.faces = extract_boundary_faces(p.conn);
    return p;
}

/// Writes nodes (x: 3 per node) and 8-node solids (conn: 8 per element, 0-based; pid per element,
/// empty: all 1) as an LS-DYNA keyword file in the temp folder (NIDs and EIDs from 1, comma
/// fields with 17 digits, so the mesh reads back bit for bit); an element whose volume comes out
/// negative has its two layers of nodes swapped. Returns the path.
inline std::string write_keyword_mesh(const std::string& name, const std::vector<real_t>& x, std::vector<index_t> conn,
                                      const std::vector<int>& pid = {})
{
    const std::string path = (std::filesystem::temp_directory_path() / name).string();
    std::ofstream k(path);
    k << "*KEYWORD\n*NODE\n";
    char buf[160];
    for (std::size_t i = 0; i < x.size() / 3; ++i)
    {
        std::snprintf(buf, sizeof buf, "%zu,%.17g,%.17g,%.17g\n", i + 1, x[3 * i], x[3 * i + 1], x[3 * i + 2]);
        k << buf;
    }
    k << "*ELEMENT_SOLID\n";
    for (std::size_t e = 0; e < conn.size() / 8; ++e)
    {
        index_t* c = &conn[8 * e];
        auto p = [&](int a) { return Vec3(x[3 * c[a]], x[3 * c[a] + 1], x[3 * c[a] + 2]); };
        // the sign of the volume: (x1 - x0) x (x3 - x0) . (x4 - x0) at the first corner
        if ((p(1) - p(0)).cross(p(3) - p(0)).dot(p(4) - p(0)) < 0.0)
            for (int a = 0; a < 4; ++a)
                std::swap(c[a], c[a + 4]);
        k << e + 1 << "," << (pid.empty() ? 1 : pid[e]);
        for (int a = 0; a < 8; ++a)
            k << "," << c[a] + 1;
        k << "\n";
    }
    k << "*END\n";
    return path;
}

inline bool is_interior(const HexMesh& m, index_t i, real_t lo, real_t hi)
{
    for (int d = 0; d < 3; ++d)
    {
        const real_t x = m.x[3 * i + d];
        if (!(x > lo && x < hi))
            return false;
    }
    return true;
}

/// A bilinear J2 material (model j2, sigy and the total-strain tangent modulus etan).
inline MaterialSpec j2_material(real_t rho, real_t E, real_t nu, real_t sigy, real_t etan)
{
    MaterialSpec m;
    m.model = "j2";
    m.rho = rho;
    m.E = E;
    m.nu = nu;
    m.sigy = sigy;
    m.etan = etan;
    return m;
}

/// A material of each model for tests that run one history through every block or kernel: steel
/// (elastic, or J2 with yield 400 MPa and tangent 2 GPa), K&C at f'c 45.6 MPa, CSCM at f'c 30 MPa.
inline MaterialSpec block_material(const std::string& model)
{
    MaterialSpec m = j2_material(7850, 200e9, 0.3, 400e6, 2e9);
    m.model = model;
    if (model == "kcc" || model == "cscm")
    {
        m.rho = 2400;
        m.fc = 45.6e6;
        m.nu = 0.19;
        m.E = 4700.0 * std::sqrt(45.6) * 1e6;
    }
    if (model == "cscm")
    {
        m.fc = 30e6;
        m.nu = 0.2;
        m.E = 21.5e9 * std::cbrt(3.0);
    }
    return m;
}

/// A single block (part 0) over all nodes of `mesh`.
inline HexBlock make_block(const HexMesh& mesh, NodeSet& nodes, Formulation f, HourglassSpec hg, ElasticParams mat,
                           BulkViscositySpec bv = {0.0, 0.0})
{
    nodes.resize(mesh.n_nodes());
    for (std::size_t i = 0; i < mesh.x.size(); ++i)
        nodes.x0[i] = nodes.x[i] = mesh.x[i];
    HexBlock b;
    b.formulation = f;
    b.hourglass = f == Formulation::Fem1pt ? hg : HourglassSpec{HourglassType::None, 0.0};
    b.bulk_viscosity = bv;
    b.material = mat;
    b.conn = mesh.conn;
    b.node_begin = 0;
    b.node_end = mesh.n_nodes();
    b.initialize(nodes);
    add_lumped_mass(b, nodes);
    return b;
}

/// Forces assembled by scatter (s) and gather (g), each on 1 and 2 threads: asserts that each
/// pair is bitwise equal (thread-count independence) and returns max |s - g| / max |g|.
inline real_t assembly_difference(const std::vector<real_t>& s1, const std::vector<real_t>& s2,
                                  const std::vector<real_t>& g1, const std::vector<real_t>& g2)
{
    real_t scale = 0.0, diff = 0.0;
    for (std::size_t j = 0; j < s1.size(); ++j)
    {
        EXPECT_EQ(s1[j], s2[j]) << "scatter, dof " << j;
        EXPECT_EQ(g1[j], g2[j]) << "gather, dof " << j;
        if (s1[j] != s2[j] || g1[j] != g2[j])
            break;
        scale = std::max(scale, std::abs(g1[j]));
        diff = std::max(diff, std::abs(s1[j] - g1[j]));
    }
    return diff / scale;
}

/// A steel part (E 200 GPa, nu 0.3, rho 7850 kg/m^3) for nodal blocks built straight from a mesh.
inline PartSpec steel_nodal_part(Formulation f, const std::string& scheme = "scni", const std::string& stab = "mscni")
{
    PartSpec ps;
    ps.name = "block";
    ps.formulation = f;
    ps.material.model = "elastic";
    ps.material.rho = 7850.0;
    ps.material.E = 200e9;
    ps.material.nu = 0.3;
    ps.nodal.scheme = scheme;
    ps.nodal.stabilization = stab;
    return ps;
}

/// One step of the linear velocity field v = A x0 (A in 1/s) on every node: v, u += dt v and
/// x = x0 + u, so the geometry stays a linear map of x0.
inline void linear_velocity_step(NodeSet& nodes, const real_t (&A)[3][3], real_t dt)
{
    for (index_t i = 0; i < nodes.size(); ++i)
        for (int d = 0; d < 3; ++d)
        {
            real_t v = 0;
            for (int j = 0; j < 3; ++j)
                v += A[d][j] * nodes.x0[3 * i + j];
            nodes.v[3 * i + d] = v;
            nodes.u[3 * i + d] += dt * v;
            nodes.x[3 * i + d] = nodes.x0[3 * i + d] + nodes.u[3 * i + d];
        }
}

inline Model model_from(const std::string& deck_text, const std::vector<std::string>& overrides = {})
{
    return Model::build(parse_deck(deck_text, "test.yaml", overrides));
}

/// The DeckError message of building the model of a deck with overrides (empty: it built).
inline std::string model_error(const std::string& deck_text, const std::vector<std::string>& overrides)
{
    try
    {
        model_from(deck_text, overrides);
    }
    catch (const DeckError& e)
    {
        return e.what();
    }
    return "";
}

/// Momentum of the unknowns, sum_I m_I v_I.
inline Vec3 momentum(const NodeSet& nodes)
{
    Vec3 p = Vec3::Zero();
    for (index_t i = 0; i < nodes.size(); ++i)
        p += nodes.mass[i] * Vec3(nodes.v[3 * i], nodes.v[3 * i + 1], nodes.v[3 * i + 2]);
    return p;
}

/// The model's (first) semi-Lagrangian RK block.
inline SemiLagrangianForceBlock& sl_block(Model& m)
{
    for (index_t k = 0; k < m.n_blocks(); ++k)
        if (auto* b = dynamic_cast<SemiLagrangianForceBlock*>(&m.block(k)))
            return *b;
    throw std::runtime_error("no semi-Lagrangian block");
}

/// The nodes' total mass.
inline real_t total_mass(const NodeSet& nodes)
{
    real_t s = 0.0;
    for (real_t m : nodes.mass)
        s += m;
    return s;
}

/// sum_I m_I |v_I|: the scale momentum errors are measured against.
inline real_t momentum_scale(const NodeSet& nodes)
{
    real_t s = 0.0;
    for (index_t i = 0; i < nodes.size(); ++i)
        s += nodes.mass[i] * Vec3(nodes.v[3 * i], nodes.v[3 * i + 1], nodes.v[3 * i + 2]).norm();
    return s;
}

/// A velocity field that deforms a column along z (x: 2 sin(80 z), z: 10 cos(150 z) + 3 m/s; z
/// in m): internal forces on every node, for momentum checks without conditions or loads.
inline void deforming_column_velocity(NodeSet& nodes)
{
    for (index_t i = 0; i < nodes.size(); ++i)
    {
        const real_t z = nodes.x0[3 * i + 2];
        nodes.v[3 * i] = 2.0 * std::sin(80.0 * z);
        nodes.v[3 * i + 2] = 10.0 * std::cos(150.0 * z) + 3.0;
    }
}

/// The displacements at the end of a run of a deck on `threads` OpenMP threads (the caller's count
/// restored after), `prepare` setting the initial state: runs on 1 and 2 threads compared bit for
/// bit show that a block's assembly does not depend on the thread count.
inline std::vector<real_t> displacements_on_threads(const std::string& deck_text,
                                                    const std::vector<std::string>& overrides, int threads,
                                                    const std::function<void(Model&)>& prepare = {})
{
    const int saved = omp_get_max_threads();
    omp_set_num_threads(threads);
    Model m = model_from(deck_text, overrides);
    if (prepare)
        prepare(m);
    RunOptions opt;
    opt.progress = false;
    run_simulation(m, opt);
    omp_set_num_threads(saved);
    return m.nodes.u;
}

/// A run to the deck's end without progress output, and its largest energy balance error after
/// time `after` (an impulsive start's transient left out).
struct RunWithBalance
{
    RunSummary summary;
    real_t balance = 0.0;
};
inline RunWithBalance run_with_balance(Model& m, real_t after)
{
    RunWithBalance r;
    RunOptions opt;
    opt.progress = false;
    r.summary = run_simulation(m, opt,
                               [&](const Model& mm, real_t t, real_t, std::int64_t)
                               {
                                   if (t > after)
                                       r.balance = std::max(r.balance, mm.energy.balance_error());
                               });
    return r;
}
} // namespace rkfem::test
