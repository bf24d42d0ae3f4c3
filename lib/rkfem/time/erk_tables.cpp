#include "rkfem/time/erk_tables.hpp"

#include <arkode/arkode_butcher_erk.h>
#include <complex>
#include <vector>

#include "rkfem/core/error.hpp"

namespace rkfem
{
void* make_erk_table(const std::string& name, int* stages, int* order)
{
    ARKodeButcherTable B = nullptr;
    if (name == "FORWARD_EULER")
    {
        realtype c[1] = {0}, A[1] = {0}, b[1] = {1};
        B = ARKodeButcherTable_Create(1, 1, 0, c, A, b, nullptr);
    }
    else if (name == "RK4")
    {
        realtype c[4] = {0, 0.5, 0.5, 1};
        realtype A[16] = {0, 0, 0, 0, 0.5, 0, 0, 0, 0, 0.5, 0, 0, 0, 0, 1, 0};
        realtype b[4] = {1.0 / 6, 1.0 / 3, 1.0 / 3, 1.0 / 6};
        B = ARKodeButcherTable_Create(4, 4, 0, c, A, b, nullptr);
    }
    else if (name == "SSPRK3")
    {
        realtype c[3] = {0, 1, 0.5};
        realtype A[9] = {0, 0, 0, 1, 0, 0, 0.25, 0.25, 0};
        realtype b[3] = {1.0 / 6, 1.0 / 6, 2.0 / 3};
        B = ARKodeButcherTable_Create(3, 3, 0, c, A, b, nullptr);
    }
    else
        B = ARKodeButcherTable_LoadERKByName(name.c_str());
    RKFEM_REQUIRE(B != nullptr, "unknown ERK table '" << name << "'");
    if (stages)
        *stages = B->stages;
    if (order)
        *order = B->q;
    return B;
}

void free_erk_table(void* table)
{
    ARKodeButcherTable_Free(static_cast<ARKodeButcherTable>(table));
}

real_t erk_imaginary_stability_limit(const std::string& name)
{
    // R(z) = sum_k g_k z^k with g_0 = 1, g_k = b^T A^(k-1) 1 (A strictly lower triangular: k <= s)
    auto* B = static_cast<ARKodeButcherTable>(make_erk_table(name));
    const int s = B->stages;
    std::vector<real_t> g{1.0}, w(static_cast<std::size_t>(s), 1.0), next(w.size());
    for (int k = 1; k <= s; ++k)
    {
        real_t gk = 0.0;
        for (int i = 0; i < s; ++i)
            gk += B->b[i] * w[static_cast<std::size_t>(i)];
        g.push_back(gk);
        for (int i = 0; i < s; ++i)
        {
            next[static_cast<std::size_t>(i)] = 0.0;
            for (int j = 0; j < s; ++j)
                next[static_cast<std::size_t>(i)] += B->A[i][j] * w[static_cast<std::size_t>(j)];
        }
        w.swap(next);
    }
    free_erk_table(B);
    auto stable = [&](real_t y)
    {
        std::complex<real_t> r = 0.0, zk = 1.0;
        for (const real_t gk : g)
        {
            r += gk * zk;
            zk *= std::complex<real_t>(0.0, y);
        }
        return std::abs(r) <= 1.0 + 1e-14; // Heun-Euler: |R(i y)| = 1 + y^4 / 8 + ..., 1e-13 at y = 1e-3
    };
    // the first y past which |R(i y)| > 1, scanned by 1e-3 up to 10, then bisected
    const real_t step = 1e-3;
    real_t y = 0.0;
    while (y + step <= 10.0 && stable(y + step))
        y += step;
    real_t lo = y, hi = y + step;
    while (hi - lo > 1e-7)
        (stable(0.5 * (lo + hi)) ? lo : hi) = 0.5 * (lo + hi);
    return lo < step ? 0.0 : lo;
}
} // namespace rkfem
