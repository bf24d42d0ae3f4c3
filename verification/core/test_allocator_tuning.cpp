// The driver's allocator tuning (core/allocator_tuning.hpp): the process re-executes once with
// glibc's tunables (or the `rkfem` launcher starts it with them), its heap is then advised for
// huge pages, a user's own choice is left as it is, and a run's results are the same bits tuned
// or not.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "../executable.hpp"
#include "rkfem/core/allocator_tuning.hpp"

using namespace rkfem;

namespace
{
const std::string kOurs = "glibc.malloc.hugetlb=1:glibc.malloc.top_pad=67108864";

/// The probe's line under `env` (assignments), with the variables the tuning reads cleared first.
std::string probe(const std::string& env)
{
    const test::Result r =
        test::run_shell("env -u GLIBC_TUNABLES -u RKFEM_ALLOCATOR -u RKFEM_ALLOCATOR_TUNED " + env + " " RKFEM_PROBE);
    EXPECT_EQ(r.code, 0) << r.output;
    return r.output;
}

/// Can the kernel give huge pages where asked (THP not off)?
bool thp_available()
{
    std::ifstream f("/sys/kernel/mm/transparent_hugepage/enabled");
    std::string modes;
    std::getline(f, modes);
    return !modes.empty() && modes.find("[never]") == std::string::npos;
}

std::string read_file(const std::filesystem::path& p)
{
    std::ifstream f(p, std::ios::binary);
    std::ostringstream s;
    s << f.rdbuf();
    return s.str();
}
} // namespace

TEST(AllocatorTuning, ReexecutesOnceWithGlibcsTunablesAndTheHeapIsAdvisedForHugePages)
{
    if (!allocator_tunable())
        GTEST_SKIP() << "this build does not tune (not glibc, or a sanitizer)";
    const std::string tuned = probe("");
    EXPECT_NE(tuned.find("tunables=" + kOurs + " marker=1 "), std::string::npos) << tuned;
    EXPECT_NE(tuned.find("starts=2"), std::string::npos) << tuned; // started directly: executed once more
    if (thp_available())
    {
        EXPECT_NE(tuned.find("heap_huge_advised=1"), std::string::npos) << tuned;
    }
    // untuned: the opt-out, and a process that already carries the marker (no second re-execution)
    for (const std::string env : {"RKFEM_ALLOCATOR=default", "RKFEM_ALLOCATOR_TUNED=1"})
    {
        const std::string plain = probe(env);
        EXPECT_NE(plain.find("tunables=- "), std::string::npos) << env << ": " << plain;
        EXPECT_NE(plain.find("heap_huge_advised=0"), std::string::npos) << env << ": " << plain;
    }
}

TEST(AllocatorTuning, AUsersOwnTunablesAreKept)
{
    if (!allocator_tunable())
        GTEST_SKIP() << "this build does not tune (not glibc, or a sanitizer)";
    // a hugetlb setting of the user's: left alone, no re-execution
    const std::string own = probe("GLIBC_TUNABLES=glibc.malloc.hugetlb=0");
    EXPECT_NE(own.find("tunables=glibc.malloc.hugetlb=0 marker=0 heap_huge_advised=0"), std::string::npos) << own;
    // other tunables: kept, ours after them
    const std::string other = probe("GLIBC_TUNABLES=glibc.malloc.arena_max=2");
    EXPECT_NE(other.find("tunables=glibc.malloc.arena_max=2:" + kOurs + " marker=1 "), std::string::npos) << other;
}

TEST(AllocatorTuning, TheLauncherStartsTheDriverTunedOrSaysWhyNot)
{
    // `rkfem` (studies/src/launcher.cpp) executes the rkfem-core next to it in the tuned
    // environment: here the probe stands in for the driver, in a directory of their own
    const std::filesystem::path dir = std::filesystem::temp_directory_path() / "rkfem_launcher";
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    std::filesystem::copy_file(RKFEM_EXE, dir / "rkfem");
    // without a driver beside it: a message that names the path, and status 127
    const test::Result missing = test::run_shell((dir / "rkfem").string() + " check deck.yaml 2>&1");
    EXPECT_EQ(missing.code, 127) << missing.output;
    EXPECT_NE(missing.output.find("cannot run the driver " + (dir / "rkfem-core").string()), std::string::npos)
        << missing.output;
    if (allocator_tunable())
    {
        std::filesystem::copy_file(RKFEM_PROBE, dir / "rkfem-core");
        const test::Result r = test::run_shell("env -u GLIBC_TUNABLES -u RKFEM_ALLOCATOR -u RKFEM_ALLOCATOR_TUNED " +
                                               (dir / "rkfem").string());
        EXPECT_EQ(r.code, 0) << r.output;
        // tuned on arrival, by the launcher: the driver does not execute itself again
        EXPECT_NE(r.output.find("tunables=" + kOurs + " marker=1 "), std::string::npos) << r.output;
        EXPECT_NE(r.output.find("starts=1"), std::string::npos) << r.output;
        if (thp_available())
        {
            EXPECT_NE(r.output.find("heap_huge_advised=1"), std::string::npos) << r.output;
        }
        // the opt-out reaches the driver untuned
        const std::string plain =
            test::run_shell("env -u GLIBC_TUNABLES -u RKFEM_ALLOCATOR_TUNED RKFEM_ALLOCATOR=default " +
                            (dir / "rkfem").string())
                .output;
        EXPECT_NE(plain.find("tunables=- marker=0 heap_huge_advised=0"), std::string::npos) << plain;
        EXPECT_NE(plain.find("starts=1"), std::string::npos) << plain;
    }
    std::filesystem::remove_all(dir);
}

TEST(AllocatorTuning, ARunIsTheSameBitsTunedOrNot)
{
    const std::filesystem::path dir = std::filesystem::temp_directory_path() / "rkfem_allocator_tuning";
    std::filesystem::remove_all(dir);
    const std::string args = std::string(" run ") + RKFEM_SOURCE_DIR +
                             "/studies/decks/column_wave_cloud.yaml --quiet --set time.end=2us "
                             "--set 'parts.column.generator.size=[3 mm, 3 mm, 20 mm]' --out ";
    for (const std::string env : {"RKFEM_ALLOCATOR=default", ""})
    {
        const test::Result r =
            test::run_shell("env -u GLIBC_TUNABLES -u RKFEM_ALLOCATOR -u RKFEM_ALLOCATOR_TUNED " + env + " " RKFEM_EXE +
                            args + (dir / (env.empty() ? "tuned" : "plain")).string() + " 2>&1");
        ASSERT_EQ(r.code, 0) << r.output;
    }
    const std::string plain = read_file(dir / "plain" / "history.csv"),
                      tuned = read_file(dir / "tuned" / "history.csv");
    EXPECT_GT(plain.size(), 100u);
    EXPECT_EQ(plain, tuned);
    std::filesystem::remove_all(dir);
}
