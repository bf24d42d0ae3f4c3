// Neighbour lists with a skin: against brute force, the lists hold every pair within the radius
// as long as no point has moved more than skin / 2 since the build (no rebuild is done then),
// a larger move triggers the rebuild, and a stale list after such a move can miss a pair (the
// criterion is needed, not just sufficient).
#include <gtest/gtest.h>

#include <cstdio>
#include <random>

#include "rkfem/discretization/cell_list.hpp"

using namespace rkfem;

namespace
{
/// Jittered 10 x 10 x 10 lattice, spacing 1.
std::vector<real_t> cloud(std::mt19937& rng)
{
    std::uniform_real_distribution<real_t> jit(-0.3, 0.3);
    std::vector<real_t> x;
    for (int k = 0; k < 10; ++k)
        for (int j = 0; j < 10; ++j)
            for (int i = 0; i < 10; ++i)
                for (real_t c : {i + jit(rng), j + jit(rng), k + jit(rng)})
                    x.push_back(c);
    return x;
}

/// Pairs (i, j) within r missing from the lists.
int missing_pairs(const NeighbourList& nl, const std::vector<real_t>& x, real_t r)
{
    const index_t n = static_cast<index_t>(x.size() / 3);
    int missing = 0;
    for (index_t i = 0; i < n; ++i)
        for (index_t j = 0; j < n; ++j)
        {
            real_t s = 0.0;
            for (int d = 0; d < 3; ++d)
                s += (x[3 * i + d] - x[3 * j + d]) * (x[3 * i + d] - x[3 * j + d]);
            if (s < r * r &&
                !std::binary_search(nl.ids().begin() + nl.offsets()[i], nl.ids().begin() + nl.offsets()[i + 1], j))
                ++missing;
        }
    return missing;
}
} // namespace

TEST(NeighbourList, CompleteUntilHalfTheSkinIsUsed)
{
    std::mt19937 rng(7);
    std::vector<real_t> x = cloud(rng);
    const real_t r = 1.6, skin = 0.4;
    NeighbourList nl(r, skin);
    EXPECT_TRUE(nl.update(x));
    EXPECT_EQ(missing_pairs(nl, x, r), 0);
    const index_t entries = nl.offsets().back();
    // every point moves by less than skin / 2 in a random direction, five times over (each time
    // measured from the build): no rebuild, still complete
    std::normal_distribution<real_t> g(0.0, 1.0);
    const std::vector<real_t> x0 = x;
    for (int round = 0; round < 5; ++round)
    {
        for (std::size_t i = 0; i < x.size() / 3; ++i)
        {
            Vec3 u(g(rng), g(rng), g(rng));
            u *= 0.199 * skin / u.norm();
            for (int d = 0; d < 3; ++d)
                x[3 * i + d] = x0[3 * i + d] + u[d];
        }
        EXPECT_FALSE(nl.update(x)) << round;
        EXPECT_EQ(missing_pairs(nl, x, r), 0) << round;
    }
    EXPECT_EQ(nl.rebuilds(), 1);
    std::printf("1000 points, radius %.1f, skin %.1f: %d list entries (%.1f per point), no rebuild in 5 moves "
                "of 0.199 skin\n",
                r, skin, entries, entries / 1000.0);
    // one point moves by more than skin / 2: the next update rebuilds, and the list is complete
    x[3 * 555] += 0.6 * skin;
    EXPECT_TRUE(nl.update(x));
    EXPECT_EQ(nl.rebuilds(), 2);
    EXPECT_EQ(missing_pairs(nl, x, r), 0);
}

TEST(NeighbourList, AStaleListMissesPairsAfterALargerMove)
{
    // two points just outside radius + skin move towards each other by skin (each 0.55 skin,
    // past the skin / 2 criterion): the old list lacks the pair that is now within the radius
    const real_t r = 1.0, skin = 0.2;
    std::vector<real_t> x = {0.0, 0.0, 0.0, r + skin + 0.01, 0.0, 0.0};
    NeighbourList nl(r, skin);
    nl.update(x);
    NeighbourList stale = nl;
    x[0] += 0.55 * skin;
    x[3] -= 0.55 * skin;
    EXPECT_EQ(missing_pairs(stale, x, r), 2); // (0, 1) and (1, 0)
    EXPECT_NEAR(stale.max_displacement(x), 0.55 * skin, 1e-15);
    EXPECT_TRUE(nl.update(x));
    EXPECT_EQ(missing_pairs(nl, x, r), 0);
}
