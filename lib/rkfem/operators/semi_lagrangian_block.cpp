#include "rkfem/operators/semi_lagrangian_block.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>

#include <omp.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "rkfem/approximation/rk/rk_region_detail.hpp"
#include "rkfem/core/parallel.hpp"
#include "rkfem/discretization/cell_list.hpp"
#include "rkfem/materials/elastic.hpp"
#include "rkfem/operators/bulk_viscosity.hpp"
#include "rkfem/operators/kernels/assumed_strain_hourglass.hpp"
#include "rkfem/operators/kernels/rate_form.hpp"
#include "rkfem/operators/nodal_force.hpp"

namespace rkfem
{
namespace
{
/// Per-thread scratch of the force pass, sized to the longest neighbour row (kept between steps).
struct Scratch
{
    RkSample sample;
    std::vector<real_t> b;    ///< 3 per row entry: the smoothed gradient
    std::vector<real_t> face; ///< 6 x 3 per row entry: grad Psi at the face centres (0: not covering)
};

Scratch& scratch()
{
    thread_local Scratch s;
    return s;
}

/// A particle's smoothing cell: the parallelepiped about x + c with half-edge vectors e_i
/// (cells[12 p ..]: c, e_1, e_2, e_3). Face f lies on edge f / 2, on its - side for even f: its
/// centre x + c -+ e_i and its outward area vector -+ 4 e_j x e_k ((i, j, k) cyclic).
struct Cell
{
    Vec3 c, e[3];
    Cell() = default;
    explicit Cell(const real_t* v)
        : c(v[0], v[1], v[2]), e{{v[3], v[4], v[5]}, {v[6], v[7], v[8]}, {v[9], v[10], v[11]}}
    {
    }
    real_t volume() const { return 8.0 * e[0].dot(e[1].cross(e[2])); }
    /// The longest half-edge (0 for a separated particle's empty cell).
    real_t longest_half_edge() const
    {
        real_t w2 = 0.0;
        for (const Vec3& k : e)
            w2 = std::max(w2, k[0] * k[0] + k[1] * k[1] + k[2] * k[2]);
        return std::sqrt(w2);
    }
    Vec3 centre(const Vec3& x, int f) const { return x + c + (f % 2 == 0 ? -1.0 : 1.0) * e[f / 2]; }
    Vec3 area(int f) const
    {
        const int i = f / 2;
        return (f % 2 == 0 ? -4.0 : 4.0) * e[(i + 1) % 3].cross(e[(i + 2) % 3]);
    }
    void store(real_t* v) const
    {
        for (int d = 0; d < 3; ++d)
        {
            v[d] = c[d];
            for (int k = 0; k < 3; ++k)
                v[3 + 3 * k + d] = e[k][d];
        }
    }
};

/// The cell moved by the velocity gradient over dt, as material lines move in a linear field
/// (e <- e + dt L e, c <- c + dt L c). No cell is ever squared up: a cell made the cube of its
/// volume past 4:1 (an earlier rule) loses the stretch the supports follow, and a block sheared
/// past strain 1.5 or a Taylor bar's foot then blew up.
Cell advance(const Cell& cell, const Mat3& L, real_t dt)
{
    Cell out = cell;
    out.c += dt * (L * cell.c);
    for (int k = 0; k < 3; ++k)
        out.e[k] += dt * (L * cell.e[k]);
    return out;
}

/// Sub-cell s (0..7, bit i: the + side of e_i) of a cell: the half-size parallelepiped at that corner.
Cell sub_cell(const Cell& cell, int s)
{
    Cell part = cell;
    for (int i = 0; i < 3; ++i)
    {
        part.e[i] = 0.5 * cell.e[i];
        part.c += ((s >> i) & 1 ? 1.0 : -1.0) * part.e[i];
    }
    return part;
}

/// The cell mapped by a deformation gradient F (reference resets).
Cell deform(const Cell& cell, const Mat3& F)
{
    Cell out = cell;
    out.c = F * cell.c;
    for (int k = 0; k < 3; ++k)
        out.e[k] = F * cell.e[k];
    return out;
}

/// A face centre counts as covered where its moment matrix's pivot ratio is above this (the
/// shape functions' own 1e-12 only guards the solve): at a crack face a centre half a spacing
/// beyond the last layer of particles is reached by that layer and, with weight 4e-7, by the one
/// behind it (a / h 1.51), a pivot ratio near 1e-7 whose functions are of the size of 10^3 and
/// set the neighbours flying. Beside particles that separated under compression (an SL panel
/// struck by an FSP with separation_damage 0.99, fsp_impact.yaml) centres with ratios between
/// 1e-4 and 1e-3 did the same at 9.2 us (a threshold of 1e-4 or less blew up there; 1e-3 and 1e-2
/// ran through). The least ratio of an intact body's centres, measured at the start: 2.9e-2 on box
/// and cylinder meshes (the column, the Taylor bar, P6's target), 3.7e-2 and 5.0e-2 on jittered
/// clouds, so 1e-3 leaves them a factor of 30.
constexpr real_t kCoverPivot = 1e-3;

/// SD-SNNI's sample points per cell (sub_point_offset), the most any pass samples.
constexpr int kSubPoints = 36;

/// SD-SNNI's sample points: the face centres of a cell's eight half-size sub-cells, 36 distinct
/// ones. In cell coordinates (x = x_L + c + sum_i xi_i e_i, xi in [-1, 1]^3) point q = 12 i + 4 a +
/// 2 j + k lies at xi_i = a - 1 and +-1/2 (j, k: 0 for -1/2) on the two other axes, i + 1 and i + 2
/// (mod 3): the 24 quarters of the cell's faces (a = 0, 2) and the 12 of its midplanes (a = 1).
Vec3 sub_point_offset(const Cell& cell, int q)
{
    const int i = q / 12, a = (q / 4) % 3, j = (q / 2) % 2, k = q % 2;
    return cell.c + static_cast<real_t>(a - 1) * cell.e[i] + (j ? 0.5 : -0.5) * cell.e[(i + 1) % 3] +
           (k ? 0.5 : -0.5) * cell.e[(i + 2) % 3];
}

/// Per-thread scratch of the fast passes (kept between steps), in flat arrays. The candidates
/// are the row's particles (not free ones, where `free` is given) whose supports reach the cell's
/// sample points, and each point's own list of them (collect: about 56 of a P6 particle's 200
/// row entries cover a face centre). At each sample point q (a face centre, or one of SD-SNNI's
/// 36 points) the windows of its listed candidates (every candidate, where the cell was halved)
/// are formed in one loop in vector lanes, those that do not cover it dropped (pack), and the
/// rest on the packed arrays: the moment sums (rk_region_detail's, as the set-up's region
/// evaluator forms them), the 4 x 4 solve, the values (and gradients), and later the point's
/// velocity and its forces. The plain twin is points_plain's evaluate_at (rk_solve_sample over the covering
/// particles one by one): the same functions to round-off.
struct FastScratch
{
    /// Which of the row's particles a cell's candidates are: those whose support covers one of
    /// its sample points (SNNI's six face centres: in a body's interior 81 of the 125 of
    /// FaceBox; SD-SNNI's 36 points), each point's own listed, or those that reach a box: of its
    /// face centres (the cells halved toward the particle, gradient_cell, have their points in
    /// it) or of its corners (SD-SNNI's points lie past the face centres' box on a rotated or
    /// sheared cell).
    enum class Reach
    {
        FaceCentres,
        SubCellPoints,
        FaceBox,
        WholeCell,
    };
    // per candidate
    std::vector<index_t> cand_k;    ///< its row entry (ascending)
    std::vector<index_t> slot;      ///< its place among the covering ones (the reset tables)
    std::vector<real_t> px, py, pz; ///< its position minus the cell's centre
    std::vector<real_t> ca, cinv_a; ///< its support radius and its inverse
    std::vector<real_t> vx, vy, vz; ///< its velocity (gather_velocities)
    std::vector<real_t> cover;      ///< 1 where it covers a point since reset_cover
    std::vector<real_t> fx, fy, fz; ///< the cell's force on it (forces)
    // per sample point q, packed (the covering candidates), cap apart
    std::vector<index_t> idx; ///< kSubPoints x cap: the covering candidates
    std::vector<index_t> all; ///< 0, 1, ..., cap - 1 (every candidate)
    int listed = 0;           ///< idx's first rows hold the listed points' candidates (collect)
    std::vector<real_t> psi;  ///< kSubPoints x cap: Psi
    std::vector<real_t> grad; ///< 18 x cap: grad Psi at the six face centres (3 f + d)
    std::size_t m[kSubPoints] = {};
    // the last point, packed: x - x_k, the window and its gradient
    std::vector<real_t> kd0, kd1, kd2, kphi, kq0, kq1, kq2;
    std::size_t n = 0, cap = 0; ///< candidates; the arrays' room per point
    // per row entry (collect): the offset from the cell's centre, the support, the points reached
    std::vector<real_t> rx, ry, rz, ra;
    std::vector<std::uint64_t> rbits;
    std::size_t rcap = 0;
    real_t n_cover = 0.0, a_min = 0.0; ///< the last point's covering count and least radius
    RkSample sample;                   ///< orders above 1
    Cell gcell;                        ///< the reset tables' gradient cell
    struct Collected                   ///< the last collect's arguments (widen)
    {
        Cell cell;
        Vec3 xL;
        const index_t* row;
        index_t nr, begin;
        const std::vector<real_t>* x;
        const std::vector<real_t>* radius;
        const std::vector<char>* free;
        SupportShape shape;
        Reach reach;
    } at{};

