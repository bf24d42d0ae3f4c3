// The material-point driver: each path against its analytic answer, and the command line.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <sys/wait.h>

#include "rkfem/analysis/material_point.hpp"
#include "rkfem/config/deck.hpp"
#include "rkfem/materials/elastic.hpp"

using namespace rkfem;

namespace
{
MaterialPointDeck deck(const std::string& model, const std::string& type, real_t strain, real_t conf = 0.0,
                       real_t angle = 0.0)
{
    MaterialPointDeck d;
    d.material.model = model;
    d.material.rho = 7850;
    d.material.E = 200e9;
    d.material.nu = 0.3;
    d.material.sigy = 400e6;
    d.material.etan = 2e9;
    d.load_path.type = type;
    d.load_path.strain = strain;
    d.load_path.rate = 1.0;
    d.load_path.confinement = conf;
    d.load_path.angle = angle;
    d.load_path.steps = 400;
    return d;
}
} // namespace

TEST(MaterialPoint, PathsAgainstAnalyticAnswers)
{
    const real_t E = 200e9, nu = 0.3;
    // uniaxial stress, bilinear J2: sigma = sigy + etan (eps - sigy/E), lateral stress 0
    {
        const auto h = run_material_point(deck("j2", "uniaxial-stress", 0.02));
        const real_t expect = 400e6 + 2e9 * (0.02 - 400e6 / E);
        EXPECT_NEAR(h.back().stress[0], expect, 1e-8 * expect);
        EXPECT_NEAR(h.back().stress[1], 0.0, 1e-6 * expect);
    }
    // uniaxial strain, elastic: sigma_xx = (lambda + 2 mu) eps, lateral lambda eps
    {
        const auto h = run_material_point(deck("elastic", "uniaxial-strain", -0.001));
        const ElasticParams el = ElasticParams::from_E_nu(7850, E, nu);
        EXPECT_NEAR(h.back().stress[0], -0.001 * el.plane_wave_modulus(), 1e-9 * 0.001 * el.plane_wave_modulus());
        EXPECT_NEAR(h.back().stress[1], -0.001 * el.lambda, 1e-9 * 0.001 * el.plane_wave_modulus());
    }
    // hydrostatic, elastic: p = -K eps_v
    {
        const auto h = run_material_point(deck("elastic", "hydrostatic", -0.003));
        const real_t K = E / (3 * (1 - 2 * nu));
        EXPECT_NEAR(h.back().stress[0], -0.003 * K, 1e-9 * 0.003 * K);
    }
    // pure shear, J2 perfectly... bilinear: tau = sigma_y(eps_p) / sqrt(3) once plastic
    {
        const auto h = run_material_point(deck("j2", "pure-shear", 0.02));
        const real_t sy = 400e6 + (200e9 * 2e9 / (200e9 - 2e9)) * h.back().plastic_strain;
        EXPECT_NEAR(h.back().stress[3], sy / std::sqrt(3.0), 1e-9 * sy);
    }
    // triaxial, elastic: lateral -p held, axial -p + E eps_axial
    {
        const auto h = run_material_point(deck("elastic", "triaxial", -0.001, 50e6));
        EXPECT_NEAR(h.back().stress[1], -50e6, 1e-6 * 50e6);
        // the axial strain of the isotropic phase is -p / (3K); the second phase adds E eps
        EXPECT_NEAR(h.back().stress[0], -50e6 - E * 0.001, 1e-6 * E * 0.001);
    }
    // rotation of a stressed point: invariants unchanged, components rotated by 90 degrees
    {
        const auto h = run_material_point(deck("elastic", "rotation", 0.001, 0.0, 0.5 * M_PI));
        const MaterialPointRecord& before = h[400];
        const MaterialPointRecord& after = h.back();
        EXPECT_NEAR(after.stress[1], before.stress[0], 1e-10 * before.stress[0]);
        EXPECT_NEAR(after.stress[0], before.stress[1], 1e-10 * before.stress[0]);
        EXPECT_NEAR(after.stress[0] + after.stress[1] + after.stress[2],
                    before.stress[0] + before.stress[1] + before.stress[2], 1e-12 * before.stress[0]);
    }
    // the same for a yielded J2 point (uniaxial strain 1 % is past yield): invariants and the
    // plastic strain unchanged by the rotation
    {
        const auto h = run_material_point(deck("j2", "rotation", 0.01, 0.0, 0.3 * M_PI));
        const MaterialPointRecord& before = h[400];
        const MaterialPointRecord& after = h.back();
        auto invariants = [](const real_t* s)
        {
            const real_t I1 = s[0] + s[1] + s[2];
            const real_t J2 =
                ((s[0] - s[1]) * (s[0] - s[1]) + (s[1] - s[2]) * (s[1] - s[2]) + (s[2] - s[0]) * (s[2] - s[0])) / 6.0 +
                s[3] * s[3] + s[4] * s[4] + s[5] * s[5];
            return std::pair{I1, J2};
        };
        const auto [i1a, j2a] = invariants(before.stress);
        const auto [i1b, j2b] = invariants(after.stress);
        EXPECT_GT(before.plastic_strain, 0.0);
        EXPECT_NEAR(after.plastic_strain, before.plastic_strain, 1e-12 * before.plastic_strain); // round-off returns
        EXPECT_NEAR(i1b, i1a, 1e-10 * std::abs(i1a));
        EXPECT_NEAR(j2b, j2a, 1e-10 * j2a);
    }
}

