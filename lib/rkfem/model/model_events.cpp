// Events between steps that change the discretization (erosion; conversion in
// adaptivity/conversion.cpp), and the assembly plan
// they keep up to date.
#include "rkfem/model/model.hpp"

#include <algorithm>
#include <utility>

#include "rkfem/approximation/fem/hex8_volume_gradient.hpp"
#include "rkfem/core/error.hpp"
#include "rkfem/core/parallel.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <sstream>

namespace rkfem
{
void Model::remove_elements(index_t block, const std::vector<char>& keep)
{
    RKFEM_REQUIRE(block >= 0 && block < static_cast<index_t>(meshes.size()), "remove_elements: no block " << block);
    RKFEM_REQUIRE(!nodal_block(block), "remove_elements: part '" << parts[block].name
                                                                 << "' is integrated at its nodes; only Gauss-point "
                                                                    "FE parts lose elements");
    eroded_.resize(meshes.size());
    drop_elements(block, keep, eroded_[static_cast<std::size_t>(block)]);
}

void Model::drop_elements(index_t block, const std::vector<char>& keep, ErodedElements& gone)
{
    const HexBlock& blk = meshes[block];
    for (index_t e = 0; e < blk.n_elements(); ++e)
        if (!keep[static_cast<std::size_t>(e)])
        {
            gone.conn.insert(gone.conn.end(), blk.conn.begin() + 8 * e, blk.conn.begin() + 8 * e + 8);
            gone.volume0.push_back(blk.volume0[static_cast<std::size_t>(e)]);
        }
    meshes[block].remove_elements(keep, nodes);
    index_t offset = 0;
    for (std::size_t ip = 0; ip < parts.size(); ++ip)
    {
        parts[ip].element_offset = offset;
        offset += meshes[ip].n_elements();
    }
    plan_assembly();
    refresh_contact_surfaces(); // eroding contact: the newly exposed faces join the surfaces
    ++topology_version_;
}

namespace
{
/// An element's step as the kernels take it: V over its largest face area, over the wave speed.
real_t area_time_step(const real_t (&x)[8][3], real_t V, real_t c)
{
    const real_t area = largest_face_area(x);
    return area > 0.0 ? V / area / c : 0.0;
}
} // namespace

void Model::element_corners(index_t block, index_t e, real_t (&x)[8][3], real_t (&X)[8][3]) const
{
    const HexBlock& blk = meshes[static_cast<std::size_t>(block)];
    for (int I = 0; I < 8; ++I)
        for (int d = 0; d < 3; ++d)
        {
            const std::size_t j = 3 * static_cast<std::size_t>(blk.conn[8 * e + I]) + d;
            x[I][d] = nodes.x[j];
            X[I][d] = nodes.x0[j];
        }
    for (int I = 0; I < 8; ++I)
        if (kinematics.carries_coefficients(blk.conn[8 * e + I])) // a particle of a coupled part
        {
            const Vec3 p = kinematics.position(nodes.x0, nodes.u, blk.conn[8 * e + I]);
            for (int d = 0; d < 3; ++d)
                x[I][d] = p[d];
        }
}

namespace
{
/// An element's shape measures, each formed when first asked for (the erosion and conversion
/// criteria read one or two of them, every step, for every element): the same expressions
/// whichever are asked, so the same values as element_shape's.
class ShapeMeasures
{
  public:
    ShapeMeasures(const Model& m, index_t block, index_t e)
        : c_(m.meshes[static_cast<std::size_t>(block)].material.wave_speed()),
          conn_(m.meshes[static_cast<std::size_t>(block)].conn.data() + 8 * static_cast<std::size_t>(e))
    {
        m.element_corners(block, e, x_, X_);
    }
    /// the largest principal logarithmic strain of the mean deformation gradient
    /// F = sum_I x_I (x) b0_I / V0 (lambda_max^2 the largest eigenvalue of F^T F)
    real_t principal_strain()
    {
        reference();
        Eigen::Matrix3d F = Eigen::Matrix3d::Zero();
        for (int I = 0; I < 8; ++I)
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j)
                    F(i, j) += x_[I][i] * b0_[I][j] / V0_;
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
        eig.computeDirect(F.transpose() * F, Eigen::EigenvaluesOnly);
        return 0.5 * std::log(std::max(eig.eigenvalues().maxCoeff(), 1e-300));
    }
    real_t volumetric_strain()
    {
        reference();
        return volume() / V0_ - 1.0;
    }
    /// the element's step as the kernels take it: V over its largest face area, over the wave speed
    real_t time_step() { return area_time_step(x_, volume(), c_); }
    /// the smallest scaled corner Jacobian (1 a box; degenerate corners skipped: hex_mesh.hpp)
    real_t scaled_jacobian() const { return smallest_scaled_jacobian(x_, conn_); }
    /// the longest edge over the shortest (hex_mesh.hpp)
    real_t aspect_ratio() const { return edge_aspect_ratio(x_, conn_); }

