#pragma once
/// @file output_spec.hpp
/// Field output storage (deck key `output: {precision, compression}`), read by the results writer.

namespace rkfem
{
/// Field output storage (results.h5): `output: {precision, compression}`.
struct OutputSpec
{
    bool single = true;  ///< fields as 32-bit floats (coordinates stay 64-bit); false: all 64-bit
    int compression = 0; ///< gzip level 0-9 (with byte shuffle); 0: none
};
} // namespace rkfem
