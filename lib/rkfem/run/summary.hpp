#pragma once
/// @file summary.hpp
/// DIR/summary.json: deck, resolved parameters, steps, end time, wall time, energies, balance
/// error, hourglass ratio and per-probe extrema.
#include <string>

#include "rkfem/config/deck.hpp"

namespace rkfem
{
class Model;
struct RunOptions;
struct RunSummary;

/// A 16-hex-digit hash (FNV-1a, 64 bit) of the resolved deck in SI (to_yaml): two runs with the
/// same hash ran the same problem. summary.json carries it as deck_hash; studies skip on it.
std::string resolved_deck_hash(const Deck& deck);

/// A 16-hex-digit hash (FNV-1a, 64 bit) of the running executable's file (/proc/self/exe, read
/// once per process): two runs with the same id ran the same solver build. summary.json carries
/// it as `build`, and a study reuses a completed case only when both its deck_hash and its build
/// match (a rebuilt solver runs every case again). Empty where the file cannot be read; a case
/// without a build is never reused.
const std::string& solver_build_id();

/// The data files a deck reads (keyword meshes, point files), each as "absolute path<TAB>hash" on its own
/// line, the hash a 16-hex-digit FNV-1a of the file's bytes ("missing" where it cannot be read).
/// A checkpoint stores it; restart compares it with the files it finds.
std::string data_file_hashes(const Deck& deck);

void write_summary_json(const std::string& path, const Model& model, const RunOptions& options,
                        const RunSummary& summary);
} // namespace rkfem
