#pragma once
/// @file file_output.hpp
/// Writing an output file whole or not at all: the text goes to PATH.tmp, is flushed and checked,
/// and renamed over PATH; any failure (a full disk, a directory in the way, no permission) throws
/// rkfem::Error naming the file and the reason, and leaves PATH as it was.
#include <string>

namespace rkfem
{
void write_file_whole(const std::string& path, const std::string& text);

/// Throws rkfem::Error when PATH exists and is not a regular file (a directory, a device, a
/// fifo, a dangling or looping link): an output that could not be written there, said before a
/// run starts.
void require_writable_file_path(const std::string& path);
} // namespace rkfem
