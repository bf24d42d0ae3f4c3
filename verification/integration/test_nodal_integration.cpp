// Nodal integration operators on hex-dual cells: the integration constraint (IC1, discrete
// divergence theorem) to round-off for SCNI and SD-SCNI with RK and FE functions, linear
// gradient reproduction at every point, SCNI gradients against brute-force quadrature, and
// DNI's failure of IC1 on an irregular cloud (recorded).
#include <gtest/gtest.h>

#include <cstdio>
#include <map>
#include <omp.h>

#include "nodal_common.hpp"
#include "rkfem/approximation/fem/hex8_basis.hpp"

using namespace rkfem;
using namespace rkfem::test;

namespace
{
constexpr real_t h = 0.25;

/// max_I |sum_L b_I(L) V_L - sum_K Psi_I(x_K) n_K A_K| * h / V_total
real_t ic1_error(const HexMesh& mesh, const IntegrationOperator& op, const ShapeEvaluator& shapes)
{
    const index_t n = mesh.n_nodes();
    std::vector<Vec3> lhs(static_cast<std::size_t>(n), Vec3::Zero()), rhs = lhs;
    real_t vol = 0.0;
    for (index_t p = 0; p < op.n_points(); ++p)
    {
        vol += op.weight[p];
        for (index_t k = op.offsets[p]; k < op.offsets[p + 1]; ++k)
            lhs[op.nodes[k]] += op.weight[p] * op.gradient(k);
    }
    std::vector<index_t> nodes;
    std::vector<real_t> psi;
    for (const BoundaryPoint& b : boundary_quadrature(mesh))
    {
        shapes.values(b.element, b.point.xi, b.point.x, nodes, psi);
        for (std::size_t k = 0; k < nodes.size(); ++k)
            rhs[nodes[k]] += psi[k] * b.point.nda;
    }
    real_t err = 0.0;
    for (index_t i = 0; i < n; ++i)
        err = std::max(err, (lhs[i] - rhs[i]).norm());
    return err * h / vol;
}

} // namespace

TEST(NodalIntegration, IntegrationConstraintHoldsToRoundOffForConformingCells)
{
    const HexMesh mesh = distorted_box(4, h, 0.3);
    const RkShapeFunctions rk = rk_on_mesh(mesh);
    RkShapes rks(rk);
    FemShapes fes(mesh);
    struct Row
    {
        const char* name;
        IntegrationOperator op;
        const ShapeEvaluator* shapes;
    };
    const Row rows[] = {{"rkpm scni", build_scni(mesh, rks), &rks},
                        {"rkpm sd-scni", build_sd_scni(mesh, rks), &rks},
                        {"fem-nodal scni", build_scni(mesh, fes), &fes},
                        {"fem-nodal sd-scni", build_sd_scni(mesh, fes), &fes}};
    for (const Row& r : rows)
    {
        const real_t ic = ic1_error(mesh, r.op, *r.shapes);
        const real_t lin = linear_gradient_error(mesh, r.op, h);
        std::printf("%-18s IC1 error %.2e, linear gradient error %.2e\n", r.name, ic, lin);
        EXPECT_LT(ic, 1e-13) << r.name;
        EXPECT_LT(lin, 1e-12) << r.name;
    }
    // the stabilization of MSCNI has no net effect on linear fields
    const IntegrationOperator stab = build_mscni_stabilization(rows[0].op, rows[1].op);
    real_t lin_stab = 0.0;
    for (index_t p = 0; p < stab.n_points(); ++p)
    {
        Mat3 g = Mat3::Zero();
        for (index_t k = stab.offsets[p]; k < stab.offsets[p + 1]; ++k)
            g += mesh.node(stab.nodes[k]) * stab.gradient(k).transpose();
        lin_stab = std::max(lin_stab, g.cwiseAbs().maxCoeff());
    }
    std::printf("mscni stabilization: linear-field strain %.2e\n", lin_stab);
    EXPECT_LT(lin_stab, 1e-12);
}

