#pragma once
/// @file study_detail.hpp
/// What the study driver's files share (internal to run/): study_read.cpp reads a study file,
/// study_metrics.cpp reads a case's history and summary and extracts its metrics, study_write.cpp
/// writes the table, study.cpp runs the cases.
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "rkfem/run/study.hpp"

namespace rkfem::study_detail
{
namespace fs = std::filesystem;
inline constexpr real_t nan = std::numeric_limits<real_t>::quiet_NaN();

/// A message on one line (newlines become "; ").
std::string one_line(std::string s);
/// table.csv, table.md and the table in table.h5 of a study's results, each written whole or not at all.
void write_outputs(const Study& st, const std::vector<StudyCaseResult>& results, const fs::path& out);
} // namespace rkfem::study_detail
