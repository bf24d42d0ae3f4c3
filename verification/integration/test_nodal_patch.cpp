// GCC 12 reports a false "may be used uninitialized" inside Eigen's AVX-512 dense kernels here.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
// ... and, in the asan (RelWithDebInfo) build, "used uninitialized" in GCC's own AVX-512
// intrinsics header (its "__m512d __Y = __Y" idiom), inlined from Eigen's packet transposes.
#pragma GCC diagnostic ignored "-Wuninitialized"
// Static linear patch test on a jittered 5x5x5-node cloud, solved with CHOLMOD on the assembled
// stiffness: SCNI, SD-SCNI and MSCNI with RK functions and with FE functions (fem-nodal) reproduce
// a linear displacement field to 1e-10; DNI does not (its error is recorded). Spurious modes:
// eigenvalues of the free block's stiffness; a stable scheme has exactly the 6 rigid-body modes.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cstdio>

#include "nodal_common.hpp"

using namespace rkfem;
using namespace rkfem::test;

namespace
{
constexpr real_t h = 0.25;
const ElasticParams mat = ElasticParams::from_E_nu(1.0, 1e3, 0.3);

/// MSCNI stabilization coefficient used by these tests (c_s = 1 reproduces SD-SCNI exactly).
constexpr real_t c_stab = 0.5;

SparseMatrix stiffness(const Operators& ops, index_t n, real_t cs = c_stab)
{
    return operator_stiffness(ops, mat, n, cs);
}

PatchResult patch_test(Scheme scheme)
{
    const HexMesh mesh = distorted_box(4, h, 0.3);
    const RkShapeFunctions rk = rk_on_mesh(mesh);
    const Operators ops = build(scheme, mesh, rk);
    RkShapes rks(rk);
    FemShapes fes(mesh);
    const bool is_rk = scheme == Scheme::RkDni || scheme == Scheme::RkScni || scheme == Scheme::RkSdScni ||
                       scheme == Scheme::RkMscni || scheme == Scheme::RkNsni;
    return linear_patch(mesh, 4 * h, ops, is_rk ? static_cast<const ShapeEvaluator&>(rks) : fes, mat, c_stab);
}

class LinearPatch : public ::testing::TestWithParam<Scheme>
{
};

struct Spectrum
{
    int zero_modes = 0;        ///< eigenvalues below 1e-8 of the largest
    real_t lowest_ratio = 0.0; ///< 7th eigenvalue (first deformation mode) / largest
};

/// Eigenvalues of the free block's stiffness (n_el^3 elements).
Spectrum spectrum(Scheme scheme, real_t jitter, int n_el = 4)
{
    const HexMesh mesh = distorted_box(n_el, h, jitter);
    const RkShapeFunctions rk = rk_on_mesh(mesh);
    const Operators ops = build(scheme, mesh, rk);
    const Eigen::MatrixXd K(stiffness(ops, mesh.n_nodes()));
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(K, Eigen::EigenvaluesOnly);
    const Eigen::VectorXd lam = es.eigenvalues();
    Spectrum sp;
    for (Eigen::Index i = 0; i < lam.size(); ++i)
        sp.zero_modes += lam[i] < 1e-8 * lam[lam.size() - 1];
    sp.lowest_ratio = lam[6] / lam[lam.size() - 1];
    return sp;
}
} // namespace

TEST_P(LinearPatch, PassesToRoundOffOnJitteredNodes)
{
    const PatchResult r = patch_test(GetParam());
    std::printf("%-18s displacement error %.2e, strain error %.2e\n", scheme_name(GetParam()), r.displacement_error,
                r.strain_error);
    EXPECT_LT(r.displacement_error, 1e-10);
    EXPECT_LT(r.strain_error, 1e-10);
}

INSTANTIATE_TEST_SUITE_P(ConformingSchemes, LinearPatch,
                         ::testing::Values(Scheme::RkScni, Scheme::RkSdScni, Scheme::RkMscni, Scheme::RkNsni,
                                           Scheme::FemScni, Scheme::FemSdScni, Scheme::FemMscni),
                         [](const auto& info) { return std::string(scheme_name(info.param)); });

// The same patch on the solids pre-processors write as degenerate hexes: each hex of the jittered
// box split into two wedges (N1 N2 N3 N3 N4 N5 N6 N6), six tetrahedra (N1 N2 N3 N3 N4 N4 N4 N4) or
// six pyramids about its centre (N1 N2 N3 N4 N5 N5 N5 N5).
// A nodal cell is still the union of the images of its element's natural octants (a node repeated
// takes the octants of both corners; the facet between them cancels, a collapsed facet has no
// area), so the cells tile the solid and their facets integrate x n dA exactly, provided the two
// solids on a triangle divide it alike: they do when both repeat the same node, which
// canonical_tetrahedra arranges (each triangle repeats its last node). Then the conforming schemes
// pass to round-off, and the meshes' nodes serve as RK particles and fem-nodal nodes. The Kuhn
// tetrahedra as split repeat different nodes on shared triangles (unmatched_triangle finds one);
// so written, SCNI missed the patch by O(1) (2026-12-07: rkpm strain error 1.25, fem-nodal 1.30).
class LinearPatchOnDegenerateSolids : public ::testing::TestWithParam<Scheme>
{
};

