#include "rkfem/operators/contact_channel.hpp"

#include "rkfem/core/state_archive.hpp"

#include "rkfem/approximation/rk/kinematic_map.hpp"

namespace rkfem
{
void ContactChannel::resize(index_t n_nodes)
{
    n_nodes_ = n_nodes;
    std::vector<real_t>().swap(f);
    std::vector<char>().swap(mark_);
    touched_.clear();
    prev_nodes_.clear();
    prev_f_.clear();
}

void ContactChannel::clear()
{
    for (index_t i : touched_)
    {
        for (int d = 0; d < 3; ++d)
            f[3 * static_cast<std::size_t>(i) + d] = 0.0;
        mark_[static_cast<std::size_t>(i)] = 0;
    }
    touched_.clear();
}

void ContactChannel::add(index_t node, const Vec3& force)
{
    if (map_ == nullptr || !map_->carries_coefficients(node))
        return add_unknown(node, force);
    map_->for_row(node, [&](index_t j, real_t w) { add_unknown(j, w * force); });
}

void ContactChannel::allocate()
{
    f.assign(3 * static_cast<std::size_t>(n_nodes_), 0.0);
    mark_.assign(static_cast<std::size_t>(n_nodes_), 0);
}

void ContactChannel::add_unknown(index_t node, const Vec3& force)
{
    if (f.empty())
        allocate();
    const std::size_t i = static_cast<std::size_t>(node);
    if (!mark_[i])
    {
        mark_[i] = 1;
        touched_.push_back(node);
    }
    for (int d = 0; d < 3; ++d)
        f[3 * i + d] += force[d];
}

real_t ContactChannel::step_work(const real_t* u, const real_t* u_prev) const
{
    real_t w = 0.0;
    for (std::size_t k = 0; k < prev_nodes_.size(); ++k)
        for (int d = 0; d < 3; ++d)
        {
            const std::size_t j = 3 * static_cast<std::size_t>(prev_nodes_[k]) + d;
            w += 0.5 * prev_f_[3 * k + d] * (u[j] - u_prev[j]);
        }
    for (index_t i : touched_)
        for (int d = 0; d < 3; ++d)
        {
            const std::size_t j = 3 * static_cast<std::size_t>(i) + d;
            w += 0.5 * f[j] * (u[j] - u_prev[j]);
        }
    return w;
}

void ContactChannel::commit()
{
    prev_nodes_ = touched_; // capacity is reused
    prev_f_.resize(3 * touched_.size());
    for (std::size_t k = 0; k < touched_.size(); ++k)
        for (int d = 0; d < 3; ++d)
            prev_f_[3 * k + d] = f[3 * static_cast<std::size_t>(touched_[k]) + d];
}

void ContactChannel::save_state(StateArchive& a) const
{
    a.put("contact_channel.f", f);
    a.put("contact_channel.touched", touched_);
    a.put("contact_channel.mark", mark_);
    a.put("contact_channel.prev_nodes", prev_nodes_);
    a.put("contact_channel.prev_f", prev_f_);
}

void ContactChannel::load_state(const StateArchive& a)
{
    // the arrays as the checkpoint's run had them: none before its first contact force
    std::vector<real_t> saved_f;
    a.get("contact_channel.f", saved_f);
    if (saved_f.empty())
        resize(n_nodes_);
    else
    {
        allocate();
        a.get_same_size("contact_channel.f", f);
        a.get_same_size("contact_channel.mark", mark_);
    }
    a.get("contact_channel.touched", touched_);
    a.get("contact_channel.prev_nodes", prev_nodes_);
    a.get("contact_channel.prev_f", prev_f_);
}
} // namespace rkfem