    /// The candidates of the cell about xL by `reach`, in row order.
    void collect(const Cell& cell, const Vec3& xL, const index_t* row, index_t nr, index_t begin,
                 const std::vector<real_t>& x, const std::vector<real_t>& radius, const std::vector<char>* free,
                 SupportShape shape, Reach reach)
    {
        at = {cell, xL, row, nr, begin, &x, &radius, free, shape, reach};
        if (cap < static_cast<std::size_t>(nr))
        {
            cap = static_cast<std::size_t>(nr);
            for (std::vector<real_t>* v : {&px, &py, &pz, &ca, &cinv_a, &vx, &vy, &vz, &cover, &fx, &fy, &fz, &kd0,
                                           &kd1, &kd2, &kphi, &kq0, &kq1, &kq2})
                v->resize(cap);
            cand_k.resize(cap);
            slot.resize(cap);
            idx.resize(kSubPoints * cap);
            all.resize(cap);
            for (std::size_t c = 0; c < cap; ++c)
                all[c] = static_cast<index_t>(c);
            psi.resize(kSubPoints * cap);
            grad.resize(18 * cap);
        }
        const Vec3 xc = xL + cell.c;
        // the listed points (offsets from the cell's centre) and the box
        Vec3 points[kSubPoints];
        int np = 0;
        if (reach == Reach::FaceCentres)
            for (; np < 6; ++np)
                points[np] = (np % 2 == 0 ? -1.0 : 1.0) * cell.e[np / 2];
        else if (reach == Reach::SubCellPoints)
            for (; np < kSubPoints; ++np)
                points[np] = sub_point_offset(cell, np) - cell.c;
        const bool whole = reach == Reach::WholeCell || reach == Reach::SubCellPoints;
        Vec3 ext = Vec3::Zero();
        for (int i = 0; i < 3; ++i)
            ext = whole ? Vec3(ext + cell.e[i].cwiseAbs()) : Vec3(ext.cwiseMax(cell.e[i].cwiseAbs()));
        // in vector lanes over the row: each particle's offset from the cell's centre and the
        // points it reaches (bit q: point q; bit 63: the box), then the candidates and each
        // point's list in row order
        if (rcap < static_cast<std::size_t>(nr))
        {
            rcap = static_cast<std::size_t>(nr);
            for (std::vector<real_t>* v : {&rx, &ry, &rz, &ra})
                v->resize(rcap);
            rbits.resize(rcap);
        }
        const real_t c0 = xc[0], c1 = xc[1], c2 = xc[2], x0 = ext[0], x1 = ext[1], x2 = ext[2];
        const real_t* xs = x.data();
        const real_t* rad = radius.data();
        real_t *qx = rx.data(), *qy = ry.data(), *qz = rz.data(), *qa = ra.data();
        std::uint64_t* bits = rbits.data();
        constexpr std::uint64_t box_bit = std::uint64_t{1} << 63;
        const std::size_t b3 = 3 * static_cast<std::size_t>(begin);
        RKFEM_SIMD()
        for (index_t k = 0; k < nr; ++k)
        {
            const std::size_t j = static_cast<std::size_t>(row[k]);
            const real_t p0 = xs[b3 + 3 * j] - c0, p1 = xs[b3 + 3 * j + 1] - c1, p2 = xs[b3 + 3 * j + 2] - c2;
            const real_t a = rad[j];
            qx[k] = p0;
            qy[k] = p1;
            qz[k] = p2;
            qa[k] = a;
            bits[k] = std::abs(p0) < a + x0 && std::abs(p1) < a + x1 && std::abs(p2) < a + x2 ? box_bit : 0;
        }
        // bit q: the support covers point q, as the windows' test
        for (int q = 0; q < np; ++q)
        {
            const real_t e0 = points[q][0], e1 = points[q][1], e2 = points[q][2];
            const std::uint64_t bit = std::uint64_t{1} << q;
            if (shape == SupportShape::Box)
            {
                RKFEM_SIMD()
                for (index_t k = 0; k < nr; ++k)
                {
                    const real_t a = qa[k];
                    const bool in = std::abs(qx[k] - e0) < a && std::abs(qy[k] - e1) < a && std::abs(qz[k] - e2) < a;
                    bits[k] |= in ? bit : 0;
                }
            }
            else
            {
                RKFEM_SIMD()
                for (index_t k = 0; k < nr; ++k)
                {
                    const real_t d0 = qx[k] - e0, d1 = qy[k] - e1, d2 = qz[k] - e2, a = qa[k];
                    bits[k] |= d0 * d0 + d1 * d1 + d2 * d2 < a * a ? bit : 0;
                }
            }
        }
        std::size_t count = 0;
        listed = np;
        std::fill_n(m, kSubPoints, 0);
        const std::uint64_t wanted = np > 0 ? ~box_bit : box_bit;
        for (index_t k = 0; k < nr; ++k)
        {
            std::uint64_t b = bits[k] & wanted;
            if (b == 0 || (free != nullptr && (*free)[static_cast<std::size_t>(row[k])]))
                continue;
            for (; np > 0 && b != 0; b &= b - 1)
            {
                const int q = std::countr_zero(b);
                idx[static_cast<std::size_t>(q) * cap + m[q]++] = static_cast<index_t>(count);
            }
            cand_k[count] = k;
            px[count] = qx[k];
            py[count] = qy[k];
            pz[count] = qz[k];
            ca[count] = qa[k];
            cinv_a[count] = 1.0 / qa[k];
            ++count;
        }
        n = count;
    }
    /// Where the candidates are the listed points', those of the points' box instead (for a cell
    /// halved toward the particle); false where they are already.
    bool widen()
    {
        if (listed == 0)
            return false;
        const Collected c = at;
        collect(c.cell, c.xL, c.row, c.nr, c.begin, *c.x, *c.radius, c.free, c.shape,
                c.reach == Reach::SubCellPoints ? Reach::WholeCell : Reach::FaceBox);
        return true;
    }
    void reset_cover() { std::fill_n(cover.begin(), n, 0.0); }
    /// The candidates' velocities, from the row.
    void gather_velocities(const index_t* row, index_t begin, const std::vector<real_t>& v)
    {
        for (std::size_t c = 0; c < n; ++c)
        {
            const std::size_t g = 3 * static_cast<std::size_t>(begin + row[cand_k[c]]);
            vx[c] = v[g];
            vy[c] = v[g + 1];
            vz[c] = v[g + 2];
        }
    }
    /// The largest squared speed of a covering candidate relative to vL.
    real_t closing2(const Vec3& vL) const
    {
        const real_t *ux = vx.data(), *uy = vy.data(), *uz = vz.data(), *cv = cover.data();
        const real_t w0 = vL[0], w1 = vL[1], w2 = vL[2];
        real_t big = 0.0;
        RKFEM_SIMD(reduction(max : big))
        for (std::size_t c = 0; c < n; ++c)
        {
            const real_t d0 = ux[c] - w0, d1 = uy[c] - w1, d2 = uz[c] - w2;
            big = rk_region_detail::larger(big, cv[c] > 0.0 ? d0 * d0 + d1 * d1 + d2 * d2 : 0.0);
        }
        return big;
    }
    /// Point q's covering candidates and their values (m[q] of them).
    const index_t* covering(int q) const { return &idx[static_cast<std::size_t>(q) * cap]; }
    const real_t* values(int q) const { return &psi[static_cast<std::size_t>(q) * cap]; }
    /// Face f's gradients, component d.
    const real_t* gradients(int f, int d) const
    {
        return &grad[(3 * static_cast<std::size_t>(f) + static_cast<std::size_t>(d)) * cap];
    }
    /// v^h at point q: sum Psi_q v over its covering candidates.
    Vec3 interpolate(int q) const
    {
        const index_t* id = covering(q);
        const real_t* ps = values(q);
        const real_t *ux = vx.data(), *uy = vy.data(), *uz = vz.data();
        real_t a0 = 0.0, a1 = 0.0, a2 = 0.0;
        RKFEM_SIMD(reduction(+ : a0, a1, a2))
        for (std::size_t e = 0; e < m[q]; ++e)
        {
            const index_t c = id[e];
            a0 += ps[e] * ux[c];
            a1 += ps[e] * uy[c];
            a2 += ps[e] * uz[c];
        }
        return {a0, a1, a2};
    }
    /// grad v^h at face centre f: sum v (x) grad Psi_f over its covering candidates.
    Mat3 velocity_gradient(int f) const
    {
        const index_t* id = covering(f);
        const real_t *g0 = gradients(f, 0), *g1 = gradients(f, 1), *g2 = gradients(f, 2);
        const real_t *ux = vx.data(), *uy = vy.data(), *uz = vz.data();
        real_t s00 = 0, s01 = 0, s02 = 0, s10 = 0, s11 = 0, s12 = 0, s20 = 0, s21 = 0, s22 = 0;
        RKFEM_SIMD(reduction(+ : s00, s01, s02, s10, s11, s12, s20, s21, s22))
        for (std::size_t e = 0; e < m[f]; ++e)
        {
            const index_t c = id[e];
            const real_t v0 = ux[c], v1 = uy[c], v2 = uz[c];
            s00 += v0 * g0[e];
            s01 += v0 * g1[e];
            s02 += v0 * g2[e];
            s10 += v1 * g0[e];
            s11 += v1 * g1[e];
            s12 += v1 * g2[e];
            s20 += v2 * g0[e];
            s21 += v2 * g1[e];
            s22 += v2 * g2[e];
        }
        Mat3 G;
        G << s00, s01, s02, s10, s11, s12, s20, s21, s22;
        return G;
    }
    /// The cell's force on each candidate into fx, fy, fz: sum_q Psi_q t_q over the first
    /// `points` points, and sum_f S_f grad Psi_f over the six face centres where S (6 Voigt
    /// stresses per face) is given. A point's covering candidates are distinct, so each point's
    /// loop adds in vector lanes.
    void forces(int points, const real_t (*t)[3], const real_t (*S)[6])
    {
        real_t *ox = fx.data(), *oy = fy.data(), *oz = fz.data();
        std::fill_n(ox, n, 0.0);
        std::fill_n(oy, n, 0.0);
        std::fill_n(oz, n, 0.0);
        for (int q = 0; q < points; ++q)
        {
            const index_t* id = covering(q);
            const real_t* ps = values(q);
            const real_t t0 = t[q][0], t1 = t[q][1], t2 = t[q][2];
            if (S == nullptr)
            {
                RKFEM_SIMD()
                for (std::size_t e = 0; e < m[q]; ++e)
                {
                    const index_t c = id[e];
                    ox[c] += ps[e] * t0;
                    oy[c] += ps[e] * t1;
                    oz[c] += ps[e] * t2;
                }
                continue;
            }
            const real_t* s = S[q]; // q a face centre
            const real_t *g0 = gradients(q, 0), *g1 = gradients(q, 1), *g2 = gradients(q, 2);
            RKFEM_SIMD()
            for (std::size_t e = 0; e < m[q]; ++e)
            {
                const index_t c = id[e];
                ox[c] += ps[e] * t0 + s[0] * g0[e] + s[3] * g1[e] + s[5] * g2[e];
                oy[c] += ps[e] * t1 + s[3] * g0[e] + s[1] * g1[e] + s[4] * g2[e];
                oz[c] += ps[e] * t2 + s[5] * g0[e] + s[4] * g1[e] + s[2] * g2[e];
            }
        }
    }

    /// The functions at the cell's centre + off into point q's packed rows (with `gradients`,
    /// their gradients too: q a face, 0..5), its covering candidates marked in cover. False
    /// where the moment matrix is singular (kCoverPivot).
    bool functions_at(int q, const Vec3& off, const RkParams& rk, bool gradients)
    {
        // the candidates to look at: the point's own (collect's lists, for the cell's own
        // points), or every one
        const bool own = q < listed;
        const index_t* id = own ? &idx[static_cast<std::size_t>(q) * cap] : all.data();
        const std::size_t len = own ? m[q] : n;
        switch (rk.kernel)
        {
        case KernelType::CubicBSpline:
            windows_of<KernelType::CubicBSpline>(off, id, len, rk.support, gradients);
            break;
        case KernelType::QuinticBSpline:
            windows_of<KernelType::QuinticBSpline>(off, id, len, rk.support, gradients);
            break;
        case KernelType::Gaussian:
            windows_of<KernelType::Gaussian>(off, id, len, rk.support, gradients);
            break;
        }
        pack(q, id, len, gradients);
        return rk.order == 1 ? solve_linear(q, gradients) : solve_other(q, rk.order, gradients);
    }

