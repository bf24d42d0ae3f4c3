#include "rkfem/core/memory_limit.hpp"

#include <fstream>
#include <limits>
#include <string>
#include <sys/resource.h>
#include <unistd.h>

namespace rkfem
{
namespace
{
/// The first number in a file ("max" or unreadable: `otherwise`)
double read_bytes(const char* path, double otherwise = std::numeric_limits<double>::infinity())
{
    std::ifstream in(path);
    std::string word;
    if (!(in >> word) || word == "max")
        return otherwise;
    try
    {
        return std::stod(word);
    }
    catch (...)
    {
        return otherwise;
    }
}

double rlimit_bytes(int resource)
{
    rlimit r{};
    if (getrlimit(resource, &r) != 0 || r.rlim_cur == RLIM_INFINITY)
        return std::numeric_limits<double>::infinity();
    return static_cast<double>(r.rlim_cur);
}
} // namespace

MemoryLimit usable_memory()
{
    const double inf = std::numeric_limits<double>::infinity();
    MemoryLimit best{inf, "nothing could be read"};
    auto consider = [&](double bytes, const char* what)
    {
        if (bytes < best.bytes)
            best = {bytes < 0.0 ? 0.0 : bytes, what};
    };
    const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
    if (pages > 0 && page > 0)
        consider(static_cast<double>(pages) * static_cast<double>(page), "physical memory");
    // the address space in use (statm's first field, pages) counts against RLIMIT_AS
    const double as = rlimit_bytes(RLIMIT_AS);
    if (as < inf)
    {
        double in_use = 0.0;
        std::ifstream statm("/proc/self/statm");
        if (statm >> in_use && page > 0)
            in_use *= static_cast<double>(page);
        consider(as - in_use, "ulimit -v (address space)");
    }
    consider(rlimit_bytes(RLIMIT_DATA), "ulimit -d (data)");
    const double v2 = read_bytes("/sys/fs/cgroup/memory.max");
    if (v2 < inf)
        consider(v2 - read_bytes("/sys/fs/cgroup/memory.current", 0.0), "the control group's memory.max");
    const double v1 = read_bytes("/sys/fs/cgroup/memory/memory.limit_in_bytes");
    if (v1 < 1e18) // v1 writes a huge number for no limit
        consider(v1 - read_bytes("/sys/fs/cgroup/memory/memory.usage_in_bytes", 0.0),
                 "the control group's memory.limit_in_bytes");
    return best;
}
} // namespace rkfem
