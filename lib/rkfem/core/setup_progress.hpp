#pragma once
/// @file setup_progress.hpp
/// Progress of set-up work (building a model: RK shape functions, smoothed gradients,
/// stabilization, Voronoi cells), for a user who would otherwise wait in silence. Builders name
/// a phase and its item count, and count items as they finish (from any thread); a sink the
/// driver installs gets a line once the set-up has run longer than a delay, then at most every
/// interval, and the phase's last line when it ends. Without a sink (the library's default, and
/// tests) nothing is printed and a count costs one relaxed atomic add.
#include <cstdint>
#include <functional>
#include <string>

namespace rkfem::setup_progress
{
/// Where lines go (the driver: stderr, with '\r' on a terminal); `delay`: seconds of set-up
/// before the first line; `interval`: seconds between lines. An empty sink silences.
void install(std::function<void(const std::string& line, bool last)> sink, double delay = 2.0, double interval = 0.5);
/// A phase of `total` items begins (serial code, between parallel loops).
void phase(const std::string& name, std::int64_t total);
/// `n` items of the phase are done (any thread).
void advance(std::int64_t n = 1);
/// The phase ends: its last line, if any line of it was shown.
void done();

/// A phase for the scope of a builder: begins in the constructor, ends in the destructor.
class Phase
{
  public:
    Phase(const std::string& name, std::int64_t total) { phase(name, total); }
    ~Phase() { done(); }
    Phase(const Phase&) = delete;
    Phase& operator=(const Phase&) = delete;
};
} // namespace rkfem::setup_progress