TEST(NodalIntegration, DirectNodalIntegrationViolatesTheConstraintOnIrregularClouds)
{
    const HexMesh mesh = distorted_box(4, h, 0.3);
    const RkShapeFunctions rk = rk_on_mesh(mesh);
    RkShapes rks(rk);
    const IntegrationOperator dni = build_dni(mesh, rks);
    const real_t ic = ic1_error(mesh, dni, rks);
    std::printf("rkpm dni IC1 error %.2e (linear gradient error %.2e: direct gradients reproduce)\n", ic,
                linear_gradient_error(mesh, dni, h));
    EXPECT_GT(ic, 1e-4);
    EXPECT_LT(linear_gradient_error(mesh, dni, h), 1e-12);
}

TEST(NodalIntegration, ScniGradientsAgreeWithBruteForceQuadrature)
{
    // For interior nodes of a jittered cloud: (a) the boundary integral of Psi n over the nodal
    // cell with 10x10 Gauss points per facet equals the volume integral of the direct gradient
    // with 10^3 points per sub-hex (divergence theorem; checks geometry and gradients), and
    // (b) the production 2x2 facet rule is within its quadrature error of it.
    const HexMesh mesh = distorted_box(4, h, 0.3);
    const RkShapeFunctions rk = rk_on_mesh(mesh);
    const IntegrationOperator scni = build_scni(mesh, RkShapes(rk));
    std::vector<index_t> inc_off, inc;
    node_element_incidence(mesh, inc_off, inc);
    const int ng = 10;
    real_t gx[ng], gw[ng];
    {
        // Gauss-Legendre on [-1, 1] by Newton on P_n
        for (int i = 0; i < ng; ++i)
        {
            real_t x = std::cos(M_PI * (i + 0.75) / (ng + 0.5));
            for (int it = 0; it < 100; ++it)
            {
                real_t p0 = 1, p1 = x;
                for (int k = 2; k <= ng; ++k)
                {
                    const real_t p2 = ((2 * k - 1) * x * p1 - (k - 1) * p0) / k;
                    p0 = p1;
                    p1 = p2;
                }
                const real_t dp = ng * (x * p1 - p0) / (x * x - 1);
                x -= p1 / dp;
                if (std::abs(p1 / dp) < 1e-16)
                    break;
            }
            real_t p0 = 1, p1 = x;
            for (int k = 2; k <= ng; ++k)
            {
                const real_t p2 = ((2 * k - 1) * x * p1 - (k - 1) * p0) / k;
                p0 = p1;
                p1 = p2;
            }
            gx[i] = x;
            gw[i] = 2.0 * (1 - x * x) / (ng * ng * p0 * p0);
        }
    }
    const std::vector<index_t> nb = face_neighbours(mesh);
    RkSample s;
    real_t worst_div = 0.0, worst_2x2 = 0.0;
    for (index_t L = 0; L < mesh.n_nodes(); ++L)
    {
        if (!is_interior(mesh, L, 0.5 * h, 3.5 * h))
            continue;
        std::map<index_t, Vec3> surf, volu;
        real_t V = 0.0;
        for (index_t q = inc_off[L]; q < inc_off[L + 1]; ++q)
        {
            const index_t e = inc[q] / 8;
            const int a = inc[q] % 8;
            real_t xe[8][3];
            for (int I = 0; I < 8; ++I)
                for (int d = 0; d < 3; ++d)
                    xe[I][d] = mesh.x[3 * mesh.conn[8 * e + I] + d];
            const real_t sgn[3] = {hex8_nodes[a][0], hex8_nodes[a][1], hex8_nodes[a][2]};
            // volume integral over the octant
            for (int i = 0; i < ng; ++i)
                for (int j = 0; j < ng; ++j)
                    for (int k = 0; k < ng; ++k)
                    {
                        const real_t xi[3] = {sgn[0] * 0.5 * (1 + gx[i]), sgn[1] * 0.5 * (1 + gx[j]),
                                              sgn[2] * 0.5 * (1 + gx[k])};
                        real_t N[8], dNdx[8][3];
                        hex8_shape(xi, N);
                        const real_t detJ = hex8_gradients(xe, xi, dNdx);
                        Vec3 x = Vec3::Zero();
                        for (int I = 0; I < 8; ++I)
                            x += N[I] * Vec3(xe[I][0], xe[I][1], xe[I][2]);
                        const real_t w = gw[i] * gw[j] * gw[k] * 0.125 * detJ;
                        V += w;
                        rk.evaluate(x, true, s);
                        for (index_t m = 0; m < s.size(); ++m)
                            volu.try_emplace(s.nodes[m], Vec3::Zero()).first->second += w * s.grad[m];
                    }
            // surface integral over the cell boundary facets of this sub-hex (10x10 per facet)
            SubHex sh;
            build_sub_hex(xe, a, sh);
            for (int d = 0; d < 3; ++d)
                for (int side = 0; side < 2; ++side)
                {
                    const int f = 2 * d + side;
                    if (sh.element_face[f] >= 0 && nb[6 * e + sh.element_face[f]] >= 0)
                        continue;
                    const int p = (d + 1) % 3, r = (d + 2) % 3;
                    const real_t orient = side == 0 ? -sgn[d] : sgn[d];
                    for (int i = 0; i < ng; ++i)
                        for (int j = 0; j < ng; ++j)
                        {
                            real_t xi[3];
                            xi[d] = side == 0 ? 0.0 : sgn[d];
                            xi[p] = sgn[p] * 0.5 * (1 + gx[i]);
                            xi[r] = sgn[r] * 0.5 * (1 + gx[j]);
                            real_t N[8], dN[8][3];
                            hex8_shape(xi, N);
                            hex8_shape_derivatives(xi, dN);
                            Vec3 x = Vec3::Zero(), xp = Vec3::Zero(), xr = Vec3::Zero();
                            for (int I = 0; I < 8; ++I)
                            {
                                const Vec3 X(xe[I][0], xe[I][1], xe[I][2]);
                                x += N[I] * X;
                                xp += dN[I][p] * X;
                                xr += dN[I][r] * X;
                            }
                            const Vec3 nda = orient * 0.25 * gw[i] * gw[j] * xp.cross(xr);
                            rk.evaluate(x, false, s);
                            for (index_t m = 0; m < s.size(); ++m)
                                surf.try_emplace(s.nodes[m], Vec3::Zero()).first->second += s.psi[m] * nda;
                        }
                }
        }
        real_t gmax = 0.0;
        for (const auto& [n, g] : volu)
            gmax = std::max(gmax, g.norm() / V);
        for (const auto& [n, g] : volu)
            worst_div = std::max(worst_div, (g - surf.try_emplace(n, Vec3::Zero()).first->second).norm() / V / gmax);
        for (index_t k = scni.offsets[L]; k < scni.offsets[L + 1]; ++k)
            worst_2x2 = std::max(
                worst_2x2,
                (scni.gradient(k) - surf.try_emplace(scni.nodes[k], Vec3::Zero()).first->second / V).norm() / gmax);
    }
    std::printf("divergence theorem (10x10 facets vs 10^3 volume): %.2e; 2x2 SCNI vs 10x10: %.2e of max |b|\n",
                worst_div, worst_2x2);
    EXPECT_LT(worst_div, 1e-4);
    EXPECT_LT(worst_2x2, 1e-2); // quadrature error of the 2x2 rule on RK functions (3.4e-3 here)
}

