// GCC 12 reports a false "may be used uninitialized" in its own AVX-512 intrinsics header (the
// "__m512d __Y = __Y" idiom), inlined from Eigen's dense solver here: 227 warnings on an AVX-512
// machine, every value initialised.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"

#include "rkfem/analysis/timoshenko_beam.hpp"

#include <Eigen/Dense>
#include <cmath>

namespace rkfem
{
StepResponse step_response(const TimoshenkoBeam& b, real_t q, real_t x0, real_t t_end, int n_samples)
{
    const int ne = b.elements;
    const real_t h = b.length / ne;
    const real_t A = b.width * b.depth, I = b.width * b.depth * b.depth * b.depth / 12;
    const real_t G = b.E / (2 * (1 + b.nu));
    const real_t kappa = b.shear_factor > 0 ? b.shear_factor : 10 * (1 + b.nu) / (12 + 11 * b.nu);
    // unknowns (w, theta) per node; node 0 clamped, so node j > 0 holds rows 2 (j - 1) and 2 (j - 1) + 1
    const int n = 2 * ne;
    Eigen::MatrixXd K = Eigen::MatrixXd::Zero(n, n), M = Eigen::MatrixXd::Zero(n, n);
    Eigen::VectorXd F = Eigen::VectorXd::Zero(n);
    for (int e = 0; e < ne; ++e)
    {
        // element dofs w1, th1, w2, th2; bending EI th'^2, shear kappa G A (w' - th)^2 at the midpoint
        Eigen::Matrix4d ke = Eigen::Matrix4d::Zero(), me = Eigen::Matrix4d::Zero();
        ke(1, 1) = ke(3, 3) = b.E * I / h;
        ke(1, 3) = ke(3, 1) = -b.E * I / h;
        const Eigen::Vector4d B(-1 / h, -0.5, 1 / h, -0.5);
        ke += kappa * G * A * h * B * B.transpose();
        const real_t mw = b.rho * A * h / 6, mt = b.rho * I * h / 6;
        me(0, 0) = me(2, 2) = 2 * mw;
        me(0, 2) = me(2, 0) = mw;
        me(1, 1) = me(3, 3) = 2 * mt;
        me(1, 3) = me(3, 1) = mt;
        // consistent nodal loads of q over [max(xa, x0), xb]
        const real_t xa = e * h, xb = (e + 1) * h, lo = std::max(xa, x0);
        Eigen::Vector4d fe = Eigen::Vector4d::Zero();
        if (xb > lo)
        {
            const real_t s2 = ((xb - xa) * (xb - xa) - (lo - xa) * (lo - xa)) / (2 * h); // int (x - xa) / h
            fe(2) = q * s2;
            fe(0) = q * (xb - lo) - q * s2;
        }
        const int dof[4] = {2 * e - 2, 2 * e - 1, 2 * e, 2 * e + 1};
        for (int i = 0; i < 4; ++i)
        {
            if (dof[i] < 0)
                continue;
            F(dof[i]) += fe(i);
            for (int j = 0; j < 4; ++j)
                if (dof[j] >= 0)
                {
                    K(dof[i], dof[j]) += ke(i, j);
                    M(dof[i], dof[j]) += me(i, j);
                }
        }
    }
    const Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> eig(K, M);
    const Eigen::VectorXd w2 = eig.eigenvalues();
    const Eigen::MatrixXd& V = eig.eigenvectors(); // M-orthonormal
    const int tip = n - 2;
    StepResponse r;
    r.static_tip = K.ldlt().solve(F)(tip);
    r.first_period = 2 * M_PI / std::sqrt(w2(0));
    const Eigen::VectorXd amp = (V.row(tip).transpose().array() * (V.transpose() * F).array() / w2.array()).matrix();
    r.time.resize(n_samples);
    r.tip.resize(n_samples);
    for (int k = 0; k < n_samples; ++k)
    {
        const real_t t = t_end * k / (n_samples - 1);
        const real_t u = (amp.array() * (1 - (w2.array().sqrt() * t).cos())).sum();
        r.time[k] = t;
        r.tip[k] = u;
        if (std::abs(u) > std::abs(r.peak_tip))
        {
            r.peak_tip = u;
            r.peak_time = t;
        }
    }
    return r;
}
} // namespace rkfem
