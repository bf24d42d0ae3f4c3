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

#include "rkfem/core/huge_pages.hpp"
#include "rkfem/core/stream_stores.hpp"
#include "rkfem/time/arkode_stepper.hpp"
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

/// Values of order 1 formed by the library's loops and by the same expressions here: the
/// compiler may contract a product and a sum into one fused multiply-add in either place, so
/// they agree to a few roundings (1e-15), not bitwise.
void expect_close(real_t got, real_t want, index_t i, const char* what)
{
    ASSERT_NEAR(got, want, 1e-15 * std::max(1.0, std::abs(want))) << what << " at " << i;
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
    expect_z("linear combination", [&](std::size_t i) { return 1.0 * Z0[i] + 2.0 * X[i] + -1.0 * Y[i]; });
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

TEST(StateVector, RecordedDifferenceEqualsTheStoredOne)
{
    // y's v half recorded as (y_u - x_v) * s: the linear sum forms it on the fly with the same
    // operations as a stored half (so bitwise the same values), a read writes it out, and x's
    // values stay held for it when x itself is overwritten
    Fixture f;
    N_Vector x = f.filled(fx), y = N_VClone(x), z = N_VClone(x);
    const std::vector<real_t> X = values_of(x);
    const real_t s = 0.3, a = 1.0, b = 0.7;
    real_t* yu = StatePool::overwrite_with_difference(y, x, s);
    for (index_t i = 0; i < n3; ++i)
        yu[i] = fy(i);
    auto dv = [&](index_t i) { return (fy(i) - X[n3 + i]) * s; };

    N_VLinearSum(a, x, b, y, z);
    EXPECT_EQ(f.pool->counters().fused_differences, 1);
    EXPECT_EQ(f.pool->counters().materialized_differences, 0);
    std::vector<real_t> Z = values_of(z);
    for (index_t i = 0; i < n3; ++i)
    {
        expect_close(Z[i], a * X[i] + b * fy(i), i, "u");
        expect_close(Z[n3 + i], a * X[n3 + i] + b * dv(i), i, "v");
    }
    N_VLinearSum(b, y, a, x, z); // the recorded vector first
    EXPECT_EQ(f.pool->counters().fused_differences, 2);
    EXPECT_EQ(values_of(z), Z);

    // x overwritten: y still refers to the values it was recorded over
    const StatePool::Halves xh = StatePool::overwrite(x);
    std::fill(xh.u, xh.u + n3, 9.0);
    std::fill(xh.v, xh.v + n3, 9.0);
    N_VLinearSum(a, x, b, y, y); // in place on the recorded vector
    EXPECT_EQ(f.pool->counters().fused_differences, 3);
    Z = values_of(y);
    for (index_t i = 0; i < n3; ++i)
    {
        expect_close(Z[i], a * 9.0 + b * fy(i), i, "u");
        expect_close(Z[n3 + i], a * 9.0 + b * dv(i), i, "v");
    }

    // any other read writes the half out
    yu = StatePool::overwrite_with_difference(z, x, s);
    for (index_t i = 0; i < n3; ++i)
        yu[i] = fy(i);
    Z = values_of(z);
    EXPECT_EQ(f.pool->counters().materialized_differences, 1);
    for (index_t i = 0; i < n3; ++i)
        ASSERT_EQ(Z[n3 + i], (fy(i) - 9.0) * s) << i;
    N_VDestroy(z);
    N_VDestroy(y);
    N_VDestroy(x);
}

namespace
{
/// n values starting at the given offset (in values) from a 64-byte line boundary, so the
/// streaming loops' peel, whole lines and tail all run.
struct Misaligned
{
    std::vector<real_t> store;
    real_t* p = nullptr;
    Misaligned(index_t n, index_t offset) : store(static_cast<std::size_t>(n) + 16, -7.0)
    {
        p = store.data();
        p += values_to_line(p) + offset;
    }
};

void expect_close(const real_t* got, const std::function<real_t(index_t)>& want, index_t n, const char* what)
{
    for (index_t i = 0; i < n; ++i)
        expect_close(got[i], want(i), i, what);
}
} // namespace

TEST(StateVector, StreamingStoresWriteEveryValueOfLargeArrays)
{
    // arrays past kStreamBytes are written with streaming stores where the CPU has AVX-512: the
    // arkode-cd kick and the update with a recorded difference must still give every value
    const index_t n = static_cast<index_t>(kStreamBytes / sizeof(real_t)) + 1003;
    Misaligned v(n, 3), a(n, 1), vf(n, 5), du(n, 2);
    for (index_t i = 0; i < n; ++i)
        v.p[i] = fx(i), a.p[i] = fy(i);
    // without AVX-512 the kick and update run their plain loops: the values must be the same
    std::printf("large arrays: %s\n", stream_pays(n) ? "streamed" : "plain loops (no AVX-512 here)");
    const real_t h_prev = 0.7, h = 0.9;
    arkode_cd_kick(n, v.p, a.p, h_prev, h, vf.p, du.p, nullptr);
    expect_close(
        vf.p, [&](index_t i) { return fx(i) + 0.5 * h_prev * fy(i); }, n, "v(n)");
    expect_close(
        du.p, [&](index_t i) { return fx(i) + 0.5 * h_prev * fy(i) + 0.5 * h * fy(i); }, n, "v(n+1/2)");
    EXPECT_EQ(vf.p[n], -7.0); // nothing written past the end
    EXPECT_EQ(du.p[-1], -7.0);

    SUNContext ctx = nullptr;
    SUNContext_Create(nullptr, &ctx);
    {
        std::shared_ptr<StatePool> pool = StatePool::create(n);
        N_Vector x = pool->make_vector(ctx), y = N_VClone(x), z = N_VClone(x);
        const StatePool::Halves xh = StatePool::overwrite(x);
        for (index_t i = 0; i < n; ++i)
            xh.u[i] = fx(i), xh.v[i] = fy(i);
        real_t* yu = StatePool::overwrite_with_difference(y, x, 1.0 / h);
        std::copy(du.p, du.p + n, yu);
        N_VLinearSum(1.0, x, h, y, z);
        EXPECT_EQ(pool->counters().fused_differences, 1);
        const StatePool::Halves zh = StatePool::values(z);
        expect_close(
            zh.u, [&](index_t i) { return fx(i) + h * du.p[i]; }, n, "u(n+1)");
        expect_close(
            zh.v, [&](index_t i) { return fy(i) + h * ((du.p[i] - fy(i)) * (1.0 / h)); }, n, "v(n+1/2)");
        N_VDestroy(z);
        N_VDestroy(y);
        N_VDestroy(x);
    }
    SUNContext_Free(&ctx);
}

TEST(StreamStores, BatchesOfLargeLineAlignedFieldsStreamWholeLines)
{
    // the element and particle kernels' stress fields (6 components, structure of arrays): a
    // batch of 8 points is one line per component when the field starts on a line (LineVector,
    // kept by use_huge_pages) and n is a multiple of 8; then, past kStreamBytes, it streams
    const std::size_t n = (kStreamBytes / (6 * sizeof(real_t)) / 8 + 64) * 8;
    LineVector<real_t> field(6 * n + 8, -7.0);
    use_huge_pages(field);
    ASSERT_EQ(reinterpret_cast<std::uintptr_t>(field.data()) % 64, 0u);
    auto value = [](int k, std::size_t i) { return 1000.0 * k + 0.5 * static_cast<real_t>(i); };
    auto write = [&](real_t* out, std::size_t nn, std::size_t i0, bool may_stream)
    {
        real_t v[6][8];
        for (int k = 0; k < 6; ++k)
            for (int l = 0; l < 8; ++l)
                v[k][l] = value(k, i0 + l);
        const bool streamed = store_batch8<6>(v, out, nn, i0, may_stream);
        _mm_sfence();
        for (int k = 0; k < 6; ++k)
            for (int l = 0; l < 8; ++l)
                EXPECT_EQ(out[k * nn + i0 + l], value(k, i0 + l)) << "component " << k << ", point " << i0 + l;
        return streamed;
    };
    const bool avx512 = stream_pays(static_cast<index_t>(6 * n));
    for (std::size_t i0 : {std::size_t{0}, std::size_t{8}, n / 16 * 8, n - 8})
        EXPECT_EQ(write(field.data(), n, i0, true), avx512) << "batch at " << i0;
    EXPECT_FALSE(write(field.data(), n, 16, false)) << "the caller did not ask (no fence after it)";
    EXPECT_FALSE(write(field.data() + 1, n, 0, true)) << "lines not aligned";
    EXPECT_FALSE(write(field.data(), n - 4, 0, true)) << "n not a multiple of 8";
    EXPECT_FALSE(write(field.data(), 64, 0, true)) << "a field that fits in cache";
    EXPECT_EQ(field[6 * n], -7.0); // nothing past the end
}
