#pragma once
/// @file rk_translates.hpp
/// Set-up work on RK functions that repeats on translates. Where a mesh repeats itself (the
/// layers of an extruded cylinder, the interior of a structured block), what an element's facet
/// points or a particle's neighbourhood read of the RK functions is a translate of what another
/// element or particle reads: the same particles relative to the item, with the same radii, so
/// the same values up to the round-off of the coordinates. find_rk_translates groups the items
/// of a set-up pass so that the pass computes one item of each group (its source) and the others
/// take its results, their particles matched to the source's slot by slot (the regions are
/// ascending lists of the same length that agree slot by slot).
///
/// Two items are translates when their own geometry (what `frame` appends: lengths relative to
/// the item's reference point, flags as 0 or 1 m) agrees and their regions (the particles whose
/// supports reach the box `frame` gives, RkShapeFunctions::particles_near_box) have the same size
/// and agree particle by particle in position relative to the reference point and in radius,
/// each within the tolerance `translate_tolerance` gives. Candidates are found by a hash of the
/// values rounded to 2^16 tolerances, then compared value by value: an item that does not match
/// the first earlier item with its hash is its own source. So a source always comes before the
/// items that take its results, and with `share` false every item is its own source (the plain
/// pass, which the tests hold the shared one to).
///
/// What sharing changes: a taker's results are its source's, computed from positions that differ
/// from the taker's own by at most the tolerance (so by about the round-off with which the
/// coordinates were made); a value near a cut (the drop tolerance's, a support's edge) is cut as
/// the source's was.
#include <algorithm>
#include <cstdint>
#include <limits>
#include <vector>

#include <omp.h>

#include "rkfem/approximation/rk/rk_shape.hpp"
#include "rkfem/core/parallel.hpp"

namespace rkfem
{
struct RkTranslates
{
    std::vector<index_t> source;    ///< per item: the item whose results it takes (itself: computed here)
    std::vector<index_t> offsets;   ///< item i's region: particles[offsets[i] .. offsets[i + 1])
    std::vector<index_t> particles; ///< the regions, each ascending
    /// per item: the difference between its particles and its source's, where that is one
    /// number for the whole region (the translates of a mesh numbered along the translation),
    /// else kNoShift
    std::vector<index_t> shift;
    real_t tolerance = 0.0; ///< [m]
    static constexpr index_t kNoShift = std::numeric_limits<index_t>::min();

