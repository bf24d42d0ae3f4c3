#include "rkfem/run/summary.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iterator>
#include <limits>
#include <sstream>
#include <vector>

#include "rkfem/core/file_output.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/io/json_text.hpp"
#include "rkfem/io/keyword_file.hpp"
#include "rkfem/run/simulation.hpp"

namespace rkfem
{
namespace
{

std::string num(double v)
{
    if (!std::isfinite(v))
        return "null";
    std::ostringstream os;
    os << std::setprecision(12) << v;
    return os.str();
}

/// FNV-1a (64 bit) of n bytes, continuing from h
std::uint64_t fnv1a(const char* bytes, std::size_t n, std::uint64_t h = 14695981039346656037ull)
{
    for (std::size_t k = 0; k < n; ++k)
    {
        h ^= static_cast<unsigned char>(bytes[k]);
        h *= 1099511628211ull;
    }
    return h;
}

/// FNV-1a's step over 64-bit words (n a multiple of 8), continuing from h: a byte at a time the
/// multiply's latency made hashing the driver's executable a noticeable share of a short run
/// (measurements: docs/performance.md)
std::uint64_t fnv1a_words(const char* bytes, std::size_t n, std::uint64_t h)
{
    for (std::size_t k = 0; k + 8 <= n; k += 8)
    {
        std::uint64_t w;
        std::memcpy(&w, bytes + k, 8);
        h ^= w;
        h *= 1099511628211ull;
    }
    return h;
}

std::string hex16(std::uint64_t h)
{
    char text[17];
    std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(h));
    return text;
}
} // namespace

std::string resolved_deck_hash(const Deck& deck)
{
    const std::string text = to_yaml(deck);
    return hex16(fnv1a(text.data(), text.size()));
}

std::string data_file_hashes(const Deck& deck)
{
    std::string out;
    auto hash_file = [&](const std::string& f)
    {
        const std::string path = std::filesystem::absolute(f).lexically_normal().string();
        std::ifstream in(f, std::ios::binary);
        if (!in)
        {
            out += path + "\tmissing\n";
            return;
        }
        const std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
        out += path + "\t" + hex16(fnv1a(bytes.data(), bytes.size())) + "\n";
    };
    for (const PartSpec& p : deck.parts)
        for (const std::string* f : {&p.generator.mesh_file, &p.generator.points_file})
        {
            if (f->empty())
                continue;
            hash_file(*f);
            if (f != &p.generator.mesh_file || p.generator.type != GeneratorSpec::Type::Keyword)
                continue;
            // and the files a keyword mesh *INCLUDEs, in reading order (the reader's own list)
            std::vector<std::string> included;
            try
            {
                read_keyword_blocks(*f, p.generator.loc, &included);
            }
            catch (const DeckError&)
            {
                out += std::filesystem::absolute(*f).lexically_normal().string() + "\tan include unreadable\n";
            }
            for (std::size_t i = 1; i < included.size(); ++i) // [0] is the mesh file, hashed above
                hash_file(included[i]);
        }
    return out;
}

const std::string& solver_build_id()
{
    static const std::string id = []
    {
        std::ifstream in("/proc/self/exe", std::ios::binary);
        if (!in)
            return std::string();
        // the file's 64-bit words, then its last bytes one at a time
        std::uint64_t h = fnv1a(nullptr, 0);
        std::vector<char> chunk(1 << 16);
        while (in)
        {
            in.read(chunk.data(), static_cast<std::streamsize>(chunk.size()));
            const std::size_t n = static_cast<std::size_t>(in.gcount()), whole = n / 8 * 8;
            h = fnv1a(chunk.data() + whole, n - whole, fnv1a_words(chunk.data(), whole, h));
        }
        return hex16(h);
    }();
    return id;
}