TEST(MaterialPoint, CommandLineWritesTheHistoryAndRejectsBadDecks)
{
    namespace fs = std::filesystem;
    const fs::path out = fs::temp_directory_path() / "rkfem_mp";
    fs::remove_all(out);
    const std::string cmd = std::string(RKFEM_EXE) + " material-point " + RKFEM_SOURCE_DIR +
                            "/studies/material_points/steel_uniaxial.yaml --out " + out.string() + " --quiet";
    ASSERT_EQ(std::system(cmd.c_str()), 0);
    std::ifstream in(out / "stress_strain.csv");
    std::string line, last;
    int rows = 0;
    while (std::getline(in, line))
        last = line, ++rows;
    EXPECT_EQ(rows, 2002); // header + initial state + 2000 steps
    // final: 10 % strain, eps_p on the 0.05-0.10 segment, sigma = sigma_y(eps_p)
    std::vector<real_t> v;
    std::stringstream ss(last);
    for (std::string cell; std::getline(ss, cell, ',');)
        v.push_back(std::stod(cell));
    const real_t ep = v[13], sy = 1026e6 + (1072e6 - 1026e6) * (ep - 0.05) / 0.05;
    EXPECT_NEAR(v[7], sy, 1e-8 * sy);
    // the HDF5 copy holds the same final stress
    {
        const hid_t f = H5Fopen((out / "stress_strain.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
        ASSERT_GE(f, 0);
        const hid_t d = H5Dopen2(f, "stress", H5P_DEFAULT);
        const hid_t s = H5Dget_space(d);
        hsize_t dims[2] = {0, 0};
        H5Sget_simple_extent_dims(s, dims, nullptr);
        std::vector<double> stress(dims[0] * dims[1]);
        H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, stress.data());
        H5Sclose(s);
        H5Dclose(d);
        H5Fclose(f);
        EXPECT_EQ(dims[0], 2001u);
        EXPECT_EQ(dims[1], 6u);
        EXPECT_NEAR(stress[6 * (dims[0] - 1)], v[7], 1e-4 * sy); // CSV holds 12 digits
    }
    // a bad deck: exit code 2, the key named
    const fs::path bad = fs::temp_directory_path() / "rkfem_mp_bad.yaml";
    std::ofstream(bad) << "material: {model: j2, rho: 7850 kg/m^3, E: 200 GPa, nu: 0.3, sigy: 400 MPa}\n"
                          "path: {type: uniaxial-stres, strain: 0.01, rate: 1 1/s}\n";
    const int rc = std::system((std::string(RKFEM_EXE) + " material-point " + bad.string() + " --out " +
                                (out / "bad").string() + " 2>/dev/null")
                                   .c_str());
    EXPECT_EQ(WEXITSTATUS(rc), 2);
    EXPECT_FALSE(fs::exists(out / "bad"));
}
