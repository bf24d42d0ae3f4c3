#pragma once
/// @file stream_stores.hpp
/// Non-temporal ("streaming") stores for loops that write whole arrays far larger than the
/// caches (the ARKODE central-difference kick and solution update). A plain store first reads
/// the cache line it writes (read for ownership); a streaming store does not, so a loop that
/// reads three arrays and writes two moves five arrays through memory instead of seven. In
/// cache they would only evict what the next loop reads, so they are used past kStreamBytes
/// per array only; past it both the kick and the update gained with them
/// (measurements: docs/performance.md).
#include <algorithm>
#include <cstddef>
#include <cstdint>

#include "rkfem/core/simd.hpp"
#include "rkfem/core/types.hpp"

namespace rkfem
{
inline constexpr std::size_t kStreamBytes = std::size_t{8} << 20;

/// True when streaming stores pay off for output arrays of n values: past kStreamBytes, with
/// AVX-512.
inline bool stream_pays(index_t n)
{
#if defined(__AVX512F__)
    return static_cast<std::size_t>(n) * sizeof(real_t) > kStreamBytes;
#else
    (void)n;
    return false;
#endif
}

/// How many values from p on come before a 64-byte boundary.
inline index_t values_to_line(const real_t* p)
{
    return static_cast<index_t>(((64 - (reinterpret_cast<std::uintptr_t>(p) & 63)) & 63) / sizeof(real_t));
}

#if defined(__AVX512F__)
/// out[i] = value(i) for i in [i0, i1): whole 64-byte lines of out as 8 values from lanes(i)
/// with streaming stores, the values before the first line boundary and after the last by
/// value(i). A loop writing several arrays calls it once per array over a block that stays in
/// L1, so the inputs it reads again come from there (each array gets its own line alignment);
/// it ends its blocks with simd::stream_fence().
template <class Value, class Lanes>
inline void stream_range(index_t i0, index_t i1, real_t* out, Value&& value, Lanes&& lanes)
{
    const index_t i_line = std::min(i1, i0 + values_to_line(out + i0));
    for (; i0 < i_line; ++i0)
        out[i0] = value(i0);
    for (; i0 + 8 <= i1; i0 += 8)
        simd::stream_store(out + i0, lanes(i0));
    for (; i0 < i1; ++i0)
        out[i0] = value(i0);
}
#endif
/// The component stride of a structure-of-arrays field of n points that store_batch8 can write
/// in whole lines: n rounded up to a multiple of 8.
inline std::size_t batch8_stride(std::size_t n)
{
    return (n + 7) / 8 * 8;
}

/// Writes one batch of 8 points' K components, v[k][l], into a structure-of-arrays field out
/// (component k of point i at out[k n + i]) from point i0 on. With may_stream (the caller fences:
/// ChunkedScatter::run_chunks ends every chunk with simd::stream_fence), a field past kStreamBytes and
/// 64-byte aligned component lines (n a multiple of 8), each component is one streaming store of
/// a whole line: the field is not read for ownership (the element and particle kernels' stress
/// update writes 48 bytes per point that it would otherwise first read).
/// Returns whether it streamed.
template <int K>
inline bool store_batch8(const real_t (&v)[K][8], real_t* out, std::size_t n, std::size_t i0, bool may_stream)
{
#if defined(__AVX512F__)
    if (may_stream && n % 8 == 0 && stream_pays(static_cast<index_t>(K * n)) &&
        (reinterpret_cast<std::uintptr_t>(out + i0) & 63) == 0)
    {
        for (int k = 0; k < K; ++k)
            simd::stream_store(out + k * n + i0, simd::load(v[k]));
        return true;
    }
#else
    (void)may_stream;
#endif
    for (int k = 0; k < K; ++k)
        for (int l = 0; l < 8; ++l)
            out[k * n + i0 + l] = v[k][l];
    return false;
}
} // namespace rkfem
