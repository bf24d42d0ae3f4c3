#include "rkfem/time/state_vector.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "rkfem/core/error.hpp"
#include "rkfem/core/huge_pages.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/core/stream_stores.hpp"

#include "rkfem/time/state_vector_detail.hpp"

namespace rkfem
{
using namespace state_vector_detail;

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
} // namespace rkfem