  private:
    void reference()
    {
        if (!have_V0_)
            V0_ = hex8_volume_gradient(X_, b0_);
        have_V0_ = true;
    }
    real_t volume()
    {
        if (!have_V_)
        {
            real_t b[8][3];
            V_ = hex8_volume_gradient(x_, b);
        }
        have_V_ = true;
        return V_;
    }
    real_t x_[8][3], X_[8][3], b0_[8][3];
    real_t V_ = 0.0, V0_ = 0.0;
    bool have_V_ = false, have_V0_ = false;
    real_t c_;
    const index_t* conn_;
};
} // namespace

Model::ElementShape Model::element_shape(index_t block, index_t e) const
{
    ShapeMeasures m(*this, block, e);
    ElementShape g;
    g.principal_strain = m.principal_strain();
    g.volumetric_strain = m.volumetric_strain();
    g.time_step = m.time_step();
    return g;
}

real_t Model::element_time_step(index_t block, index_t e) const
{
    return ShapeMeasures(*this, block, e).time_step();
}

bool Model::meets(const ElementCriteria& c, index_t b, index_t e) const
{
    if ((c.plastic_strain > 0 && element_history(b, e, History::PlasticStrain) >= c.plastic_strain) ||
        (c.damage > 0 && element_history(b, e, History::Damage) >= c.damage))
        return true;
    if (!c.geometric())
        return false;
    ShapeMeasures g(*this, b, e); // only the measures the criteria name
    return (c.principal_strain > 0 && g.principal_strain() >= c.principal_strain) ||
           (c.volumetric_strain > 0 && g.volumetric_strain() >= c.volumetric_strain) ||
           (c.time_step > 0 && g.time_step() < c.time_step) ||
           (c.scaled_jacobian > 0 && g.scaled_jacobian() <= c.scaled_jacobian) ||
           (c.aspect_ratio > 0 && g.aspect_ratio() >= c.aspect_ratio);
}

bool Model::benign(const ElementCriteria::Reversion& r, index_t b, index_t e) const
{
    if ((r.plastic_strain >= 0 && element_history(b, e, History::PlasticStrain) > r.plastic_strain) ||
        (r.damage >= 0 && element_history(b, e, History::Damage) > r.damage))
        return false;
    if (r.scaled_jacobian <= 0 && r.aspect_ratio <= 0)
        return true;
    const ShapeMeasures g(*this, b, e);
    return !(r.scaled_jacobian > 0 && g.scaled_jacobian() < r.scaled_jacobian) &&
           !(r.aspect_ratio > 0 && g.aspect_ratio() > r.aspect_ratio);
}

namespace
{
/// Runs an event; an error it throws (an event that cannot be made is no input error) stops the
/// run there as an instability does, with its output so far and this state written.
template <class Event> void stops_the_run(real_t t, std::int64_t step, Event&& event)
{
    try
    {
        event();
    }
    catch (const InstabilityError&)
    {
        throw;
    }
    catch (const Error& e)
    {
        std::ostringstream os;
        os << e.what() << " (at t = " << t << " s, step " << step << ")";
        throw InstabilityError(os.str(), t);
    }
}
} // namespace

bool Model::check_due(real_t& next, real_t t, real_t interval)
{
    if (interval <= 0.0)
        return true;
    if (t < next)
        return false;
    next = (std::floor(t / interval * (1 + kScheduleSlack)) + 1) * interval;
    return true;
}

bool Model::apply_events(real_t t, std::int64_t step)
{
    bool changed = false;
    for (index_t b = 0; b < static_cast<index_t>(meshes.size()); ++b)
    {
        const PartSpec& ps = deck_.parts[static_cast<std::size_t>(b)];
        const index_t ne = meshes[b].n_elements();
        if (ps.refinement.active())
        {
            stops_the_run(t, step, [&] { changed = refinement_events(b, t) || changed; });
            if (!ps.converts())
                continue;
        }
        if (ps.converts())
        {
            // evolutionary coupling: FE and transition elements that meet the criteria turn RK
            // (at the first step end at or past each multiple of the interval)
            next_conversion_check_.resize(meshes.size(), 0.0);
            if (!check_due(next_conversion_check_[static_cast<std::size_t>(b)], t, ps.conversion.interval))
                continue;
            // (semi-Lagrangian conversion: the block's elements are all FE, no flags)
            const std::vector<char>& rk = rk_elements_[static_cast<std::size_t>(b)];
            std::vector<char>& convert = event_flags_; // scratch kept between steps: no allocation
            convert.assign(static_cast<std::size_t>(ne), 0);
            // each element on its own (meets reads the committed state): on the threads
            const bool any = parallel_for_any("rkfem::conversion_criteria", ne,
                                              [&](index_t e)
                                              {
                                                  if ((!rk.empty() && rk[e]) || !meets(ps.conversion, b, e))
                                                      return false;
                                                  convert[e] = 1;
                                                  return true;
                                              });
            if (any)
            {
                refresh_motion(); // the motion of the step, before the model changes
                buffer_and_cap(b, ps.conversion, convert);
            }
            // a conversion that cannot be made is no input error: the run stops there
            stops_the_run(t, step,
                          [&]
                          {
                              if (any && convert_elements(b, convert) > 0)
                                  changed = true;
                              // and back: RK elements whose region has become benign (the same check times)
                              if (ps.conversion.revert.active())
                              {
                                  std::vector<char>& revert = event_flags_;
                                  reversion_flags(b, revert);
                                  if (std::find(revert.begin(), revert.end(), char{1}) != revert.end())
                                  {
                                      if (!any)
                                          refresh_motion();
                                      if (revert_elements(b, revert) > 0)
                                          changed = true;
                                  }
                              }
                          });
            continue;
        }
        // J2 failure on Gauss-point elements deletes the element once all its points have failed
        // (LS-DYNA MAT_024 FAIL); the damage index of a J2 point is its failed flag, 0 or 1
        const bool fails = ps.material.model == "j2" && ps.material.fail > 0.0 && !fe_side(b);
        if ((!ps.erosion.active() && !fails) || nodal_block(b))
            continue;
        std::vector<char>& keep = event_flags_; // scratch kept between steps: no allocation
        keep.assign(static_cast<std::size_t>(ne), 1);
        const bool removed = parallel_for_any("rkfem::erosion_criteria", ne,
                                              [&](index_t e)
                                              {
                                                  const bool erode =
                                                      (ps.erosion.active() && meets(ps.erosion, b, e)) ||
                                                      (fails && element_history(b, e, History::Damage) >= 1.0);
                                                  keep[e] = !erode;
                                                  return erode;
                                              });
        if (!removed)
            continue;
        refresh_motion(); // the motion of the step, before the model changes
        eroded_elements_ += static_cast<index_t>(std::count(keep.begin(), keep.end(), 0));
        remove_elements(b, keep);
        changed = true;
    }
    return changed;
}

