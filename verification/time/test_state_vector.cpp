// rkfem's N_Vector for the ARKODE state (time/state_vector.hpp): every operation against the
// same arithmetic on plain arrays (bitwise: the loops are the same expressions), copies that
// share storage and stay independent once either side is written, constants that cost no pass,
// and lending the halves to a NodeSet's arrays without copying.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

#include <sundials/sundials_context.h>

#include "rkfem/time/state_vector.hpp"

using namespace rkfem;

namespace
{
constexpr index_t n3 = 5003; // odd, over the 4096-value chunks of the reductions

struct Fixture
{
    SUNContext ctx = nullptr;
    std::shared_ptr<StatePool> pool;
    Fixture()
    {
        SUNContext_Create(nullptr, &ctx);
        pool = StatePool::create(n3);
    }
    ~Fixture()
    {
        pool.reset();
        SUNContext_Free(&ctx);
    }
    /// A vector with value f(i) at global index i (u half first).
    N_Vector filled(const std::function<real_t(index_t)>& f)
    {
        N_Vector v = pool->make_vector(ctx);
        const StatePool::Halves h = StatePool::overwrite(v);
        for (index_t i = 0; i < n3; ++i)
        {
            h.u[i] = f(i);
            h.v[i] = f(n3 + i);
        }
        return v;
    }
};

std::vector<real_t> values_of(N_Vector x)
{
    const StatePool::Halves h = StatePool::values(x);
    std::vector<real_t> out(h.u, h.u + n3);
    out.insert(out.end(), h.v, h.v + n3);
    return out;
}

real_t fx(index_t i)
{
    return std::sin(0.37 * i) + 0.1;
}
real_t fy(index_t i)
{
    return std::cos(0.11 * i) - 0.05 * (i % 7);
}
} // namespace

TEST(StateVector, OperationsEqualThePlainLoops)
{
    Fixture fx_;
    N_Vector x = fx_.filled(fx), y = fx_.filled(fy), z = N_VClone(x);
    std::vector<real_t> X = values_of(x), Y = values_of(y);
    const std::size_t n = X.size();
    auto expect_z = [&](const char* what, const std::function<real_t(std::size_t)>& ref)
    {
        const std::vector<real_t> Z = values_of(z);
        for (std::size_t i = 0; i < n; ++i)
            ASSERT_EQ(Z[i], ref(i)) << what << " at " << i;
    };
    N_VLinearSum(1.5, x, -0.25, y, z);
    expect_z("linear sum", [&](std::size_t i) { return 1.5 * X[i] + -0.25 * Y[i]; });
    N_VProd(x, y, z);
    expect_z("prod", [&](std::size_t i) { return X[i] * Y[i]; });
    N_VDiv(x, y, z);
    expect_z("div", [&](std::size_t i) { return X[i] / Y[i]; });
    N_VScale(-3.0, x, z);
    expect_z("scale", [&](std::size_t i) { return -3.0 * X[i]; });
    N_VAbs(y, z);
    expect_z("abs", [&](std::size_t i) { return std::abs(Y[i]); });
    N_VInv(x, z);
    expect_z("inv", [&](std::size_t i) { return 1.0 / X[i]; });
    N_VAddConst(x, 0.5, z);
    expect_z("add const", [&](std::size_t i) { return X[i] + 0.5; });
    N_VCompare(0.5, x, z);
    expect_z("compare", [&](std::size_t i) { return std::abs(X[i]) >= 0.5 ? 1.0 : 0.0; });

    // reductions (sums in any order agree to round-off)
    real_t dot = 0, l1 = 0, mx = 0, mn = 1e300, ss = 0, mq = 1e300;
    for (std::size_t i = 0; i < n; ++i)
    {
        dot += X[i] * Y[i];
        l1 += std::abs(X[i]);
        mx = std::max(mx, std::abs(X[i]));
        mn = std::min(mn, X[i]);
        ss += X[i] * Y[i] * X[i] * Y[i];
        if (Y[i] != 0)
            mq = std::min(mq, X[i] / Y[i]);
    }
    EXPECT_NEAR(N_VDotProd(x, y), dot, 1e-12 * l1);
    EXPECT_NEAR(N_VL1Norm(x), l1, 1e-12 * l1);
    EXPECT_EQ(N_VMaxNorm(x), mx);
    EXPECT_EQ(N_VMin(x), mn);
    EXPECT_NEAR(N_VWrmsNorm(x, y), std::sqrt(ss / n), 1e-12 * std::sqrt(ss / n));
    EXPECT_NEAR(N_VWL2Norm(x, y), std::sqrt(ss), 1e-12 * std::sqrt(ss));
    EXPECT_EQ(N_VMinQuotient(x, y), mq);

    // fused: z = X[0] + 2 X[1] - X[2] with z aliasing X[0] (ARKODE's accumulating form)
    N_VLinearSum(1.0, x, 0.0, y, z);
    std::vector<real_t> Z0 = values_of(z);
    N_Vector terms[3] = {z, x, y};
    realtype c[3] = {1.0, 2.0, -1.0};
    ASSERT_EQ(N_VLinearCombination(3, c, terms, z), 0);
    expect_z("linear combination",
             [&](std::size_t i) { return 1.0 * Z0[i] + 2.0 * X[i] + -1.0 * Y[i]; });
    N_Vector zs[2] = {z, N_VClone(x)};
    N_Vector ys[2] = {y, x};
    realtype a[2] = {0.5, -2.0};
    ASSERT_EQ(N_VScaleAddMulti(2, a, x, ys, zs), 0);
    expect_z("scale add multi", [&](std::size_t i) { return 0.5 * X[i] + Y[i]; });
    const std::vector<real_t> Z1 = values_of(zs[1]);
    for (std::size_t i = 0; i < n; ++i)
        ASSERT_EQ(Z1[i], -2.0 * X[i] + X[i]);
    N_VDestroy(zs[1]);

    // inverse test and constraint mask
    N_Vector w = fx_.filled([](index_t i) { return i == 17 ? 0.0 : 2.0; });
    EXPECT_EQ(N_VInvTest(w, z), SUNFALSE);
    expect_z("inv test", [](std::size_t i) { return i == 17 ? 0.0 : 0.5; });
    N_Vector cons = fx_.filled([](index_t) { return 1.0; }); // x_i >= 0 everywhere
    const bool all_non_negative = *std::min_element(X.begin(), X.end()) >= 0.0;
    ASSERT_FALSE(all_non_negative); // x has negative entries: the test must see a violation
    EXPECT_EQ(N_VConstrMask(cons, x, z), SUNFALSE);
    expect_z("constraint mask", [&](std::size_t i) { return X[i] >= 0.0 ? 0.0 : 1.0; });
    for (N_Vector v : {x, y, z, w, cons})
        N_VDestroy(v);
}

