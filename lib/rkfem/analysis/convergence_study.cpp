#include "rkfem/analysis/convergence_study.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <hdf5.h>
#include <yaml-cpp/yaml.h>

#include "rkfem/config/deck.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/io/hdf5_dataset.hpp"

namespace rkfem
{
namespace
{
SourceLocation at(const std::string& file, const YAML::Node& n, const std::string& path)
{
    return {file + ":" + std::to_string(n.Mark().line + 1), path};
}

std::string text(const std::string& file, const YAML::Node& m, const std::string& key, const std::string& path,
                 const std::vector<std::string>& options, const std::string& fallback)
{
    if (!m[key])
        return fallback;
    const std::string v = m[key].as<std::string>();
    for (const auto& o : options)
        if (v == o)
            return v;
    std::string all;
    for (const auto& o : options)
        all += (all.empty() ? "" : " | ") + o;
    throw DeckError(at(file, m[key], path + "." + key), "'" + v + "' is not a valid choice", "expected one of " + all);
}

real_t number(const std::string& file, const YAML::Node& m, const std::string& key, const std::string& path,
              real_t fallback)
{
    if (!m[key])
        return fallback;
    try
    {
        return m[key].as<real_t>();
    }
    catch (const YAML::Exception&)
    {
        throw DeckError(at(file, m[key], path + "." + key), "is not a number", "expected a number");
    }
}

} // namespace

namespace
{
ConvergenceSweep read_sweep_checked(const std::string& path)
{
    YAML::Node root;
    const std::string source = read_deck_text(path, "a YAML sweep definition"); // regular files only
    try
    {
        root = YAML::Load(source);
    }
    catch (const YAML::Exception& e)
    {
        throw DeckError({path + ":" + std::to_string(e.mark.line + 1), "(file)"}, e.msg,
                        "expected a YAML sweep definition");
    }
    if (!root.IsMap())
        throw DeckError({path, "(file)"}, root.IsNull() ? "is empty" : "is not a YAML mapping",
                        "expected keys title, resolutions, cases (studies/sweeps/mms_smoke.yaml is an example)");
    ConvergenceSweep s;
    for (auto it = root.begin(); it != root.end(); ++it)
    {
        const std::string k = it->first.as<std::string>();
        if (k != "title" && k != "resolutions" && k != "cases")
            throw DeckError(at(path, it->first, k), "unknown key", "expected title, resolutions, cases");
    }
    s.title = root["title"] ? root["title"].as<std::string>() : "convergence";
    const YAML::Node res = root["resolutions"];
    if (!res || !res.IsSequence() || res.size() < 2)
        throw DeckError(at(path, res ? res : root, "resolutions"), "missing or too short",
                        "expected a list of at least two resolutions (elements per side), e.g. [8, 16]");
    for (std::size_t i = 0; i < res.size(); ++i)
    {
        int v = 0;
        try
        {
            v = res[i].as<int>();
        }
        catch (const YAML::Exception&)
        {
            throw DeckError(at(path, res[i], "resolutions." + std::to_string(i)), "is not an integer",
                            "expected elements per side, e.g. 8");
        }
        if (v < 2)
            throw DeckError(at(path, res[i], "resolutions." + std::to_string(i)), "is below 2",
                            "expected >= 2 elements per side");
        if (!s.resolutions.empty() && v <= s.resolutions.back())
            throw DeckError(at(path, res[i], "resolutions." + std::to_string(i)),
                            std::to_string(v) + " does not refine " + std::to_string(s.resolutions.back()),
                            "expected increasing resolutions (a rate needs two different h), e.g. [4, 8, 16]");
        s.resolutions.push_back(v);
    }
    const YAML::Node cases = root["cases"];
    if (!cases || !cases.IsSequence() || cases.size() == 0)
        throw DeckError(at(path, cases ? cases : root, "cases"), "missing or empty", "expected a list of cases");
    for (std::size_t i = 0; i < cases.size(); ++i)
    {
        const YAML::Node c = cases[i];
        const std::string p = "cases." + std::to_string(i);
        for (auto it = c.begin(); it != c.end(); ++it)
        {
            const std::string k = it->first.as<std::string>();
            static const std::vector<std::string> keys = {
                "formulation", "scheme", "stabilization", "normalized_support", "support", "kernel",
                "order",       "solver", "boundary"};
            if (std::find(keys.begin(), keys.end(), k) == keys.end())
                throw DeckError(at(path, it->first, p + "." + k), "unknown key",
                                "expected formulation, scheme, stabilization, normalized_support, support, kernel, "
                                "order, solver, boundary");
        }
        MmsCase mc;
        mc.formulation = text(path, c, "formulation", p, {"rkpm", "fem-nodal"}, "rkpm") == "rkpm"
                             ? Formulation::Rkpm
                             : Formulation::FemNodal;
        mc.scheme = text(path, c, "scheme", p, {"scni", "sd-scni", "dni", "snni", "sd-snni"}, "scni");
        if (mc.formulation == Formulation::FemNodal && (mc.scheme == "snni" || mc.scheme == "sd-snni"))
            throw DeckError(at(path, c["scheme"], p + ".scheme"),
                            mc.scheme + " integrates RK particles on their own (semi-Lagrangian) cells",
                            "expected formulation rkpm with scheme " + mc.scheme);
        if (mc.formulation == Formulation::FemNodal && mc.scheme == "dni")
            throw DeckError(
                at(path, c["scheme"], p + ".scheme"),
                "direct nodal integration of trilinear FE functions is undefined (their gradient jumps at nodes)",
                "expected scheme scni or sd-scni with formulation fem-nodal");
        mc.stabilization = number(path, c, "stabilization", p, 0.0);
        if (c["stabilization"] && mc.scheme != "scni" && mc.scheme != "snni")
            throw DeckError(at(path, c["stabilization"], p + ".stabilization"),
                            "stabilizes scheme scni (MSCNI) or snni (the face-gradient term) only",
                            "expected no stabilization with scheme " + mc.scheme);
        if (!(mc.stabilization >= 0))
            throw DeckError(at(path, c["stabilization"], p + ".stabilization"), "is negative",
                            "expected the MSCNI coefficient c_s >= 0 (0: none, 1: the RKPM2D default)");
        mc.rk.normalized_support = number(path, c, "normalized_support", p, 1.51);
        const real_t a = mc.rk.normalized_support;
        if (!(a >= 1.0 && a <= 4.0))
            throw DeckError(at(path, c["normalized_support"], p + ".normalized_support"), "is outside [1, 4]",
                            "expected a / h between 1 and 4 (box 1.5-1.8, sphere 1.6-2.0)");
        if (std::abs(a - std::round(a)) < 1e-6)
            throw DeckError(at(path, c["normalized_support"], p + ".normalized_support"), "is an integer",
                            "expected a non-integer a/h such as 1.51");
        mc.rk.support =
            text(path, c, "support", p, {"box", "sphere"}, "box") == "box" ? SupportShape::Box : SupportShape::Sphere;
        const std::string k =
            text(path, c, "kernel", p, {"cubic-bspline", "quintic-bspline", "gaussian"}, "cubic-bspline");
        mc.rk.kernel = k == "quintic-bspline" ? KernelType::QuinticBSpline
                       : k == "gaussian"      ? KernelType::Gaussian
                                              : KernelType::CubicBSpline;
        mc.rk.order = text(path, c, "order", p, {"1", "2"}, "1") == "1" ? 1 : 2;
        const std::string solver = text(path, c, "solver", p, {"auto", "direct", "pcg"}, "auto");
        mc.boundary = text(path, c, "boundary", p, {"traction", "dirichlet"}, "traction") == "dirichlet"
                          ? MmsBoundary::Dirichlet
                          : MmsBoundary::Traction;
        mc.solver = solver == "direct" ? MmsSolver::Direct : solver == "pcg" ? MmsSolver::Pcg : MmsSolver::Auto;
        for (std::size_t j = 0; j < s.cases.size(); ++j)
            if (s.cases[j].table_name() == mc.table_name())
                throw DeckError(at(path, c, p),
                                "the same case as cases." + std::to_string(j) + " (line " +
                                    std::to_string(cases[j].Mark().line + 1) + "); both would write table " +
                                    mc.table_name(),
                                "expected cases that differ in formulation, scheme, stabilization, normalized_support, "
                                "support, kernel, order, boundary or solver");
        s.cases.push_back(mc);
    }
    return s;
}
} // namespace

ConvergenceSweep read_sweep(const std::string& path)
{
    try
    {
        return read_sweep_checked(path);
    }
    catch (const YAML::Exception& e)
    {
        // a key that is not a plain name (`? [a, b]`), or a node of an unexpected kind
        throw DeckError({e.mark.is_null() ? path : path + ":" + std::to_string(e.mark.line + 1), "(file)"}, e.msg,
                        "expected a sweep whose keys are plain names");
    }
}

std::vector<std::vector<MmsResult>> run_sweep(const ConvergenceSweep& s, const std::string& out_dir, bool quiet)
{
    std::filesystem::create_directories(out_dir);
    std::vector<std::vector<MmsResult>> all;
    std::ofstream csv(out_dir + "/convergence.csv");
    csv << "case,formulation,scheme,stabilization,normalized_support,n,h,dofs,l2,h1,l2_rate,h1_rate,seconds,pcg_"
           "iterations\n";
    const hid_t f = H5Fcreate((out_dir + "/convergence.h5").c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    RKFEM_REQUIRE(f >= 0, "cannot create " << out_dir << "/convergence.h5");
    for (const MmsCase& base : s.cases)
    {
        std::vector<MmsResult> rs;
        std::vector<real_t> col[8];
        for (int n : s.resolutions)
        {
            MmsCase c = base;
            c.n = n;
            rs.push_back(solve_mms(c));
            const MmsResult& r = rs.back();
            real_t l2r = NAN, h1r = NAN;
            if (rs.size() > 1)
            {
                const MmsResult& q = rs[rs.size() - 2];
                l2r = observed_rate(q.l2, r.l2, q.h, r.h);
                h1r = observed_rate(q.h1, r.h1, q.h, r.h);
            }
            if (!quiet)
            {
                std::printf("%-24s h = 1/%-3d dofs %8d  L2 %.4e  H1 %.4e  rates %6.3f %6.3f  (%.1f s",
                            base.label().c_str(), n, r.dofs, r.l2, r.h1, l2r, h1r, r.seconds);
                if (r.iterations > 0)
                    std::printf(", %d PCG iterations", r.iterations);
                std::printf(")\n");
                std::fflush(stdout);
            }
            csv << '"' << base.label() << "\"," << (base.formulation == Formulation::Rkpm ? "rkpm" : "fem-nodal") << ','
                << base.scheme << ',' << base.stabilization << ',' << base.rk.normalized_support << ',' << n << ','
                << r.h << ',' << r.dofs << ',' << r.l2 << ',' << r.h1 << ',' << l2r << ',' << h1r << ',' << r.seconds
                << ',' << r.iterations << '\n';
            const real_t vals[8] = {
                static_cast<real_t>(n), r.h, static_cast<real_t>(r.dofs), r.l2, r.h1, l2r, h1r, r.seconds};
            for (int k = 0; k < 8; ++k)
                col[k].push_back(vals[k]);
        }
        const std::string name = base.table_name();
        const hid_t g = H5Gcreate2(f, name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
        const char* names[8] = {"n", "h", "dofs", "l2", "h1", "l2_rate", "h1_rate", "seconds"};
        for (int k = 0; k < 8; ++k)
            write_dataset(g, names[k], col[k].data(), col[k].size());
        H5Gclose(g);
        all.push_back(std::move(rs));
    }
    H5Fclose(f);
    return all;
}
} // namespace rkfem