NodalBlock* Model::nodal_block(index_t part)
{
    return const_cast<NodalBlock*>(std::as_const(*this).nodal_block(part));
}

const NodalBlock* Model::nodal_block(index_t part) const
{
    const index_t k = part_nodal_[static_cast<std::size_t>(part)];
    return k < 0 ? nullptr : std::as_const(*blocks_[static_cast<std::size_t>(k)].block).nodal_points();
}

FeSide* Model::fe_side(index_t part)
{
    return const_cast<FeSide*>(std::as_const(*this).fe_side(part));
}

const FeSide* Model::fe_side(index_t part) const
{
    const index_t k = part_fe_side_[static_cast<std::size_t>(part)];
    return k < 0 ? nullptr : &static_cast<const FeSideForceBlock&>(*blocks_[static_cast<std::size_t>(k)].block).side();
}

void Model::plan_assembly()
{
    // each block's node range (an FE side's: its part's)
    std::vector<std::pair<index_t, index_t>> range;
    for (std::size_t k = 0; k < blocks_.size(); ++k)
    {
        const index_t part = blocks_[k].part;
        // a block with nodal points covers their nodes (a converting part's semi-Lagrangian block
        // holds a refinement's pool past the FE mesh's nodes, whose forces it adds)
        if (const NodalBlock* nb = std::as_const(*blocks_[k].block).nodal_points())
            range.emplace_back(nb->node_begin, nb->node_end);
        else
            range.emplace_back(meshes[static_cast<std::size_t>(part)].node_begin,
                               meshes[static_cast<std::size_t>(part)].node_end);
    }
    // a block adds when its nodes are another block's too (a coupled part's nodal block and FE
    // side share the part's nodes)
    for (std::size_t a = 0; a < blocks_.size(); ++a)
    {
        blocks_[a].add = false;
        for (std::size_t b = 0; b < blocks_.size(); ++b)
            if (a != b && range[a].first < range[b].second && range[b].first < range[a].second)
                blocks_[a].add = true;
    }
    // the union of the adding blocks' ranges, as disjoint sorted intervals
    std::vector<std::pair<index_t, index_t>> shared;
    for (std::size_t a = 0; a < range.size(); ++a)
        if (blocks_[a].add)
            shared.push_back(range[a]);
    std::sort(shared.begin(), shared.end());
    shared_node_ranges_.clear();
    for (const auto& r : shared)
        if (!shared_node_ranges_.empty() && r.first <= shared_node_ranges_.back().second)
            shared_node_ranges_.back().second = std::max(shared_node_ranges_.back().second, r.second);
        else
            shared_node_ranges_.push_back(r);
}

real_t Model::restart_after_event(TimeStepper& stepper, real_t t, real_t dt)
{
    event_a_ = nodes.a;
    const real_t kinetic = energy.kinetic;
    const StepReport rep = stepper.initialize(*this, t);
    // prescribed velocities imposed again through a new kinematic map (a conversion made
    // constrained nodes particles): the supports did that work; what the events changed
    // themselves (refinement's velocities) is theirs
    energy.external_work += energy.kinetic - kinetic - event_kinetic_;
    energy.eroded -= event_kinetic_;
    event_kinetic_ = 0.0;
    energy.book_event(nodes, event_a_, dt);
    return rep.dt_stable;
}
} // namespace rkfem
