#pragma once
/// @file simd.hpp
/// RKFEM_WIDE_VECTORS marks a kernel whose lane loops are 8 doubles wide (batches of 8 elements
/// or points): it asks GCC for 512-bit vectors where the CPU has AVX-512. GCC 12 prefers 256-bit
/// vectors on AVX-512 CPUs, which halves these loops' width; other kernels keep that default
/// (the 2x2x2 hex kernel is slower with 512-bit vectors; measurements: docs/performance.md).
/// Elsewhere it does nothing.
#if defined(__AVX512F__)
#define RKFEM_WIDE_VECTORS __attribute__((target("prefer-vector-width=512")))
#else
#define RKFEM_WIDE_VECTORS
#endif

#include <cmath>
#include <cstdint>
#include <cstring>
#include <type_traits>

/// Marks a small scalar routine whose indexed loads and stores GCC's vectorizers would turn into
/// gathers and scatters on the stack (a 4 x 4 factorization that pivots through an index): each
/// scatter stalls the scalar loads that follow it. The routine is then called, not inlined.
#if defined(__GNUC__) && !defined(__clang__)
#define RKFEM_SCALAR_CODE __attribute__((optimize("no-tree-vectorize", "no-tree-slp-vectorize")))
#else
#define RKFEM_SCALAR_CODE
#endif

/// Inlined into the batch kernels whatever the size heuristics say: their arguments are arrays
/// of lane vectors, which stay in registers only when the call is inlined.
#define RKFEM_LANE_INLINE inline __attribute__((always_inline))

#include <immintrin.h>

#if !defined(__AVX512F__)
// In a build for the SSE2 baseline GCC notes that a 32-byte vector passed by value has another
// ABI where AVX is enabled (once per translation unit, wherever dvec first crosses a call): the
// lane helpers and kernels are inline or internal, no such call crosses a library boundary.
#pragma GCC diagnostic ignored "-Wpsabi"
#endif

