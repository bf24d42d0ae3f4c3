// A probe for test_allocator_tuning: calls tune_allocator as the driver does, then fills a
// 64 MiB heap of small blocks (as the set-up's rows are) and prints what the process runs with:
//   tunables=<GLIBC_TUNABLES or -> marker=<0|1> heap_huge_advised=<0|1> anon_huge_kib=<n>
// heap_huge_advised: the [heap] mapping carries the kernel's 'hg' flag (madvise MADV_HUGEPAGE,
// which glibc.malloc.hugetlb=1 asks for); anon_huge_kib: the heap's AnonHugePages; starts: how
// many times main() began (the environment carries the count across an execution: 2 when
// tune_allocator executed the probe again, 1 when it arrived tuned or stayed untuned).
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "rkfem/core/allocator_tuning.hpp"

int main(int, char** argv)
{
    const char* before = std::getenv("RKFEM_PROBE_STARTS");
    const int starts = (before != nullptr ? std::atoi(before) : 0) + 1;
    setenv("RKFEM_PROBE_STARTS", std::to_string(starts).c_str(), 1);
    rkfem::tune_allocator(argv);
    std::vector<std::unique_ptr<char[]>> blocks; // 64 KiB each: below glibc's mmap threshold, so on the heap
    for (int i = 0; i < 1024; ++i)
    {
        blocks.emplace_back(new char[65536]);
        for (int k = 0; k < 65536; k += 4096)
            blocks.back()[k] = static_cast<char>(k);
    }
    std::ifstream smaps("/proc/self/smaps");
    std::string line;
    bool in_heap = false, advised = false;
    long huge_kib = 0;
    while (std::getline(smaps, line))
    {
        std::istringstream in(line);
        std::string first;
        in >> first;
        if (!first.empty() && first.back() != ':' && first.find('-') != std::string::npos)
            in_heap = line.find("[heap]") != std::string::npos; // a mapping's first line
        else if (in_heap && first == "VmFlags:")
            advised = advised || line.find(" hg") != std::string::npos;
        else if (in_heap && first == "AnonHugePages:")
        {
            long kib = 0;
            in >> kib;
            huge_kib += kib;
        }
    }
    const char* t = std::getenv("GLIBC_TUNABLES");
    std::printf("tunables=%s marker=%d heap_huge_advised=%d anon_huge_kib=%ld starts=%d\n", t ? t : "-",
                std::getenv("RKFEM_ALLOCATOR_TUNED") ? 1 : 0, advised ? 1 : 0, huge_kib, starts);
    return 0;
}
