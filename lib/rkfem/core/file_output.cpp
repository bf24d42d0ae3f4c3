#include "rkfem/core/file_output.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "rkfem/core/error.hpp"

namespace rkfem
{
void write_file_whole(const std::string& path, const std::string& text)
{
    const std::string tmp = path + ".tmp";
    {
        std::ofstream o(tmp, std::ios::binary | std::ios::trunc);
        if (!o)
            throw Error("cannot write " + path + ": cannot create " + tmp + " (" + std::strerror(errno) + ")");
        o << text;
        o.flush();
        if (!o)
        {
            const int err = errno;
            o.close();
            std::remove(tmp.c_str());
            throw Error("cannot write " + path + " (" + std::strerror(err) + ")");
        }
    }
    std::error_code ec;
    std::filesystem::rename(tmp, path, ec);
    if (ec)
    {
        std::remove(tmp.c_str());
        throw Error("cannot write " + path + " (" + ec.message() + ")");
    }
}

void require_writable_file_path(const std::string& path)
{
    std::error_code ec;
    const auto st = std::filesystem::symlink_status(path, ec);
    if (ec || st.type() == std::filesystem::file_type::not_found)
        return; // nothing there: it will be created
    if (std::filesystem::is_regular_file(std::filesystem::status(path, ec)) && !ec)
        return;
    throw Error(path + " exists and is not a regular file; expected a file rkfem can write (move what is in the way)");
}
} // namespace rkfem