// The drop tolerance (rk.drop_tolerance, RkShapes): SCNI with the functions below 1e-5 of the
// largest dropped at each facet point, the rest corrected to reproduce 1 and x there. IC1 and
// linear gradient reproduction stay at round-off (a facet point shared by two cells gets the same
// values from both); on a regular lattice at a/h = 1.51 an interior node's stencil falls
// to 27 entries (81 non-zero before: the dropped ones reach the cell's faces from 1.5 h away,
// with values below 1e-6 of the largest; jittered 0.3 h, 124 -> 117), and no gradient moves by
// more than 1e-4 of the largest.
TEST(NodalIntegration, DropToleranceKeepsTheConstraintAndShrinksTheStencil)
{
    for (const real_t jitter : {0.0, 0.3})
    {
        const HexMesh mesh = distorted_box(6, h, jitter);
        const RkShapeFunctions rk = rk_on_mesh(mesh);
        const RkShapes full(rk), dropped(rk, 1e-5);
        const IntegrationOperator a = build_scni(mesh, full), b = build_scni(mesh, dropped);
        const real_t ic = ic1_error(mesh, b, dropped), lin = linear_gradient_error(mesh, b, h);
        // the interior node (3, 3, 3): its stencils, and the largest change of any gradient
        const index_t centre = 3 + 7 * (3 + 7 * 3);
        real_t change = 0.0, scale = 0.0;
        for (index_t p = 0; p < a.n_points(); ++p)
        {
            std::map<index_t, Vec3> g; // a's entries minus b's, by node (zero where absent)
            for (index_t k = a.offsets[p]; k < a.offsets[p + 1]; ++k)
                g.emplace(a.nodes[k], Vec3::Zero());
            for (index_t k = b.offsets[p]; k < b.offsets[p + 1]; ++k)
                g.emplace(b.nodes[k], Vec3::Zero());
            for (index_t k = a.offsets[p]; k < a.offsets[p + 1]; ++k)
            {
                g[a.nodes[k]] += a.gradient(k);
                scale = std::max(scale, a.gradient(k).norm());
            }
            for (index_t k = b.offsets[p]; k < b.offsets[p + 1]; ++k)
                g[b.nodes[k]] -= b.gradient(k);
            for (const auto& [n, d] : g)
                change = std::max(change, d.norm());
        }
        const index_t na = a.offsets[centre + 1] - a.offsets[centre], nb = b.offsets[centre + 1] - b.offsets[centre];
        std::printf("jitter %.1f: IC1 error %.2e, linear gradient error %.2e, centre stencil %d -> %d entries, "
                    "entries %d -> %d, largest gradient change / largest gradient %.2e\n",
                    jitter, ic, lin, na, nb, a.n_entries(), b.n_entries(), change / scale);
        EXPECT_LT(ic, 1e-13);
        EXPECT_LT(lin, 1e-12);
        EXPECT_LT(change / scale, 1e-4); // a few times the tolerance: 4e-6 regular, 2e-5 jittered
        if (jitter == 0.0)
        {
            EXPECT_EQ(na, 81);
            EXPECT_EQ(nb, 27);
        }
        else
            EXPECT_LT(b.n_entries(), a.n_entries());
    }
}

