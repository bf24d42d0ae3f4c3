#pragma once
/// @file checkpoint.hpp
/// A checkpoint file: a StateArchive as HDF5 (one 1-D byte dataset per entry, under /state,
/// attribute `format` on the root). Written to PATH.tmp, closed, then renamed over PATH, so a
/// run killed while writing leaves the previous checkpoint whole and never a partial one under
/// the name restart reads.
#include <string>

#include "rkfem/core/state_archive.hpp"

namespace rkfem
{
/// The format written and the only one read.
inline constexpr int kCheckpointFormat = 2; ///< 2: every entry with a Fletcher-32 checksum (1 still read)

/// Writes `archive` to `path` (through path + ".tmp" and a rename). Throws Error.
void write_checkpoint(const std::string& path, const StateArchive& archive);

/// Reads a checkpoint written by write_checkpoint. Throws Error naming the file when it cannot be
/// opened, is not a checkpoint, or has another format.
StateArchive read_checkpoint(const std::string& path);
/// fsync of a directory (after renames in it), so that they survive a crash of the machine;
/// errors are ignored (a file system without it).
void sync_directory(const std::string& dir);

} // namespace rkfem
