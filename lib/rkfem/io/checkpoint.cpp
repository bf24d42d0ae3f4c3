#include "rkfem/io/checkpoint.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <hdf5.h>
#include <unistd.h>

#include "rkfem/core/error.hpp"

namespace rkfem
{
namespace
{
/// HDF5's own error stack printing off while `work` runs (a missing or damaged file is reported
/// by rkfem, in one line).
template <class F> auto quietly(F&& work)
{
    H5E_auto2_t func = nullptr;
    void* data = nullptr;
    H5Eget_auto2(H5E_DEFAULT, &func, &data);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    struct Restore
    {
        H5E_auto2_t f;
        void* d;
        ~Restore() { H5Eset_auto2(H5E_DEFAULT, f, d); }
    } restore{func, data};
    return work();
}
} // namespace

void write_checkpoint(const std::string& path, const StateArchive& archive)
{
    const std::string tmp = path + ".tmp";
    quietly(
        [&]
        {
            const hid_t f = H5Fcreate(tmp.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
            if (f < 0)
                throw Error("cannot create checkpoint " + tmp);
            bool ok = true;
            const hid_t g = H5Gcreate2(f, "state", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
            ok = ok && g >= 0;
            for (const auto& [name, bytes] : archive.entries())
            {
                if (!ok)
                    break;
                const hsize_t n = bytes.size();
                const hid_t space = H5Screate_simple(1, &n, nullptr);
                // a Fletcher-32 checksum per chunk (HDF5's filter, checked by every read): a
                // changed byte makes the restart refuse the checkpoint instead of running on it
                hid_t dcpl = H5P_DEFAULT;
                if (n > 0)
                {
                    dcpl = H5Pcreate(H5P_DATASET_CREATE);
                    const hsize_t chunk = std::min<hsize_t>(n, hsize_t{1} << 22);
                    H5Pset_chunk(dcpl, 1, &chunk);
                    H5Pset_fletcher32(dcpl);
                }
                const hid_t set = H5Dcreate2(g, name.c_str(), H5T_NATIVE_UCHAR, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
                if (dcpl != H5P_DEFAULT)
                    H5Pclose(dcpl);
                ok = set >= 0 &&
                     (n == 0 || H5Dwrite(set, H5T_NATIVE_UCHAR, H5S_ALL, H5S_ALL, H5P_DEFAULT, bytes.data()) >= 0);
                if (set >= 0)
                    H5Dclose(set);
                H5Sclose(space);
            }
            if (g >= 0)
                H5Gclose(g);
            const int format = kCheckpointFormat;
            const hid_t as = H5Screate(H5S_SCALAR);
            const hid_t a = H5Acreate2(f, "format", H5T_NATIVE_INT, as, H5P_DEFAULT, H5P_DEFAULT);
            ok = ok && a >= 0 && H5Awrite(a, H5T_NATIVE_INT, &format) >= 0;
            if (a >= 0)
                H5Aclose(a);
            H5Sclose(as);
            ok = H5Fclose(f) >= 0 && ok;
            if (!ok)
            {
                std::remove(tmp.c_str());
                throw Error("cannot write checkpoint " + tmp + " (disk full?)");
            }
        });
    // the file's bytes on the disk before its name says it is whole
    if (const int fd = ::open(tmp.c_str(), O_RDONLY | O_CLOEXEC); fd >= 0)
    {
        const int rc = ::fsync(fd);
        ::close(fd);
        if (rc != 0)
        {
            std::remove(tmp.c_str());
            throw Error("cannot write checkpoint " + tmp + " (fsync: " + std::strerror(errno) + ")");
        }
    }
    std::error_code ec;
    std::filesystem::rename(tmp, path, ec);
    if (ec)
        throw Error("cannot rename " + tmp + " to " + path + ": " + ec.message());
    sync_directory(std::filesystem::path(path).parent_path().string());
}

void sync_directory(const std::string& dir)
{
    if (const int fd = ::open(dir.empty() ? "." : dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC); fd >= 0)
    {
        ::fsync(fd);
        ::close(fd);
    }
}

StateArchive read_checkpoint(const std::string& path)
{
    return quietly(
        [&]
        {
            std::error_code ec; // a link loop or an unreadable folder: no checkpoint, not an exception
            if (!std::filesystem::is_regular_file(path, ec))
                throw Error("no checkpoint " + path + " (run with --checkpoint-interval writes one)");
            const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
            if (f < 0)
                throw Error("cannot open checkpoint " + path + ": not an HDF5 file, or damaged");
            StateArchive archive;
            int format = -1;
            const hid_t a = H5Aexists(f, "format") > 0 ? H5Aopen(f, "format", H5P_DEFAULT) : -1;
            if (a >= 0)
            {
                H5Aread(a, H5T_NATIVE_INT, &format);
                H5Aclose(a);
            }
            const hid_t g = H5Lexists(f, "state", H5P_DEFAULT) > 0 ? H5Gopen2(f, "state", H5P_DEFAULT) : -1;
            if ((format != kCheckpointFormat && format != 1) || g < 0) // 1: before checksums
            {
                if (g >= 0)
                    H5Gclose(g);
                H5Fclose(f);
                throw Error("checkpoint " + path + " has format " + std::to_string(format) +
                            "; this rkfem reads format " + std::to_string(kCheckpointFormat));
            }
            hsize_t n = 0;
            H5Gget_num_objs(g, &n);
            bool ok = true;
            std::vector<unsigned char> bytes;
            for (hsize_t i = 0; i < n && ok; ++i)
            {
                char name[512];
                if (H5Gget_objname_by_idx(g, i, name, sizeof name) < 0)
                {
                    ok = false;
                    break;
                }
                const hid_t set = H5Dopen2(g, name, H5P_DEFAULT);
                const hid_t space = set >= 0 ? H5Dget_space(set) : -1;
                const hssize_t count = space >= 0 ? H5Sget_simple_extent_npoints(space) : -1;
                ok = count >= 0;
                if (ok)
                {
                    bytes.resize(static_cast<std::size_t>(count));
                    ok = count == 0 || H5Dread(set, H5T_NATIVE_UCHAR, H5S_ALL, H5S_ALL, H5P_DEFAULT, bytes.data()) >= 0;
                    archive.put_bytes(name, bytes.data(), bytes.size());
                }
                if (space >= 0)
                    H5Sclose(space);
                if (set >= 0)
                    H5Dclose(set);
            }
            H5Gclose(g);
            H5Fclose(f);
            if (!ok)
                throw Error("checkpoint " + path +
                            " is damaged (an entry cannot be read, or its checksum does not match)");
            return archive;
        });
}
} // namespace rkfem
