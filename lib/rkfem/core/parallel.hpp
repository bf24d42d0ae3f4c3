#pragma once
/// @file parallel.hpp
/// One loop shim over OpenMP. Kernels never spell pragmas; every loop carries a label so that
/// timers and profilers can name it.
#include <algorithm>
#include <array>
#include <exception>
#include <limits>
#include <memory>
#include <omp.h>
#include <vector>

#include "rkfem/core/types.hpp"

/// A vectorization hint for the loop that follows, with OpenMP's simd clauses if any:
/// `RKFEM_SIMD()` or `RKFEM_SIMD(reduction(+ : s) reduction(min : m))`. The one place the kernels'
/// loop pragmas are spelled, as parallel_for is for their threads.
#define RKFEM_PRAGMA(...) _Pragma(#__VA_ARGS__)
#define RKFEM_SIMD(...) RKFEM_PRAGMA(omp simd __VA_ARGS__)

namespace rkfem
{
/// The first exception thrown inside a parallel loop, kept to be rethrown after it (an exception
/// must not leave an OpenMP region): `catch (...) { errors.capture(); }` in the loop, then
/// `errors.rethrow()`, which throws it with its own type.
class ParallelErrors
{
  public:
    void capture()
    {
#pragma omp critical(rkfem_parallel_errors)
        if (!error_)
            error_ = std::current_exception();
    }
    void rethrow() const
    {
        if (error_)
            std::rethrow_exception(error_);
    }

  private:
    std::exception_ptr error_;
};

/// Runs body(i) for i in [0, n) on the OpenMP team (static schedule, so the assignment of
/// indices to threads is reproducible).
template <class Body> inline void parallel_for(const char* /*label*/, index_t n, Body&& body)
{
#pragma omp parallel for schedule(static)
    for (index_t i = 0; i < n; ++i)
        body(i);
}

/// Runs body(i) for i in [0, n) on the OpenMP team, each thread taking the next index when it
/// is free (dynamic schedule): for a few coarse tasks of uneven cost whose results do not depend
/// on the thread that runs them (ChunkedScatter's chunks, each with its own buffer), where a
/// static split of 3 chunks over 2 threads would leave one thread idle for a whole chunk.
template <class Body> inline void parallel_for_tasks(const char* /*label*/, index_t n, Body&& body)
{
#pragma omp parallel for schedule(dynamic, 1)
    for (index_t i = 0; i < n; ++i)
        body(i);
}

/// Minimum of f(i) over [0, n). Deterministic: min is exact regardless of order.
template <class F> inline real_t parallel_reduce_min(const char* /*label*/, index_t n, F&& f)
{
    real_t result = std::numeric_limits<real_t>::max();
#pragma omp parallel for schedule(static) reduction(min : result)
    for (index_t i = 0; i < n; ++i)
        result = std::min(result, f(i));
    return result;
}

/// Runs f(i) for i in [0, n) as parallel_for does, where f also says whether item i is flagged
/// (e.g. a value is not finite): true when any is. An OR reduction, which vectorizes beside the
/// loop's own work (a floating-point sum would run as one dependency chain).
template <class F> inline bool parallel_for_any(const char* /*label*/, index_t n, F&& f)
{
    int any = 0;
#pragma omp parallel for schedule(static) reduction(| : any)
    for (index_t i = 0; i < n; ++i)
        any |= f(i) ? 1 : 0;
    return any != 0;
}

/// K sums of f(i, out) over [0, n) at once (f adds its K terms into out), reproducible for a
/// given thread count only through a fixed-chunk two-level sum: chunks of 4096 are summed
/// serially, then chunk sums in order; one pass over the data.
template <int K, class F> inline std::array<real_t, K> parallel_reduce_sums(const char* /*label*/, index_t n, F&& f)
{
    constexpr index_t chunk = 4096;
    const index_t n_chunks = (n + chunk - 1) / chunk;
    std::array<real_t, K> total{};
    if (n_chunks <= 1)
    {
        for (index_t i = 0; i < n; ++i)
            f(i, total);
        return total;
    }
    // chunk sums on the stack for up to 4 M items (no allocation per call), on the heap beyond
    constexpr index_t max_stack = 1024;
    std::array<real_t, K> stack_sums[max_stack];
    std::vector<std::array<real_t, K>> heap;
    std::array<real_t, K>* sums = stack_sums;
    if (n_chunks > max_stack)
    {
        heap.resize(static_cast<std::size_t>(n_chunks));
        sums = heap.data();
    }
#pragma omp parallel for schedule(static)
    for (index_t c = 0; c < n_chunks; ++c)
    {
        std::array<real_t, K> s{};
        const index_t end = std::min(n, (c + 1) * chunk);
        for (index_t i = c * chunk; i < end; ++i)
            f(i, s);
        sums[c] = s;
    }
    for (index_t c = 0; c < n_chunks; ++c)
        for (int k = 0; k < K; ++k)
            total[k] += sums[c][k];
    return total;
}

/// Sum of f(i) over [0, n), reproducible for a given thread count only through a fixed-chunk
/// two-level sum: chunks of 4096 are summed serially, then chunk sums in order.
template <class F> inline real_t parallel_reduce_sum(const char* label, index_t n, F&& f)
{
    return parallel_reduce_sums<1>(label, n, [&](index_t i, std::array<real_t, 1>& out) { out[0] += f(i); })[0];
}

inline int max_threads()
{
    return omp_get_max_threads();
}
/// The team size of the parallel loops that follow (results do not depend on it).
inline void set_threads(int n)
{
    omp_set_num_threads(n);
}
} // namespace rkfem
