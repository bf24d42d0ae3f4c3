#include "rkfem/time/state_vector.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "rkfem/core/error.hpp"
#include "rkfem/core/huge_pages.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/stream_stores.hpp"

namespace rkfem
{
namespace
{
/// A vector: its values are a storage (shared copy on write) or, without one, a constant.
struct Content
{
    std::shared_ptr<StatePool> pool;
    StateStorage* s = nullptr;
    real_t value = 0.0; ///< the constant, when s == nullptr
};

Content& content(N_Vector v)
{
    return *static_cast<Content*>(v->content);
}
index_t half_len(N_Vector v)
{
    return content(v).pool->half_length();
}

/// The v half of a difference's base, for reading (taken back if it is lent).
const real_t* base_v(StatePool& pool, StateStorage* base)
{
    if (pool.v_lent(base))
        pool.reclaim();
    return base->half[1].data();
}

/// Forgets s's recorded v half (its values are about to be overwritten, or nobody needs them).
void drop_difference(StatePool& pool, StateStorage* s)
{
    if (s->diff_base == nullptr)
        return;
    StateStorage* base = s->diff_base;
    s->diff_base = nullptr;
    pool.release(base);
}

/// Writes s's recorded v half out: v_i = (u_i - base_v_i) * scale.
void materialize_difference(StatePool& pool, StateStorage* s)
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
StateStorage* readable(Content& c)
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
StateStorage* writable(Content& c)
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
N_Vector_ID op_get_id(N_Vector)
{
    return SUNDIALS_NVEC_CUSTOM;
}

N_Vector op_clone_empty(N_Vector w)
{
    N_Vector v = N_VNewEmpty(w->sunctx);
    if (v == nullptr)
        return nullptr;
    if (N_VCopyOps(w, v) != 0)
    {
        N_VFreeEmpty(v);
        return nullptr;
    }
    v->content = new Content{content(w).pool};
    return v;
}

N_Vector op_clone(N_Vector w)
{
    return op_clone_empty(w);
} // values: the constant 0

void op_destroy(N_Vector v)
{
    if (v == nullptr)
        return;
    if (v->content != nullptr)
    {
        Content* c = static_cast<Content*>(v->content);
        if (c->s != nullptr)
            c->pool->release(c->s);
        delete c;
        v->content = nullptr;
    }
    N_VFreeEmpty(v);
}

void op_space(N_Vector v, sunindextype* lrw, sunindextype* liw)
{
    *lrw = 2 * static_cast<sunindextype>(half_len(v));
    *liw = 1;
}

sunindextype op_length(N_Vector v)
{
    return 2 * static_cast<sunindextype>(half_len(v));
}

// the halves are two arrays: there is no one pointer to hand out (ERKStep never asks)
realtype* op_array_pointer(N_Vector)
{
    return nullptr;
}

/// z = a x + b y over [i0, i1) where y's v half is recorded: y_v = (y_u - base_v) scale.
void linear_sum_difference(index_t i0, index_t i1, real_t a, const real_t* __restrict xu, const real_t* __restrict xv,
                           real_t b, const real_t* __restrict yu, const real_t* __restrict bv, real_t scale,
                           real_t* __restrict zu, real_t* __restrict zv)
{
    for (index_t i = i0; i < i1; ++i)
    {
        const real_t yv = (yu[i] - bv[i]) * scale;
        zu[i] = a * xu[i] + b * yu[i];
        zv[i] = a * xv[i] + b * yv;
    }
}

void op_linear_sum(realtype a, N_Vector x, realtype b, N_Vector y, N_Vector z)
{
    auto recorded = [](const Content& c) { return c.s != nullptr && c.s->diff_base != nullptr; };
    if (recorded(content(x)) && !recorded(content(y)))
    {
        std::swap(a, b); // ERKStep passes (y(n), f) or (f, y(n)): the recorded one goes second
        std::swap(x, y);
    }
    Content& cy = content(y);
    if (!recorded(cy) || content(x).s == cy.s)
    {
        map2(x, y, z, [a, b](real_t xi, real_t yi) { return a * xi + b * yi; });
        return;
    }
    // y's v half is a recorded difference: z = a x + b y in one loop that forms it on the fly
    // (the operations of writing it out first: the same values, up to where the compiler fuses
    // a multiply and an add)
    StatePool& pool = *cy.pool;
    const StateStorage* xs = readable(content(x));
    StateStorage* ys = cy.s;
    StateStorage* base = ys->diff_base;
    const real_t scale = ys->diff_scale;
    ++ys->refs; // z may be y: its storage and base stay until the loop has run
    ++base->refs;
    const real_t* bv = base_v(pool, base);
    StateStorage* zs = writable(content(z));
    const real_t *xu = xs->half[0].data(), *xv = xs->half[1].data(), *yu = ys->half[0].data();
    real_t *zu = zs->half[0].data(), *zv = zs->half[1].data();
    const index_t n = pool.half_length();
    constexpr index_t block = 2048;
    [[maybe_unused]] const bool stream = stream_pays(n); // read on AVX-512 builds only
    parallel_for("rkfem::nv::linear_sum_difference", (n + block - 1) / block,
                 [&](index_t blk)
                 {
                     const index_t i0 = blk * block, i1 = std::min(n, i0 + block);
#if defined(__AVX512F__)
                     if (stream)
                     {
                         // one array at a time over the block (stream_stores.hpp)
                         const __m512d va = _mm512_set1_pd(a), vb = _mm512_set1_pd(b), vs = _mm512_set1_pd(scale);
                         stream_range(
                             i0, i1, zu, [&](index_t i) { return a * xu[i] + b * yu[i]; },
                             [&](index_t i) {
                                 return _mm512_fmadd_pd(va, _mm512_loadu_pd(xu + i),
                                                        _mm512_mul_pd(vb, _mm512_loadu_pd(yu + i)));
                             });
                         stream_range(
                             i0, i1, zv, [&](index_t i) { return a * xv[i] + b * ((yu[i] - bv[i]) * scale); },
                             [&](index_t i)
                             {
                                 const __m512d yv =
                                     _mm512_mul_pd(_mm512_sub_pd(_mm512_loadu_pd(yu + i), _mm512_loadu_pd(bv + i)), vs);
                                 return _mm512_fmadd_pd(va, _mm512_loadu_pd(xv + i), _mm512_mul_pd(vb, yv));
                             });
                         _mm_sfence();
                         return;
                     }
#endif
                     linear_sum_difference(i0, i1, a, xu, xv, b, yu, bv, scale, zu, zv);
                 });
    pool.count_pass(); // y read (x's and z's passes are counted by readable and writable)
    pool.count_difference(true);
    pool.release(base);
    pool.release(ys);
}

void op_const(realtype c, N_Vector z)
{
    Content& cz = content(z);
    if (cz.s != nullptr)
        cz.pool->release(cz.s);
    cz.s = nullptr;
    cz.value = c;
}

void op_prod(N_Vector x, N_Vector y, N_Vector z)
{
    map2(x, y, z, [](real_t xi, real_t yi) { return xi * yi; });
}

void op_div(N_Vector x, N_Vector y, N_Vector z)
{
    map2(x, y, z, [](real_t xi, real_t yi) { return xi / yi; });
}

void op_scale(realtype c, N_Vector x, N_Vector z)
{
    Content &cx = content(x), &cz = content(z);
    if (c == 1.0)
    {
        // a copy: share x's storage (or its constant); nothing is read or written
        if (cx.s != cz.s || cx.s == nullptr)
        {
            if (cx.s != nullptr)
                ++cx.s->refs;
            if (cz.s != nullptr)
                cz.pool->release(cz.s);
            cz.s = cx.s;
            cz.value = cx.value;
        }
        cz.pool->count_shared_copy();
        return;
    }
    if (cx.s == nullptr)
    {
        op_const(c * cx.value, z);
        return;
    }
    map1(x, z, [c](real_t xi) { return c * xi; });
}

void op_abs(N_Vector x, N_Vector z)
{
    map1(x, z, [](real_t xi) { return std::abs(xi); });
}

void op_inv(N_Vector x, N_Vector z)
{
    map1(x, z, [](real_t xi) { return 1.0 / xi; });
}

void op_add_const(N_Vector x, realtype b, N_Vector z)
{
    map1(x, z, [b](real_t xi) { return xi + b; });
}

realtype op_dot(N_Vector x, N_Vector y)
{
    return sum2(x, y, [](real_t xi, real_t yi) { return xi * yi; });
}

realtype op_max_norm(N_Vector x)
{
    return -min1(x, [](real_t xi) { return -std::abs(xi); });
}

/// sum (x_i w_i)^2; constant weights c need no pass over w, and none over x when c = 0 (the
/// fixed-step steppers' error weights: no accuracy is asked of a fixed step).
realtype op_wsqrsum_local(N_Vector x, N_Vector w)
{
    const Content& cw = content(w);
    if (cw.s == nullptr)
    {
        if (cw.value == 0.0)
            return 0.0;
        return cw.value * cw.value * sum1(x, [](real_t xi) { return xi * xi; });
    }
    return sum2(x, w,
                [](real_t xi, real_t wi)
                {
                    const real_t p = xi * wi;
                    return p * p;
                });
}

realtype op_wrms_norm(N_Vector x, N_Vector w)
{
    return std::sqrt(op_wsqrsum_local(x, w) / static_cast<real_t>(op_length(x)));
}

realtype op_wrms_norm_mask(N_Vector x, N_Vector w, N_Vector id)
{
    const StateStorage* xs = readable(content(x));
    const StateStorage* ws = readable(content(w));
    const StateStorage* is = readable(content(id));
    const index_t n = half_len(x);
    real_t s = 0.0;
    for (int h = 0; h < 2; ++h)
    {
        const real_t *px = xs->half[h].data(), *pw = ws->half[h].data(), *pi = is->half[h].data();
        s += parallel_reduce_sum("rkfem::nv::wsqrsum_mask", n,
                                 [&](index_t i)
                                 {
                                     const real_t p = pi[i] > 0.0 ? px[i] * pw[i] : 0.0;
                                     return p * p;
                                 });
    }
    return std::sqrt(s / static_cast<real_t>(op_length(x)));
}

realtype op_min(N_Vector x)
{
    return min1(x, [](real_t xi) { return xi; });
}

realtype op_wl2_norm(N_Vector x, N_Vector w)
{
    return std::sqrt(sum2(x, w,
                          [](real_t xi, real_t wi)
                          {
                              const real_t p = xi * wi;
                              return p * p;
                          }));
}

realtype op_l1_norm(N_Vector x)
{
    return sum1(x, [](real_t xi) { return std::abs(xi); });
}

void op_compare(realtype c, N_Vector x, N_Vector z)
{
    map1(x, z, [c](real_t xi) { return std::abs(xi) >= c ? 1.0 : 0.0; });
}

booleantype op_inv_test(N_Vector x, N_Vector z)
{
    const real_t zeros = sum1(x, [](real_t xi) { return xi == 0.0 ? 1.0 : 0.0; });
    map1(x, z, [](real_t xi) { return xi == 0.0 ? 0.0 : 1.0 / xi; });
    return zeros == 0.0 ? SUNTRUE : SUNFALSE;
}

/// m_i = 1 where x_i violates constraint c_i (2: > 0, 1: >= 0, -1: <= 0, -2: < 0), else 0.
booleantype op_constr_mask(N_Vector c, N_Vector x, N_Vector m)
{
    map2(c, x, m,
         [](real_t ci, real_t xi)
         {
             const bool bad = (ci == 2.0 && !(xi > 0.0)) || (ci == 1.0 && !(xi >= 0.0)) ||
                              (ci == -1.0 && !(xi <= 0.0)) || (ci == -2.0 && !(xi < 0.0));
             return bad ? 1.0 : 0.0;
         });
    return sum1(m, [](real_t mi) { return mi; }) == 0.0 ? SUNTRUE : SUNFALSE;
}

realtype op_min_quotient(N_Vector num, N_Vector denom)
{
    const StateStorage* ns = readable(content(num));
    const StateStorage* ds = readable(content(denom));
    const index_t n = half_len(num);
    real_t m = std::numeric_limits<real_t>::max();
    for (int h = 0; h < 2; ++h)
    {
        const real_t *pn = ns->half[h].data(), *pd = ds->half[h].data();
        m = std::min(m, parallel_reduce_min("rkfem::nv::min_quotient", n,
                                            [&](index_t i) {
                                                return pd[i] == 0.0 ? std::numeric_limits<real_t>::max()
                                                                    : pn[i] / pd[i];
                                            }));
    }
    return m;
}

/// z = sum_k c_k X_k; z may be one of the X_k (ARKODE's accumulating form).
int op_linear_combination(int nv, realtype* c, N_Vector* X, N_Vector z)
{
    if (nv == 1)
    {
        op_scale(c[0], X[0], z);
        return 0;
    }
    if (nv == 2)
    {
        op_linear_sum(c[0], X[0], c[1], X[1], z);
        return 0;
    }
    constexpr int max_terms = 32;
    RKFEM_REQUIRE(nv <= max_terms, "N_VLinearCombination: " << nv << " terms, at most " << max_terms);
    const StateStorage* xs[max_terms];
    for (int k = 0; k < nv; ++k)
        xs[k] = readable(content(X[k]));
    StateStorage* zs = writable(content(z));
    const index_t n = half_len(z);
    for (int h = 0; h < 2; ++h)
    {
        const real_t* px[max_terms];
        for (int k = 0; k < nv; ++k)
            px[k] = xs[k]->half[h].data();
        real_t* pz = zs->half[h].data();
        parallel_for("rkfem::nv::linear_combination", n,
                     [&](index_t i)
                     {
                         real_t s = c[0] * px[0][i];
                         for (int k = 1; k < nv; ++k)
                             s += c[k] * px[k][i];
                         pz[i] = s;
                     });
    }
    return 0;
}

/// Z_k = a_k x + Y_k.
int op_scale_add_multi(int nv, realtype* a, N_Vector x, N_Vector* Y, N_Vector* Z)
{
    for (int k = 0; k < nv; ++k)
        op_linear_sum(a[k], x, 1.0, Y[k], Z[k]);
    return 0;
}

void install_ops(N_Vector v)
{
    N_Vector_Ops o = v->ops;
    o->nvgetvectorid = op_get_id;
    o->nvclone = op_clone;
    o->nvcloneempty = op_clone_empty;
    o->nvdestroy = op_destroy;
    o->nvspace = op_space;
    o->nvgetarraypointer = op_array_pointer;
    o->nvgetlength = op_length;
    o->nvgetlocallength = op_length;
    o->nvlinearsum = op_linear_sum;
    o->nvconst = op_const;
    o->nvprod = op_prod;
    o->nvdiv = op_div;
    o->nvscale = op_scale;
    o->nvabs = op_abs;
    o->nvinv = op_inv;
    o->nvaddconst = op_add_const;
    o->nvdotprod = op_dot;
    o->nvmaxnorm = op_max_norm;
    o->nvwrmsnorm = op_wrms_norm;
    o->nvwrmsnormmask = op_wrms_norm_mask;
    o->nvmin = op_min;
    o->nvwl2norm = op_wl2_norm;
    o->nvl1norm = op_l1_norm;
    o->nvcompare = op_compare;
    o->nvinvtest = op_inv_test;
    o->nvconstrmask = op_constr_mask;
    o->nvminquotient = op_min_quotient;
    o->nvlinearcombination = op_linear_combination;
    o->nvscaleaddmulti = op_scale_add_multi;
    o->nvdotprodlocal = op_dot;
    o->nvmaxnormlocal = op_max_norm;
    o->nvminlocal = op_min;
    o->nvl1normlocal = op_l1_norm;
    o->nvinvtestlocal = op_inv_test;
    o->nvconstrmasklocal = op_constr_mask;
    o->nvminquotientlocal = op_min_quotient;
    o->nvwsqrsumlocal = op_wsqrsum_local;
}
} // namespace

std::shared_ptr<StatePool> StatePool::create(index_t n3)
{
    std::shared_ptr<StatePool> p(new StatePool(n3));
    p->self_ = p;
    return p;
}

StatePool::~StatePool() = default;

N_Vector StatePool::make_vector(SUNContext ctx)
{
    N_Vector v = N_VNewEmpty(ctx);
    RKFEM_REQUIRE(v != nullptr, "N_VNewEmpty failed");
    install_ops(v);
    v->content = new Content{self_.lock()};
    return v;
}

StateStorage* StatePool::acquire()
{
    StateStorage* s = nullptr;
    if (!free_.empty())
    {
        s = free_.back();
        free_.pop_back();
    }
    else
    {
        all_.push_back(std::make_unique<StateStorage>());
        s = all_.back().get();
        for (auto& h : s->half)
        {
            h.assign(static_cast<std::size_t>(n3_), 0.0);
            use_huge_pages(h);
        }
        ++counters_.storages;
    }
    s->refs = 1;
    return s;
}

void StatePool::release(StateStorage* s)
{
    if (--s->refs > 0)
        return;
    if (s == lent_)
        reclaim();
    drop_difference(*this, s);
    free_.push_back(s);
}

void StatePool::reclaim()
{
    if (lent_ == nullptr)
        return;
    if (lent_u_ != nullptr)
        std::swap(*lent_u_, lent_->half[0]);
    if (lent_v_ != nullptr)
        std::swap(*lent_v_, lent_->half[1]);
    lent_ = nullptr;
    lent_u_ = lent_v_ = nullptr;
}

void StatePool::lend(N_Vector y, std::vector<real_t>& u, std::vector<real_t>& v)
{
    RKFEM_REQUIRE(static_cast<index_t>(u.size()) == n3_ && static_cast<index_t>(v.size()) == n3_,
                  "StatePool::lend: arrays of " << u.size() << " and " << v.size() << " values, expected " << n3_);
    reclaim();
    Content& c = content(y);
    StateStorage* s = readable(c);
    --counters_.passes; // lending reads nothing
    std::swap(u, s->half[0]);
    std::swap(v, s->half[1]);
    lent_ = s;
    lent_u_ = &u;
    lent_v_ = &v;
}

void StatePool::return_v()
{
    if (lent_ != nullptr && lent_v_ != nullptr)
    {
        std::swap(*lent_v_, lent_->half[1]);
        lent_v_ = nullptr;
    }
}

void StatePool::detach()
{
    lent_ = nullptr;
    lent_u_ = lent_v_ = nullptr;
}

StatePool::Halves StatePool::values(N_Vector y)
{
    StateStorage* s = readable(content(y));
    return {s->half[0].data(), s->half[1].data()};
}

StatePool::Halves StatePool::overwrite(N_Vector y)
{
    StateStorage* s = writable(content(y));
    return {s->half[0].data(), s->half[1].data()};
}

real_t* StatePool::overwrite_with_difference(N_Vector y, N_Vector x, real_t scale)
{
    Content& cx = content(x);
    if (cx.s == nullptr)
        readable(cx); // a constant gets values to refer to
    StateStorage* base = cx.s;
    ++base->refs; // before y is prepared: y's old storage may be x's
    StateStorage* s = writable(content(y));
    RKFEM_REQUIRE(s != base, "StatePool::overwrite_with_difference: y and x share a storage");
    s->diff_base = base;
    s->diff_scale = scale;
    return s->half[0].data();
}

StatePool::Ref::Ref(N_Vector y)
{
    Content& c = content(y);
    if (c.s == nullptr)
        readable(c); // a constant gets values to hold
    pool_ = c.pool;
    s_ = c.s;
    ++s_->refs;
}

StatePool::Ref& StatePool::Ref::operator=(Ref&& o) noexcept
{
    if (this != &o)
    {
        reset();
        pool_ = std::move(o.pool_);
        s_ = o.s_;
        o.s_ = nullptr;
    }
    return *this;
}

void StatePool::Ref::reset()
{
    if (s_ != nullptr)
        pool_->release(s_);
    s_ = nullptr;
    pool_.reset();
}

const std::vector<real_t>& StatePool::Ref::half(int h) const
{
    RKFEM_REQUIRE(s_ != nullptr, "StatePool::Ref: empty");
    if (pool_->is_lent(s_))
        pool_->reclaim();
    return s_->half[h];
}

bool is_state_vector(N_Vector y)
{
    return y != nullptr && y->ops != nullptr && y->ops->nvclone == op_clone;
}
} // namespace rkfem
