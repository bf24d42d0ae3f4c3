#include "rkfem/core/allocator_tuning.hpp"

#include <cstdlib>
#include <cstring>
#include <string>

#if defined(__unix__)
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
bool contains(const char* text, const char* what)
{
    return text != nullptr && std::strstr(text, what) != nullptr;
}
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

#if defined(RKFEM_TUNABLE_ALLOCATOR)
namespace
{
/// The environment as it was before set_tuned_environment, to put back when an exec fails.
struct SavedEnvironment
{
    bool had_tunables = false;
    std::string tunables;
};

/// Sets the marker and GLIBC_TUNABLES for a tuned process; false (and the environment as it
/// was) where tuning does not apply: already tuned or marked, the user's own hugetlb choice,
/// RKFEM_ALLOCATOR=default, valgrind.
bool set_tuned_environment(SavedEnvironment& saved)
{
    // the marker: set before the one (re-)execution, so there is never a second (a process whose
    // tunables the loader dropped still runs, untuned)
    constexpr const char* marker = "RKFEM_ALLOCATOR_TUNED";
    const char* choice = std::getenv("RKFEM_ALLOCATOR");
    const char* env_tunables = std::getenv("GLIBC_TUNABLES");
    if (std::getenv(marker) != nullptr || (choice != nullptr && std::string(choice) == "default") ||
        contains(env_tunables, "glibc.malloc.hugetlb") || contains(std::getenv("LD_PRELOAD"), "vgpreload"))
        return false;
    saved.had_tunables = env_tunables != nullptr;
    saved.tunables = saved.had_tunables ? env_tunables : ""; // getenv's string may not outlive setenv
    std::string value = saved.tunables.empty() ? std::string() : saved.tunables + ":";
    value += "glibc.malloc.hugetlb=1:glibc.malloc.top_pad=67108864";
    return setenv(marker, "1", 1) == 0 && setenv("GLIBC_TUNABLES", value.c_str(), 1) == 0;
}

/// Puts GLIBC_TUNABLES back (the marker stays: no retry).
void restore_environment(const SavedEnvironment& saved)
{
    if (saved.had_tunables)
        setenv("GLIBC_TUNABLES", saved.tunables.c_str(), 1);
    else
        unsetenv("GLIBC_TUNABLES");
}
} // namespace
#endif

void tune_allocator(char** argv)
{
#if defined(RKFEM_TUNABLE_ALLOCATOR)
    if (argv == nullptr || argv[0] == nullptr)
        return;
    SavedEnvironment saved;
    if (!set_tuned_environment(saved))
        return;
    execv("/proc/self/exe", argv);
    // not executed: go on untuned, with the environment as it was
    restore_environment(saved);
#else
    (void)argv;
#endif
}

void exec_tuned(const char* path, char** argv)
{
#if defined(RKFEM_TUNABLE_ALLOCATOR)
    SavedEnvironment saved;
    const bool tuned = set_tuned_environment(saved);
    execv(path, argv);
    if (tuned)
        restore_environment(saved);
#elif defined(__unix__)
    execv(path, argv);
#else
    (void)path;
    (void)argv;
#endif
}
} // namespace rkfem