  private:
    template <KernelType K>
    void windows_of(const Vec3& off, const index_t* id, std::size_t len, SupportShape shape, bool gradients)
    {
        if (shape == SupportShape::Box)
            gradients ? windows<K, SupportShape::Box, true>(off, id, len)
                      : windows<K, SupportShape::Box, false>(off, id, len);
        else
            gradients ? windows<K, SupportShape::Sphere, true>(off, id, len)
                      : windows<K, SupportShape::Sphere, false>(off, id, len);
    }
    /// The windows (and their gradients, G) at the cell's centre + off of the candidates id[e],
    /// e < len, into the point's arrays (kd*, kphi, kq*: place e), the covering ones marked in
    /// cover; the covering count and the least covering radius (RkRegionValues::slopes' windows).
    template <KernelType K, SupportShape S, bool G> void windows(const Vec3& off, const index_t* id, std::size_t len)
    {
        using namespace rk_region_detail;
        const real_t o0 = off[0], o1 = off[1], o2 = off[2];
        const real_t *pxs = px.data(), *pys = py.data(), *pzs = pz.data(), *ia = cinv_a.data(), *ra = ca.data();
        real_t *d0s = kd0.data(), *d1s = kd1.data(), *d2s = kd2.data(), *ph = kphi.data(), *cv = cover.data();
        real_t *g0s = kq0.data(), *g1s = kq1.data(), *g2s = kq2.data();
        real_t count = 0, least = std::numeric_limits<real_t>::infinity();
        RKFEM_SIMD(reduction(+ : count) reduction(min : least))
        for (std::size_t e = 0; e < len; ++e)
        {
            const index_t k = id[e];
            const real_t d0 = o0 - pxs[k], d1 = o1 - pys[k], d2 = o2 - pzs[k];
            const real_t inv_a = ia[k];
            real_t w = 0.0, g0 = 0.0, g1 = 0.0, g2 = 0.0;
            if constexpr (G)
                window_gradient_at<K, S>(d0, d1, d2, inv_a, w, g0, g1, g2);
            else
                w = window_at<K, S>(d0, d1, d2, inv_a);
            const bool covers = w > 0.0;
            d0s[e] = d0;
            d1s[e] = d1;
            d2s[e] = d2;
            ph[e] = covers ? w : 0.0;
            if (covers)
                cv[k] = 1.0;
            count += covers ? 1.0 : 0.0;
            least = std::min(least, covers ? ra[k] : std::numeric_limits<real_t>::infinity());
            if constexpr (G)
            {
                g0s[e] = g0;
                g1s[e] = g1;
                g2s[e] = g2;
            }
        }
        n_cover = count;
        a_min = least;
    }
    /// Point q's covering candidates into its row of idx (m[q] of them) and its arrays packed
    /// to them, in place: nothing to move where every candidate looked at covers (a face's own list).
    void pack(int q, const index_t* id, std::size_t len, bool gradients)
    {
        index_t* out = &idx[static_cast<std::size_t>(q) * cap];
        const std::size_t count = static_cast<std::size_t>(n_cover);
        m[q] = count;
        if (count == len)
        {
            if (out != id)
                std::copy_n(id, len, out);
            return;
        }
        std::size_t j = 0;
        for (std::size_t e = 0; e < len; ++e)
            if (kphi[e] > 0.0)
            {
                out[j] = id[e];
                kd0[j] = kd0[e];
                kd1[j] = kd1[e];
                kd2[j] = kd2[e];
                kphi[j] = kphi[e];
                if (gradients)
                {
                    kq0[j] = kq0[e];
                    kq1[j] = kq1[e];
                    kq2[j] = kq2[e];
                }
                ++j;
            }
    }
    /// sum w, sum w d_i, sum w d_i d_j over the packed point (rk_region_detail's order).
    void moments(std::size_t count, const real_t* w, real_t out[10]) const
    {
        using namespace rk_region_detail;
        const real_t *d0s = kd0.data(), *d1s = kd1.data(), *d2s = kd2.data();
        real_t s0 = 0, s1 = 0, s2 = 0, s3 = 0, s11 = 0, s12 = 0, s13 = 0, s22 = 0, s23 = 0, s33 = 0;
        RKFEM_SIMD(reduction(+ : s0, s1, s2, s3, s11, s12, s13, s22, s23, s33))
        for (std::size_t k = 0; k < count; ++k)
            add_moments(w[k], d0s[k], d1s[k], d2s[k], s0, s1, s2, s3, s11, s12, s13, s22, s23, s33);
        const real_t s[10] = {s0, s1, s2, s3, s11, s12, s13, s22, s23, s33};
        std::copy(s, s + 10, out);
    }
    /// Order 1 (rk_region_detail's algebra, as RkRegionValues::gradients_linear): b = M^-1 e_0,
    /// Psi_k = phi_k b.H_k, gradients by linear_gradient_coefficients and linear_value_gradient.
    bool solve_linear(int q, bool gradients)
    {
        using namespace rk_region_detail;
        if (n_cover < 4.0)
            return false;
        const std::size_t count = m[q];
        const real_t inv_s = 1.0 / a_min;
        real_t sums[10];
        moments(count, kphi.data(), sums);
        const Eigen::Matrix4d M = scaled_moments(sums, inv_s);
        const Ldlt4 ldlt(M);
        if (!ldlt.pivots_above(kCoverPivot))
            return false;
        const Eigen::Vector4d b = ldlt.solve(Eigen::Vector4d(1.0, 0.0, 0.0, 0.0));
        const real_t c0 = b[0], c1 = b[1] * inv_s, c2 = b[2] * inv_s, c3 = b[3] * inv_s;
        const real_t *d0 = kd0.data(), *d1 = kd1.data(), *d2 = kd2.data(), *ph = kphi.data();
        real_t* ps = &psi[static_cast<std::size_t>(q) * cap];
        if (!gradients)
        {
            RKFEM_SIMD()
            for (std::size_t k = 0; k < count; ++k)
                ps[k] = ph[k] * (c0 + c1 * d0[k] + c2 * d1[k] + c3 * d2[k]);
            return true;
        }
        real_t slope_sums[3][10], e[3][4];
        moments(count, kq0.data(), slope_sums[0]);
        moments(count, kq1.data(), slope_sums[1]);
        moments(count, kq2.data(), slope_sums[2]);
        linear_gradient_coefficients(M, ldlt, b, slope_sums, inv_s, e);
        const real_t c[4] = {c0, c1, c2, c3};
        const real_t *r0 = kq0.data(), *r1 = kq1.data(), *r2 = kq2.data();
        real_t *g0 = &grad[(3 * static_cast<std::size_t>(q)) * cap], *g1 = g0 + cap, *g2 = g1 + cap;
        RKFEM_SIMD()
        for (std::size_t k = 0; k < count; ++k)
            linear_value_gradient(c, e, ph[k], r0[k], r1[k], r2[k], d0[k], d1[k], d2[k], ps[k], g0[k], g1[k], g2[k]);
        return true;
    }
    /// Other orders: the packed point through rk_solve_sample.
    bool solve_other(int q, int order, bool gradients)
    {
        const std::size_t count = m[q];
        sample.clear();
        for (std::size_t e = 0; e < count; ++e)
        {
            sample.nodes.push_back(static_cast<index_t>(e));
            sample.phi.push_back(kphi[e]);
            sample.dphi.emplace_back(kq0[e], kq1[e], kq2[e]);
            sample.dx.emplace_back(kd0[e], kd1[e], kd2[e]);
        }
        if (!rk_solve_sample(sample, a_min, order, gradients, kCoverPivot))
            return false;
        real_t* ps = &psi[static_cast<std::size_t>(q) * cap];
        for (std::size_t e = 0; e < count; ++e)
        {
            ps[e] = sample.psi[e];
            if (gradients)
                for (int d = 0; d < 3; ++d)
                    grad[(3 * static_cast<std::size_t>(q) + static_cast<std::size_t>(d)) * cap + e] = sample.grad[e][d];
        }
        return true;
    }
};

/// Particle L as a pass takes it: its neighbour row and the row's length, the offset of its
/// values in the node arrays (3 per node), its position in x and its committed cell.
struct ParticleAt
{
    const index_t* row;
    index_t n;
    std::size_t g;
    Vec3 x;
    Cell cell;
};
ParticleAt particle_at(index_t L, index_t begin, const std::vector<index_t>& offsets, const std::vector<index_t>& ids,
                       const std::vector<real_t>& x, const std::vector<real_t>& cells)
{
    const std::size_t g = 3 * static_cast<std::size_t>(begin + L);
    return {&ids[static_cast<std::size_t>(offsets[L])], offsets[L + 1] - offsets[L], g, Vec3(x[g], x[g + 1], x[g + 2]),
            Cell(&cells[12 * static_cast<std::size_t>(L)])};
}

FastScratch& fast_scratch()
{
    thread_local FastScratch s;
    return s;
}

/// The forces of sc.forces added where out(k) puts row entry k's (3 values), for the candidates
/// that cover a point of the cell (the others get none).
template <class Out> void scatter_forces(const FastScratch& sc, Out&& out)
{
    for (std::size_t c = 0; c < sc.n; ++c)
        if (sc.cover[c] > 0.0)
        {
            real_t* to = out(sc.cand_k[c]);
            to[0] += sc.fx[c];
            to[1] += sc.fy[c];
            to[2] += sc.fz[c];
        }
}

/// Face f (0..5, as Cell::area's) of sub-cell s (bit i of s: the +1/2 half along axis i): its
/// sample point q and its outward area vector (a quarter of the cell's face f area).
int sub_face_point(int s, int f)
{
    const int i = f / 2, side = f % 2; // side 0: toward -e_i
    const int a = ((s >> i) & 1) + side;
    return 12 * i + 4 * a + 2 * ((s >> ((i + 1) % 3)) & 1) + ((s >> ((i + 2) % 3)) & 1);
}

/// A particle's cell with a side halved toward the particle (the side of face f).
void halve(Cell& cell, int f)
{
    const int i = f / 2;
    cell.e[i] *= 0.5;
    cell.c -= (f % 2 == 0 ? -1.0 : 1.0) * cell.e[i];
}

/// The cell the smoothed gradient is taken on and the functions at its face centres (into
/// sc's rows 0..5, with their gradients where asked): the particle's cell, or, where a face
/// centre is not covered (kCoverPivot: a crack face, a free surface a cell reaches past), the
/// cell halved on that side, toward the particle, up to four times in all. A half cell is a
/// parallelepiped still, so linear fields stay exact; the integration weight stays the
/// particle's volume. False: still uncovered (it has separated).
bool gradient_cell(FastScratch& sc, const Cell& cell, const RkParams& rk, bool gradients, Cell& gcell)
{
    gcell = cell;
    for (int attempt = 0; attempt <= 4; ++attempt)
    {
        sc.reset_cover();
        int failed = -1;
        for (int f = 0; f < 6 && failed < 0; ++f)
            if (!sc.functions_at(f, gcell.c - cell.c + (f % 2 == 0 ? -1.0 : 1.0) * gcell.e[f / 2], rk, gradients))
                failed = f;
        if (failed < 0)
            return true;
        sc.widen(); // the halved cell's points may reach particles that covered no face centre
        halve(gcell, failed);
    }
    return false;
}

/// sigma g for a Voigt stress
Vec3 traction(const real_t s[6], const real_t g[3])
{
    return {s[0] * g[0] + s[3] * g[1] + s[5] * g[2], s[3] * g[0] + s[1] * g[1] + s[4] * g[2],
            s[5] * g[0] + s[4] * g[1] + s[2] * g[2]};
}

/// Psi (and grad Psi) at point p from the row's particles that cover it; sample.nodes holds the
/// row positions. False where the moment matrix is singular.
bool evaluate_at(const Vec3& p, const index_t* row, index_t n, index_t begin, const std::vector<real_t>& x,
                 const std::vector<real_t>& radius, const RkParams& rk, RkSample& sample, const std::vector<char>& free)
{
    sample.clear();
    real_t scale = kNoLimit;
    const bool box = rk.support == SupportShape::Box;
    for (index_t k = 0; k < n; ++k)
    {
        const index_t j = row[k];
        if (free[static_cast<std::size_t>(j)])
            continue;
        const std::size_t g = 3 * static_cast<std::size_t>(begin + j);
        const Vec3 dx(p[0] - x[g], p[1] - x[g + 1], p[2] - x[g + 2]);
        const real_t a = radius[static_cast<std::size_t>(j)];
        if (box && (std::abs(dx[0]) >= a || std::abs(dx[1]) >= a || std::abs(dx[2]) >= a))
            continue;
        real_t phi = 0.0;
        Vec3 dphi;
        if (kernel_3d(rk.kernel, rk.support, dx, a, phi, dphi) && phi > 0.0)
        {
            sample.nodes.push_back(k);
            sample.phi.push_back(phi);
            sample.dphi.push_back(dphi);
            sample.dx.push_back(dx);
            scale = std::min(scale, a);
        }
    }
    return rk_solve_sample(sample, scale, rk.order, true, kCoverPivot);
}

/// The plain twin of gradient_cell: on the same gradient cell, b_J (sc.b, 3 per row entry) and
/// grad Psi_J at its face centres (sc.face, 18 per row entry, 0 where J does not cover the
/// centre), from every particle of the row. False: still uncovered after four halvings.
bool plain_gradient(const Vec3& xL, const Cell& cell, const index_t* row, index_t n, index_t begin,
                    const std::vector<real_t>& x, const std::vector<real_t>& radius, const RkParams& rk,
                    const std::vector<char>& free, Scratch& sc)
{
    Cell gcell = cell;
    for (int attempt = 0; attempt <= 4; ++attempt)
    {
        sc.b.assign(3 * static_cast<std::size_t>(n), 0.0);
        sc.face.assign(18 * static_cast<std::size_t>(n), 0.0);
        const real_t inv_V = 1.0 / gcell.volume();
        int failed = -1;
        for (int f = 0; f < 6 && failed < 0; ++f)
        {
            if (!evaluate_at(gcell.centre(xL, f), row, n, begin, x, radius, rk, sc.sample, free))
            {
                failed = f;
                break;
            }
            const Vec3 af = inv_V * gcell.area(f);
            for (index_t e = 0; e < sc.sample.size(); ++e)
            {
                const std::size_t k = static_cast<std::size_t>(sc.sample.nodes[e]);
                for (int d = 0; d < 3; ++d)
                {
                    sc.b[3 * k + d] += sc.sample.psi[e] * af[d];
                    sc.face[18 * k + 3 * static_cast<std::size_t>(f) + d] = sc.sample.grad[e][d];
                }
            }
        }
        if (failed < 0)
            return true;
        halve(gcell, failed);
    }
    return false;
}
} // namespace

SemiLagrangianForceBlock::SemiLagrangianForceBlock(NodalBlock state, std::vector<real_t> radius0,
                                                   std::vector<real_t> cells, SemiLagrangianOptions options)
    : state_(std::move(state)), radius0_(std::move(radius0)), opt_(options)
{
    const index_t np = state_.n_points();
    const std::size_t n = static_cast<std::size_t>(np);
    RKFEM_REQUIRE(np == state_.node_end - state_.node_begin && radius0_.size() == n &&
                      (cells.empty() || cells.size() == 12 * n),
                  "semi-Lagrangian block: one stress point, one support radius and one cell per particle expected, "
                  "got "
                      << np << " points, " << radius0_.size() << " radii and " << cells.size() / 12 << " cells for "
                      << state_.node_end - state_.node_begin << " particles");
    for (index_t p = 0; p < np; ++p)
        RKFEM_REQUIRE(state_.points.owner[p] == state_.node_begin + p,
                      "semi-Lagrangian block: point " << p << " is not owned by particle " << p);
    // the Lagrangian operators served the build (volumes, lengths); their entries are not used
    IntegrationOperator pts;
    pts.weight = state_.points.weight;
    pts.position = state_.points.position;
    pts.owner = state_.points.owner;
    pts.offsets.assign(n + 1, 0);
    state_.points = std::move(pts);
    state_.stabilization = IntegrationOperator{};
    state_.point_stencils = StencilTable{};
    state_.stab_stencils = StencilTable{};
    state_.stab_triplets = TripletTable{};
    state_.points_in_table = state_.stab_in_table = state_.stab_in_triplets = false;
    state_.stabilization_triplets = false;
    state_.scatter = ChunkedScatter{};
    std::vector<index_t>().swap(state_.interp_offsets);
    std::vector<index_t>().swap(state_.interp_nodes);
    std::vector<real_t>().swap(state_.interp_values);
    state_.stabilization_coefficient = opt_.stabilization_coefficient;
    state_.stab_stress.assign(6 * static_cast<std::size_t>(subs()) * n, 0.0);
    state_.stab_stress_trial = state_.stab_stress;
    // cells: given, or cubes of the particles' volumes about them
    if (cells.empty())
    {
        cells.assign(12 * n, 0.0);
        for (std::size_t p = 0; p < n; ++p)
            for (int k = 0; k < 3; ++k)
                cells[12 * p + 3 + 4 * static_cast<std::size_t>(k)] = 0.5 * std::cbrt(state_.points.weight[p]);
    }
    RKFEM_REQUIRE((!opt_.dormant && opt_.spares == 0) || !resets(),
                  "semi-Lagrangian block: dormant particles (conversion, refinement) need tables rebuilt every step");
    RKFEM_REQUIRE(opt_.spares >= 0 && opt_.spares <= np,
                  "semi-Lagrangian block: " << opt_.spares << " spare particles of " << np);
    // dormant from the start: every particle of a conversion, the refinement's pool (the last ones)
    const std::size_t first_asleep = opt_.dormant ? 0 : n - static_cast<std::size_t>(opt_.spares);
    for (std::size_t p = first_asleep; p < n; ++p)
        std::fill_n(&cells[12 * p], 12, 0.0); // empty until a conversion or a split gives one
    state_.cells = std::move(cells);
    state_.cells_trial = state_.cells;
    state_.jacobian.assign(n, 0.0);
    for (std::size_t p = 0; p < first_asleep; ++p)
    {
        const real_t V = Cell(&state_.cells[12 * p]).volume();
        RKFEM_REQUIRE(V > 0.0, "semi-Lagrangian block: particle " << p << "'s cell has volume " << V);
        state_.jacobian[p] = V / state_.points.weight[p];
    }
    volume_trial_ = state_.jacobian;
    v0_ = state_.points.weight;
    width0_.assign(n, 1.0); // dormant: any positive width (a dormant support is its start's)
    for (std::size_t p = 0; p < first_asleep; ++p)
        width0_[p] = Cell(&state_.cells[12 * p]).longest_half_edge();
    if (first_asleep < n)
    {
        dormant_.assign(n, 0);
        std::fill(dormant_.begin() + static_cast<std::ptrdiff_t>(first_asleep), dormant_.end(), char{1});
    }
    level_.assign(n, 0);
    radius_ = radius0_;
    if (resets())
    {
        // the reference of the start: u = 0, the particles' volumes and step lengths
        state_.reference.assign(5 * n + 1, 0.0);
        for (std::size_t p = 0; p < n; ++p)
        {
            state_.reference[3 * n + p] = Cell(&state_.cells[12 * p]).volume();
            state_.reference[4 * n + p] = state_.length0[p];
        }
        u_rel_.assign(3 * static_cast<std::size_t>(state_.node_end), 0.0);
        NodalBlockOptions o = state_.options();
        o.share_stencils = false; // rows of a moving cloud: nothing to share
        state_.set_options(o);
    }
    cell_reach_.assign(n, 0.0);
    point_sums_.assign(4 * n, 0.0);
    for (std::size_t p = first_asleep; p < n; ++p)
        point_sums_[4 * p + 3] = kNoLimit; // a dormant particle's pass: nothing, no step limit
    bad_.assign(n, 0);
    free_.assign(n, 0);
}

void SemiLagrangianForceBlock::activate(index_t p, const real_t* cell, real_t V0, real_t w0)
{
    const std::size_t q = static_cast<std::size_t>(p);
    RKFEM_REQUIRE(p >= 0 && p < n_particles() && V0 > 0.0 && w0 > 0.0, "semi-Lagrangian activation: particle "
                                                                           << p << " of " << n_particles() << ", V0 "
                                                                           << V0 << ", w0 " << w0);
    const real_t V = Cell(cell).volume();
    RKFEM_REQUIRE(V > 0.0, "semi-Lagrangian activation: particle " << p << "'s cell has volume " << V);
    if (dormant(p))
    {
        const std::size_t m = static_cast<std::size_t>(subs()), ns = m * static_cast<std::size_t>(n_particles());
        for (int k = 0; k < 6; ++k)
            for (std::size_t f = 0; f < m; ++f)
                state_.stab_stress[k * ns + m * q + f] = state_.stab_stress_trial[k * ns + m * q + f] = 0.0;
        dormant_[q] = 0;
    }
    std::copy_n(cell, 12, &state_.cells[12 * q]);
    std::copy_n(cell, 12, &state_.cells_trial[12 * q]);
    state_.points.weight[q] = v0_[q] = V0;
    state_.jacobian[q] = volume_trial_[q] = V / V0;
    width0_[q] = w0;
    radius_built_.clear(); // the next pass builds the lists again
}

void SemiLagrangianForceBlock::restore_activation(const std::vector<real_t>& dormant, const std::vector<real_t>& w0)
{
    const std::size_t n = static_cast<std::size_t>(n_particles());
    RKFEM_REQUIRE(dormant.size() == n && w0.size() == n, "semi-Lagrangian block: a checkpoint's activation has "
                                                             << dormant.size() << " flags and " << w0.size()
                                                             << " widths for " << n << " particles");
    dormant_.assign(n, 0);
    for (std::size_t p = 0; p < n; ++p)
        dormant_[p] = dormant[p] != 0.0;
    width0_ = w0;
    v0_ = state_.points.weight;
    volume_trial_ = state_.jacobian;
    radius_built_.clear();
}

Vec3 SemiLagrangianForceBlock::outward_normal(index_t p, const std::vector<real_t>& x) const
{
    if (offsets_.size() != static_cast<std::size_t>(n_particles()) + 1 || radius_.empty() || state_.jacobian[p] == 0.0)
        return Vec3::Zero();
    const index_t nb = state_.node_begin;
    auto at = [&](index_t q) { return Vec3(x[3 * (nb + q)], x[3 * (nb + q) + 1], x[3 * (nb + q) + 2]); };
    const Vec3 xp = at(p);
    Vec3 g = Vec3::Zero();
    real_t scale = 0.0; // the sum of |V_J grad phi_J|: the gradient's size where it cancels
    for (index_t e = offsets_[p]; e < offsets_[p + 1]; ++e)
    {
        const index_t j = ids_[e];
        if (state_.jacobian[j] == 0.0)
            continue;
        real_t phi = 0.0;
        Vec3 dphi;
        if (kernel_3d(opt_.rk.kernel, opt_.rk.support, xp - at(j), radius_[j], phi, dphi))
        {
            g += volume(j) * dphi;
            scale += volume(j) * dphi.norm();
        }
    }
    const real_t a = g.norm();
    return a > 1e-8 * scale ? Vec3(-g / a) : Vec3::Zero();
}

real_t SemiLagrangianForceBlock::radius(index_t p) const
{
    // the kernel follows the cell's volume and its longest stretch: where the material spreads
    // (a Taylor bar's foot spreads its particles apart around the rim while their volumes stay)
    // the support keeps reaching the neighbours across the stretch
    const real_t stretch = Cell(&state_.cells[12 * static_cast<std::size_t>(p)]).longest_half_edge() / width0_[p];
    return radius0_[p] * std::max({1.0, std::cbrt(volume(p) / v0_[p]), stretch});
}

void SemiLagrangianForceBlock::extents()
{
    const bool box = opt_.rk.support == SupportShape::Box;
    for (index_t p = 0; p < n_particles(); ++p)
    {
        radius_[p] = radius(p);
        // how far the cell's face centres lie from the particle (along each axis for box kernels);
        // SD-SNNI's sub-cell face centres lie on the cell's faces and midplanes, past the face
        // centres on a sheared cell (or for sphere kernels): there, the farthest corner, which
        // bounds every point of the cell
        const Cell cell(&state_.cells[12 * static_cast<std::size_t>(p)]);
        real_t r = 0.0;
        for (int f = 0; f < 6; ++f)
        {
            const Vec3 d = cell.c + (f % 2 == 0 ? -1.0 : 1.0) * cell.e[f / 2];
            r = std::max(r, box ? d.cwiseAbs().maxCoeff() : d.norm());
        }
        for (int q = 0; q < (opt_.sub_cells ? 8 : 0); ++q)
        {
            Vec3 d = cell.c;
            for (int i = 0; i < 3; ++i)
                d += ((q >> i) & 1 ? 1.0 : -1.0) * cell.e[i];
            r = std::max(r, box ? d.cwiseAbs().maxCoeff() : d.norm());
        }
        cell_reach_[p] = r;
    }
}

void SemiLagrangianForceBlock::update_neighbours(const std::vector<real_t>& x)
{
    const index_t np = n_particles();
    extents();
    if (rebuilds_ > 0 && static_cast<index_t>(radius_built_.size()) == np)
    {
        const std::size_t b = 3 * static_cast<std::size_t>(state_.node_begin);
        const real_t d2 = -parallel_reduce_min("rkfem::semi_lagrangian::displacement", np,
                                               [&](index_t p)
                                               {
                                                   real_t s = 0.0;
                                                   if (dormant(p))
                                                       return -s; // in no list
                                                   for (int d = 0; d < 3; ++d)
                                                   {
                                                       const real_t u = x[b + 3 * p + d] - x_built_[3 * p + d];
                                                       s += u * u;
                                                   }
                                                   return -s;
                                               });
        // a pair (L, J) is needed where |x_L - x_J| < a_J + r_L (r: the cell's reach); the lists
        // hold the pairs within max(a_J + r_L, a_L + r_J) + skin at the build
        real_t da = 0.0, dr = 0.0;
        for (index_t p = 0; p < np; ++p)
        {
            da = std::max(da, radius_[p] - radius_built_[p]);
            dr = std::max(dr, cell_reach_[p] - reach_built_[p]);
        }
        if (2.0 * std::sqrt(d2) + da + dr <= opt_.skin)
            return;
    }
    build_neighbours(x);
}

void SemiLagrangianForceBlock::build_neighbours(const std::vector<real_t>& x)
{
    const index_t np = n_particles();
    const std::size_t b = 3 * static_cast<std::size_t>(state_.node_begin);
    x_built_.assign(x.begin() + static_cast<std::ptrdiff_t>(b), x.begin() + static_cast<std::ptrdiff_t>(b + 3 * np));
    radius_built_ = radius_;
    reach_built_ = cell_reach_;
    const real_t skin = opt_.skin;
    real_t a_max = 0.0, r_max = 0.0;
    for (index_t p = 0; p < np; ++p)
        a_max = std::max(a_max, radius_[p]), r_max = std::max(r_max, cell_reach_[p]);
    const real_t R = a_max + r_max + skin;
    const bool box = opt_.rk.support == SupportShape::Box;
    // a cell list of bin size R: the 27 bins about a particle hold every particle within R along
    // each axis
    auto within = [&](index_t i, index_t j)
    {
        real_t s = 0.0, m = 0.0;
        for (int d = 0; d < 3; ++d)
        {
            const real_t u = x_built_[3 * j + d] - x_built_[3 * i + d];
            s += u * u;
            m = std::max(m, std::abs(u));
        }
        const real_t r = std::max(radius_[j] + cell_reach_[i], radius_[i] + cell_reach_[j]) + skin;
        return box ? m < r : s < r * r;
    };
    if (dormant_.empty())
        build_neighbour_rows(CellList(x_built_, R), x_built_, np, within, offsets_, ids_);
    else
    {
        // conversion: rows for the particles that are not dormant, over them alone (in order, so
        // each row stays ascending); a dormant particle's row is empty
        std::vector<index_t> on;
        std::vector<real_t> xa;
        for (index_t p = 0; p < np; ++p)
            if (!dormant(p))
            {
                on.push_back(p);
                xa.insert(xa.end(), x_built_.begin() + 3 * p, x_built_.begin() + 3 * p + 3);
            }
        std::vector<index_t> off, ids;
        const CellList active_cells(xa, R);
        build_neighbour_rows(
            active_cells, xa, static_cast<index_t>(on.size()),
            [&](index_t i, index_t j) { return within(on[i], on[j]); }, off, ids);
        offsets_.assign(static_cast<std::size_t>(np) + 1, 0);
        for (std::size_t k = 0; k < on.size(); ++k)
            offsets_[static_cast<std::size_t>(on[k]) + 1] = off[k + 1] - off[k];
        for (index_t p = 0; p < np; ++p)
            offsets_[p + 1] += offsets_[p];
        ids_.resize(ids.size());
        for (std::size_t k = 0; k < ids.size(); ++k)
            ids_[k] = on[static_cast<std::size_t>(ids[k])];
    }
    // refinement's interfaces: particles with a neighbour of another level
    mixed_.clear();
    if (std::any_of(level_.begin(), level_.end(), [](char l) { return l != 0; }))
    {
        mixed_.assign(static_cast<std::size_t>(np), 0);
        for (index_t p = 0; p < np; ++p)
            for (index_t k = offsets_[p]; k < offsets_[p + 1]; ++k)
                if (level_[static_cast<std::size_t>(ids_[k])] != level_[static_cast<std::size_t>(p)])
                {
                    mixed_[static_cast<std::size_t>(p)] = 1;
                    break;
                }
    }
    plan_assembly();
    ++rebuilds_;
}

void SemiLagrangianForceBlock::plan_assembly()
{
    const index_t np = n_particles(), begin = state_.node_begin;
    // chunks of particles in order, about n / 16 (at least 256: a particle's pass costs some
    // microseconds), doubled while they take over 3 buffers per node; the largest still scatters
    // at up to 8 buffers per node with a chunk covering at most 3/4 of the block (nodal_block.cpp)
    real_t worst = 0.0, spread = 0.0;
    auto cut = [&](index_t size)
    {
        scatter_.clear();
        scatter_.node_begin = begin;
        scatter_.node_end = begin + np;
        const std::size_t added = scatter_.add_chunks(np, size,
                                                      [&](index_t first, index_t last, index_t& lo, index_t& hi)
                                                      {
                                                          for (index_t k = offsets_[first]; k < offsets_[last]; ++k)
                                                          {
                                                              lo = std::min(lo, begin + ids_[k]);
                                                              hi = std::max(hi, begin + ids_[k] + 1);
                                                          }
                                                      });
        worst = static_cast<real_t>(added) / (4.0 * static_cast<real_t>(std::max<index_t>(np, 1)));
        spread = scatter_.chunks.empty() ? 0.0 : worst / static_cast<real_t>(scatter_.chunks.size());
        return ChunkedScatter::local(added, np);
    };
    index_t size = ChunkedScatter::chunk_size(np, 1, 256);
    const bool local = ChunkedScatter::cut_until_local(size, std::max<index_t>(2048, np / 4), cut);
    const bool scatter = opt_.assembly == Assembly::Scatter ||
                         (opt_.assembly == Assembly::Automatic && (local || (worst <= 8.0 && spread <= 0.75)));
    if (np > 0 && scatter)
    {
        scatter_.finish();
        std::vector<index_t>().swap(transpose_);
        std::vector<real_t>().swap(pair_force_);
        return;
    }
    scatter_.clear();
    // the gather: the lists are symmetric (one reach for all), so (L, J)'s twin is L's place in J's row
    transpose_.resize(ids_.size());
    parallel_for("rkfem::semi_lagrangian::transpose", np,
                 [&](index_t i)
                 {
                     for (index_t k = offsets_[i]; k < offsets_[i + 1]; ++k)
                     {
                         const index_t j = ids_[k];
                         const auto first = ids_.begin() + offsets_[j], last = ids_.begin() + offsets_[j + 1];
                         transpose_[k] = static_cast<index_t>(std::lower_bound(first, last, i) - ids_.begin());
                     }
                 });
    pair_force_.resize(3 * ids_.size());
}

template <class Point> void SemiLagrangianForceBlock::run_points(const char* label, Point&& point)
{
    const index_t begin = state_.node_begin;
    if (!scatter_.empty())
    {
        scatter_.run_chunks(label, 0, static_cast<index_t>(scatter_.chunks.size()), 1,
                            [&](index_t L, real_t* buf, index_t lo)
                            {
                                const index_t* row = &ids_[static_cast<std::size_t>(offsets_[L])];
                                point(L, [&](index_t k)
                                      { return buf + 4 * static_cast<std::size_t>(begin + row[k] - lo); });
                            });
        return;
    }
    parallel_for(label, n_particles(),
                 [&](index_t L)
                 {
                     real_t* pf = &pair_force_[3 * static_cast<std::size_t>(offsets_[L])];
                     std::fill(pf, pf + 3 * static_cast<std::size_t>(offsets_[L + 1] - offsets_[L]), 0.0);
                     point(L, [&](index_t k) { return pf + 3 * static_cast<std::size_t>(k); });
                 });
}

std::size_t SemiLagrangianForceBlock::memory_bytes() const
{
    auto bytes = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
    const NodalBlock& b = state_;
    std::size_t n = 0;
    for (const std::vector<real_t>* v : {&b.stab_stress,   &b.stab_stress_trial,
                                         &b.jacobian,      &b.cells,
                                         &b.cells_trial,   &b.reference,
                                         &b.length0,       &radius0_,
                                         &radius_,         &v0_,
                                         &width0_,         &u_rel_,
                                         &volume_trial_,   &x_built_,
                                         &cell_reach_,     &radius_built_,
                                         &reach_built_,    &pair_force_,
                                         &point_sums_,     &scatter_.buffer,
                                         &b.points.weight, &b.points.position})
        n += bytes(*v);
    n += (b.stress.capacity() + b.stress_trial.capacity()) * sizeof(real_t);
    for (const std::vector<index_t>* v : {&offsets_, &ids_, &transpose_, &b.points.owner, &b.points.offsets,
                                          &b.points.nodes, &scatter_.node_chunk_offsets, &scatter_.node_chunks})
        n += bytes(*v);
    n += bytes(b.points.grad) + bytes(bad_) + bytes(free_) + bytes(dormant_);
    b.plastic.each_array(
        [&](const auto& committed, const auto& trial)
        {
            n += bytes(committed);
            n += bytes(trial);
        });
    return n;
}

bool SemiLagrangianForceBlock::update_point(index_t L, const Mat3& Lg, real_t dt, real_t closing, PointUpdate& u)
{
    const Cell cell(&state_.cells[12 * static_cast<std::size_t>(L)]);
    const NodalBlock& blk = state_;
    const ElasticParams mat = blk.material;
    const std::size_t p = static_cast<std::size_t>(L);
    real_t d[6], s_old[6];
    split_rate(Lg, d, u.w);
    for (int k = 0; k < 6; ++k)
        s_old[k] = u.sig[k] = blk.stress[k * blk.stress_stride + p];
    const real_t trd = d[0] + d[1] + d[2];
    const Cell moved = advance(cell, Lg, dt);
    moved.store(&state_.cells_trial[12 * p]);
    const real_t ratio = moved.volume() / blk.points.weight[L];
    volume_trial_[p] = ratio;
    if (!(ratio > 0.0) || !std::isfinite(ratio))
        return false;
    if (!blk.plastic.active())
        elastic_update(mat, d, u.w, dt, u.sig);
    else
    {
        state_.plastic.update(p, d, u.w, dt, u.sig);
        if (opt_.plastic_scaling)
            u.share = assumed_strain_tangent_share<real_t>(s_old, u.sig, d, u.w, mat.mu, dt);
    }
    for (int k = 0; k < 6; ++k)
        state_.stress_trial[k * blk.stress_stride + p] = u.sig[k];
    u.V = blk.points.weight[L] * ratio;
    const real_t c = mat.wave_speed(), q1 = blk.bulk_viscosity.quadratic, q2 = blk.bulk_viscosity.linear;
    const real_t len = std::cbrt(ratio) * blk.length0[p]; // q on the point's length, the step alpha times
    u.q = bulk_q(mat.rho / ratio, c, len, trd, q1, q2);
    real_t* sums = &point_sums_[4 * p];
    sums[0] = dt * u.V * stress_power(s_old, u.sig, d);
    sums[1] = -dt * u.V * u.q * trd;
    sums[2] = 0.0;
    // the digest's 7.2: moving particles step at l / (c + the largest speed of a covering
    // particle relative to this one), with the bulk viscosity's term as elements have it
    sums[3] = blk.dt_factor * element_dt(c + closing, len, trd, q1, q2);
    return true;
}

void SemiLagrangianForceBlock::update_face(index_t L, int f, const Mat3& Lf, const PointUpdate& u, real_t dt,
                                           real_t sf[6])
{
    ElasticParams smat = state_.material;
    smat.lambda *= opt_.stabilization_coefficient;
    smat.mu *= opt_.stabilization_coefficient;
    real_t df[6], unused[3], sf_old[6];
    split_rate(Lf, df, unused);
    // component-major, sub-point subs L + f, as the nodal blocks' stabilization stresses
    const std::size_t m = static_cast<std::size_t>(subs());
    const std::size_t ns = m * static_cast<std::size_t>(n_particles());
    const std::size_t at = m * static_cast<std::size_t>(L) + static_cast<std::size_t>(f);
    for (int k = 0; k < 6; ++k)
        sf_old[k] = sf[k] = state_.stab_stress[k * ns + at];
    elastic_update(smat, df, u.w, dt, sf);
    if (u.share < 1.0)
        scale_stabilization_load(hughes_winget(u.w[0], u.w[1], u.w[2], dt), sf_old, u.share, sf);
    for (int k = 0; k < 6; ++k)
        state_.stab_stress_trial[k * ns + at] = sf[k];
    point_sums_[4 * static_cast<std::size_t>(L) + 2] +=
        dt * u.V / static_cast<real_t>(m) * stress_power(sf_old, sf, df);
}

void SemiLagrangianForceBlock::stabilization_stresses(index_t L, const Mat3* departure, int m, const PointUpdate& u,
                                                      real_t dt, real_t sq[6], real_t (*ss)[6])
{
    const real_t s[6] = {u.sig[0] - u.q, u.sig[1] - u.q, u.sig[2] - u.q, u.sig[3], u.sig[4], u.sig[5]};
    std::copy(s, s + 6, sq);
    if (!(opt_.stabilization_coefficient > 0.0))
        return;
    for (int f = 0; f < m; ++f)
    {
        update_face(L, f, departure[f], u, dt, ss[f]);
        for (int k = 0; k < 6; ++k)
            sq[k] -= ss[f][k] / static_cast<real_t>(m);
    }
}

bool SemiLagrangianForceBlock::separated_at_start(index_t L)
{
    bad_[L] = 0;
    if (!free_[static_cast<std::size_t>(L)])
        return false;
    if (!dormant(L)) // a dormant particle's trial state is empty from the start
        separate_trial(L);
    return true;
}

void SemiLagrangianForceBlock::separate_trial(index_t L)
{
    const std::size_t p = static_cast<std::size_t>(L);
    std::fill_n(&state_.cells_trial[12 * p], 12, 0.0);
    for (int k = 0; k < 6; ++k)
        state_.stress_trial[k * state_.stress_stride + p] = 0.0;
    const std::size_t m = static_cast<std::size_t>(subs()), ns = m * static_cast<std::size_t>(n_particles());
    for (int k = 0; k < 6; ++k)
        for (std::size_t f = 0; f < m; ++f)
            state_.stab_stress_trial[k * ns + m * p + f] = 0.0;
    volume_trial_[p] = 0.0;
    real_t* sums = &point_sums_[4 * p];
    sums[0] = sums[1] = sums[2] = 0.0;
    sums[3] = kNoLimit;
}

void SemiLagrangianForceBlock::points_plain(const NodeSet& nodes, real_t dt)
{
    const bool stabilized = opt_.stabilization_coefficient > 0.0;
    const index_t begin = state_.node_begin;
    const std::vector<real_t>& x = nodes.x;
    const std::vector<real_t>& vel = nodes.v;
    run_points("rkfem::semi_lagrangian::points_plain",
               [&](index_t L, auto&& out)
               {
                   Scratch& sc = scratch();
                   const auto [row, n, gL, xL, cell] = particle_at(L, begin, offsets_, ids_, x, state_.cells);
                   if (separated_at_start(L))
                       return;
                   if (!plain_gradient(xL, cell, row, n, begin, x, radius_, opt_.rk, free_, sc))
                   {
                       separate_trial(L); // too few particles cover its cell: it has separated
                       return;
                   }
                   auto velocity = [&](index_t k)
                   {
                       const std::size_t g = 3 * static_cast<std::size_t>(begin + row[k]);
                       return Vec3(vel[g], vel[g + 1], vel[g + 2]);
                   };
                   Mat3 Lg = Mat3::Zero();
                   real_t closing = 0.0;
                   const Vec3 vL(vel[gL], vel[gL + 1], vel[gL + 2]);
                   for (index_t k = 0; k < n; ++k)
                   {
                       const Vec3 bk(sc.b[3 * k], sc.b[3 * k + 1], sc.b[3 * k + 2]);
                       Lg += velocity(k) * bk.transpose();
                       bool covers = bk.squaredNorm() > 0.0;
                       for (int q = 0; q < 18 && !covers; ++q)
                           covers = sc.face[18 * k + q] != 0.0;
                       if (covers)
                           closing = std::max(closing, (velocity(k) - vL).norm());
                   }
                   PointUpdate u;
                   if (!update_point(L, Lg, dt, closing, u))
                   {
                       bad_[L] = 1;
                       return;
                   }
                   const real_t sq[6] = {u.sig[0] - u.q, u.sig[1] - u.q, u.sig[2] - u.q, u.sig[3], u.sig[4], u.sig[5]};
                   for (index_t k = 0; k < n; ++k)
                   {
                       const Vec3 t = u.V * traction(sq, &sc.b[3 * k]);
                       real_t* pf = out(k);
                       for (int a = 0; a < 3; ++a)
                           pf[a] += t[a];
                   }
                   if (!stabilized)
                       return;
                   // the face centres' stabilization stresses, each from its gradient's departure from b
                   for (int f = 0; f < 6; ++f)
                   {
                       auto g = [&](index_t k)
                       {
                           const real_t* gf = &sc.face[18 * k + 3 * static_cast<std::size_t>(f)];
                           return Vec3(gf[0] - sc.b[3 * k], gf[1] - sc.b[3 * k + 1], gf[2] - sc.b[3 * k + 2]);
                       };
                       Mat3 Lf = Mat3::Zero();
                       for (index_t k = 0; k < n; ++k)
                           Lf += velocity(k) * g(k).transpose();
                       real_t sf[6];
                       update_face(L, f, Lf, u, dt, sf);
                       for (index_t k = 0; k < n; ++k)
                       {
                           const Vec3 gk = g(k);
                           const real_t gg[3] = {gk[0], gk[1], gk[2]};
                           const Vec3 t = u.V / 6.0 * traction(sf, gg);
                           real_t* pf = out(k);
                           for (int a = 0; a < 3; ++a)
                               pf[a] += t[a];
                       }
                   }
               });
}

void SemiLagrangianForceBlock::points_sub_cells(const NodeSet& nodes, real_t dt)
{
    const index_t begin = state_.node_begin;
    const std::vector<real_t>& x = nodes.x;
    const std::vector<real_t>& vel = nodes.v;
    run_points("rkfem::semi_lagrangian::points_sub_cells",
               [&](index_t L, auto&& out)
               {
                   FastScratch& sc = fast_scratch();
                   const auto [row, n, gL, xL, cell] = particle_at(L, begin, offsets_, ids_, x, state_.cells);
                   if (separated_at_start(L))
                       return;
                   sc.collect(cell, xL, row, n, begin, x, radius_, &free_, opt_.rk.support,
                              FastScratch::Reach::SubCellPoints);
                   // the functions at the 36 points; where one on the cell's surface is not covered, the
                   // cell halved on that side, toward the particle (gradient_cell's rule), up to four times
                   Cell gcell = cell;
                   bool covered = false;
                   for (int attempt = 0; attempt <= 4 && !covered; ++attempt)
                   {
                       sc.reset_cover();
                       int failed = -1;
                       for (int q = 0; q < kSubPoints && failed < 0; ++q)
                           if (!sc.functions_at(q, sub_point_offset(gcell, q) - cell.c, opt_.rk, false))
                               failed = q;
                       covered = failed < 0;
                       const int a = (failed / 4) % 3;
                       if (!covered && a == 1)
                           break; // a midplane point: the cell's own middle is not covered
                       if (!covered)
                       {
                           sc.widen(); // the halved cell's points may reach particles no listed point did
                           halve(gcell, 2 * (failed / 12) + a / 2);
                       }
                   }
                   if (!covered)
                   {
                       separate_trial(L); // too few particles cover its cell: it has separated
                       return;
                   }
                   // v^h at each point, the largest closing speed of a covering particle
                   sc.gather_velocities(row, begin, vel);
                   const real_t closing2 = sc.closing2(Vec3(vel[gL], vel[gL + 1], vel[gL + 2]));
                   Vec3 vh[kSubPoints];
                   for (int q = 0; q < kSubPoints; ++q)
                       vh[q] = sc.interpolate(q);
                   // each sub-cell's smoothed velocity gradient L_s = (1 / V_s) sum_f v^h(x_f) (x) A_f, and
                   // the particle's, their mean (SNNI on the cell with four points per face)
                   const real_t Vg = gcell.volume(), Vs = Vg / 8.0;
                   Mat3 Ls[8];
                   Mat3 Lg = Mat3::Zero();
                   for (int sub = 0; sub < 8; ++sub)
                   {
                       Ls[sub].setZero();
                       for (int f = 0; f < 6; ++f)
                           Ls[sub] += vh[sub_face_point(sub, f)] * (0.25 * gcell.area(f)).transpose();
                       Ls[sub] /= Vs;
                       Lg += Ls[sub] / 8.0;
                   }
                   PointUpdate u;
                   if (!update_point(L, Lg, dt, std::sqrt(closing2), u))
                   {
                       bad_[L] = 1;
                       return;
                   }
                   // f_J = sum_s (V / 8) T_s b^s_J, T_s = sigma - q 1 - mean_s sigma_s + sigma_s, with
                   // (V / 8) b^s_J = (V / V_g) sum_f Psi_J(x_f) A_f over the sub-cell's faces: a traction
                   // per point, then scattered by its functions
                   for (Mat3& l : Ls)
                       l -= Lg; // the departures
                   real_t sq[6], ss[8][6] = {};
                   stabilization_stresses(L, Ls, 8, u, dt, sq, ss);
                   real_t t[kSubPoints][3] = {};
                   for (int sub = 0; sub < 8; ++sub)
                   {
                       real_t T[6];
                       for (int k = 0; k < 6; ++k)
                           T[k] = sq[k] + ss[sub][k];
                       for (int f = 0; f < 6; ++f)
                       {
                           const Vec3 af = (0.25 * u.V / Vg) * gcell.area(f);
                           const real_t a[3] = {af[0], af[1], af[2]};
                           const Vec3 tf = traction(T, a);
                           for (int d = 0; d < 3; ++d)
                               t[sub_face_point(sub, f)][d] += tf[d];
                       }
                   }
                   sc.forces(kSubPoints, t, nullptr);
                   scatter_forces(sc, out);
               });
}

void SemiLagrangianForceBlock::points_fast(const NodeSet& nodes, real_t dt)
{
    const bool stabilized = opt_.stabilization_coefficient > 0.0;
    const index_t begin = state_.node_begin;
    const std::vector<real_t>& x = nodes.x;
    const std::vector<real_t>& vel = nodes.v;
    run_points("rkfem::semi_lagrangian::points",
               [&](index_t L, auto&& out)
               {
                   FastScratch& sc = fast_scratch();
                   const auto [row, n, gL, xL, cell] = particle_at(L, begin, offsets_, ids_, x, state_.cells);
                   if (separated_at_start(L))
                       return;
                   sc.collect(cell, xL, row, n, begin, x, radius_, &free_, opt_.rk.support,
                              FastScratch::Reach::FaceCentres);
                   // the functions' gradients at the face centres serve the face-gradient term only
                   Cell gcell;
                   if (!gradient_cell(sc, cell, opt_.rk, stabilized, gcell))
                   {
                       separate_trial(L); // too few particles cover its cell: it has separated
                       return;
                   }
                   sc.gather_velocities(row, begin, vel);
                   const real_t closing2 = sc.closing2(Vec3(vel[gL], vel[gL + 1], vel[gL + 2]));
                   const real_t Vg = gcell.volume();
                   // L = (1 / V) sum_f v^h(x_f) (x) A_f, on the gradient's cell
                   Mat3 G[6];
                   Mat3 Lg = Mat3::Zero();
                   for (int f = 0; f < 6; ++f)
                   {
                       Lg += sc.interpolate(f) * gcell.area(f).transpose();
                       G[f] = stabilized ? sc.velocity_gradient(f) : Mat3::Zero();
                   }
                   Lg /= Vg;
                   PointUpdate u;
                   if (!update_point(L, Lg, dt, std::sqrt(closing2), u))
                   {
                       bad_[L] = 1;
                       return;
                   }
                   // f_J = V_n (sigma - q 1 - (1/6) sum_f sigma_f) b_J + (V_n / 6) sum_f sigma_f grad Psi_J(x_f),
                   // with V_n b_J = (V_n / V) sum_f Psi_J(x_f) A_f: a traction per face centre, then
                   // each candidate's force from its functions there
                   for (Mat3& g : G)
                       g -= Lg; // the departures
                   real_t sq[6], sf[6][6] = {};
                   stabilization_stresses(L, G, 6, u, dt, sq, sf);
                   real_t t[6][3], S[6][6];
                   for (int f = 0; f < 6; ++f)
                   {
                       const Vec3 af = (u.V / Vg) * gcell.area(f);
                       const real_t a[3] = {af[0], af[1], af[2]};
                       const Vec3 tf = traction(sq, a);
                       for (int d = 0; d < 3; ++d)
                           t[f][d] = tf[d];
                       for (int k = 0; k < 6; ++k)
                           S[f][k] = (u.V / 6.0) * sf[f][k];
                   }
                   sc.forces(6, t, stabilized ? S : nullptr);
                   scatter_forces(sc, out);
               });
}

ForcePassResult SemiLagrangianForceBlock::add_forces(NodeSet& nodes, real_t dt, bool add)
{
    if (resets())
        return reference_pass(nodes, dt, add);
    const index_t np = n_particles();
    const index_t begin = state_.node_begin;
    update_neighbours(nodes.x);
    for (std::size_t p = 0; p < free_.size(); ++p)
        free_[p] = state_.jacobian[p] == 0.0; // a free particle's cell is empty
    if (opt_.sub_cells)
        points_sub_cells(nodes, dt);
    else if (opt_.plain)
        points_plain(nodes, dt);
    else
        points_fast(nodes, dt);
    ForcePassResult r;
    for (index_t p = 0; p < np; ++p)
        if (bad_[p])
        {
            r.bad_element = p;
            return r;
        }
    for (index_t p = 0; p < np; ++p)
    {
        const real_t* sums = &point_sums_[4 * static_cast<std::size_t>(p)];
        r.d_internal += sums[0];
        r.d_bulk_viscosity += sums[1];
        r.d_hourglass += sums[2];
        // where particles of two levels meet, a fine particle's function seen from a coarse
        // cell's face centres couples it more stiffly than its own estimate says: a column whose
        // refined particles merge back in places went unstable at the finest particle's step
        // (dt_scale 0.9) and ran at 0.45, so the step of a particle with a neighbour of another
        // level is halved (test_refinement: a pulse refined and coarsened)
        const real_t dt_p = !mixed_.empty() && mixed_[static_cast<std::size_t>(p)] ? 0.5 * sums[3] : sums[3];
        if (dt_p < r.dt_stable)
        {
            r.dt_stable = dt_p;
            r.dt_element = p;
        }
    }
    if (!scatter_.empty())
    {
        scatter_.reduce(nodes.f_int, add);
        return r;
    }
    // each particle's force: the entries (L, J) of the rows its own row names, in its row's order
    parallel_for("rkfem::semi_lagrangian::gather", np,
                 [&](index_t J)
                 {
                     Vec3 f = Vec3::Zero();
                     for (index_t k = offsets_[J]; k < offsets_[J + 1]; ++k)
                     {
                         const std::size_t t = 3 * static_cast<std::size_t>(transpose_[k]);
                         f += Vec3(pair_force_[t], pair_force_[t + 1], pair_force_[t + 2]);
                     }
                     real_t* out = &nodes.f_int[3 * static_cast<std::size_t>(begin + J)];
                     for (int a = 0; a < 3; ++a)
                         out[a] = add ? out[a] + f[a] : f[a];
                 });
    return r;
}

void SemiLagrangianForceBlock::commit()
{
    state_.commit();
    if (resets())
    {
        state_.reference.back() += 1.0; // the steps since the reset
        return;
    }
    state_.jacobian.swap(volume_trial_);
    volume_trial_ = state_.jacobian;
    // separation: a particle whose material has failed past separation_damage leaves the kernels
    if (opt_.separation_damage > 0.0 && state_.plastic.active())
        for (index_t p = 0; p < n_particles(); ++p)
        {
            const std::size_t q = static_cast<std::size_t>(p);
            if (state_.jacobian[q] > 0.0 && state_.plastic.damage(q) >= opt_.separation_damage)
            {
                std::fill_n(&state_.cells[12 * q], 12, 0.0);
                std::fill_n(&state_.cells_trial[12 * q], 12, 0.0);
                for (int k = 0; k < 6; ++k)
                    state_.stress[k * state_.stress_stride + q] = 0.0;
                state_.jacobian[q] = volume_trial_[q] = 0.0;
            }
        }
}

ForcePassResult SemiLagrangianForceBlock::reference_pass(NodeSet& nodes, real_t dt, bool add)
{
    const std::size_t n = static_cast<std::size_t>(n_particles());
    const std::size_t b = 3 * static_cast<std::size_t>(state_.node_begin);
    if (!tables_built_)
        build_reference_tables(nodes); // the start, or a restart's reference
    if (state_.reference.back() >= static_cast<real_t>(opt_.reset_interval))
        reset_reference(nodes);
    ForcePassResult r;
    for (std::size_t p = 0; p < n; ++p)
        if (bad_[p])
        {
            r.bad_element = static_cast<index_t>(p);
            return r;
        }
    for (std::size_t i = 0; i < 3 * n; ++i)
        u_rel_[b + i] = nodes.u[b + i] - state_.reference[i];
    r = nodal_internal_force(state_, nodes, dt, u_rel_.data());
    if (r.bad_element < 0)
        assemble_nodal_forces(state_, nodes, add);
    return r;
}

void SemiLagrangianForceBlock::reset_reference(const NodeSet& nodes)
{
    const index_t np = n_particles();
    const std::size_t n = static_cast<std::size_t>(np);
    const std::size_t b = 3 * static_cast<std::size_t>(state_.node_begin);
    std::vector<real_t>& ref = state_.reference;
    for (std::size_t i = 0; i < 3 * n; ++i)
        u_rel_[b + i] = nodes.u[b + i] - ref[i];
    parallel_for("rkfem::semi_lagrangian::reset", np,
                 [&](index_t p)
                 {
                     // F since the last reset, on its tables
                     Mat3 F = Mat3::Identity();
                     const StencilView st = state_.point_view(p);
                     for (index_t j = 0; j < st.size; ++j)
                     {
                         const std::size_t g = 3 * static_cast<std::size_t>(st.base + st.offset[j]);
                         const Vec3 du(u_rel_[g], u_rel_[g + 1], u_rel_[g + 2]);
                         F += du * Vec3(st.grad[3 * j], st.grad[3 * j + 1], st.grad[3 * j + 2]).transpose();
                     }
                     const std::size_t q = static_cast<std::size_t>(p);
                     const Cell moved = deform(Cell(&state_.cells[12 * q]), F);
                     moved.store(&state_.cells[12 * q]);
                     moved.store(&state_.cells_trial[12 * q]);
                     const real_t V = moved.volume();
                     ref[4 * n + q] *= std::cbrt(V / ref[3 * n + q]);
                     ref[3 * n + q] = V;
                     for (int d = 0; d < 3; ++d)
                         ref[3 * q + d] = nodes.u[b + 3 * q + d];
                 });
    ref.back() = 0.0;
    build_reference_tables(nodes);
}

void SemiLagrangianForceBlock::build_reference_tables(const NodeSet& nodes)
{
    const index_t np = n_particles();
    const std::size_t n = static_cast<std::size_t>(np);
    const index_t begin = state_.node_begin;
    const std::size_t b = 3 * static_cast<std::size_t>(begin);
    const std::vector<real_t>& ref = state_.reference;
    // the reference configuration, its volumes and lengths
    std::vector<real_t>& xr = u_rel_; // positions here, differences again in the pass
    for (std::size_t i = 0; i < 3 * n; ++i)
        xr[b + i] = nodes.x0[b + i] + ref[i];
    for (std::size_t p = 0; p < n; ++p)
    {
        state_.points.weight[p] = ref[3 * n + p];
        state_.length0[p] = ref[4 * n + p];
        state_.jacobian[p] = 1.0;
        for (int d = 0; d < 3; ++d)
            state_.points.position[3 * p + d] = xr[b + 3 * p + d];
    }
    if (opt_.sub_cells)
    {
        // SD-SNNI: the static sub-cell tables (snni_operators, the plain algebra; a reset is
        // rare), weights the cells' volumes, the reference's
        IntegrationOperator pts, stab;
        bad_.assign(n, 0);
        if (!snni_operators(xr, SubPoints::SubCells, pts, stab))
        {
            bad_[static_cast<std::size_t>(uncovered_)] = 1;
            return;
        }
        state_.points = std::move(pts);
        state_.stabilization = std::move(stab);
        state_.build_tables();
        tables_built_ = true;
        return;
    }
    update_neighbours(xr);
    IntegrationOperator& pts = state_.points;
    IntegrationOperator& stab = state_.stabilization;
    // per particle the row's particles that cover a face centre (the candidates in sc.cover)
    std::vector<index_t> count(n + 1, 0);
    auto faces = [&](index_t L, FastScratch& sc)
    {
        const auto [row, nr, gL, xL, cell] = particle_at(L, begin, offsets_, ids_, xr, state_.cells);
        sc.collect(cell, xL, row, nr, begin, xr, radius_, nullptr, opt_.rk.support, FastScratch::Reach::FaceCentres);
        return gradient_cell(sc, cell, opt_.rk, true, sc.gcell);
    };
    // one pass over the particles (each particle's functions formed once): each thread's
    // contiguous range into rows of its own, then joined in particle order, so the tables are
    // the same whatever the thread count
    struct Rows
    {
        std::vector<index_t> nodes;
        std::vector<real_t> grad, stab_grad; ///< 3 per entry; 6 x 3 per entry (face-major per particle)
    };
    const int teams = omp_get_max_threads();
    std::vector<Rows> rows(static_cast<std::size_t>(teams));
    std::vector<index_t> first(static_cast<std::size_t>(teams) + 1, np);
#pragma omp parallel num_threads(teams)
    {
        const int t = omp_get_thread_num(), nt = omp_get_num_threads();
        const index_t lo = static_cast<index_t>(static_cast<std::int64_t>(np) * t / nt),
                      hi = static_cast<index_t>(static_cast<std::int64_t>(np) * (t + 1) / nt);
        first[static_cast<std::size_t>(t)] = lo;
        Rows& out = rows[static_cast<std::size_t>(t)];
        out.nodes.clear();
        out.grad.clear();
        out.stab_grad.clear();
        FastScratch& sc = fast_scratch();
        for (index_t L = lo; L < hi; ++L)
        {
            bad_[L] = !faces(L, sc);
            if (bad_[L])
                continue;
            // the union of the faces' functions, in row order
            const index_t* row = &ids_[static_cast<std::size_t>(offsets_[L])];
            index_t m = 0;
            for (std::size_t c = 0; c < sc.n; ++c)
                if (sc.cover[c] > 0.0)
                {
                    out.nodes.push_back(begin + row[sc.cand_k[c]]);
                    sc.slot[c] = m++;
                }
            count[static_cast<std::size_t>(L) + 1] = m;
            const Cell& cell = sc.gcell; // the gradient's cell
            const real_t inv_V = 1.0 / cell.volume();
            const std::size_t g0 = out.grad.size(), mm = 3 * static_cast<std::size_t>(m);
            out.grad.resize(g0 + mm, 0.0);
            real_t* bg = &out.grad[g0];
            for (int f = 0; f < 6; ++f)
            {
                const Vec3 af = inv_V * cell.area(f);
                const index_t* id = sc.covering(f);
                const real_t* ps = sc.values(f);
                for (std::size_t e = 0; e < sc.m[f]; ++e)
                    for (int d = 0; d < 3; ++d)
                        bg[3 * static_cast<std::size_t>(sc.slot[static_cast<std::size_t>(id[e])]) + d] += ps[e] * af[d];
            }
            for (int f = 0; f < 6; ++f)
            {
                const std::size_t s0 = out.stab_grad.size();
                out.stab_grad.resize(s0 + mm);
                real_t* sg = &out.stab_grad[s0];
                for (std::size_t q = 0; q < mm; ++q)
                    sg[q] = -out.grad[g0 + q];
                const index_t* id = sc.covering(f);
                for (std::size_t e = 0; e < sc.m[f]; ++e)
                    for (int d = 0; d < 3; ++d)
                        sg[3 * static_cast<std::size_t>(sc.slot[static_cast<std::size_t>(id[e])]) + d] +=
                            sc.gradients(f, d)[e];
            }
        }
    }
    pts.offsets.resize(n + 1);
    pts.offsets[0] = 0;
    for (std::size_t p = 0; p < n; ++p)
        pts.offsets[p + 1] = pts.offsets[p] + count[p + 1];
    const std::size_t entries = static_cast<std::size_t>(pts.offsets[n]);
    pts.nodes.resize(entries);
    pts.grad.resize(3 * entries);
    stab.weight.resize(6 * n);
    stab.position.resize(18 * n);
    stab.owner.resize(6 * n);
    stab.parent.resize(6 * n);
    stab.offsets.resize(6 * n + 1);
    stab.offsets[0] = 0;
    for (std::size_t p = 0; p < n; ++p)
        for (std::size_t f = 0; f < 6; ++f)
            stab.offsets[6 * p + f + 1] = stab.offsets[6 * p + f] + count[p + 1];
    stab.nodes.resize(6 * entries);
    stab.grad.resize(18 * entries);
    parallel_for("rkfem::semi_lagrangian::join_tables", teams,
                 [&](index_t t)
                 {
                     const Rows& r = rows[static_cast<std::size_t>(t)];
                     std::size_t at = 0; // the team's entries so far
                     for (index_t L = first[static_cast<std::size_t>(t)]; L < first[static_cast<std::size_t>(t) + 1];
                          ++L)
                     {
                         const std::size_t p = static_cast<std::size_t>(L);
                         for (std::size_t f = 0; f < 6; ++f)
                         {
                             stab.weight[6 * p + f] = pts.weight[p] / 6.0;
                             stab.owner[6 * p + f] = pts.owner[p];
                             stab.parent[6 * p + f] = L;
                             for (int d = 0; d < 3; ++d)
                                 stab.position[18 * p + 3 * f + d] = pts.position[3 * p + d];
                         }
                         const std::size_t m = static_cast<std::size_t>(count[p + 1]),
                                           k0 = static_cast<std::size_t>(pts.offsets[p]);
                         std::copy_n(r.nodes.begin() + static_cast<std::ptrdiff_t>(at), m,
                                     pts.nodes.begin() + static_cast<std::ptrdiff_t>(k0));
                         std::copy_n(r.grad.begin() + static_cast<std::ptrdiff_t>(3 * at), 3 * m,
                                     pts.grad.begin() + static_cast<std::ptrdiff_t>(3 * k0));
                         for (std::size_t f = 0; f < 6; ++f)
                         {
                             const std::size_t s0 = static_cast<std::size_t>(stab.offsets[6 * p + f]);
                             std::copy_n(r.nodes.begin() + static_cast<std::ptrdiff_t>(at), m,
                                         stab.nodes.begin() + static_cast<std::ptrdiff_t>(s0));
                             std::copy_n(r.stab_grad.begin() + static_cast<std::ptrdiff_t>(3 * (6 * at + f * m)), 3 * m,
                                         stab.grad.begin() + static_cast<std::ptrdiff_t>(3 * s0));
                         }
                         at += m;
                     }
                 });
    state_.build_tables();
    tables_built_ = true;
}

PointFault SemiLagrangianForceBlock::fault(index_t bad, const NodeSet&) const
{
    std::ostringstream os;
    const real_t j = (resets() ? state_.jacobian : volume_trial_)[static_cast<std::size_t>(bad)];
    if (!(j > 0.0) || !std::isfinite(j))
        os << "has a non-positive or NaN volume ratio V / V0 = " << j;
    else
        os << "has a singular RK moment matrix at a face of its smoothing cell (too few particles cover it: "
              "the particle has separated from its neighbours)";
    return {true, -1, state_.points.owner[static_cast<std::size_t>(bad)], os.str()};
}

bool SemiLagrangianForceBlock::smoothed_gradient(index_t p, const std::vector<real_t>& x, std::vector<index_t>& nodes,
                                                 std::vector<real_t>& grad, std::vector<real_t>* face_gradients)
{
    extents();
    build_neighbours(x);
    const index_t* row = &ids_[static_cast<std::size_t>(offsets_[p])];
    const index_t n = offsets_[p + 1] - offsets_[p];
    const std::size_t gp = 3 * static_cast<std::size_t>(state_.node_begin + p);
    const Vec3 xp(x[gp], x[gp + 1], x[gp + 2]);
    nodes.assign(row, row + n);
    for (index_t& j : nodes)
        j += state_.node_begin;
    Scratch sc;
    if (!plain_gradient(xp, Cell(&state_.cells[12 * static_cast<std::size_t>(p)]), row, n, state_.node_begin, x,
                        radius_, opt_.rk, free_, sc))
        return false;
    grad = sc.b;
    if (face_gradients)
        *face_gradients = sc.face;
    return true;
}

bool SemiLagrangianForceBlock::field_gradients(const std::vector<index_t>& particles, const std::vector<real_t>& x,
                                               const std::vector<const std::vector<real_t>*>& fields,
                                               std::vector<real_t>& out)
{
    extents();
    build_neighbours(x);
    for (std::size_t p = 0; p < free_.size(); ++p)
        free_[p] = state_.jacobian[p] == 0.0; // as a pass takes them
    const std::size_t nf = fields.size();
    out.assign(9 * nf * particles.size(), 0.0);
    Scratch sc;
    for (std::size_t k = 0; k < particles.size(); ++k)
    {
        const index_t p = particles[k];
        const index_t* row = &ids_[static_cast<std::size_t>(offsets_[p])];
        const index_t n = offsets_[p + 1] - offsets_[p];
        const std::size_t gp = 3 * static_cast<std::size_t>(state_.node_begin + p);
        const Vec3 xp(x[gp], x[gp + 1], x[gp + 2]);
        if (!plain_gradient(xp, Cell(&state_.cells[12 * static_cast<std::size_t>(p)]), row, n, state_.node_begin, x,
                            radius_, opt_.rk, free_, sc))
            return false;
        for (index_t e = 0; e < n; ++e)
        {
            const std::size_t g = 3 * static_cast<std::size_t>(state_.node_begin + row[e]);
            for (std::size_t f = 0; f < nf; ++f)
            {
                real_t* G = &out[9 * (nf * k + f)];
                for (int i = 0; i < 3; ++i)
                    for (int j = 0; j < 3; ++j)
                        G[3 * i + j] += (*fields[f])[g + i] * sc.b[3 * static_cast<std::size_t>(e) + j];
            }
        }
    }
    return true;
}

bool SemiLagrangianForceBlock::snni_operators(const std::vector<real_t>& x, SubPoints sub, IntegrationOperator& points,
                                              IntegrationOperator& stabilization)
{
    extents();
    const bool sub_cells = sub == SubPoints::SubCells;
    if (sub_cells)
    {
        // the sub-cells' face centres reach past the cell's own ones on sheared cells: the
        // lists take the reach of the cell's corners
        const bool box = opt_.rk.support == SupportShape::Box;
        for (index_t p = 0; p < n_particles(); ++p)
        {
            const Cell cell(&state_.cells[12 * static_cast<std::size_t>(p)]);
            for (int q = 0; q < 8; ++q)
            {
                Vec3 d = cell.c;
                for (int i = 0; i < 3; ++i)
                    d += ((q >> i) & 1 ? 1.0 : -1.0) * cell.e[i];
                cell_reach_[p] = std::max(cell_reach_[p], box ? d.cwiseAbs().maxCoeff() : d.norm());
            }
        }
    }
    build_neighbours(x);
    points = IntegrationOperator{};
    stabilization = IntegrationOperator{};
    const index_t begin = state_.node_begin;
    Scratch sc;
    std::vector<real_t> b, bs;
    auto add_row = [](IntegrationOperator& op, real_t w, const Vec3& at, index_t owner, index_t parent,
                      const index_t* row, index_t n, index_t begin_, auto&& g)
    {
        op.weight.push_back(w);
        for (int d = 0; d < 3; ++d)
            op.position.push_back(at[d]);
        op.owner.push_back(owner);
        if (parent >= 0)
            op.parent.push_back(parent);
        for (index_t k = 0; k < n; ++k)
        {
            const Vec3 gk = g(k);
            if (gk.squaredNorm() == 0.0)
                continue;
            op.nodes.push_back(begin_ + row[k]);
            for (int d = 0; d < 3; ++d)
                op.grad.push_back(gk[d]);
        }
        op.offsets.push_back(op.n_entries());
    };
    for (index_t L = 0; L < n_particles(); ++L)
    {
        const index_t* row = &ids_[static_cast<std::size_t>(offsets_[L])];
        const index_t n = offsets_[L + 1] - offsets_[L];
        const std::size_t gL = 3 * static_cast<std::size_t>(begin + L);
        const Vec3 xL(x[gL], x[gL + 1], x[gL + 2]);
        const Cell cell(&state_.cells[12 * static_cast<std::size_t>(L)]);
        const real_t V = cell.volume();
        const std::size_t n3 = 3 * static_cast<std::size_t>(n);
        b.assign(n3, 0.0);
        uncovered_ = L;
        if (!sub_cells)
        {
            if (!plain_gradient(xL, cell, row, n, begin, x, radius_, opt_.rk, free_, sc))
                return false;
            b = sc.b;
        }
        else
        {
            bs.assign(8 * n3, 0.0);
            for (int s = 0; s < 8; ++s)
            {
                if (!plain_gradient(xL, sub_cell(cell, s), row, n, begin, x, radius_, opt_.rk, free_, sc))
                    return false;
                std::copy(sc.b.begin(), sc.b.end(), bs.begin() + static_cast<std::ptrdiff_t>(s * n3));
                for (std::size_t k = 0; k < n3; ++k)
                    b[k] += 0.125 * sc.b[k];
            }
        }
        auto at = [](const std::vector<real_t>& v, std::size_t o) { return Vec3(v[o], v[o + 1], v[o + 2]); };
        add_row(points, V, xL, begin + L, -1, row, n, begin, [&](index_t k) { return at(b, 3 * k); });
        for (int q = 0; q < (sub_cells ? 8 : 6); ++q)
        {
            if (sub_cells)
                add_row(stabilization, V / 8.0, xL + sub_cell(cell, q).c, begin + L, L, row, n, begin,
                        [&](index_t k) { return Vec3(at(bs, q * n3 + 3 * k) - at(b, 3 * k)); });
            else
                add_row(stabilization, V / 6.0, cell.centre(xL, q), begin + L, L, row, n, begin,
                        [&](index_t k) { return Vec3(at(sc.face, 18 * k + 3 * q) - at(b, 3 * k)); });
        }
    }
    return true;
}
} // namespace rkfem

