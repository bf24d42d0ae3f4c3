// The lane shuffles the batch kernels move data with: exact permutations, checked element by
// element (a wrong index moves a value to another point or component, which a sum can hide).
#include <gtest/gtest.h>

#include "rkfem/core/simd.hpp"

TEST(Simd, TriplesSplitAndJoinByComponent)
{
#if defined(__AVX512F__)
    // 8 triples node-major: value 10 l + c at position 3 l + c (lane l, component c)
    alignas(64) double in[24], out[24], comp[3][8];
    for (int l = 0; l < 8; ++l)
        for (int c = 0; c < 3; ++c)
            in[3 * l + c] = 10.0 * l + c;
    __m512d X, Y, Z;
    rkfem::simd::load_triples(in, X, Y, Z);
    _mm512_store_pd(comp[0], X);
    _mm512_store_pd(comp[1], Y);
    _mm512_store_pd(comp[2], Z);
    for (int c = 0; c < 3; ++c)
        for (int l = 0; l < 8; ++l)
            EXPECT_EQ(comp[c][l], 10.0 * l + c) << "component " << c << ", lane " << l;
    // and back: store_triples is load_triples' inverse
    rkfem::simd::store_triples(out, X, Y, Z);
    for (int k = 0; k < 24; ++k)
        EXPECT_EQ(out[k], in[k]) << "position " << k;
#else
    GTEST_SKIP() << "built without AVX-512: the triples' shuffles are not compiled";
#endif
}
