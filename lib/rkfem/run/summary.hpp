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

void write_summary_json(const std::string& path, const Model& model, const RunOptions& options,
                        const RunSummary& summary);
} // namespace rkfem