TEST(NodalIntegration, OnePassScniAndSubCellsAreTheSeparateBuildsBitForBit)
{
    // build_scni_sd evaluates each sub-hex facet point once for the sub-cell and the nodal cell;
    // its operators are build_scni's and build_sd_scni's, entry for entry, on a jittered mesh
    // with RK and FE shapes
    const real_t h = 1e-3;
    const HexMesh mesh = distorted_box(5, h, 0.3);
    const RkShapeFunctions rk = rk_on_mesh(mesh, RkParams{});
    const RkShapes rks(rk);
    const FemShapes fes(mesh);
    for (const ShapeEvaluator* shapes :
         {static_cast<const ShapeEvaluator*>(&rks), static_cast<const ShapeEvaluator*>(&fes)})
    {
        IntegrationOperator scni, sd;
        build_scni_sd(mesh, *shapes, scni, &sd);
        const IntegrationOperator a = build_scni(mesh, *shapes), b = build_sd_scni(mesh, *shapes);
        for (const auto& [fused, plain] : {std::pair{&scni, &a}, std::pair{&sd, &b}})
        {
            EXPECT_EQ(fused->weight, plain->weight);
            EXPECT_EQ(fused->position, plain->position);
            EXPECT_EQ(fused->owner, plain->owner);
            EXPECT_EQ(fused->offsets, plain->offsets);
            EXPECT_EQ(fused->nodes, plain->nodes);
            EXPECT_EQ(fused->grad, plain->grad);
        }
        EXPECT_GT(sd.n_entries(), scni.n_entries());
    }
}

