#pragma once
/// @file hdf5_dataset.hpp
/// Writing one dataset into an open HDF5 file or group (the writers' common step): real arrays
/// as IEEE 64-bit little-endian, index arrays as 32-bit integers; rows x cols, 1-D when cols = 1.
#include <algorithm>
#include <hdf5.h>
#include <string>

#include "rkfem/core/error.hpp"
#include "rkfem/core/types.hpp"

namespace rkfem
{
/// One dataset of `rows` x `cols` values of C++ type T stored as `file_type` (HDF5 converts,
/// e.g. doubles to 32-bit floats). deflate 1-9: chunks of about 64k values, byte shuffle and gzip
/// at that level (any HDF5 reader, ParaView included, inflates them); 0: contiguous, raw.
template <class T>
void write_dataset_as(hid_t loc, const char* name, const T* data, hsize_t rows, hsize_t cols, hid_t file_type,
                      hid_t memory_type, int deflate = 0)
{
    const hsize_t dims[2] = {rows, cols};
    const int rank = cols > 1 ? 2 : 1;
    const hid_t space = H5Screate_simple(rank, dims, nullptr);
    hid_t dcpl = H5P_DEFAULT;
    if (deflate > 0 && rows > 0)
    {
        dcpl = H5Pcreate(H5P_DATASET_CREATE);
        const hsize_t chunk[2] = {std::min<hsize_t>(rows, std::max<hsize_t>(1, 65536 / cols)), cols};
        H5Pset_chunk(dcpl, rank, chunk);
        H5Pset_shuffle(dcpl);
        H5Pset_deflate(dcpl, static_cast<unsigned>(deflate));
    }
    const hid_t set = H5Dcreate2(loc, name, file_type, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    if (dcpl != H5P_DEFAULT)
        H5Pclose(dcpl);
    if (set < 0)
    {
        H5Sclose(space);
        throw Error(std::string("HDF5: cannot create dataset ") + name);
    }
    const herr_t written = H5Dwrite(set, memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data);
    H5Dclose(set);
    H5Sclose(space);
    if (written < 0)
        throw Error(std::string("HDF5: cannot write dataset ") + name + " (disk full?)");
}

inline void write_dataset(hid_t loc, const char* name, const real_t* data, hsize_t rows, hsize_t cols = 1)
{
    write_dataset_as(loc, name, data, rows, cols, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE);
}

inline void write_dataset_int(hid_t loc, const char* name, const index_t* data, hsize_t rows, hsize_t cols = 1)
{
    write_dataset_as(loc, name, data, rows, cols, H5T_STD_I32LE, H5T_NATIVE_INT32);
}
} // namespace rkfem
