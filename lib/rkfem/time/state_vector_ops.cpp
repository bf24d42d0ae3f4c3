/// @file state_vector_ops.cpp
/// The SUNDIALS N_Vector operations of the state vector (element-wise, over its storages).
#include "rkfem/time/state_vector_detail.hpp"

namespace rkfem
{
using namespace state_vector_detail;
namespace
{
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
                         const simd::dvec va = simd::broadcast(a), vb = simd::broadcast(b), vs = simd::broadcast(scale);
                         stream_range(
                             i0, i1, zu, [&](index_t i) { return a * xu[i] + b * yu[i]; },
                             [&](index_t i) { return simd::mul_add(va, simd::load(xu + i), vb * simd::load(yu + i)); });
                         stream_range(
                             i0, i1, zv, [&](index_t i) { return a * xv[i] + b * ((yu[i] - bv[i]) * scale); },
                             [&](index_t i)
                             {
                                 const simd::dvec yv = (simd::load(yu + i) - simd::load(bv + i)) * vs;
                                 return simd::mul_add(va, simd::load(xv + i), vb * yv);
                             });
                         simd::stream_fence();
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

} // namespace

void state_vector_detail::install_ops(N_Vector v)
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

bool is_state_vector(N_Vector y)
{
    return y != nullptr && y->ops != nullptr && y->ops->nvclone == op_clone;
}
} // namespace rkfem