// build_scni_rk (by elements: each facet point evaluated once for both cells, RkRegionValues)
// against build_scni with RkShapes (node by node, the plain twin), and its sub-cells against
// build_scni_sd's: the same points, weights and stencils, gradients to round-off, on a jittered
// mesh with and without the drop tolerance and with a quadratic basis; the same bits on 1 and 2
// threads (colour by colour, no race).
TEST(NodalIntegration, ScniByElementsIsTheNodeByNodeBuildToRoundOff)
{
    const real_t h = 1e-3;
    const HexMesh mesh = distorted_box(5, h, 0.3);
    std::vector<index_t> colour_offsets, by_colour;
    colour_elements(mesh, colour_offsets, by_colour);
    EXPECT_EQ(colour_offsets.size(), 9u); // 8 colours on a structured mesh
    for (std::size_t c = 0; c + 1 < colour_offsets.size(); ++c)
    {
        std::vector<int> seen(static_cast<std::size_t>(mesh.n_nodes()), 0);
        for (index_t q = colour_offsets[c]; q < colour_offsets[c + 1]; ++q)
            for (int a = 0; a < 8; ++a)
                EXPECT_EQ(seen[mesh.conn[8 * by_colour[q] + a]]++, 0) << "colour " << c << " shares a node";
    }
    for (const auto& [order, tau] : {std::pair{1, 0.0}, std::pair{1, 1e-5}, std::pair{2, 0.0}})
    {
        RkParams p;
        p.order = order;
        p.normalized_support = order == 1 ? 1.51 : 2.3;
        const RkShapeFunctions rk = rk_on_mesh(mesh, p);
        const IntegrationOperator plain = build_scni(mesh, RkShapes(rk, tau));
        const IntegrationOperator fast = build_scni_rk(mesh, rk, tau);
        ASSERT_EQ(fast.weight.size(), plain.weight.size());
        for (std::size_t p = 0; p < plain.weight.size(); ++p) // Gauss det J against the facets' x . n dA
            EXPECT_NEAR(fast.weight[p], plain.weight[p], 1e-14 * plain.weight[p]);
        const real_t difference = gradient_difference(fast, plain);
        std::printf("order %d, tau %.0e: %d entries, largest gradient difference %.2e of the largest gradient\n", order,
                    tau, plain.n_entries(), difference);
        EXPECT_LT(difference, 1e-13); // measured up to 3.2e-15
        // with MSCNI's sub-cells (build_scni_sd's)
        IntegrationOperator sd, plain_scni, plain_sd;
        const IntegrationOperator with_sd = build_scni_rk(mesh, rk, tau, &sd);
        build_scni_sd(mesh, RkShapes(rk, tau), plain_scni, &plain_sd);
        EXPECT_EQ(with_sd.grad, fast.grad);
        ASSERT_EQ(sd.weight.size(), plain_sd.weight.size());
        for (std::size_t p = 0; p < plain_sd.weight.size(); ++p)
            EXPECT_NEAR(sd.weight[p], plain_sd.weight[p], 1e-14 * plain_sd.weight[p]);
        const real_t sd_difference = gradient_difference(sd, plain_sd);
        std::printf("  sub-cells: %d entries, largest gradient difference %.2e of the largest gradient\n",
                    plain_sd.n_entries(), sd_difference);
        EXPECT_LT(sd_difference, 1e-13);
        const int threads = omp_get_max_threads();
        omp_set_num_threads(1);
        const IntegrationOperator serial = build_scni_rk(mesh, rk, tau);
        omp_set_num_threads(2);
        const IntegrationOperator two = build_scni_rk(mesh, rk, tau);
        omp_set_num_threads(threads);
        EXPECT_EQ(serial.grad, two.grad);
        EXPECT_EQ(serial.grad, fast.grad);
    }
}

