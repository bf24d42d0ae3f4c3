#pragma once
/// @file summary.hpp
/// DIR/summary.json: deck, resolved parameters, steps, end time, wall time, energies, balance
/// error, hourglass ratio and per-probe extrema.
#include <string>

namespace rkfem
{
class Model;
struct RunOptions;
struct RunSummary;

void write_summary_json(const std::string& path, const Model& model, const RunOptions& options,
                        const RunSummary& summary);
} // namespace rkfem
