#include "rkfem/operators/chunked_scatter.hpp"

#include <algorithm>

#include "rkfem/core/error.hpp"
#include "rkfem/core/huge_pages.hpp"
#include "rkfem/core/parallel.hpp"

namespace rkfem
{
index_t ChunkedScatter::chunk_size(index_t n, index_t multiple)
{
    const index_t c = std::clamp<index_t>(n / 16, 2048, 32768);
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
}

void ChunkedScatter::clear()
{
    chunks.clear();
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
              buffer.begin() + static_cast<std::ptrdiff_t>(ch.buffer + 4 * static_cast<std::size_t>(ch.hi - ch.lo)), 0.0);
}

void ChunkedScatter::reduce(std::vector<real_t>& f)
{
    RKFEM_REQUIRE(std::find(buffer_zero.begin(), buffer_zero.end(), 0) != buffer_zero.end(),
                  "chunked scatter: reduce() called twice for one force pass (the first consumed the sums)");
    parallel_for("rkfem::scatter_reduce", node_end - node_begin,
                 [&](index_t i)
                 {
                     const index_t n = node_begin + i;
                     real_t s[3] = {0.0, 0.0, 0.0};
                     for (index_t k = node_chunk_offsets[i]; k < node_chunk_offsets[i + 1]; ++k)
                     {
                         const Chunk& ch = chunks[static_cast<std::size_t>(node_chunks[k])];
                         real_t* b = &buffer[ch.buffer + 4 * static_cast<std::size_t>(n - ch.lo)];
                         s[0] += b[0], s[1] += b[1], s[2] += b[2];
                         b[0] = b[1] = b[2] = b[3] = 0.0;
                     }
                     for (int a = 0; a < 3; ++a)
                         f[3 * static_cast<std::size_t>(n) + a] = s[a];
                 });
    std::fill(buffer_zero.begin(), buffer_zero.end(), 1);
}
} // namespace rkfem