// Translates (rk_translates.hpp) on a lattice whose coordinates are exact binary fractions, 6 x
// 6 x 6 elements of h = 1/64 with a = 1.51 h: an element's region is the particles within a of
// its box, nodes i - 1 .. i + 2 along each axis, cut off only by the first and the last element
// (whose faces are the boundary's), so the elements fall into 3 x 3 x 3 = 27 classes; a
// particle's region is its neighbours i - 1 .. i + 1, cut off at nodes 0 and 6: 27 classes again.
// The lattice is numbered lexicographically, so every translate's particles are its source's
// face_neighbours (faces bucketed by their smallest node, earlier_twin_faces) against a map of
// the sorted face keys in element order, the plain twin: the same neighbours on the P1
// cylinder's mesh and on a jittered box, every neighbour relation symmetric, and the boundary
// faces those extract_boundary_faces finds. A non-manifold mesh (three elements on one face)
// gives what the map gave: the first element's neighbour is the last.
TEST(NodalIntegration, FaceNeighboursAreThoseOfAMapOfTheFaces)
{
    auto plain = [](const HexMesh& mesh)
    {
        std::vector<index_t> nb(6 * static_cast<std::size_t>(mesh.n_elements()), -1);
        std::map<std::array<index_t, 4>, index_t> seen;
        for (index_t e = 0; e < mesh.n_elements(); ++e)
            for (int f = 0; f < 6; ++f)
            {
                std::array<index_t, 4> key;
                for (int k = 0; k < 4; ++k)
                    key[k] = mesh.conn[8 * e + hex_faces[f][k]];
                std::sort(key.begin(), key.end());
                auto [it, inserted] = seen.emplace(key, 6 * e + f);
                if (!inserted)
                {
                    nb[6 * e + f] = it->second / 6;
                    nb[it->second] = e;
                }
            }
        return nb;
    };
    const real_t inch = 0.0254;
    HexMesh three = generate_box(Vec3::Zero(), Vec3::Constant(1.0), {2, 1, 1});
    // a third element on the face between the two: a copy of the second
    three.conn.insert(three.conn.end(), three.conn.begin() + 8, three.conn.begin() + 16);
    const HexMesh meshes[] = {generate_cylinder(Vec3::Zero(), 3 * inch, 12 * inch, 0.5 * inch, false),
                              distorted_box(5, 1e-3, 0.3), three};
    for (const HexMesh& m : meshes)
    {
        const HexMesh* mesh = &m;
        const std::vector<index_t> nb = face_neighbours(*mesh);
        EXPECT_EQ(nb, plain(*mesh));
        if (mesh == &meshes[2])
            continue;
        std::size_t boundary = 0;
        for (std::size_t k = 0; k < nb.size(); ++k)
        {
            boundary += nb[k] < 0;
            if (nb[k] >= 0)
            {
                const auto& other = nb.begin() + 6 * nb[k];
                EXPECT_EQ(std::count(other, other + 6, static_cast<index_t>(k / 6)), 1) << "face " << k;
            }
        }
        EXPECT_EQ(boundary, extract_boundary_faces(mesh->conn).size());
    }
}

