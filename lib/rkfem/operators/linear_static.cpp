#include "rkfem/operators/linear_static.hpp"

#include <Eigen/CholmodSupport>
#include <Eigen/UmfPackSupport>
#include <algorithm>

#include "rkfem/core/error.hpp"

namespace rkfem
{
SparseMatrix assemble_stiffness(const IntegrationOperator& op, const ElasticParams& mat, index_t n_nodes, real_t scale)
{
    // node-pair pattern
    std::vector<std::vector<index_t>> cols(static_cast<std::size_t>(n_nodes));
    for (index_t p = 0; p < op.n_points(); ++p)
        for (index_t a = op.offsets[p]; a < op.offsets[p + 1]; ++a)
        {
            auto& c = cols[op.nodes[a]];
            c.insert(c.end(), op.nodes.begin() + op.offsets[p], op.nodes.begin() + op.offsets[p + 1]);
        }
    std::vector<index_t> row_ptr(static_cast<std::size_t>(n_nodes) + 1, 0);
    for (index_t i = 0; i < n_nodes; ++i)
    {
        auto& c = cols[i];
        std::sort(c.begin(), c.end());
        c.erase(std::unique(c.begin(), c.end()), c.end());
        row_ptr[i + 1] = row_ptr[i] + static_cast<index_t>(c.size());
    }
    std::vector<real_t> val(9 * static_cast<std::size_t>(row_ptr.back()), 0.0);
    const real_t lam = mat.lambda, mu = mat.mu;
    for (index_t p = 0; p < op.n_points(); ++p)
    {
        const real_t w = scale * op.weight[p];
        for (index_t a = op.offsets[p]; a < op.offsets[p + 1]; ++a)
        {
            const index_t I = op.nodes[a];
            const Vec3 gI = op.gradient(a);
            const auto& c = cols[I];
            for (index_t b = op.offsets[p]; b < op.offsets[p + 1]; ++b)
            {
                const index_t J = op.nodes[b];
                const Vec3 gJ = op.gradient(b);
                const std::size_t slot = static_cast<std::size_t>(
                    row_ptr[I] + (std::lower_bound(c.begin(), c.end(), J) - c.begin()));
                const Mat3 k = w * (lam * gI * gJ.transpose() + mu * gI.dot(gJ) * Mat3::Identity() + mu * gJ * gI.transpose());
                for (int i = 0; i < 3; ++i)
                    for (int j = 0; j < 3; ++j)
                        val[9 * slot + 3 * i + j] += k(i, j);
            }
        }
    }
    std::vector<Eigen::Triplet<real_t, int>> t;
    t.reserve(val.size());
    for (index_t I = 0; I < n_nodes; ++I)
        for (index_t s = row_ptr[I]; s < row_ptr[I + 1]; ++s)
        {
            const index_t J = cols[I][s - row_ptr[I]];
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j)
                    t.emplace_back(3 * I + i, 3 * J + j, val[9 * static_cast<std::size_t>(s) + 3 * i + j]);
        }
    SparseMatrix K(3 * n_nodes, 3 * n_nodes);
    K.setFromTriplets(t.begin(), t.end());
    return K;
}

std::vector<real_t> solve_static(const SparseMatrix& K, const std::vector<real_t>& f,
                                 const std::vector<index_t>& prescribed_dofs,
                                 const std::vector<real_t>& prescribed_values)
{
    const index_t n = static_cast<index_t>(K.rows());
    RKFEM_REQUIRE(static_cast<index_t>(f.size()) == n, "solve_static: force has " << f.size() << " entries, K has " << n << " rows");
    RKFEM_REQUIRE(prescribed_dofs.size() == prescribed_values.size(), "solve_static: prescribed dofs and values differ in length");
    std::vector<real_t> u(static_cast<std::size_t>(n), 0.0);
    std::vector<index_t> map(static_cast<std::size_t>(n), 0);
    for (std::size_t k = 0; k < prescribed_dofs.size(); ++k)
    {
        map[prescribed_dofs[k]] = -1;
        u[prescribed_dofs[k]] = prescribed_values[k];
    }
    index_t nf = 0;
    for (index_t i = 0; i < n; ++i)
        if (map[i] == 0)
            map[i] = nf++;
        else
            map[i] = -1;
    Eigen::VectorXd rhs(nf);
    for (index_t i = 0; i < n; ++i)
        if (map[i] >= 0)
            rhs[map[i]] = f[i];
    std::vector<Eigen::Triplet<real_t, int>> t;
    for (int c = 0; c < K.outerSize(); ++c)
        for (SparseMatrix::InnerIterator it(K, c); it; ++it)
        {
            const index_t r = static_cast<index_t>(it.row());
            if (map[r] < 0)
                continue;
            if (map[c] >= 0)
                t.emplace_back(map[r], map[c], it.value());
            else
                rhs[map[r]] -= it.value() * u[c];
        }
    SparseMatrix Kff(nf, nf);
    Kff.setFromTriplets(t.begin(), t.end());
    Eigen::CholmodSupernodalLLT<SparseMatrix, Eigen::Lower> chol;
    chol.compute(Kff);
    RKFEM_REQUIRE(chol.info() == Eigen::Success,
                  "static solve: the stiffness with " << prescribed_dofs.size() << " prescribed dofs is not positive definite "
                                                      "(a zero-energy mode is free, or the integration is rank deficient)");
    const Eigen::VectorXd uf = chol.solve(rhs);
    for (index_t i = 0; i < n; ++i)
        if (map[i] >= 0)
            u[i] = uf[map[i]];
    return u;
}
std::vector<real_t> solve_static_constrained(const SparseMatrix& K, const std::vector<real_t>& f, const SparseMatrix& C,
                                             const std::vector<real_t>& g)
{
    const index_t n = static_cast<index_t>(K.rows()), m = static_cast<index_t>(C.rows());
    RKFEM_REQUIRE(static_cast<index_t>(C.cols()) == n && static_cast<index_t>(g.size()) == m &&
                      static_cast<index_t>(f.size()) == n,
                  "solve_static_constrained: K " << n << " dofs, C " << m << " x " << C.cols() << ", f " << f.size()
                                                 << ", g " << g.size());
    std::vector<Eigen::Triplet<real_t, int>> t;
    t.reserve(static_cast<std::size_t>(K.nonZeros() + 2 * C.nonZeros()));
    for (int c = 0; c < K.outerSize(); ++c)
        for (SparseMatrix::InnerIterator it(K, c); it; ++it)
            t.emplace_back(static_cast<int>(it.row()), c, it.value());
    for (int c = 0; c < C.outerSize(); ++c)
        for (SparseMatrix::InnerIterator it(C, c); it; ++it)
        {
            t.emplace_back(n + static_cast<int>(it.row()), c, it.value());
            t.emplace_back(c, n + static_cast<int>(it.row()), it.value());
        }
    SparseMatrix A(n + m, n + m);
    A.setFromTriplets(t.begin(), t.end());
    Eigen::VectorXd rhs(n + m);
    for (index_t i = 0; i < n; ++i)
        rhs[i] = f[i];
    for (index_t i = 0; i < m; ++i)
        rhs[n + i] = g[i];
    Eigen::UmfPackLU<SparseMatrix> lu;
    lu.compute(A);
    RKFEM_REQUIRE(lu.info() == Eigen::Success, "constrained static solve: the saddle-point matrix with " << m
                                                   << " constraints is singular (free zero-energy mode or dependent constraints)");
    const Eigen::VectorXd x = lu.solve(rhs);
    return std::vector<real_t>(x.data(), x.data() + n);
}
} // namespace rkfem