namespace rkfem
{
void SemiLagrangianForceBlock::split(index_t p, const index_t (&spare)[7], const Vec3& xp, Vec3 (&x)[8])
{
    const std::size_t n = static_cast<std::size_t>(n_particles());
    const std::size_t q = static_cast<std::size_t>(p);
    RKFEM_REQUIRE(p >= 0 && p < n_particles() && !dormant(p) && !separated(p) && !resets() && !opt_.sub_cells,
                  "semi-Lagrangian split: particle " << p << " of " << n_particles()
                                                     << " is dormant or separated, or the block resets its tables or "
                                                        "integrates by sub-cells");
    const Cell parent(&state_.cells[12 * q]);
    Cell child;
    child.c = Vec3::Zero();
    for (int i = 0; i < 3; ++i)
        child.e[i] = 0.5 * parent.e[i];
    index_t ids[8] = {p};
    for (int k = 0; k < 7; ++k)
    {
        ids[k + 1] = spare[k];
        RKFEM_REQUIRE(spare[k] >= 0 && spare[k] < n_particles() && dormant(spare[k]),
                      "semi-Lagrangian split: spare particle " << spare[k]
                                                               << " is not a dormant particle of the block");
    }
    const real_t V0 = state_.points.weight[q] / 8.0, w0 = 0.5 * width0_[q], r0 = 0.5 * radius0_[q],
                 l0 = 0.5 * state_.length0[q], J = state_.jacobian[q];
    const int level = level_[q] + 1;
    const std::size_t m = static_cast<std::size_t>(subs()), ns = m * n, ss = state_.stress_stride;
    for (int k = 0; k < 8; ++k)
    {
        Vec3 at = xp + parent.c;
        for (int i = 0; i < 3; ++i)
            at += ((k >> i) & 1 ? 0.5 : -0.5) * parent.e[i];
        x[k] = at;
        const std::size_t c = static_cast<std::size_t>(ids[k]);
        child.store(&state_.cells[12 * c]);
        child.store(&state_.cells_trial[12 * c]);
        if (c == q)
            continue;
        for (int s = 0; s < 6; ++s)
        {
            state_.stress[s * ss + c] = state_.stress[s * ss + q];
            state_.stress_trial[s * ss + c] = state_.stress[s * ss + q];
            for (std::size_t f = 0; f < m; ++f)
                state_.stab_stress[s * ns + m * c + f] = state_.stab_stress_trial[s * ns + m * c + f] =
                    state_.stab_stress[s * ns + m * q + f];
        }
        if (state_.plastic.active())
            state_.plastic.copy_point(state_.plastic, q, c);
        dormant_[c] = 0;
    }
    for (const index_t id : ids)
    {
        const std::size_t c = static_cast<std::size_t>(id);
        state_.points.weight[c] = v0_[c] = V0;
        state_.jacobian[c] = volume_trial_[c] = J;
        width0_[c] = w0;
        radius0_[c] = r0;
        state_.length0[c] = l0;
        level_[c] = static_cast<char>(level);
        if (state_.plastic.active())
            state_.plastic.set_length(c, std::cbrt(V0));
    }
    radius_built_.clear(); // the next pass builds the lists again
}

void SemiLagrangianForceBlock::merge(const index_t (&family)[8], const Vec3& xs, const Vec3 (&x)[8])
{
    const std::size_t n = static_cast<std::size_t>(n_particles());
    const std::size_t q = static_cast<std::size_t>(family[0]);
    const std::size_t m = static_cast<std::size_t>(subs()), ns = m * n, ss = state_.stress_stride;
    Vec3 centre = Vec3::Zero();
    Cell merged;
    merged.e[0] = merged.e[1] = merged.e[2] = Vec3::Zero();
    real_t V = 0.0, V0 = 0.0, sig[6] = {0, 0, 0, 0, 0, 0};
    PlasticPoints::Share shares[8];
    for (int k = 0; k < 8; ++k)
    {
        const index_t id = family[k];
        const std::size_t c = static_cast<std::size_t>(id);
        RKFEM_REQUIRE(id >= 0 && id < n_particles() && !dormant(id) && !separated(id) && level_[c] == level_[q],
                      "semi-Lagrangian merge: particle " << id << " is dormant or separated, or of another level than "
                                                         << family[0]);
        const Cell cell(&state_.cells[12 * c]);
        centre += (x[k] + cell.c) / 8.0;
        for (int i = 0; i < 3; ++i)
            merged.e[i] += cell.e[i] / 4.0; // twice the mean
        const real_t Vk = volume(id);
        V += Vk;
        V0 += state_.points.weight[c];
        for (int s = 0; s < 6; ++s)
            sig[s] += Vk * state_.stress[s * ss + c];
        shares[k] = {&state_.plastic, c, state_.points.weight[c]};
    }
    RKFEM_REQUIRE(V > 0.0, "semi-Lagrangian merge: the siblings of particle " << family[0] << " have no volume");
    const real_t box = Cell(merged).volume();
    RKFEM_REQUIRE(box > 0.0,
                  "semi-Lagrangian merge: the siblings of particle " << family[0] << " span a cell of volume " << box);
    const real_t scale = std::cbrt(V / box);
    for (int i = 0; i < 3; ++i)
        merged.e[i] *= scale;
    merged.c = centre - xs;
    if (state_.plastic.active())
        state_.plastic.blend_point(shares, 8, q);
    for (int s = 0; s < 6; ++s)
    {
        state_.stress[s * ss + q] = state_.stress_trial[s * ss + q] = sig[s] / V;
        for (std::size_t f = 0; f < m; ++f)
            state_.stab_stress[s * ns + m * q + f] = state_.stab_stress_trial[s * ns + m * q + f] = 0.0;
    }
    merged.store(&state_.cells[12 * q]);
    merged.store(&state_.cells_trial[12 * q]);
    state_.points.weight[q] = v0_[q] = V0;
    state_.jacobian[q] = volume_trial_[q] = V / V0;
    width0_[q] *= 2.0;
    radius0_[q] *= 2.0;
    state_.length0[q] *= 2.0;
    level_[q] = static_cast<char>(level_[q] - 1);
    if (state_.plastic.active())
        state_.plastic.set_length(q, std::cbrt(V0));
    // the others sleep again: empty cells, no stress, no step limit
    for (int k = 1; k < 8; ++k)
    {
        const std::size_t c = static_cast<std::size_t>(family[k]);
        std::fill_n(&state_.cells[12 * c], 12, 0.0);
        std::fill_n(&state_.cells_trial[12 * c], 12, 0.0);
        for (int s = 0; s < 6; ++s)
        {
            state_.stress[s * ss + c] = state_.stress_trial[s * ss + c] = 0.0;
            for (std::size_t f = 0; f < m; ++f)
                state_.stab_stress[s * ns + m * c + f] = state_.stab_stress_trial[s * ns + m * c + f] = 0.0;
        }
        state_.jacobian[c] = volume_trial_[c] = 0.0;
        level_[c] = 0;
        dormant_[c] = 1;
        point_sums_[4 * c] = point_sums_[4 * c + 1] = point_sums_[4 * c + 2] = 0.0;
        point_sums_[4 * c + 3] = kNoLimit;
    }
    radius_built_.clear();
}

void SemiLagrangianForceBlock::restore_refinement(const std::vector<real_t>& radius0,
                                                  const std::vector<real_t>& length0, const std::vector<real_t>& levels)
{
    const std::size_t n = static_cast<std::size_t>(n_particles());
    RKFEM_REQUIRE(radius0.size() == n && length0.size() == n && levels.size() == n,
                  "semi-Lagrangian block: a checkpoint's refinement has "
                      << radius0.size() << " radii, " << length0.size() << " lengths and " << levels.size()
                      << " levels for " << n << " particles");
    radius0_ = radius0;
    state_.length0 = length0;
    for (std::size_t p = 0; p < n; ++p)
        level_[p] = static_cast<char>(levels[p]);
    radius_built_.clear();
}
} // namespace rkfem
