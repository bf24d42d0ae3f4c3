#include "rkfem/operators/kernels/chunked_scatter.hpp"

#include <algorithm>
#include <immintrin.h>

#include "rkfem/core/error.hpp"
#include "rkfem/core/huge_pages.hpp"
#include "rkfem/core/parallel.hpp"

namespace rkfem
{
index_t ChunkedScatter::chunk_size(index_t n, index_t multiple, index_t smallest)
{
    const index_t c = std::clamp<index_t>(n / 16, smallest, 32768);
    return (c + multiple - 1) / multiple * multiple;
}

void ChunkedScatter::finish()
{
    const index_t nn = node_end - node_begin;
    node_chunk_offsets.assign(static_cast<std::size_t>(nn) + 1, 0);
    for (const Chunk& ch : chunks)
        for (index_t n = ch.lo; n < ch.hi; ++n)
            ++node_chunk_offsets[n - node_begin + 1];
    for (index_t i = 0; i < nn; ++i)
        node_chunk_offsets[i + 1] += node_chunk_offsets[i];
    node_chunks.resize(static_cast<std::size_t>(node_chunk_offsets.back()));
    std::vector<index_t> fill(node_chunk_offsets.begin(), node_chunk_offsets.end() - 1);
    for (index_t c = 0; c < static_cast<index_t>(chunks.size()); ++c)
        for (index_t n = chunks[c].lo; n < chunks[c].hi; ++n)
            node_chunks[fill[n - node_begin]++] = c;
    buffer.assign(next_buffer_, 0.0);
    use_huge_pages(buffer);
    buffer_zero.assign(chunks.size(), 1);
    // runs: a new one where the covering chunks change; long runs are cut (load balance)
    runs.clear();
    auto same_chunks = [&](index_t a, index_t b)
    {
        const index_t na = node_chunk_offsets[a + 1] - node_chunk_offsets[a];
        return na == node_chunk_offsets[b + 1] - node_chunk_offsets[b] &&
               std::equal(node_chunks.begin() + node_chunk_offsets[a], node_chunks.begin() + node_chunk_offsets[a + 1],
                          node_chunks.begin() + node_chunk_offsets[b]);
    };
    for (index_t i = 0; i < nn; ++i)
        if (runs.empty() || runs.back().last - runs.back().first >= 4096 || !same_chunks(runs.back().first, i))
            runs.push_back({i, i + 1, node_chunk_offsets[i + 1] - node_chunk_offsets[i]});
        else
            runs.back().last = i + 1;
}

void ChunkedScatter::clear()
{
    chunks.clear();
    runs.clear();
    node_chunk_offsets.clear();
    node_chunks.clear();
    buffer.clear();
    buffer_zero.clear();
    next_buffer_ = 0;
}

void ChunkedScatter::zero(index_t c)
{
    if (buffer_zero[static_cast<std::size_t>(c)])
        return;
    const Chunk& ch = chunks[static_cast<std::size_t>(c)];
    std::fill(buffer.begin() + static_cast<std::ptrdiff_t>(ch.buffer),
              buffer.begin() + static_cast<std::ptrdiff_t>(ch.buffer + 4 * static_cast<std::size_t>(ch.hi - ch.lo)),
              0.0);
}

void ChunkedScatter::reduce(std::vector<real_t>& f, bool add)
{
    RKFEM_REQUIRE(std::find(buffer_zero.begin(), buffer_zero.end(), 0) != buffer_zero.end(),
                  "chunked scatter: reduce() called twice for one force pass (the first consumed the sums)");
    parallel_for("rkfem::scatter_reduce", static_cast<index_t>(runs.size()),
                 [&](index_t r)
                 {
                     const Run& run = runs[static_cast<std::size_t>(r)];
                     const index_t* cover = node_chunks.data() + node_chunk_offsets[run.first];
                     real_t* out = &f[3 * static_cast<std::size_t>(node_begin + run.first)];
                     index_t i = 0;
#if defined(__AVX512F__)
                     if (run.chunks <= 64)
                     {
                         // the run's first node in each covering chunk's buffer
                         real_t* src[64];
                         const index_t nc = run.chunks;
                         for (index_t c = 0; c < nc; ++c)
                         {
                             const Chunk& ch = chunks[static_cast<std::size_t>(cover[c])];
                             src[c] = &buffer[ch.buffer + 4 * static_cast<std::size_t>(node_begin + run.first - ch.lo)];
                         }
                         // 8 nodes per step: 4 padded quadruples per chunk summed from zero in chunk
                         // order (the scalar sums' order), then packed to 3 vectors of triples
                         const __m512i p0 = _mm512_setr_epi64(0, 1, 2, 4, 5, 6, 8, 9),
                                       p1 = _mm512_setr_epi64(2, 4, 5, 6, 8, 9, 10, 12),
                                       p2 = _mm512_setr_epi64(5, 6, 8, 9, 10, 12, 13, 14);
                         const __m512d zero = _mm512_setzero_pd();
                         for (; i + 8 <= run.last - run.first; i += 8)
                         {
                             __m512d q[4] = {zero, zero, zero, zero};
                             for (index_t c = 0; c < nc; ++c)
                                 for (int k = 0; k < 4; ++k)
                                 {
                                     real_t* b = src[c] + 4 * i + 8 * k;
                                     q[k] = _mm512_add_pd(q[k], _mm512_loadu_pd(b));
                                     _mm512_storeu_pd(b, zero);
                                 }
                             __m512d t0 = _mm512_permutex2var_pd(q[0], p0, q[1]);
                             __m512d t1 = _mm512_permutex2var_pd(q[1], p1, q[2]);
                             __m512d t2 = _mm512_permutex2var_pd(q[2], p2, q[3]);
                             if (add)
                             {
                                 t0 = _mm512_add_pd(_mm512_loadu_pd(out + 3 * i), t0);
                                 t1 = _mm512_add_pd(_mm512_loadu_pd(out + 3 * i + 8), t1);
                                 t2 = _mm512_add_pd(_mm512_loadu_pd(out + 3 * i + 16), t2);
                             }
                             _mm512_storeu_pd(out + 3 * i, t0);
                             _mm512_storeu_pd(out + 3 * i + 8, t1);
                             _mm512_storeu_pd(out + 3 * i + 16, t2);
                         }
                     }
#endif
                     for (; i < run.last - run.first; ++i)
                     {
                         real_t s[3] = {0.0, 0.0, 0.0};
                         for (index_t c = 0; c < run.chunks; ++c)
                         {
                             const Chunk& ch = chunks[static_cast<std::size_t>(cover[c])];
                             real_t* b =
                                 &buffer[ch.buffer + 4 * static_cast<std::size_t>(node_begin + run.first + i - ch.lo)];
                             s[0] += b[0], s[1] += b[1], s[2] += b[2];
                             b[0] = b[1] = b[2] = b[3] = 0.0;
                         }
                         for (int a = 0; a < 3; ++a)
                             out[3 * i + a] = add ? out[3 * i + a] + s[a] : s[a];
                     }
                 });
    std::fill(buffer_zero.begin(), buffer_zero.end(), 1);
}
} // namespace rkfem
