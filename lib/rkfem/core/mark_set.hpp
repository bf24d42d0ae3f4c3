#pragma once
/// @file mark_set.hpp
/// A set of ids in [0, n) held as a bitmap with the range of words it has touched. Adding an id
/// costs one OR; reading the set back gives its ids in ascending order (a sorted list without a
/// sort) and clears the words it read, so the set is empty again for its next use at the cost of
/// its own range only. RK set-up keeps one per thread: the particles near a box
/// (RkShapeFunctions::particles_near_box) and the particles of a node's SCNI row (build_scni_rk).
#include <algorithm>
#include <cstdint>
#include <limits>
#include <vector>

#include "rkfem/core/types.hpp"

namespace rkfem
{
class MarkSet
{
  public:
    /// Room for ids below n (it only grows; the set stays as it is).
    void reserve(std::size_t n)
    {
        const std::size_t words = (n + 63) / 64;
        if (bits_.size() < words)
            bits_.resize(words, 0);
    }
    /// Adds id; true when it was not in the set.
    bool insert(index_t id)
    {
        const std::size_t w = word(id);
        cover_words(w, w);
        const std::uint64_t bit = std::uint64_t{1} << (id & 63);
        const bool fresh = (bits_[w] & bit) == 0;
        bits_[w] |= bit;
        return fresh;
    }
    /// Adds id without widening the range the set reads back: the caller gives it (cover).
    void set(index_t id) { bits_[word(id)] |= std::uint64_t{1} << (id & 63); }
    /// The ids added by set() lie in [first, last] (nothing when first > last).
    void cover(index_t first, index_t last)
    {
        if (first <= last)
            cover_words(word(first), word(last));
    }
    /// Calls f(id) for every id of the set, ascending, and empties it.
    template <class F> void drain(F&& f)
    {
        for (std::size_t w = first_; w <= last_ && first_ <= last_; ++w)
        {
            for (std::uint64_t b = bits_[w]; b != 0; b &= b - 1)
                f(static_cast<index_t>(64 * w + static_cast<std::size_t>(__builtin_ctzll(b))));
            bits_[w] = 0;
        }
        reset();
    }
    /// The number of ids in the set, which it empties.
    index_t drain_count()
    {
        index_t n = 0;
        for (std::size_t w = first_; w <= last_ && first_ <= last_; ++w)
        {
            n += static_cast<index_t>(__builtin_popcountll(bits_[w]));
            bits_[w] = 0;
        }
        reset();
        return n;
    }

  private:
    static std::size_t word(index_t id) { return static_cast<std::size_t>(id) >> 6; }
    void cover_words(std::size_t first, std::size_t last)
    {
        first_ = std::min(first_, first);
        last_ = std::max(last_, last);
    }
    void reset()
    {
        first_ = std::numeric_limits<std::size_t>::max();
        last_ = 0;
    }

    std::vector<std::uint64_t> bits_;
    std::size_t first_ = std::numeric_limits<std::size_t>::max(), last_ = 0;
};
} // namespace rkfem
