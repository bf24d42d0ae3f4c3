#include "rkfem/core/allocator_tuning.hpp"

#include <cstdlib>
#include <cstring>
#include <string>

#if defined(__linux__)
#include <unistd.h>
#endif

#if defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(memory_sanitizer) || __has_feature(thread_sanitizer)
#define RKFEM_SANITIZED 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define RKFEM_SANITIZED 1
#endif

#if defined(__linux__) && defined(__GLIBC__) && !defined(RKFEM_SANITIZED)
#define RKFEM_TUNABLE_ALLOCATOR 1
#endif

namespace rkfem
{
#if defined(RKFEM_TUNABLE_ALLOCATOR)
namespace
{
bool contains(const char* text, const char* what) { return text != nullptr && std::strstr(text, what) != nullptr; }
} // namespace
#endif

bool allocator_tunable()
{
#if defined(RKFEM_TUNABLE_ALLOCATOR)
    return true;
#else
    return false;
#endif
}

void tune_allocator(char** argv)
{
#if defined(RKFEM_TUNABLE_ALLOCATOR)
    // the marker: set before the one re-execution, so there is never a second (a process whose
    // tunables the loader dropped still runs, untuned)
    constexpr const char* marker = "RKFEM_ALLOCATOR_TUNED";
    const char* choice = std::getenv("RKFEM_ALLOCATOR");
    const char* env_tunables = std::getenv("GLIBC_TUNABLES");
    if (std::getenv(marker) != nullptr || (choice != nullptr && std::string(choice) == "default") ||
        contains(env_tunables, "glibc.malloc.hugetlb") || contains(std::getenv("LD_PRELOAD"), "vgpreload") ||
        argv == nullptr || argv[0] == nullptr)
        return;
    const bool had_tunables = env_tunables != nullptr;
    const std::string tunables = had_tunables ? env_tunables : ""; // getenv's string may not outlive setenv
    std::string value = tunables.empty() ? std::string() : tunables + ":";
    value += "glibc.malloc.hugetlb=1:glibc.malloc.top_pad=67108864";
    if (setenv(marker, "1", 1) != 0 || setenv("GLIBC_TUNABLES", value.c_str(), 1) != 0)
        return;
    execv("/proc/self/exe", argv);
    // not executed: go on untuned, with the environment as it was (the marker stays: no retry)
    if (had_tunables)
        setenv("GLIBC_TUNABLES", tunables.c_str(), 1);
    else
        unsetenv("GLIBC_TUNABLES");
#else
    (void)argv;
#endif
}
} // namespace rkfem
