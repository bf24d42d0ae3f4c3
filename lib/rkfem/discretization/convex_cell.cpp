#include "rkfem/discretization/convex_cell.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "rkfem/core/error.hpp"

namespace rkfem
{
void ConvexCell::reset_box(const Vec3& lo, const Vec3& hi)
{
    x_.clear();
    for (int k = 0; k < 8; ++k) // vertex k: bit d set -> hi along d
        x_.emplace_back((k & 1) ? hi[0] : lo[0], (k & 2) ? hi[1] : lo[1], (k & 4) ? hi[2] : lo[2]);
    // counter-clockwise seen from outside: -x, +x, -y, +y, -z, +z
    face_vertices_ = {0, 4, 6, 2, 1, 3, 7, 5, 0, 1, 5, 4, 2, 6, 7, 3, 0, 2, 3, 1, 4, 5, 7, 6};
    face_offsets_ = {0, 4, 8, 12, 16, 20, 24};
    face_tag_.assign(6, kBox);
}

bool ConvexCell::cut(const Vec3& n, real_t c, int tag, real_t eps)
{
    const int nv = static_cast<int>(x_.size());
    dist_.resize(static_cast<std::size_t>(nv));
    side_.resize(static_cast<std::size_t>(nv));
    bool any_out = false, any_in = false;
    for (int v = 0; v < nv; ++v)
    {
        const real_t d = n.dot(x_[v]) - c;
        dist_[v] = d;
        side_[v] = d > eps ? 1 : (d < -eps ? -1 : 0); // beyond, on, within
        any_out = any_out || side_[v] > 0;
        any_in = any_in || side_[v] < 0;
    }
    if (!any_out)
        return false;
    RKFEM_REQUIRE(any_in, "convex cell: the cut (" << n.transpose() << ") . x <= " << c << " leaves nothing");
    // the kept vertices, then one new vertex per edge from within to beyond (both faces of the
    // edge take the same one: computed from the edge's ends in one order)
    new_id_.assign(static_cast<std::size_t>(nv), -1);
    new_x_.clear();
    for (int v = 0; v < nv; ++v)
        if (side_[v] <= 0)
        {
            new_id_[v] = static_cast<int>(new_x_.size());
            new_x_.push_back(x_[v]);
        }
    const std::size_t n_kept = new_x_.size();
    edge_vertex_.clear(); // (lower end, upper end, new vertex) per crossing edge
    auto crossing = [&](int a, int b)
    {
        if (a > b)
            std::swap(a, b);
        for (std::size_t k = 0; k < edge_vertex_.size(); k += 3)
            if (edge_vertex_[k] == a && edge_vertex_[k + 1] == b)
                return edge_vertex_[k + 2];
        const real_t t = dist_[a] / (dist_[a] - dist_[b]);
        const int id = static_cast<int>(new_x_.size());
        new_x_.push_back(x_[a] + t * (x_[b] - x_[a]));
        edge_vertex_.insert(edge_vertex_.end(), {a, b, id});
        return id;
    };
    // every face clipped to the kept side (a face left with fewer than 3 vertices goes)
    new_offsets_.assign(1, 0);
    new_vertices_.clear();
    new_tags_.clear();
    new_vertices_.reserve(face_vertices_.size() + 2 * static_cast<std::size_t>(nv));
    for (int f = 0; f < n_faces(); ++f)
    {
        const int k0 = face_offsets_[f], m = face_offsets_[f + 1] - k0;
        const int* fv = face_vertices_.data() + k0;
        const std::size_t start = new_vertices_.size();
        // most faces lie wholly on the kept side of a cut: their vertices carry over, renumbered
        // (what the loop below does for them, without its tests)
        bool beyond = false;
        for (int k = 0; k < m; ++k)
            beyond = beyond || side_[fv[k]] > 0;
        if (!beyond)
            for (int k = 0; k < m; ++k)
                new_vertices_.push_back(new_id_[fv[k]]);
        else
            for (int k = 0; k < m; ++k)
            {
                const int a = fv[k], b = fv[k + 1 < m ? k + 1 : 0];
                if (side_[a] <= 0)
                    new_vertices_.push_back(new_id_[a]);
                if (side_[a] * side_[b] < 0)
                    new_vertices_.push_back(crossing(a, b));
            }
        if (new_vertices_.size() - start < 3)
        {
            new_vertices_.resize(start);
            continue;
        }
        new_offsets_.push_back(static_cast<int>(new_vertices_.size()));
        new_tags_.push_back(face_tag_[f]);
    }
    // the cross-section: the kept vertices on the plane and the new ones, a convex polygon,
    // ordered by angle about n (counter-clockwise seen from beyond, outside the cell)
    section_.clear();
    for (int v = 0; v < nv; ++v)
        if (side_[v] == 0)
            section_.push_back(new_id_[v]);
    for (std::size_t v = n_kept; v < new_x_.size(); ++v)
        section_.push_back(static_cast<int>(v));
    if (section_.size() >= 3)
    {
        Vec3 centre = Vec3::Zero();
        for (int v : section_)
            centre += new_x_[v];
        centre /= static_cast<real_t>(section_.size());
        const Vec3 nn = n.normalized();
        const Vec3 u = (std::abs(nn[0]) < 0.6 ? Vec3::UnitX() : Vec3::UnitY()).cross(nn).normalized();
        const Vec3 w = nn.cross(u);
        angle_.resize(new_x_.size());
        for (int v : section_)
        {
            const Vec3 r = new_x_[v] - centre;
            angle_[v] = std::atan2(r.dot(w), r.dot(u));
        }
        std::sort(section_.begin(), section_.end(), [&](int a, int b) { return angle_[a] < angle_[b]; });
        new_vertices_.insert(new_vertices_.end(), section_.begin(), section_.end());
        new_offsets_.push_back(static_cast<int>(new_vertices_.size()));
        new_tags_.push_back(tag);
    }
    // keep the vertices some face uses (a kept vertex whose faces all went is dropped)
    side_.assign(new_x_.size(), -1); // reused: the compacted id
    for (int v : new_vertices_)
        side_[v] = 0;
    int used = 0;
    for (std::size_t v = 0; v < new_x_.size(); ++v)
        if (side_[v] == 0)
        {
            side_[v] = used;
            new_x_[used++] = new_x_[v];
        }
    new_x_.resize(static_cast<std::size_t>(used));
    for (int& v : new_vertices_)
        v = side_[v];
    x_.swap(new_x_);
    face_offsets_.swap(new_offsets_);
    face_vertices_.swap(new_vertices_);
    face_tag_.swap(new_tags_);
    return true;
}
} // namespace rkfem