// The sub-hexes' Gauss points eight at a time (sub_hex_points): the volumes and NSNI's second
// moments of the nodal cells against their point-by-point twins to round-off on a jittered mesh,
// and the moments against the exact values on a lattice of spacing h (interior cell a cube of
// side h: h^5 / 12 per axis; a corner's of side h/2 from its node: h^5 / 96; an edge node's
// a box h x h/2 x h/2: h^3 / 12 (h/2)^2 along the edge, (h/2)^3 / 3 h h/2 across, both h^5 / 48).
TEST(NodalIntegration, SubHexPointsAtOnceAreThePlainQuadratureToRoundOff)
{
    const real_t h = 1e-3;
    const HexMesh mesh = distorted_box(6, h, 0.3);
    real_t worst_volume = 0.0;
    for (index_t e = 0; e < mesh.n_elements(); ++e)
    {
        real_t xe[8][3];
        for (int I = 0; I < 8; ++I)
            for (int d = 0; d < 3; ++d)
                xe[I][d] = mesh.x[3 * static_cast<std::size_t>(mesh.conn[8 * e + I]) + d];
        for (int a = 0; a < 8; ++a)
        {
            const real_t plain = sub_hex_volume_plain(xe, a);
            ASSERT_GT(plain, 0.0);
            worst_volume = std::max(worst_volume, std::abs(sub_hex_volume(xe, a) - plain) / plain);
        }
    }
    const std::vector<real_t> m = nodal_second_moments(mesh), plain = nodal_second_moments_plain(mesh);
    ASSERT_EQ(m.size(), plain.size());
    real_t worst_moment = 0.0;
    for (std::size_t k = 0; k < m.size(); ++k)
    {
        ASSERT_GT(plain[k], 0.0);
        worst_moment = std::max(worst_moment, std::abs(m[k] - plain[k]) / plain[k]);
    }
    std::printf("largest relative difference: sub-hex volume %.2e, second moment %.2e\n", worst_volume, worst_moment);
    EXPECT_LT(worst_volume, 1e-14);
    EXPECT_LT(worst_moment, 1e-13);
    // exact on a lattice
    const int n = 4;
    const HexMesh box = generate_box(Vec3::Zero(), Vec3::Constant(n * h), {n, n, n});
    const std::vector<real_t> mb = nodal_second_moments(box);
    const real_t h5 = h * h * h * h * h;
    auto node = [&](int i, int j, int k) { return static_cast<std::size_t>((k * (n + 1) + j) * (n + 1) + i); };
    for (int d = 0; d < 3; ++d)
    {
        EXPECT_NEAR(mb[3 * node(2, 2, 2) + d], h5 / 12, 1e-13 * h5) << d;
        EXPECT_NEAR(mb[3 * node(0, 0, 0) + d], h5 / 96, 1e-13 * h5) << d;
        EXPECT_NEAR(mb[3 * node(2, 0, 0) + d], h5 / 48, 1e-13 * h5) << d;
    }
}

// plus one number. Without sharing, every item is its own source.
TEST(NodalIntegration, TranslatesOfALatticeAreItsTwentySevenBoundaryClasses)
{
    const real_t hl = 1.0 / 64.0;
    const HexMesh mesh = generate_box(Vec3::Zero(), Vec3::Constant(6 * hl), {6, 6, 6});
    const RkShapeFunctions rk = rkfem::rk_on_mesh(mesh, RkParams{});
    const std::vector<index_t> nb = face_neighbours(mesh);
    auto element_translates = [&](bool share)
    {
        return find_rk_translates(
            rk, mesh.n_elements(),
            [&](index_t e, Vec3& lo, Vec3& hi, Vec3& ref, std::vector<real_t>& own)
            {
                ref = lo = mesh.node(mesh.conn[8 * e]);
                hi = mesh.node(mesh.conn[8 * e + 6]);
                for (int f = 0; f < 6; ++f)
                    own.push_back(nb[6 * e + f] < 0 ? 1.0 : 0.0);
            },
            share);
    };
    for (const RkTranslates& t : {element_translates(true), particle_translates(rk)})
    {
        EXPECT_EQ(t.n_sources(), 27);
        for (index_t i = 0; i < t.size(); ++i)
        {
            ASSERT_LE(t.source[i], i) << "a source comes first";
            EXPECT_TRUE(t.computed(t.source[i]));
            ASSERT_EQ(t.region_size(i), t.region_size(t.source[i]));
            EXPECT_NE(t.shift[i], RkTranslates::kNoShift);
            for (index_t k = 0; k < t.region_size(i); ++k)
            {
                EXPECT_EQ(t.counterpart(i, t.region(t.source[i])[k]), t.region(i)[k]);
                EXPECT_EQ(t.counterpart_by_search(i, t.region(t.source[i])[k]), t.region(i)[k]);
            }
        }
    }
    EXPECT_EQ(element_translates(false).n_sources(), mesh.n_elements());
    EXPECT_EQ(particle_translates(rk, false).n_sources(), mesh.n_nodes());
}

