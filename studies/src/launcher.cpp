// `rkfem`: starts the driver (rkfem-core, next to it) with glibc's malloc tuned for the set-up
// (core/allocator_tuning.hpp). The driver would otherwise execute itself once more to read the
// tunables, loading its shared libraries (HDF5, SuiteSparse, SUNDIALS, GMP; about 18 ms here)
// twice; this launcher links only the C and C++ runtimes and costs about 1 ms. The driver
// still tunes itself when it is started directly.
#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstring>
#include <string>
#include <unistd.h>

#include "rkfem/core/allocator_tuning.hpp"

int main(int argc, char** argv)
{
    (void)argc;
    // the driver sits in this program's own directory
    char self[PATH_MAX];
    const ssize_t n = readlink("/proc/self/exe", self, sizeof(self) - 1);
    std::string core = "rkfem-core";
    if (n > 0)
    {
        self[n] = '\0';
        const char* slash = std::strrchr(self, '/');
        core = std::string(self, slash != nullptr ? static_cast<std::size_t>(slash - self + 1) : 0) + core;
    }
    rkfem::exec_tuned(core.c_str(), argv);
    std::fprintf(stderr, "rkfem: cannot run the driver %s: %s (it is built with rkfem, into the same directory)\n",
                 core.c_str(), std::strerror(errno));
    return 127;
}