TEST_P(LinearPatchOnDegenerateSolids, PassesToRoundOffOnWedgesAndTetrahedra)
{
    const Scheme scheme = GetParam();
    const bool is_rk =
        scheme == Scheme::RkScni || scheme == Scheme::RkSdScni || scheme == Scheme::RkMscni || scheme == Scheme::RkNsni;
    HexMesh wedges = split_into_wedges(distorted_box(4, h, 0.3));
    wedges.faces = extract_boundary_faces(wedges.conn);
    HexMesh tets = split_into_tets(distorted_box(4, h, 0.3));
    EXPECT_GE(unmatched_triangle(tets)[0], 0) << "the split tetrahedra as written share triangles alike";
    EXPECT_GT(canonical_tetrahedra(tets), 0);
    EXPECT_EQ(unmatched_triangle(tets)[0], -1);
    EXPECT_EQ(unmatched_triangle(wedges)[0], -1);
    const HexMesh pyramids = split_into_pyramids(distorted_box(4, h, 0.3));
    EXPECT_EQ(unmatched_triangle(pyramids)[0], -1); // their triangles repeat the apex on both sides
    for (const HexMesh* mesh : std::array<const HexMesh*, 3>{&wedges, &tets, &pyramids})
    {
        const RkShapeFunctions rk = rk_on_mesh(*mesh);
        const Operators ops = build(scheme, *mesh, rk);
        RkShapes rks(rk);
        FemShapes fes(*mesh);
        const PatchResult r =
            linear_patch(*mesh, 4 * h, ops, is_rk ? static_cast<const ShapeEvaluator&>(rks) : fes, mat, c_stab);
        const char* solids = mesh == &tets ? "tetrahedra" : mesh == &pyramids ? "pyramids" : "wedges";
        std::printf("%-18s on %-10s displacement error %.2e, strain error %.2e\n", scheme_name(scheme), solids,
                    r.displacement_error, r.strain_error);
        EXPECT_LT(r.displacement_error, 1e-10) << solids;
        EXPECT_LT(r.strain_error, 1e-10) << solids;
    }
}

INSTANTIATE_TEST_SUITE_P(ConformingSchemes, LinearPatchOnDegenerateSolids,
                         ::testing::Values(Scheme::RkScni, Scheme::RkSdScni, Scheme::RkMscni, Scheme::RkNsni,
                                           Scheme::FemScni, Scheme::FemSdScni, Scheme::FemMscni),
                         [](const auto& info) { return std::string(scheme_name(info.param)); });

TEST(LinearPatch, DirectNodalIntegrationFails)
{
    const PatchResult r = patch_test(Scheme::RkDni);
    std::printf("rkpm_dni           displacement error %.2e, strain error %.2e (expected to fail)\n",
                r.displacement_error, r.strain_error);
    EXPECT_GT(r.displacement_error, 1e-4);
}

TEST(SpuriousModes, StableSchemesHaveOnlyTheSixRigidBodyModes)
{
    for (Scheme s : {Scheme::RkMscni, Scheme::RkNsni, Scheme::RkSdScni, Scheme::FemMscni, Scheme::FemSdScni})
    {
        const Spectrum sp = spectrum(s, 0.2);
        std::printf("%-18s zero-energy modes: %d, first deformation mode / max: %.2e\n", scheme_name(s), sp.zero_modes,
                    sp.lowest_ratio);
        EXPECT_EQ(sp.zero_modes, 6) << scheme_name(s);
    }
}

TEST(SpuriousModes, MscniWithUnitCoefficientIsSdScni)
{
    // sum_s V_s B_s = V_L B_L over a node's sub-cells, so the cross terms cancel and
    // K_SCNI + K_stab(c_s = 1) = K_SD-SCNI (Puso et al. 2008)
    const HexMesh mesh = distorted_box(3, h, 0.2);
    const RkShapeFunctions rk = rk_on_mesh(mesh);
    const Eigen::MatrixXd Km(stiffness(build(Scheme::RkMscni, mesh, rk), mesh.n_nodes(), 1.0));
    const Eigen::MatrixXd Ks(stiffness(build(Scheme::RkSdScni, mesh, rk), mesh.n_nodes()));
    const real_t rel = (Km - Ks).cwiseAbs().maxCoeff() / Ks.cwiseAbs().maxCoeff();
    std::printf("|K_mscni(c_s = 1) - K_sd_scni| / max|K| = %.2e\n", rel);
    EXPECT_LT(rel, 1e-13);
}

TEST(SpuriousModes, NodalSchemesWithoutStabilizationHaveNoExtraZeroMode)
{
    // on these small free blocks neither SCNI nor DNI has an exact extra zero mode (DNI's
    // saw-tooth modes vanish only at interior nodes and the boundary layer stiffens them): the
    // null space is the 6 rigid-body modes; their weakness shows as low-energy modes (printed),
    // which MSCNI stiffens
    for (Scheme s : {Scheme::RkScni, Scheme::RkNsni, Scheme::RkMscni, Scheme::FemScni, Scheme::RkDni})
        for (int n_el : {4, 6})
        {
            const Spectrum sp = spectrum(s, 0.0, n_el);
            std::printf("%-18s %d^3 regular: zero-energy modes: %d, first deformation mode / max: %.2e\n",
                        scheme_name(s), n_el, sp.zero_modes, sp.lowest_ratio);
            EXPECT_EQ(sp.zero_modes, 6) << scheme_name(s) << ", " << n_el << "^3";
        }
}
