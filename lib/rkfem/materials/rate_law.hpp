#pragma once
/// @file rate_law.hpp
/// The dynamic increase factor (DIF) of concrete strength against strain rate, as a K&C user
/// sets it (LS-DYNA MAT_072R3's LCRATE): off; the built-in laws, CEB-FIP 1990 in compression
/// and Malvar & Ross (1998) in tension, each with an optional cap; or a user curve of DIF
/// against the signed strain rate, negative abscissa for tension as LCRATE takes it, linear
/// between its points and constant beyond its ends.
///
/// The strain-rate measure is the one the DIF curves are measured against: the axial strain rate
/// of a uniaxial test. In compression (pressure p >= 0) it is the magnitude of the most
/// compressive principal rate of deformation, in tension (p < 0) the largest tensile one
/// (RateLaw::loading_rate). The effective deviatoric rate sqrt(2/3 e':e'), the usual
/// "effective strain rate", reads (2/3)(1 + nu) of the axial rate while a uniaxial specimen is
/// elastic and jumps several-fold as it dilates at the peak (at 10^2 1/s axial: 79 1/s elastic,
/// 640 1/s at the peak), so the peak it gives is not the law's DIF at the test's rate (4-40 %
/// off at 10^2-10^4 1/s, verification/materials/test_kcc). Which measure LS-DYNA's MAT_072R3
/// uses for LCRATE is not established here (its manual says "effective strain rate").
///
/// Why the compressive law is capped by default: a split-Hopkinson bar's apparent compressive
/// DIF above about 10^2 1/s is largely lateral inertial confinement of the specimen (Li & Meng
/// 2003; Cotsovos & Pavlovic 2008), which a 3-D analysis resolves itself; fed the uncapped
/// CEB-FIP law, the struck concrete under an FSP (10^4-10^5 1/s) is 10-22 times its static
/// strength and a 1 km/s steel FSP bounces off it. The default caps are Tedesco & Ross's (1998)
/// limits on their bilinear fits of the split-Hopkinson data, 2.5 in compression and 6.0 in
/// tension [recalled, not re-read]; a published KCC penetration deck's own compressive curve
/// (Yin et al. 2023, Cem. Concr. Compos. 137:104911) gives 2.53 at 3,000 1/s, beside which the
/// uncapped CEB-FIP law gives 4.8 at 10^3 1/s for 35 MPa concrete.
#include <string>
#include <utility>
#include <vector>

#include "rkfem/core/types.hpp"

namespace rkfem
{
/// CEB-FIP 1990 compressive DIF (f'c in Pa, strain rate in 1/s): (r / 30e-6)^(1.026 a) up to
/// 30 1/s, g (r / 30e-6)^(1/3) above, a = 1 / (5 + 9 f'c / 10 MPa), log10 g = 6.156 a - 2.
real_t dif_compression_ceb(real_t rate, real_t fc_pa);
/// Malvar & Ross (1998) tensile DIF: (r / 1e-6)^d up to 1 1/s, b (r / 1e-6)^(1/3) above,
/// d = 1 / (1 + 8 f'c / 10 MPa), log10 b = 6 d - 2.
real_t dif_tension_malvar_ross(real_t rate, real_t fc_pa);

struct RateLaw
{
    enum class Kind
    {
        Off,           ///< DIF 1
        CebMalvarRoss, ///< CEB-FIP 1990 compression, Malvar & Ross 1998 tension, capped
        Curve          ///< user curve (LCRATE): (signed rate, DIF), negative rate = tension
    };
    Kind kind = Kind::Off;
    real_t fc = 0.0;                              ///< f'c [Pa] of the built-in laws
    real_t compression_cap = 0.0;                 ///< largest compressive DIF (0: none)
    real_t tension_cap = 0.0;                     ///< largest tensile DIF (0: none)
    std::vector<std::pair<real_t, real_t>> curve; ///< strictly increasing rates [1/s], DIF > 0

    /// The default of `rate_effects: true`: the built-in laws with the caps below.
    static RateLaw standard(real_t fc_pa);
    static constexpr real_t kDefaultCompressionCap = 2.5;
    static constexpr real_t kDefaultTensionCap = 6.0;

    bool active() const { return kind != Kind::Off; }
    /// The strain-rate measure at rate of deformation d (Voigt xx yy zz xy yz zx, tensor shear):
    /// -(smallest principal value) in compression, the largest in tension, at least 0.
    static real_t loading_rate(const real_t d[6], bool tension);
    /// DIF at effective strain rate `rate` (>= 0) in compression (tension = false) or tension.
    real_t dif(real_t rate, bool tension) const;
    /// One line for messages and `rkfem check`.
    std::string describe() const;
};
} // namespace rkfem
