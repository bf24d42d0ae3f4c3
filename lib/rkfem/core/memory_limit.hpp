#pragma once
/// @file memory_limit.hpp
/// How much more memory this process may take: the smallest of the machine's physical memory,
/// what `ulimit -v` (RLIMIT_AS) leaves beyond the address space in use, `ulimit -d`
/// (RLIMIT_DATA), and what the control group's limit (cgroup v2 memory.max, v1
/// memory.limit_in_bytes) leaves beyond its current use. Set-up compares a model's estimated
/// size with it, so that a model too large is refused with the deck's key before it allocates.

namespace rkfem
{
struct MemoryLimit
{
    double bytes = 0.0;    ///< usable; infinity when nothing could be read
    const char* what = ""; ///< which bound it is ("physical memory", "ulimit -v", ...)
};
MemoryLimit usable_memory();
} // namespace rkfem