void write_summary_json(const std::string& path, const Model& model, const RunOptions& opt, const RunSummary& s)
{
    std::ostringstream o; // written whole at the end (write_file_whole)
    const Energies& e = s.energy;
    o << "{\n";
    o << "  \"deck\": " << json_quote(opt.deck_path) << ",\n";
    o << "  \"title\": " << json_quote(model.deck().title) << ",\n";
    o << "  \"overrides\": [";
    for (std::size_t i = 0; i < opt.overrides.size(); ++i)
        o << (i ? ", " : "") << json_quote(opt.overrides[i]);
    o << "],\n";
    o << "  \"resolved_deck_si\": " << json_quote(to_yaml(model.deck())) << ",\n";
    o << "  \"deck_hash\": " << json_quote(resolved_deck_hash(model.deck())) << ",\n";
    o << "  \"build\": " << json_quote(solver_build_id()) << ",\n";
    o << "  \"status\": " << json_quote(s.status) << ",\n";
    o << "  \"run_id\": " << json_quote(s.run_id) << ",\n";
    o << "  \"message\": " << json_quote(s.message) << ",\n";
    o << "  \"setup_notes\": [";
    for (std::size_t i = 0; i < model.setup_notes.size(); ++i)
        o << (i ? ", " : "") << json_quote(model.setup_notes[i]);
    o << "],\n";
    o << "  \"nodes\": " << model.nodes.size() << ",\n";
    o << "  \"elements\": " << model.n_elements() << ",\n";
    o << "  \"eroded_elements\": " << model.eroded_elements() << ",\n";
    o << "  \"converted_elements\": " << model.converted_elements() << ",\n";
    o << "  \"reverted_elements\": " << model.reverted_elements() << ",\n";
    o << "  \"refined_particles\": " << model.refined_particles() << ",\n";
    o << "  \"coarsened_particles\": " << model.coarsened_particles() << ",\n";
    o << "  \"threads\": " << max_threads() << ",\n";
    o << "  \"thread_switches\": " << s.thread_switches << ",\n";
    o << "  \"steps_on_one_thread\": " << s.steps_on_one_thread << ",\n";
    o << "  \"steps\": " << s.steps << ",\n";
    o << "  \"history_rows\": " << (s.history_columns.empty() ? 0 : s.history.size() / s.history_columns.size())
      << ",\n";
    o << "  \"end_time\": " << num(s.end_time) << ",\n";
    if (s.failed_time >= 0.0)
        o << "  \"failed_time\": " << num(s.failed_time) << ",\n";
    o << "  \"wall_seconds\": " << num(s.wall_seconds) << ",\n";
    o << "  \"setup_seconds\": " << num(s.setup_seconds) << ",\n";
    o << "  \"stepping_seconds\": " << num(s.stepping_seconds) << ",\n";
    o << "  \"output_seconds\": " << num(s.output_seconds) << ",\n";
    o << "  \"events\": " << s.events << ",\n";
    o << "  \"event_seconds\": " << num(s.event_seconds) << ",\n";
    o << "  \"work_items\": " << model.n_work_items() << ",\n";
    o << "  \"ns_per_element_cycle\": " << num(s.ns_per_element_cycle) << ",\n";
    o << "  \"seconds_per_step\": " << num(s.steps > 0 ? s.stepping_seconds / s.steps : 0.0) << ",\n";
    o << "  \"dt_first\": " << num(s.dt_first) << ",\n";
    o << "  \"dt_min\": " << num(s.dt_min) << ",\n";
    o << "  \"dt_mean\": " << num(s.steps > 0 ? s.end_time / s.steps : 0.0) << ",\n";
    o << "  \"max_plastic_strain\": " << num(s.max_plastic_strain) << ",\n";
    o << "  \"outputs\": " << s.n_outputs << ",\n";
    o << "  \"energy\": {\"kinetic\": " << num(e.kinetic) << ", \"internal\": " << num(e.internal)
      << ", \"hourglass\": " << num(e.hourglass) << ", \"bulk_viscosity\": " << num(e.bulk_viscosity)
      << ", \"contact\": " << num(e.contact) << ", \"eroded\": " << num(e.eroded) << ", \"damping\": " << num(e.damping)
      << ", \"external_work\": " << num(e.external_work) << ", \"kinetic0\": " << num(e.kinetic0)
      << ", \"internal0\": " << num(e.internal0) << "},\n";
    o << "  \"balance_error\": " << num(e.balance_error()) << ",\n";
    o << "  \"max_balance_error\": " << num(s.max_balance_error) << ",\n";
    o << "  \"hourglass_ratio\": " << num(e.hourglass_ratio()) << ",\n";
    o << "  \"hourglass_to_total\": " << num(e.hourglass_to_total()) << ",\n";
    if (!model.contacts.empty())
    {
        o << "  \"contacts\": [";
        for (std::size_t k = 0; k < model.contacts.size(); ++k)
        {
            const Vec3 f = model.contacts[k]->resultant();
            o << (k ? ", " : "") << "{\"initial_penetrations\": " << model.contacts[k]->initial_penetrations()
              << ", \"active_nodes\": " << model.contacts[k]->active_nodes() << ", \"resultant\": [" << num(f[0])
              << ", " << num(f[1]) << ", " << num(f[2]) << "]}";
        }
        o << "],\n";
    }
    if (s.has_impact)
    {
        const ImpactMeasures& im = s.impact;
        o << "  \"impact\": {\"apparent_depth\": " << num(im.apparent_depth)
          << ", \"actual_depth\": " << num(im.actual_depth) << ", \"crater_depth\": " << num(im.crater_depth)
          << ", \"crater_diameter\": " << num(im.crater_diameter) << ", \"crater_volume\": " << num(im.crater_volume)
          << ", \"residual_velocity\": " << num(im.residual_velocity)
          << ", \"projectile_mass\": " << num(im.projectile_mass)
          << ", \"target_momentum\": " << num(im.target_momentum)
          << ", \"damaged_volume_0.5\": " << num(im.damaged_volume_half)
          << ", \"damaged_volume_threshold\": " << num(im.damaged_volume_threshold)
          << ", \"eroded_mass\": " << num(im.eroded_mass) << "},\n";
    }
    if (s.has_spall)
        o << "  \"spall\": {\"thickness\": " << num(s.spall.thickness)
          << ", \"fly_off_velocity\": " << num(s.spall.fly_off_velocity)
          << ", \"back_face_velocity\": " << num(s.spall.back_face_velocity) << "},\n";
    // each part's extent at the end (its nodes' current positions; nodes of eroded elements
    // included): a Taylor bar's final length and foot
    o << "  \"parts\": {";
    for (std::size_t ip = 0; ip < model.parts.size(); ++ip)
    {
        const PartInfo& part = model.parts[ip];
        Vec3 lo = Vec3::Constant(std::numeric_limits<real_t>::infinity()), hi = -lo;
        for (index_t i = part.node_begin; i < part.node_end; ++i)
        {
            const std::size_t k = 3 * static_cast<std::size_t>(i);
            const Vec3 x(model.nodes.x[k], model.nodes.x[k + 1], model.nodes.x[k + 2]);
            lo = lo.cwiseMin(x);
            hi = hi.cwiseMax(x);
        }
        o << (ip ? ",\n" : "\n") << "    " << json_quote(part.name) << ": {";
        const char* axis = "xyz";
        for (int d = 0; d < 3; ++d)
            o << (d ? ", " : "") << "\"" << axis[d] << "min\": " << num(lo[d]) << ", \"" << axis[d]
              << "max\": " << num(hi[d]) << ", \"length_" << axis[d] << "\": " << num(hi[d] - lo[d]);
        o << "}";
    }
    o << "},\n";
    o << "  \"probes\": {";
    const std::size_t nc = s.history_columns.size();
    const std::size_t nr = nc ? s.history.size() / nc : 0;
    const auto& probes = model.deck().probes;
    const std::size_t first_probe_column = nc - 12 * probes.size(); // probes' 12 columns each come last
    for (std::size_t p = 0; p < probes.size(); ++p)
    {
        o << (p ? ",\n" : "\n") << "    " << json_quote(probes[p].name) << ": {\"node\": " << model.probe_nodes[p];
        for (std::size_t q = 0; q < 12; ++q)
        {
            const std::size_t col = first_probe_column + 12 * p + q;
            double lo = kNoLimit, hi = -kNoLimit;
            for (std::size_t r = 0; r < nr; ++r)
            {
                lo = std::min(lo, s.history[r * nc + col]);
                hi = std::max(hi, s.history[r * nc + col]);
            }
            o << ", " << json_quote(s.history_columns[col].substr(probes[p].name.size() + 1))
              << ": {\"min\": " << num(nr ? lo : 0) << ", \"max\": " << num(nr ? hi : 0) << "}";
        }
        o << "}";
    }
    o << (probes.empty() ? "}\n" : "\n  }\n");
    o << "}\n";
    write_file_whole(path, o.str());
}
} // namespace rkfem