    index_t size() const { return static_cast<index_t>(source.size()); }
    bool computed(index_t i) const { return source[static_cast<std::size_t>(i)] == i; }
    index_t n_sources() const;
    const index_t* region(index_t i) const { return particles.data() + offsets[static_cast<std::size_t>(i)]; }
    index_t region_size(index_t i) const
    {
        return offsets[static_cast<std::size_t>(i) + 1] - offsets[static_cast<std::size_t>(i)];
    }
    /// Item i's particle in the slot where its source's region holds particle j (j must be in
    /// the source's region).
    index_t counterpart(index_t i, index_t j) const
    {
        const index_t d = shift[static_cast<std::size_t>(i)];
        return d != kNoShift ? j + d : counterpart_by_search(i, j);
    }
    index_t counterpart_by_search(index_t i, index_t j) const;
};

/// The tolerance of find_rk_translates: 1e-12 of the smallest support radius, or 64 ulp of the
/// largest coordinate where that is larger (items far from the origin carry more round-off in
/// their relative positions, and should still find their translates) [m].
real_t translate_tolerance(const RkShapeFunctions& rk);

namespace rk_translates_detail
{
/// Appends item values: per region particle, its position relative to ref and its radius.
void describe(const RkShapeFunctions& rk, const Vec3& ref, const std::vector<index_t>& ids,
              std::vector<real_t>& values);
/// A hash of the values rounded to multiples of `quantum`.
std::uint64_t hash(const std::vector<real_t>& values, real_t quantum);
/// Joins the per-thread regions and picks each item's candidate source: the first item with
/// its key (keys fold in the region size).
void join_and_group(RkTranslates& t, std::vector<std::vector<index_t>>& parts, const std::vector<index_t>& counts,
                    const std::vector<std::uint64_t>& keys);
/// The one difference between item i's region and item s's, slot by slot, or kNoShift.
index_t uniform_shift(const RkTranslates& t, index_t i, index_t s);
/// Do the value lists agree within tol?
bool same(const std::vector<real_t>& a, const std::vector<real_t>& b, real_t tol);
} // namespace rk_translates_detail

/// Groups n items into translates (see the file comment). frame(i, lo, hi, ref, own): item i's
/// box (its region is the particles whose support reaches it), its reference point, and its own
/// geometry appended to `own` (called from several threads, in any order, more than once).
template <class Frame>
RkTranslates find_rk_translates(const RkShapeFunctions& rk, index_t n, Frame&& frame, bool share = true)
{
    namespace detail = rk_translates_detail;
    RkTranslates t;
    t.tolerance = translate_tolerance(rk);
    t.source.resize(static_cast<std::size_t>(n));
    std::vector<std::uint64_t> keys(static_cast<std::size_t>(n));
    std::vector<index_t> counts(static_cast<std::size_t>(n));
    std::vector<std::vector<index_t>> parts; // per thread: its items' regions (a static schedule: in item order)
    const real_t quantum = 65536.0 * t.tolerance;
    // Room for the regions at once, from the largest of a few items' spread over the range,
    // twice over: the first thread's part for all of them (the join appends the others to it in
    // place), each other's for its share. Memory reserved and never written costs no page; grown
    // by doubling, the parts were copied into fresh pages several times (P6's target at 1/2 in:
    // 8.2 million region particles, 100 MB of pages touched for 33 MB kept).
    std::size_t per_item = 0;
    {
        std::vector<index_t> ids;
        std::vector<real_t> own;
        Vec3 lo, hi, ref;
        const index_t samples = std::min<index_t>(n, 16);
        for (index_t k = 0; k < samples; ++k)
        {
            own.clear();
            frame(static_cast<index_t>(static_cast<std::int64_t>(k) * n / samples), lo, hi, ref, own);
            rk.particles_near_box(lo, hi, ids);
            per_item = std::max(per_item, ids.size());
        }
    }
    ParallelErrors errors;
#pragma omp parallel
    {
#pragma omp single
        parts.resize(static_cast<std::size_t>(omp_get_num_threads()));
        const std::size_t threads = parts.size(), thread = static_cast<std::size_t>(omp_get_thread_num());
        std::vector<index_t>& mine = parts[thread];
        mine.reserve(2 * per_item *
                     (thread == 0 ? static_cast<std::size_t>(n) : static_cast<std::size_t>(n) / threads + 1));
        std::vector<index_t> ids;
        std::vector<real_t> values;
        Vec3 lo, hi, ref;
#pragma omp for schedule(static)
        for (index_t i = 0; i < n; ++i)
        {
            try
            {
                values.clear();
                frame(i, lo, hi, ref, values);
                rk.particles_near_box(lo, hi, ids);
                counts[static_cast<std::size_t>(i)] = static_cast<index_t>(ids.size());
                mine.insert(mine.end(), ids.begin(), ids.end());
                if (share)
                {
                    detail::describe(rk, ref, ids, values);
                    keys[static_cast<std::size_t>(i)] = detail::hash(values, quantum);
                }
            }
            catch (...)
            {
                errors.capture();
            }
        }
    }
    errors.rethrow();
    if (!share)
        for (index_t i = 0; i < n; ++i)
            keys[static_cast<std::size_t>(i)] = static_cast<std::uint64_t>(i); // every item its own key
    detail::join_and_group(t, parts, counts, keys);
    t.shift.assign(static_cast<std::size_t>(n), 0); // a source is its own translate
    if (!share)
        return t;
        // each candidate compared value by value; a taker that does not match computes for itself
#pragma omp parallel
    {
        std::vector<index_t> ids;
        std::vector<real_t> mine, theirs;
        index_t described = -1; // the source whose values `theirs` holds
        Vec3 lo, hi, ref;
        auto values_of = [&](index_t i, std::vector<real_t>& values)
        {
            values.clear();
            frame(i, lo, hi, ref, values);
            ids.assign(t.region(i), t.region(i) + t.region_size(i));
            detail::describe(rk, ref, ids, values);
        };
#pragma omp for schedule(dynamic, 256)
        for (index_t i = 0; i < n; ++i)
        {
            const index_t s = t.source[static_cast<std::size_t>(i)];
            if (s == i)
                continue;
            try
            {
                if (s != described)
                {
                    values_of(s, theirs);
                    described = s;
                }
                values_of(i, mine);
                if (detail::same(mine, theirs, t.tolerance))
                    t.shift[static_cast<std::size_t>(i)] = detail::uniform_shift(t, i, s);
                else
                    t.source[static_cast<std::size_t>(i)] = i;
            }
            catch (...)
            {
                errors.capture();
            }
        }
    }
    errors.rethrow();
    return t;
}
} // namespace rkfem
