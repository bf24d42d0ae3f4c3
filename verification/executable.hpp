#pragma once
// Running the rkfem executable (RKFEM_EXE, set by verification/CMakeLists.txt) from a test:
// its output (stdout; callers add 2>&1 for stderr) and exit code.
#include <array>
#include <cstdio>
#include <string>
#include <sys/wait.h>

namespace rkfem::test
{
struct Result
{
    int code = -1;
    std::string output;
};

/// Runs a shell command line and collects its stdout and exit code.
inline Result run_shell(const std::string& cmd)
{
    Result r;
    FILE* p = popen(cmd.c_str(), "r");
    std::array<char, 4096> buf;
    while (fgets(buf.data(), buf.size(), p))
        r.output += buf.data();
    const int status = pclose(p);
    r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return r;
}

/// Runs the rkfem executable with these arguments, stdout and stderr together.
inline Result run(const std::string& args)
{
    return run_shell(std::string(RKFEM_EXE) + " " + args + " 2>&1");
}
} // namespace rkfem::test