namespace rkfem::simd
{
/// A lane vector of kLanes doubles for the batch kernels (one batch of kLanes elements, one
/// register): 8 in an AVX-512 register where the CPU has one, else 4 in GCC's generic vector
/// (an AVX register; lowered to what the CPU has). Eight lanes without AVX-512 took two
/// registers each and spilled with 16 of them: the 1-point hex kernel ran far slower on an AVX2
/// machine (measurements: docs/performance.md). Arithmetic operators work on it directly; the
/// helpers below add the fused multiply-add, sqrt, min and max. The same helpers on real_t let
/// templates run on scalars: there mul_add is the expression a * b + c, so scalar callers
/// compile as they did when they wrote it out (GCC contracts it to an FMA where the CPU has
/// one, as it does the written form).
#if defined(__AVX512F__)
using dvec = __m512d;
inline constexpr int kLanes = 8;
inline dvec broadcast(double a)
{
    return _mm512_set1_pd(a);
}
inline dvec load(const double* p)
{
    return _mm512_loadu_pd(p);
}
inline void store(double* p, dvec a)
{
    _mm512_storeu_pd(p, a);
}
/// a b + c, fused
inline dvec mul_add(dvec a, dvec b, dvec c)
{
    return _mm512_fmadd_pd(a, b, c);
}
/// c - a b, fused
inline dvec neg_mul_add(dvec a, dvec b, dvec c)
{
    return _mm512_fnmadd_pd(a, b, c);
}
inline dvec sqrt(dvec a)
{
    return _mm512_sqrt_pd(a);
}
/// std::min's lane rule, (b < a) ? b : a (a NaN a is kept)
// (a compare and a blend: GCC 12's _mm512_min_pd / _mm512_max_pd start from an undefined
// source that -Wuninitialized reports wherever they are inlined)
inline dvec min(dvec a, dvec b)
{
    return _mm512_mask_blend_pd(_mm512_cmp_pd_mask(b, a, _CMP_LT_OQ), a, b);
}
/// std::max's lane rule, (a < b) ? b : a (a NaN a is kept)
inline dvec max(dvec a, dvec b)
{
    return _mm512_mask_blend_pd(_mm512_cmp_pd_mask(a, b, _CMP_LT_OQ), a, b);
}
/// v where x < 0, else 0
inline dvec where_negative(dvec x, dvec v)
{
    return _mm512_maskz_mov_pd(_mm512_cmp_pd_mask(x, _mm512_setzero_pd(), _CMP_LT_OQ), v);
}
#else
typedef double dvec __attribute__((vector_size(32)));
inline constexpr int kLanes = 4;
inline dvec broadcast(double a)
{
    return dvec{} + a;
}
inline dvec load(const double* p)
{
    dvec r;
    std::memcpy(&r, p, sizeof r);
    return r;
}
inline void store(double* p, dvec a)
{
    std::memcpy(p, &a, sizeof a);
}
inline dvec mul_add(dvec a, dvec b, dvec c)
{
    return a * b + c;
}
inline dvec neg_mul_add(dvec a, dvec b, dvec c)
{
    return c - a * b;
}
inline dvec sqrt(dvec a)
{
    for (int l = 0; l < kLanes; ++l)
        a[l] = std::sqrt(a[l]);
    return a;
}
inline dvec min(dvec a, dvec b)
{
    return b < a ? b : a;
}
inline dvec max(dvec a, dvec b)
{
    return a < b ? b : a;
}
inline dvec where_negative(dvec x, dvec v)
{
    return x < 0.0 ? v : dvec{};
}
#endif
inline double mul_add(double a, double b, double c)
{
    return a * b + c;
}
inline double neg_mul_add(double a, double b, double c)
{
    return c - a * b;
}
/// A scalar operand among lane vectors is broadcast.
inline dvec lanes(double a)
{
    return broadcast(a);
}
inline dvec lanes(dvec a)
{
    return a;
}
template <class A, class B, class C>
requires(!(std::is_same_v<A, double> && std::is_same_v<B, double> && std::is_same_v<C, double>)) inline dvec
    mul_add(A a, B b, C c)
{
    return mul_add(lanes(a), lanes(b), lanes(c));
}
template <class A, class B, class C>
requires(!(std::is_same_v<A, double> && std::is_same_v<B, double> && std::is_same_v<C, double>)) inline dvec
    neg_mul_add(A a, B b, C c)
{
    return neg_mul_add(lanes(a), lanes(b), lanes(c));
}
inline double min(double a, double b)
{
    return b < a ? b : a;
}
inline double max(double a, double b)
{
    return a < b ? b : a;
}
inline double sqrt(double a)
{
    return std::sqrt(a);
}
inline double where_negative(double x, double v)
{
    return x < 0.0 ? v : 0.0;
}
/// a scalar as T: itself for real_t, broadcast for a lane vector
template <class T> inline T lanes_like(double a)
{
    if constexpr (std::is_same_v<T, double>)
        return a;
    else
        return broadcast(a);
}

#if defined(__AVX512F__)
/// Eight (x, y, z) triples, node-major in a, b, c (x0 y0 z0 x1 ... z7), to one vector per
/// component (lane l = triple l): two two-source permutes per component.
inline void deinterleave3(__m512d a, __m512d b, __m512d c, __m512d& X, __m512d& Y, __m512d& Z)
{
    // X = a0 a3 a6 b1 b4 b7 c2 c5, Y = a1 a4 a7 b2 b5 c0 c3 c6, Z = a2 a5 b0 b3 b6 c1 c4 c7
    const __m512d xab = _mm512_permutex2var_pd(a, _mm512_setr_epi64(0, 3, 6, 9, 12, 15, 0, 0), b);
    const __m512d yab = _mm512_permutex2var_pd(a, _mm512_setr_epi64(1, 4, 7, 10, 13, 0, 0, 0), b);
    const __m512d zab = _mm512_permutex2var_pd(a, _mm512_setr_epi64(2, 5, 8, 11, 14, 0, 0, 0), b);
    X = _mm512_permutex2var_pd(xab, _mm512_setr_epi64(0, 1, 2, 3, 4, 5, 10, 13), c);
    Y = _mm512_permutex2var_pd(yab, _mm512_setr_epi64(0, 1, 2, 3, 4, 8, 11, 14), c);
    Z = _mm512_permutex2var_pd(zab, _mm512_setr_epi64(0, 1, 2, 3, 4, 9, 12, 15), c);
}

/// The triples of 8 consecutive nodes from p[0..23] (node-major), one vector per component.
inline void load_triples(const double* p, __m512d& X, __m512d& Y, __m512d& Z)
{
    deinterleave3(_mm512_loadu_pd(p), _mm512_loadu_pd(p + 8), _mm512_loadu_pd(p + 16), X, Y, Z);
}

/// deinterleave3's inverse: one vector per component to eight (x, y, z) triples, node-major in
/// a, b, c (x0 y0 z0 x1 ... z7).
inline void interleave3(__m512d X, __m512d Y, __m512d Z, __m512d& a, __m512d& b, __m512d& c)
{
    // a = X0 Y0 Z0 X1 Y1 Z1 X2 Y2, b = Z2 X3 Y3 Z3 X4 Y4 Z4 X5, c = Y5 Z5 X6 Y6 Z6 X7 Y7 Z7
    const __m512d xya = _mm512_permutex2var_pd(X, _mm512_setr_epi64(0, 8, 0, 1, 9, 0, 2, 10), Y);
    const __m512d xyb = _mm512_permutex2var_pd(X, _mm512_setr_epi64(0, 3, 11, 0, 4, 12, 0, 5), Y);
    const __m512d xyc = _mm512_permutex2var_pd(X, _mm512_setr_epi64(13, 0, 6, 14, 0, 7, 15, 0), Y);
    a = _mm512_permutex2var_pd(xya, _mm512_setr_epi64(0, 1, 8, 3, 4, 9, 6, 7), Z);
    b = _mm512_permutex2var_pd(xyb, _mm512_setr_epi64(10, 1, 2, 11, 4, 5, 12, 7), Z);
    c = _mm512_permutex2var_pd(xyc, _mm512_setr_epi64(0, 13, 2, 3, 14, 5, 6, 15), Z);
}

/// load_triples' inverse: the components of 8 consecutive triples to p[0..23] (node-major).
inline void store_triples(double* p, __m512d X, __m512d Y, __m512d Z)
{
    __m512d a, b, c;
    interleave3(X, Y, Z, a, b, c);
    _mm512_storeu_pd(p, a);
    _mm512_storeu_pd(p + 8, b);
    _mm512_storeu_pd(p + 16, c);
}

/// One vector per component to 8 padded quadruples (x, y, z, 0), two per output vector:
/// q[k] holds lanes 2k and 2k + 1.
inline void interleave4(__m512d X, __m512d Y, __m512d Z, __m512d q[4])
{
    const __m512d zero = _mm512_setzero_pd();
    const __m512i lo2 = _mm512_setr_epi64(0, 8, 1, 9, 2, 10, 3, 11),
                  hi2 = _mm512_setr_epi64(4, 12, 5, 13, 6, 14, 7, 15);
    const __m512d xy_a = _mm512_permutex2var_pd(X, lo2, Y), xy_b = _mm512_permutex2var_pd(X, hi2, Y);
    const __m512d z_a = _mm512_permutex2var_pd(Z, lo2, zero), z_b = _mm512_permutex2var_pd(Z, hi2, zero);
    const __m512i first = _mm512_setr_epi64(0, 1, 8, 9, 2, 3, 10, 11),
                  second = _mm512_setr_epi64(4, 5, 12, 13, 6, 7, 14, 15);
    q[0] = _mm512_permutex2var_pd(xy_a, first, z_a);
    q[1] = _mm512_permutex2var_pd(xy_a, second, z_a);
    q[2] = _mm512_permutex2var_pd(xy_b, first, z_b);
    q[3] = _mm512_permutex2var_pd(xy_b, second, z_b);
}
#endif
/// Orders the streaming stores before it (stream_store) before every store after it.
inline void stream_fence()
{
    _mm_sfence();
}

#if defined(__AVX512F__)
/// Stores 8 values at a 64-byte aligned p without reading the line first (non-temporal; the
/// writer calls stream_fence() before others read them).
inline void stream_store(double* p, __m512d a)
{
    _mm512_stream_pd(p, a);
}

/// Bit l set where the box of lane l, centre (x, y, z) and half-width reach, reaches the box
/// [lo, hi]: !(x + reach < lo) and !(x - reach > hi) per axis (unordered compares: a NaN lane is
/// in, as the scalar test has it).
inline __mmask8 boxes_reach(__m512d x, __m512d y, __m512d z, __m512d reach, const double lo[3], const double hi[3])
{
    return _mm512_cmp_pd_mask(_mm512_add_pd(x, reach), _mm512_set1_pd(lo[0]), _CMP_NLT_UQ) &
           _mm512_cmp_pd_mask(_mm512_sub_pd(x, reach), _mm512_set1_pd(hi[0]), _CMP_NGT_UQ) &
           _mm512_cmp_pd_mask(_mm512_add_pd(y, reach), _mm512_set1_pd(lo[1]), _CMP_NLT_UQ) &
           _mm512_cmp_pd_mask(_mm512_sub_pd(y, reach), _mm512_set1_pd(hi[1]), _CMP_NGT_UQ) &
           _mm512_cmp_pd_mask(_mm512_add_pd(z, reach), _mm512_set1_pd(lo[2]), _CMP_NLT_UQ) &
           _mm512_cmp_pd_mask(_mm512_sub_pd(z, reach), _mm512_set1_pd(hi[2]), _CMP_NGT_UQ);
}

/// The lanes of a set in m, in order, stored at out[0..popcount(m)); out must have room for 8.
inline void compress_store(double* out, __mmask8 m, __m512d a)
{
    _mm512_storeu_pd(out, _mm512_maskz_compress_pd(m, a));
}

/// The entries of in[0..8) whose bit is set in m, in order, stored at out (room for 8).
inline void compress_store(std::int32_t* out, __mmask8 m, const std::int32_t* in)
{
    const __m256i v = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(in));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out), _mm256_maskz_compress_epi32(m, v));
}

