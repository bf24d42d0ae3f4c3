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