TEST(StateVector, CopiesShareStorageAndStayIndependent)
{
    Fixture f;
    N_Vector x = f.filled(fx), z = N_VClone(x);
    const std::vector<real_t> X = values_of(x);
    const long storages = f.pool->counters().storages, passes = f.pool->counters().passes;
    N_VScale(1.0, x, z); // a copy
    EXPECT_EQ(f.pool->counters().storages, storages);
    EXPECT_EQ(f.pool->counters().passes, passes); // nothing read or written
    EXPECT_EQ(f.pool->counters().shared_copies, 1);
    EXPECT_EQ(values_of(z), X);
    // writing the copy leaves the original alone, and the other way round
    N_VScale(2.0, z, z);
    EXPECT_EQ(values_of(x), X);
    N_VScale(1.0, x, z);
    N_VConst(7.0, x);
    EXPECT_EQ(values_of(z), X);
    EXPECT_EQ(values_of(x), std::vector<real_t>(2 * n3, 7.0));
    // a held reference keeps the values it saw while the vector moves on
    N_VScale(1.0, z, x);
    StatePool::Ref held(x);
    N_VLinearSum(1.0, x, 1.0, x, x);
    for (index_t i = 0; i < n3; ++i)
    {
        ASSERT_EQ(held.half(0)[i], X[i]);
        ASSERT_EQ(held.half(1)[i], X[n3 + i]);
        ASSERT_EQ(values_of(x)[i], X[i] + X[i]);
    }
    held.reset();
    N_VDestroy(x);
    N_VDestroy(z);
}

TEST(StateVector, ConstantsCostNoPass)
{
    Fixture f;
    N_Vector x = f.filled(fx), w = N_VClone(x);
    const std::vector<real_t> X = values_of(x);
    N_VConst(0.0, w);
    const long passes = f.pool->counters().passes;
    EXPECT_EQ(N_VWrmsNorm(x, w), 0.0); // zero weights: the norm reads nothing
    EXPECT_EQ(f.pool->counters().passes, passes);
    N_VConst(2.0, w);
    real_t ss = 0;
    for (real_t xi : X)
        ss += xi * xi;
    EXPECT_NEAR(N_VWrmsNorm(x, w), 2.0 * std::sqrt(ss / X.size()), 1e-14);
    EXPECT_EQ(f.pool->counters().passes, passes + 1); // read x once, not w
    // a constant read by a loop is materialized
    N_Vector z = N_VClone(x);
    N_VLinearSum(1.0, x, 3.0, w, z);
    const std::vector<real_t> Z = values_of(z);
    for (std::size_t i = 0; i < X.size(); ++i)
        ASSERT_EQ(Z[i], X[i] + 3.0 * 2.0);
    for (N_Vector v : {x, w, z})
        N_VDestroy(v);
}

TEST(StateVector, LendingMovesTheHalvesWithoutCopying)
{
    Fixture f;
    N_Vector y = f.filled(fx);
    const std::vector<real_t> Y = values_of(y);
    std::vector<real_t> u(n3, -1.0), v(n3, -2.0);
    const real_t* y_u = StatePool::values(y).u;
    const long passes = f.pool->counters().passes;
    f.pool->lend(y, u, v);
    EXPECT_EQ(f.pool->counters().passes, passes);
    EXPECT_EQ(u.data(), y_u); // the same array, moved
    for (index_t i = 0; i < n3; ++i)
    {
        ASSERT_EQ(u[i], Y[i]);
        ASSERT_EQ(v[i], Y[n3 + i]);
    }
    f.pool->return_v();
    EXPECT_EQ(v, std::vector<real_t>(n3, -2.0)); // v has its own array back, u stays lent
    EXPECT_EQ(u[5], Y[5]);
    // a copy of a lent vector shares without taking the half back
    N_Vector z = N_VClone(y);
    N_VScale(1.0, y, z);
    EXPECT_EQ(u[5], Y[5]);
    // an operation on the values takes the lent half back (u gets its old array again)
    EXPECT_EQ(values_of(z), Y);
    EXPECT_EQ(u, std::vector<real_t>(n3, -1.0));
    N_VDestroy(z);
    N_VDestroy(y);
}
