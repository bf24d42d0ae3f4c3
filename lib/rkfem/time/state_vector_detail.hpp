#pragma once
/// @file state_vector_detail.hpp
/// What the state vector's two files share (internal to time/): a vector's content (a storage,
/// shared copy on write, or a constant), reading and writing it, and the element-wise maps and sums
/// the N_Vector operations (state_vector_ops.cpp) are written with.
#include "rkfem/time/state_vector.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "rkfem/core/error.hpp"
#include "rkfem/core/huge_pages.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/stream_stores.hpp"

namespace rkfem::state_vector_detail
{
/// A vector: its values are a storage (shared copy on write) or, without one, a constant.
struct Content
{
    std::shared_ptr<StatePool> pool;
    StateStorage* s = nullptr;
    real_t value = 0.0; ///< the constant, when s == nullptr
};

inline Content& content(N_Vector v)
{
    return *static_cast<Content*>(v->content);
}
inline index_t half_len(N_Vector v)
{
    return content(v).pool->half_length();
}

/// The v half of a difference's base, for reading (taken back if it is lent).
inline const real_t* base_v(StatePool& pool, StateStorage* base)
{
    if (pool.v_lent(base))
        pool.reclaim();
    return base->half[1].data();
}

/// Forgets s's recorded v half (its values are about to be overwritten, or nobody needs them).
inline void drop_difference(StatePool& pool, StateStorage* s)
{
    if (s->diff_base == nullptr)
        return;
    StateStorage* base = s->diff_base;
    s->diff_base = nullptr;
    pool.release(base);
}

/// Writes s's recorded v half out: v_i = (u_i - base_v_i) * scale.
inline void materialize_difference(StatePool& pool, StateStorage* s)
{
    if (s->diff_base == nullptr)
        return;
    const real_t* __restrict u = s->half[0].data();
    const real_t* __restrict b = base_v(pool, s->diff_base);
    real_t* __restrict v = s->half[1].data();
    const real_t scale = s->diff_scale;
    parallel_for("rkfem::nv::materialize_difference", pool.half_length(),
                 [&](index_t i) { v[i] = (u[i] - b[i]) * scale; });
    drop_difference(pool, s);
    pool.count_difference(false);
}

/// The storage of x, for reading: a constant is materialized, a lent half taken back, a
/// recorded difference written out.
inline StateStorage* readable(Content& c)
{
    if (c.s == nullptr)
    {
        c.s = c.pool->acquire();
        for (auto& h : c.s->half)
        {
            real_t* p = h.data();
            const real_t value = c.value;
            parallel_for("rkfem::nv::materialize", static_cast<index_t>(h.size()), [&](index_t i) { p[i] = value; });
        }
        c.pool->count_pass();
    }
    else if (c.pool->is_lent(c.s))
        c.pool->reclaim();
    materialize_difference(*c.pool, c.s);
    c.pool->count_pass();
    return c.s;
}

/// The storage of z, for overwriting every value: its own (in place) or a fresh one.
inline StateStorage* writable(Content& c)
{
    if (c.s != nullptr && c.s->refs == 1)
    {
        if (c.pool->is_lent(c.s))
            c.pool->reclaim();
        drop_difference(*c.pool, c.s);
    }
    else
    {
        if (c.s != nullptr)
            c.pool->release(c.s);
        c.s = c.pool->acquire();
    }
    c.pool->count_pass();
    return c.s;
}

/// z_i = f(x_i) over both halves. Inputs are read before z is prepared, so z may be x.
template <class F> void map1(N_Vector x, N_Vector z, F f)
{
    const StateStorage* xs = readable(content(x));
    StateStorage* zs = writable(content(z));
    const index_t n = half_len(z);
    for (int h = 0; h < 2; ++h)
    {
        const real_t* px = xs->half[h].data();
        real_t* pz = zs->half[h].data();
        parallel_for("rkfem::nv::map1", n, [&](index_t i) { pz[i] = f(px[i]); });
    }
}

/// z_i = f(x_i, y_i) over both halves.
template <class F> void map2(N_Vector x, N_Vector y, N_Vector z, F f)
{
    const StateStorage* xs = readable(content(x));
    const StateStorage* ys = readable(content(y));
    StateStorage* zs = writable(content(z));
    const index_t n = half_len(z);
    for (int h = 0; h < 2; ++h)
    {
        const real_t *px = xs->half[h].data(), *py = ys->half[h].data();
        real_t* pz = zs->half[h].data();
        parallel_for("rkfem::nv::map2", n, [&](index_t i) { pz[i] = f(px[i], py[i]); });
    }
}

/// Sum over both halves of f(x_i) (fixed-chunk sums: independent of the thread count).
template <class F> real_t sum1(N_Vector x, F f)
{
    const StateStorage* xs = readable(content(x));
    const index_t n = half_len(x);
    real_t s = 0.0;
    for (int h = 0; h < 2; ++h)
    {
        const real_t* px = xs->half[h].data();
        s += parallel_reduce_sum("rkfem::nv::sum", n, [&](index_t i) { return f(px[i]); });
    }
    return s;
}

template <class F> real_t sum2(N_Vector x, N_Vector y, F f)
{
    const StateStorage* xs = readable(content(x));
    const StateStorage* ys = readable(content(y));
    const index_t n = half_len(x);
    real_t s = 0.0;
    for (int h = 0; h < 2; ++h)
    {
        const real_t *px = xs->half[h].data(), *py = ys->half[h].data();
        s += parallel_reduce_sum("rkfem::nv::sum", n, [&](index_t i) { return f(px[i], py[i]); });
    }
    return s;
}

/// Minimum over both halves of f(x_i).
template <class F> real_t min1(N_Vector x, F f)
{
    const StateStorage* xs = readable(content(x));
    const index_t n = half_len(x);
    real_t m = std::numeric_limits<real_t>::max();
    for (int h = 0; h < 2; ++h)
    {
        const real_t* px = xs->half[h].data();
        m = std::min(m, parallel_reduce_min("rkfem::nv::min", n, [&](index_t i) { return f(px[i]); }));
    }
    return m;
}

// ---- the N_Vector operations ----
/// Puts this file's operations into v's ops table (state_vector_ops.cpp).
void install_ops(N_Vector v);
} // namespace rkfem::state_vector_detail
