#pragma once
/// @file simd.hpp
/// RKFEM_WIDE_VECTORS marks a kernel whose lane loops are 8 doubles wide (batches of 8 elements
/// or points): it asks GCC for 512-bit vectors where the CPU has AVX-512. GCC 12 prefers 256-bit
/// vectors on AVX-512 CPUs, which halves these loops' width; other kernels keep that default
/// (the 2x2x2 hex kernel is 47% slower with 512-bit vectors). Elsewhere it does nothing.
#if defined(__AVX512F__)
#define RKFEM_WIDE_VECTORS __attribute__((target("prefer-vector-width=512")))
#else
#define RKFEM_WIDE_VECTORS
#endif

#if defined(__AVX512F__)
#include <immintrin.h>

namespace rkfem::simd
{
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

/// One vector per component to 8 padded quadruples (x, y, z, 0), two per output vector:
/// q[k] holds lanes 2k and 2k + 1.
inline void interleave4(__m512d X, __m512d Y, __m512d Z, __m512d q[4])
{
    const __m512d zero = _mm512_setzero_pd();
    const __m512i lo2 = _mm512_setr_epi64(0, 8, 1, 9, 2, 10, 3, 11), hi2 = _mm512_setr_epi64(4, 12, 5, 13, 6, 14, 7, 15);
    const __m512d xy_a = _mm512_permutex2var_pd(X, lo2, Y), xy_b = _mm512_permutex2var_pd(X, hi2, Y);
    const __m512d z_a = _mm512_permutex2var_pd(Z, lo2, zero), z_b = _mm512_permutex2var_pd(Z, hi2, zero);
    const __m512i first = _mm512_setr_epi64(0, 1, 8, 9, 2, 3, 10, 11), second = _mm512_setr_epi64(4, 5, 12, 13, 6, 7, 14, 15);
    q[0] = _mm512_permutex2var_pd(xy_a, first, z_a);
    q[1] = _mm512_permutex2var_pd(xy_a, second, z_a);
    q[2] = _mm512_permutex2var_pd(xy_b, first, z_b);
    q[3] = _mm512_permutex2var_pd(xy_b, second, z_b);
}
} // namespace rkfem::simd
#endif