/// The indices first + l of the lanes l set in m, in order, stored at out (room for 8).
inline void compress_store_iota(std::int32_t* out, __mmask8 m, std::int32_t first)
{
    const __m256i v = _mm256_add_epi32(_mm256_set1_epi32(first), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out), _mm256_maskz_compress_epi32(m, v));
}

/// The smallest and largest of the ids a loop selects 8 at a time, kept per lane (out of the
/// loop's dependency chain) and reduced once at the end.
class IdRange8
{
  public:
    /// Takes ids[l] for the lanes l set in m.
    void take(__mmask8 m, const std::int32_t* ids)
    {
        const __m256i id = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(ids));
        first_ = _mm256_mask_min_epi32(first_, m, first_, id);
        last_ = _mm256_mask_max_epi32(last_, m, last_, id);
    }
    /// The smallest and the largest id taken (int32 max and -1 when none was).
    void bounds(std::int32_t& first, std::int32_t& last) const
    {
        alignas(32) std::int32_t f[8], l[8];
        _mm256_store_si256(reinterpret_cast<__m256i*>(f), first_);
        _mm256_store_si256(reinterpret_cast<__m256i*>(l), last_);
        first = f[0];
        last = l[0];
        for (int k = 1; k < 8; ++k)
        {
            first = f[k] < first ? f[k] : first;
            last = last < l[k] ? l[k] : last;
        }
    }

  private:
    __m256i first_ = _mm256_set1_epi32(0x7fffffff), last_ = _mm256_set1_epi32(-1);
};
#endif
} // namespace rkfem::simd
