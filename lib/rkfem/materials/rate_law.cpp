#include "rkfem/materials/rate_law.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace rkfem
{
namespace
{
constexpr real_t MPa = 1e6;

/// min(dif, cap), cap 0 meaning none
real_t capped(real_t dif, real_t cap)
{
    return cap > 0.0 ? std::min(dif, cap) : dif;
}

/// The form both built-in laws take: 1 up to the static rate rs, (r / rs)^e up to the
/// transition rate, g (r / rs)^(1/3) above it.
real_t two_branch(real_t rate, real_t rs, real_t e, real_t transition, real_t g)
{
    if (rate <= rs)
        return 1.0;
    if (rate <= transition)
        return std::pow(rate / rs, e);
    return g * std::cbrt(rate / rs);
}
} // namespace

real_t dif_compression_ceb(real_t rate, real_t fc_pa)
{
    const real_t as = 1.0 / (5.0 + 9.0 * (fc_pa / MPa) / 10.0);
    return two_branch(rate, 30e-6, 1.026 * as, 30.0, std::pow(10.0, 6.156 * as - 2.0));
}

real_t dif_tension_malvar_ross(real_t rate, real_t fc_pa)
{
    const real_t d = 1.0 / (1.0 + 8.0 * (fc_pa / MPa) / 10.0);
    return two_branch(rate, 1e-6, d, 1.0, std::pow(10.0, 6.0 * d - 2.0));
}

real_t RateLaw::loading_rate(const real_t d[6], bool tension)
{
    // principal values of the symmetric 3 x 3 d by the trigonometric solution of its
    // characteristic cubic: q + 2 r cos(phi + 2 pi k / 3), phi = acos(det(B) / 2) / 3, B = (d - q I) / r
    const real_t q = (d[0] + d[1] + d[2]) / 3.0;
    const real_t off = d[3] * d[3] + d[4] * d[4] + d[5] * d[5];
    const real_t a = d[0] - q, b = d[1] - q, c = d[2] - q;
    const real_t r = std::sqrt((a * a + b * b + c * c + 2.0 * off) / 6.0);
    real_t lo = q, hi = q;
    if (r > 0.0)
    {
        // det of [[a, xy, zx], [xy, b, yz], [zx, yz, c]] / r^3
        const real_t det =
            a * (b * c - d[4] * d[4]) - d[3] * (d[3] * c - d[4] * d[5]) + d[5] * (d[3] * d[4] - b * d[5]);
        const real_t phi = std::acos(std::clamp(det / (2.0 * r * r * r), -1.0, 1.0)) / 3.0;
        hi = q + 2.0 * r * std::cos(phi);
        lo = q + 2.0 * r * std::cos(phi + 2.0943951023931954923);
    }
    return std::max(0.0, tension ? hi : -lo);
}

RateLaw RateLaw::standard(real_t fc_pa)
{
    RateLaw r;
    r.kind = Kind::CebMalvarRoss;
    r.fc = fc_pa;
    r.compression_cap = kDefaultCompressionCap;
    r.tension_cap = kDefaultTensionCap;
    return r;
}

real_t RateLaw::dif(real_t rate, bool tension) const
{
    switch (kind)
    {
    case Kind::Off:
        return 1.0;
    case Kind::CebMalvarRoss:
        return tension ? capped(dif_tension_malvar_ross(rate, fc), tension_cap)
                       : capped(dif_compression_ceb(rate, fc), compression_cap);
    case Kind::Curve:
        break;
    }
    // LCRATE: the abscissa is the signed rate, negative in tension; linear between points,
    // constant beyond the ends
    const real_t x = tension ? -rate : rate;
    real_t d = curve.back().second;
    if (x <= curve.front().first)
        d = curve.front().second;
    else
        for (std::size_t i = 1; i < curve.size(); ++i)
            if (x <= curve[i].first)
            {
                const auto& [x0, y0] = curve[i - 1];
                const auto& [x1, y1] = curve[i];
                d = y0 + (x - x0) / (x1 - x0) * (y1 - y0);
                break;
            }
    return capped(d, tension ? tension_cap : compression_cap);
}

std::string RateLaw::describe() const
{
    std::ostringstream os;
    auto cap = [&](real_t c) { return c > 0.0 ? std::to_string(c).substr(0, 6) : std::string("none"); };
    switch (kind)
    {
    case Kind::Off:
        os << "off (DIF 1)";
        break;
    case Kind::CebMalvarRoss:
        os << "CEB-FIP 1990 compression (cap " << cap(compression_cap) << "), Malvar-Ross 1998 tension (cap "
           << cap(tension_cap) << ")";
        break;
    case Kind::Curve:
        os << "curve of " << curve.size() << " points (negative rate = tension), caps " << cap(compression_cap) << " / "
           << cap(tension_cap);
        break;
    }
    os << "; rate: the most compressive principal rate where p >= 0, the most tensile where p < 0";
    return os.str();
}
} // namespace rkfem