// SCNI by elements and NSNI with sharing over translates against the plain builds (every element
// and particle evaluated), on the seed's P1 cylinder at 1 in (an extruded O-grid whose layers,
// and many columns of its core, are translates): the same stencils, gradients to round-off
// (a taker's values are its source's, computed at positions that differ from its own by the
// round-off of the coordinates), the linear patch conditions to round-off, and most elements
// and particles taking their source's results. Without the drop tolerance every stencil is the
// plain one; with it a function whose value sits within round-off of the cut could be kept where
// the plain build drops it (or the other way), but on this mesh none sits that near the cut.
TEST(NodalIntegration, SharingOverTranslatesIsThePlainBuildToRoundOff)
{
    const real_t inch = 0.0254;
    const HexMesh mesh = generate_cylinder(Vec3::Zero(), 3 * inch, 12 * inch, inch, false);
    const RkShapeFunctions rk = rkfem::rk_on_mesh(mesh, RkParams{});
    const RkTranslates particles = particle_translates(rk);
    std::printf("%d elements, %d nodes; %d particle sources\n", mesh.n_elements(), mesh.n_nodes(),
                particles.n_sources());
    EXPECT_LT(particles.n_sources(), mesh.n_nodes() / 2);
    for (const real_t tau : {0.0, 1e-5})
    {
        IntegrationOperator sd, plain_sd;
        const IntegrationOperator shared = build_scni_rk(mesh, rk, tau, &sd, true);
        const IntegrationOperator plain = build_scni_rk(mesh, rk, tau, &plain_sd, false);
        EXPECT_EQ(shared.weight, plain.weight);
        EXPECT_EQ(sd.weight, plain_sd.weight);
        const real_t lin = linear_gradient_error(mesh, shared, inch);
        std::printf("tau %.0e: linear gradient error %.2e (plain %.2e)\n", tau, lin,
                    linear_gradient_error(mesh, plain, inch));
        EXPECT_LT(lin, 1e-12);
        const IntegrationOperator nsni =
            build_nsni_stabilization(shared, rk, nodal_second_moments(mesh), tau, particles);
        const IntegrationOperator nsni_plain =
            build_nsni_stabilization(plain, rk, nodal_second_moments(mesh), tau, particle_translates(rk, false));
        const real_t d = gradient_difference(shared, plain), d_sd = gradient_difference(sd, plain_sd),
                     d_nsni = gradient_difference(nsni, nsni_plain);
        std::printf("  SCNI %.2e, sub-cells %.2e, NSNI %.2e of the largest gradient\n", d, d_sd, d_nsni);
        EXPECT_LT(d, 1e-12);      // measured 2.3e-15
        EXPECT_LT(d_sd, 1e-12);   // 3.6e-15
        EXPECT_LT(d_nsni, 1e-10); // 5.5e-13: second derivatives by differences of gradients 1e-3 a apart
    }
}
