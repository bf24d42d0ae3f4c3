#pragma once
/// @file chunked_scatter.hpp
/// Deterministic scatter assembly of nodal forces for blocks whose items (elements, stress
/// points) are ordered with locality. The items are cut into fixed chunks (a function of the
/// item count only, never of the thread count); each chunk adds its items' nodal forces, in
/// item order, into a buffer of its own over the range of nodes its items touch (4 values per
/// node: x, y, z and padding), and a node's force is the sum of the buffers that cover it, in
/// chunk order. So results do not depend on the number of threads, and the per-item force
/// tensors are never written out: the buffers stay in cache while a chunk runs.
#include <algorithm>
#include <cstddef>

#include <vector>

#include "rkfem/core/parallel.hpp"
#include "rkfem/core/simd.hpp"
#include "rkfem/core/types.hpp"

namespace rkfem
{
/// How a block assembles nodal forces; both ways are deterministic and independent of the
/// thread count. Scatter: ChunkedScatter below. Gather: each node sums its items' terms through
/// a transpose table (the terms are written out per item first). Automatic: the scatter unless
/// the item order has no locality (chunk ranges adding up to over 3 nodes per node).
enum class Assembly
{
    Automatic,
    Scatter,
    Gather,
};

struct ChunkedScatter
{
    struct Chunk
    {
        index_t first = 0, last = 0; ///< items [first, last)
        index_t lo = 0, hi = 0;      ///< the nodes its items touch lie in [lo, hi)
        std::size_t buffer = 0;      ///< offset of its buffer (4 values per node) in `buffer`
    };
    std::vector<Chunk> chunks;
    index_t node_begin = 0, node_end = 0;                 ///< the block's nodes
    std::vector<index_t> node_chunk_offsets, node_chunks; ///< local node -> covering chunks, in order
    /// Runs of consecutive nodes covered by the same chunks (built by finish()): the reduction
    /// works a run at a time, 8 nodes per vector step.
    struct Run
    {
        index_t first = 0, last = 0; ///< local nodes [first, last)
        index_t chunks = 0;          ///< its covering chunks: node_chunks[node_chunk_offsets[first] + c]
    };
    std::vector<Run> runs;
    std::vector<real_t> buffer;
    /// per chunk: its buffer is all zero (after finish() and after reduce(), which zeroes what it
    /// reads), so its next pass need not clear it
    std::vector<char> buffer_zero;

    /// Items per chunk for n items: about n / 16 within [smallest, 32768], a multiple of
    /// `multiple`. The smallest chunk suits the items' cost: 2048 for hex elements (cheap each);
    /// stress points of RK parts cost far more each and take smaller chunks, so that a part of a
    /// few thousand particles still has work for every thread (measurements: docs/performance.md).
    static index_t chunk_size(index_t n, index_t multiple, index_t smallest = 2048);

    /// The locality test on the buffer values chunks take (add_chunks) over a block of `nodes`
    /// nodes: at most 3 buffers per node, so that the reduce sums few and the buffers stay small.
    static bool local(std::size_t values, index_t nodes) { return values <= 4 * 3 * static_cast<std::size_t>(nodes); }

    /// The chunk size a block takes: from `size` on, cut(size) (which cuts the block's chunks
    /// anew and says whether their ranges are local, `local`) with the size
    /// doubled while they are not and twice it is at most `largest`. Returns whether the last
    /// cut was local; `size` is its size.
    template <class Cut> static bool cut_until_local(index_t& size, index_t largest, Cut&& cut)
    {
        bool local = cut(size);
        while (!local && 2 * size <= largest)
        {
            size *= 2;
            local = cut(size);
        }
        return local;
    }

    /// Appends chunks of `size` consecutive items of [0, n_items); `range(first, last, lo, hi)`
    /// widens [lo, hi) to the nodes that items [first, last) touch. Returns the buffer values
    /// the new chunks take (4 per covered node), for a locality test.
    template <class Range> std::size_t add_chunks(index_t n_items, index_t size, Range&& range)
    {
        std::size_t added = 0;
        for (index_t first = 0; first < n_items; first += size)
        {
            Chunk ch{first, std::min(n_items, first + size), node_end, node_begin, next_buffer_};
            range(ch.first, ch.last, ch.lo, ch.hi);
            ch.hi = std::max(ch.hi, ch.lo);
            next_buffer_ += 4 * static_cast<std::size_t>(ch.hi - ch.lo);
            added += 4 * static_cast<std::size_t>(ch.hi - ch.lo);
            chunks.push_back(ch);
        }
        return added;
    }
    /// Builds the node -> chunk table and the buffers, after the last add_chunks.
    void finish();
    void clear();
    bool empty() const { return chunks.empty(); }
    real_t* chunk_buffer(index_t c) { return buffer.data() + chunks[static_cast<std::size_t>(c)].buffer; }
    /// Zeroes chunk c's buffer unless it is zero already (a chunk's pass starts with it).
    void zero(index_t c);
    /// Runs chunks [c0, c1) in parallel, each on whichever thread is free (parallel_for_tasks:
    /// a chunk's sums do not depend on its thread): each starts from a zero buffer, then calls
    /// batch(b, buffer, lo) for its batches b of `width` items in order (the buffer covers
    /// nodes from lo on).
    template <class Batch> void run_chunks(const char* label, index_t c0, index_t c1, index_t width, Batch&& batch)
    {
        parallel_for_tasks(label, c1 - c0,
                           [&](index_t i)
                           {
                               const index_t c = c0 + i;
                               const Chunk& ch = chunks[static_cast<std::size_t>(c)];
                               real_t* buf = chunk_buffer(c);
                               zero(c);
                               buffer_zero[static_cast<std::size_t>(c)] = 0;
                               for (index_t b = ch.first / width; b * width < ch.last; ++b)
                                   batch(b, buf, ch.lo);
                               // the batches may write with streaming stores (core/stream_stores.hpp)
                               simd::stream_fence();
                           });
    }
    /// f[3 n + a] = the sum over the chunks covering node n of their buffer values, in chunk
    /// order, for the block's nodes. It consumes the buffers: each value is zeroed as it is
    /// read (the lines are in cache then), which spares the next pass a clearing sweep over
    /// memory. A second reduce() with no chunk run since the last is an error (it would give
    /// zero forces). With `add`, the block's sums are added to f instead (blocks that share
    /// nodes): f[3 n + a] += sum, the sum formed first, so the result is the same whatever the
    /// other blocks added before.
    void reduce(std::vector<real_t>& f, bool add = false);

  private:
    std::size_t next_buffer_ = 0;
};
} // namespace rkfem
