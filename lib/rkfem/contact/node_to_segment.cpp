#include "rkfem/contact/node_to_segment.hpp"

#include <algorithm>
#include <cmath>

#include "rkfem/core/parallel.hpp"
#include "rkfem/core/state_archive.hpp"

namespace rkfem
{
NodeToSegmentContact::NodeToSegmentContact(std::vector<ContactSurface> surfaces, const ContactParameters& p) : p_(p)
{
    set_surfaces(std::move(surfaces));
}

void NodeToSegmentContact::set_surfaces(std::vector<ContactSurface> surfaces)
{
    // who was in contact, and how deep, before the surfaces change
    before_.assign(passes_.size(), {});
    for (std::size_t ip = 0; ip < passes_.size(); ++ip)
    {
        const ContactSurface& slave = surfaces_[static_cast<std::size_t>(passes_[ip].slave)];
        for (std::size_t k = 0; k < passes_[ip].hits.size(); ++k)
            if (passes_[ip].hits[k].segment >= 0)
                before_[ip].push_back(
                    {slave.slave(static_cast<index_t>(k)), passes_[ip].last_penetration[k], passes_[ip].offset[k]});
    }
    surfaces_ = std::move(surfaces);
    passes_.clear();
    auto add_pass = [&](int slave, int master)
    {
        passes_.emplace_back();
        passes_.back().slave = slave;
        passes_.back().master = master;
    };
    if (surfaces_.size() == 1)
        add_pass(0, 0);
    else
    {
        add_pass(0, 1);
        add_pass(1, 0);
    }
    all_nodes_.clear();
    real_t size = 0.0, deepest = 0.0, sphere = 0.0;
    index_t n_seg = 0;
    for (const ContactSurface& s : surfaces_)
    {
        all_nodes_.insert(all_nodes_.end(), s.nodes.begin(), s.nodes.end());
        all_nodes_.insert(all_nodes_.end(), s.particles.begin(), s.particles.end());
        for (real_t r : s.particle_radius)
            sphere = std::max(sphere, r);
        for (index_t k = 0; k < s.n_segments(); ++k)
            deepest = std::max(deepest, s.depth[k]);
        size += s.area;
        n_seg += s.n_segments();
    }
    std::sort(all_nodes_.begin(), all_nodes_.end());
    all_nodes_.erase(std::unique(all_nodes_.begin(), all_nodes_.end()), all_nodes_.end());
    const std::size_t n_surf = surfaces_.size();
    corner_slot_.assign(n_surf, {});
    node_normal_.assign(n_surf, {});
    segment_area_.assign(n_surf, {});
    node_segment_offsets_.assign(n_surf, {});
    node_segments_.assign(n_surf, {});
    for (std::size_t k = 0; k < n_surf; ++k)
    {
        const ContactSurface& s = surfaces_[k];
        for (const Quad& q : s.segments)
            for (index_t n : q)
                corner_slot_[k].push_back(
                    static_cast<index_t>(std::lower_bound(s.nodes.begin(), s.nodes.end(), n) - s.nodes.begin()));
        node_normal_[k].assign(s.nodes.size(), Vec3::Zero());
        segment_area_[k].assign(s.segments.size(), Vec3::Zero());
        // node -> segments, counts then offsets then entries
        std::vector<index_t>& off = node_segment_offsets_[k];
        off.assign(s.nodes.size() + 1, 0);
        for (index_t slot : corner_slot_[k])
            ++off[static_cast<std::size_t>(slot) + 1];
        for (std::size_t i = 0; i < s.nodes.size(); ++i)
            off[i + 1] += off[i];
        std::vector<index_t> fill(off.begin(), off.end() - 1);
        node_segments_[k].resize(static_cast<std::size_t>(off.back()));
        for (std::size_t c = 0; c < corner_slot_[k].size(); ++c)
            node_segments_[k][static_cast<std::size_t>(fill[static_cast<std::size_t>(corner_slot_[k][c])]++)] =
                static_cast<index_t>(c / 4);
    }
    // the search margin: a quarter of the mean segment's edge (size: the total area)
    margin_ = n_seg > 0 ? 0.25 * std::sqrt(size / static_cast<real_t>(n_seg)) : 0.0;
    reach_ = margin_ + p_.max_penetration * deepest + p_.thickness + sphere;
    s_.searched = false;
    fresh_ = true;
    s_.active = 0;
    s_.resultant = Vec3::Zero();
}

void NodeToSegmentContact::search(const PhysicalNodes& nodes)
{
    s_.record_search(nodes, all_nodes_);
    for (Pass& pass : passes_)
    {
        const ContactSurface& master = surfaces_[static_cast<std::size_t>(pass.master)];
        const ContactSurface& slave = surfaces_[static_cast<std::size_t>(pass.slave)];
        const index_t ns = master.n_segments();
        lo_.resize(3 * static_cast<std::size_t>(ns));
        hi_.resize(3 * static_cast<std::size_t>(ns));
        for (index_t s = 0; s < ns; ++s)
        {
            Vec3 lo = Vec3::Constant(kNoLimit), hi = Vec3::Constant(-kNoLimit);
            for (index_t n : master.segments[s])
            {
                const Vec3 x = nodes.x(n);
                lo = lo.cwiseMin(x);
                hi = hi.cwiseMax(x);
            }
            for (int d = 0; d < 3; ++d)
            {
                lo_[3 * s + d] = lo[d];
                hi_[3 * s + d] = hi[d];
            }
        }
        pass.buckets.build(lo_, hi_, reach_);
        // a body's particles do not meet its own segments (they lie behind them)
        const bool self = pass.slave == pass.master;
        const index_t n_slave = self ? static_cast<index_t>(slave.nodes.size()) : slave.n_slaves();
        pass.offsets.assign(static_cast<std::size_t>(n_slave) + 1, 0);
        pass.candidates.clear();
        for (index_t k = 0; k < n_slave; ++k)
        {
            const index_t i = slave.slave(k);
            pass.buckets.for_candidates(nodes.x(i),
                                        [&](index_t s)
                                        {
                                            const Quad& q = master.segments[s];
                                            if (self && std::find(q.begin(), q.end(), i) != q.end())
                                                return; // a node never contacts a segment it belongs to
                                            pass.candidates.push_back(s);
                                        });
            pass.offsets[k + 1] = static_cast<index_t>(pass.candidates.size());
        }
        pass.hits.resize(static_cast<std::size_t>(n_slave));
        pass.offset.resize(static_cast<std::size_t>(n_slave), 0.0);
        pass.last_penetration.resize(static_cast<std::size_t>(n_slave), 0.0);
    }
}

void NodeToSegmentContact::update_node_normals(const PhysicalNodes& nodes)
{
    for (std::size_t k = 0; k < surfaces_.size(); ++k)
    {
        const ContactSurface& s = surfaces_[k];
        std::vector<Vec3>& area = segment_area_[k];
        parallel_for("rkfem::contact_segment_areas", s.n_segments(),
                     [&](index_t f)
                     {
                         const Quad& q = s.segments[f];
                         area[static_cast<std::size_t>(f)] =
                             0.5 * (nodes.x(q[2]) - nodes.x(q[0])).cross(nodes.x(q[3]) - nodes.x(q[1]));
                     });
        // each node gathers its segments' area vectors (node -> segments CSR): no races
        const std::vector<index_t>& off = node_segment_offsets_[k];
        const std::vector<index_t>& seg = node_segments_[k];
        std::vector<Vec3>& nn = node_normal_[k];
        parallel_for("rkfem::contact_node_normals", static_cast<index_t>(nn.size()),
                     [&](index_t i)
                     {
                         Vec3 n = Vec3::Zero();
                         for (index_t j = off[i]; j < off[i + 1]; ++j)
                             n += area[static_cast<std::size_t>(seg[j])];
                         const real_t len = n.norm();
                         nn[static_cast<std::size_t>(i)] = len > 0.0 ? Vec3(n / len) : Vec3::Zero();
                     });
    }
}

void NodeToSegmentContact::evaluate(Pass& pass, const PhysicalNodes& nodes) const
{
    const ContactSurface& master = surfaces_[static_cast<std::size_t>(pass.master)];
    const ContactSurface& slave = surfaces_[static_cast<std::size_t>(pass.slave)];
    const index_t n_slave = static_cast<index_t>(pass.hits.size());
    const index_t n_nodes = static_cast<index_t>(slave.nodes.size());
    const bool soft = p_.soft && s_.dt0 > 0.0 && s_.dt0 < kNoLimit;
    parallel_for(
        "rkfem::contact_node_to_segment", n_slave,
        [&](index_t k)
        {
            Hit& h = pass.hits[static_cast<std::size_t>(k)];
            h.segment = -1;
            const index_t i = slave.slave(k);
            const Vec3 xs = nodes.x(i);
            // a particle (k past the segments' nodes) is a sphere: it meets a segment's face, or
            // where its centre projects outside the segment, its edge, along the line between them
            const bool particle = k >= n_nodes;
            const real_t radius = particle ? slave.particle_radius[static_cast<std::size_t>(k - n_nodes)] : 0.0;
            const Vec3 ns = particle ? Vec3::Zero()
                                     : node_normal_[static_cast<std::size_t>(pass.slave)][static_cast<std::size_t>(k)];
            real_t best = kNoLimit;
            SegmentPoint at;
            for (index_t c = pass.offsets[k]; c < pass.offsets[k + 1]; ++c)
            {
                const index_t s = pass.candidates[c];
                const Quad& q = master.segments[s];
                const Vec3 corners[4] = {nodes.x(q[0]), nodes.x(q[1]), nodes.x(q[2]), nodes.x(q[3])};
                // the node must lie within the deepest reach of the segment's box
                const real_t reach = p_.max_penetration * master.depth[s] + p_.thickness + radius;
                const Vec3 lo = corners[0].cwiseMin(corners[1]).cwiseMin(corners[2].cwiseMin(corners[3]));
                const Vec3 hi = corners[0].cwiseMax(corners[1]).cwiseMax(corners[2].cwiseMax(corners[3]));
                if ((xs.array() < lo.array() - reach).any() || (xs.array() > hi.array() + reach).any())
                    continue;
                SegmentPoint sp = project_on_segment(corners, xs);
                real_t gap = (xs - sp.x).dot(sp.normal);
                if (particle && !sp.inside)
                {
                    const Vec3 d = xs - sp.x;
                    const real_t dist = d.norm();
                    if (!(gap > 0.0) || !(dist > 0.0))
                        continue; // behind the segment's plane: another segment's
                    sp.normal = d / dist;
                    gap = dist;
                }
                else if (!sp.inside || !(particle || sp.normal.dot(ns) < 0.0))
                    continue;
                const real_t pen = p_.thickness + radius - gap;
                // a node: the smallest penetration (the face it has just crossed); a sphere: the
                // largest (its centre's distance to the surface, continuous as it rolls over the
                // segments; the smallest jumped from segment to segment of an FSP's mushrooming
                // nose, and the jumps, held as offsets, left the spring a third of its depth)
                if (!(pen > 0.0) || pen > reach || (particle ? h.segment >= 0 && pen <= best : pen >= best))
                    continue;
                best = pen;
                h.segment = s;
                at = sp;
            }
            const std::size_t kk = static_cast<std::size_t>(k);
            real_t& offset = pass.offset[kk];
            real_t& last = pass.last_penetration[kk];
            if (fresh_)
            {
                // new surfaces: a node in contact before keeps its depth and offset
                const std::size_t ip = static_cast<std::size_t>(&pass - passes_.data());
                last = offset = 0.0;
                if (ip < before_.size())
                {
                    const auto& was = before_[ip];
                    const auto it = std::lower_bound(was.begin(), was.end(), Before{i, 0.0, 0.0},
                                                     [](const Before& x, const Before& y) { return x.node < y.node; });
                    if (it != was.end() && it->node == i)
                    {
                        last = it->penetration;
                        offset = it->offset;
                    }
                }
            }
            if (h.segment < 0)
            {
                offset = last = 0.0;
                return;
            }
            const Quad& q = master.segments[h.segment];
            real_t m_m = 0.0;
            Vec3 v_m = Vec3::Zero();
            for (int a = 0; a < 4; ++a)
            {
                h.N[a] = at.N[a];
                m_m += at.N[a] * nodes.mass(q[a]);
                v_m += at.N[a] * nodes.v(q[a]);
            }
            const Vec3 v_rel = nodes.v(i) - v_m;
            // the growth of the depth one step of approach explains (room for a step up to
            // 1.5 dt0; none at the start) acts at once; more came in sideways, across a
            // segment's edge, or with an event, and is held as an offset, which shrinks
            // as the node moves out
            const real_t approach = fresh_ && !s_.started ? 0.0 : 1.5 * s_.dt0 * std::max(0.0, -v_rel.dot(at.normal));
            offset = std::min(offset, best) + std::max(0.0, best - last - approach);
            last = best;
            best -= offset;
            const real_t m_s = nodes.mass(i);
            const real_t m_star = m_s * m_m / (m_s + m_m);
            // the slave node's area that faces the segment
            const std::size_t ss = static_cast<std::size_t>(pass.slave);
            real_t area = particle ? 4.0 * radius * radius : 0.0; // a particle: its cube's face
            if (!particle)
                for (index_t j = node_segment_offsets_[ss][k]; j < node_segment_offsets_[ss][k + 1]; ++j)
                    area += 0.25 * std::max(0.0, -segment_area_[ss][node_segments_[ss][j]].dot(at.normal));
            real_t k_pen = p_.penalty_scale * master.bulk_modulus[h.segment] * area / master.depth[h.segment];
            if (soft)
                k_pen = std::max(k_pen, p_.soft_scale * m_star / (s_.dt0 * s_.dt0));
            const real_t fn =
                p_.damping.active() ? p_.damping.force(k_pen, best, -v_rel.dot(at.normal), m_star) : k_pen * best;
            h.f = fn * at.normal;
            if (p_.friction.active() && s_.dt0 > 0.0)
            {
                const Vec3 v_t = v_rel - v_rel.dot(at.normal) * at.normal;
                h.f += p_.friction.force(v_t, fn, m_star, s_.dt0);
            }
            h.k = k_pen;
        });
}

void NodeToSegmentContact::add_forces(const PhysicalNodes& nodes, const ContactClock& clock, ContactChannel& channel)
{
    s_.see(clock);
    if (s_.search_due(nodes, all_nodes_, margin_))
        search(nodes);
    update_node_normals(nodes);
    s_.resultant = Vec3::Zero();
    s_.active = 0;
    node_k_.resize(static_cast<std::size_t>(nodes.size()), 0.0);
    for (Pass& pass : passes_)
    {
        evaluate(pass, nodes);
        const ContactSurface& master = surfaces_[static_cast<std::size_t>(pass.master)];
        const ContactSurface& slave = surfaces_[static_cast<std::size_t>(pass.slave)];
        const real_t side = pass.slave == 0 ? 1.0 : -1.0; // resultant on surface 0
        for (std::size_t k = 0; k < pass.hits.size(); ++k)
        {
            const Hit& h = pass.hits[k];
            if (h.segment < 0)
                continue;
            const index_t i = slave.slave(static_cast<index_t>(k));
            channel.add(i, h.f);
            node_k_[static_cast<std::size_t>(i)] += h.k;
            const Quad& q = master.segments[h.segment];
            for (int a = 0; a < 4; ++a)
            {
                channel.add(q[a], -h.N[a] * h.f);
                node_k_[static_cast<std::size_t>(q[a])] += h.N[a] * h.k;
            }
            s_.resultant += side * h.f;
            ++s_.active;
        }
    }
    if (fresh_ && !s_.started)
        for (const Pass& pass : passes_)
            for (real_t o : pass.offset)
                s_.initial_penetrations += o > 0.0;
    s_.started = true;
    fresh_ = false;
    before_.clear();
    // The step. The springs on a node (as slave, and as a corner of the master segments other
    // nodes hit, in both passes) add up to k_n. Gershgorin's bound on M^-1 K_contact gives at
    // most 2 max_n(k_n / m_n) = 2 kappa, and the elements' modes at most (2 / dt0)^2 (dt0 their
    // critical step: a node of the smallest element at the contact takes its highest mode in
    // full), so omega^2 <= 4 / dt0^2 + 2 kappa and central difference's omega dt <= 2 needs
    //   dt <= dt0 / sqrt(1 + kappa dt0^2 / 2)
    // (the run's dt_scale then applies to it as to the elements' step). At the default penalties
    // kappa dt0^2 is about 0.1-0.3: a step 2-7 % below the elements'. (The earlier bound,
    // dt0 sqrt(2 / (1 + k dt0^2 / m*)) per hit, took a surface node's modes at most sqrt(2) / dt0
    // and missed the springs that meet at a node: a stiff penalty on a graded mesh (the Hertz
    // test's) went unstable.)
    real_t k_over_m = 0.0;
    for (const index_t i : all_nodes_)
    {
        const std::size_t ii = static_cast<std::size_t>(i);
        if (node_k_[ii] > 0.0)
            k_over_m = std::max(k_over_m, node_k_[ii] / nodes.mass(i));
        node_k_[ii] = 0.0;
    }
    s_.bound_step(k_over_m, p_.damping.step_factor());
}

void NodeToSegmentContact::save_state(StateArchive& a, const std::string& prefix) const
{
    for (std::size_t k = 0; k < passes_.size(); ++k)
    {
        const Pass& pass = passes_[k];
        const std::string pp = prefix + "pass." + std::to_string(k) + ".";
        a.put(pp + "offsets", pass.offsets);
        a.put(pp + "candidates", pass.candidates);
        a.put_raw(pp + "hits", pass.hits);
        a.put(pp + "offset", pass.offset);
        a.put(pp + "last_penetration", pass.last_penetration);
    }
    s_.save(a, prefix);
    a.put_value(prefix + "margin", margin_);
    a.put_value(prefix + "reach", reach_);
    a.put_value(prefix + "fresh", fresh_);
}

void NodeToSegmentContact::load_state(const StateArchive& a, const std::string& prefix)
{
    for (std::size_t k = 0; k < passes_.size(); ++k)
    {
        Pass& pass = passes_[k];
        const std::string pp = prefix + "pass." + std::to_string(k) + ".";
        a.get(pp + "offsets", pass.offsets);
        a.get(pp + "candidates", pass.candidates);
        a.get_raw(pp + "hits", pass.hits);
        a.get(pp + "offset", pass.offset);
        a.get(pp + "last_penetration", pass.last_penetration);
    }
    s_.load(a, prefix);
    margin_ = a.value<real_t>(prefix + "margin");
    reach_ = a.value<real_t>(prefix + "reach");
    fresh_ = a.value<bool>(prefix + "fresh");
    before_.clear();
}
} // namespace rkfem
