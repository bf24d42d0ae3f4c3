#include "rkfem/approximation/rk/rk_translates.hpp"

#include <algorithm>
#include <bit>
#include <limits>
#include <unordered_map>

namespace rkfem
{
index_t RkTranslates::n_sources() const
{
    index_t count = 0;
    for (index_t i = 0; i < size(); ++i)
        count += computed(i) ? 1 : 0;
    return count;
}

index_t RkTranslates::counterpart_by_search(index_t i, index_t j) const
{
    const index_t s = source[static_cast<std::size_t>(i)];
    const index_t* begin = region(s);
    const index_t* at = std::lower_bound(begin, begin + region_size(s), j);
    return region(i)[at - begin];
}

real_t translate_tolerance(const RkShapeFunctions& rk)
{
    real_t a_min = std::numeric_limits<real_t>::max(), x_max = 0.0;
    for (index_t i = 0; i < rk.size(); ++i)
    {
        a_min = std::min(a_min, rk.radius(i));
        x_max = std::max(x_max, rk.position(i).cwiseAbs().maxCoeff());
    }
    return std::max(1e-12 * a_min, 64.0 * std::numeric_limits<real_t>::epsilon() * x_max);
}

namespace rk_translates_detail
{
void describe(const RkShapeFunctions& rk, const Vec3& ref, const std::vector<index_t>& ids, std::vector<real_t>& values)
{
    for (index_t j : ids)
    {
        const Vec3 d = rk.position(j) - ref;
        values.insert(values.end(), {d[0], d[1], d[2], rk.radius(j)});
    }
}

std::uint64_t hash(const std::vector<real_t>& values, real_t quantum)
{
    // FNV-1a over the rounded values' bits (rounded as doubles: no integer overflow, and -0 is
    // made +0 so that a rounded zero hashes one way), in four streams of every fourth value,
    // folded at the end: one stream's multiply waits on the one before (4 cycles a value)
    const real_t inv = 1.0 / quantum;
    constexpr std::uint64_t prime = 1099511628211ull;
    std::uint64_t h[4];
    for (int s = 0; s < 4; ++s)
        h[s] = (1469598103934665603ull + static_cast<std::uint64_t>(s)) ^ values.size();
    auto mix = [&](std::uint64_t& into, real_t v)
    { into = (into ^ std::bit_cast<std::uint64_t>(std::nearbyint(v * inv) + 0.0)) * prime; };
    const std::size_t n = values.size();
    std::size_t k = 0;
    for (; k + 4 <= n; k += 4)
    {
        mix(h[0], values[k]);
        mix(h[1], values[k + 1]);
        mix(h[2], values[k + 2]);
        mix(h[3], values[k + 3]);
    }
    for (; k < n; ++k)
        mix(h[k % 4], values[k]);
    std::uint64_t out = h[0];
    for (int s = 1; s < 4; ++s)
        out = (out ^ h[s]) * prime;
    return out;
}

void join_and_group(RkTranslates& t, std::vector<std::vector<index_t>>& parts, const std::vector<index_t>& counts,
                    const std::vector<std::uint64_t>& keys)
{
    const std::size_t n = counts.size();
    t.offsets.assign(n + 1, 0);
    for (std::size_t i = 0; i < n; ++i)
        t.offsets[i + 1] = t.offsets[i] + counts[i];
    // the first part in place (find_rk_translates reserves its room for all), the others after it
    t.particles.clear();
    if (!parts.empty())
        t.particles.swap(parts.front());
    t.particles.reserve(static_cast<std::size_t>(t.offsets[n]));
    for (std::size_t k = 1; k < parts.size(); ++k)
    {
        t.particles.insert(t.particles.end(), parts[k].begin(), parts[k].end());
        std::vector<index_t>().swap(parts[k]);
    }
    std::unordered_map<std::uint64_t, index_t> first;
    first.reserve(n);
    for (std::size_t i = 0; i < n; ++i)
        t.source[i] = first.try_emplace(keys[i], static_cast<index_t>(i)).first->second;
}

index_t uniform_shift(const RkTranslates& t, index_t i, index_t s)
{
    const index_t n = t.region_size(i);
    const index_t *mine = t.region(i), *theirs = t.region(s);
    const index_t d = n > 0 ? mine[0] - theirs[0] : 0;
    for (index_t k = 1; k < n; ++k)
        if (mine[k] - theirs[k] != d)
            return RkTranslates::kNoShift;
    return d;
}

bool same(const std::vector<real_t>& a, const std::vector<real_t>& b, real_t tol)
{
    if (a.size() != b.size())
        return false;
    bool ok = true;
    for (std::size_t k = 0; k < a.size(); ++k)
        ok &= std::abs(a[k] - b[k]) <= tol;
    return ok;
}
} // namespace rk_translates_detail
} // namespace rkfem
