#include "rkfem/operators/linear_static.hpp"

#include <Eigen/CholmodSupport>
#include <Eigen/UmfPackSupport>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "rkfem/core/error.hpp"
#include "rkfem/core/parallel.hpp"

namespace rkfem
{
namespace
{
/// Node -> (entry, point) lists of an operator: the entries that touch each node, in point order.
void transpose_entries(const IntegrationOperator& op, index_t n_nodes, std::vector<index_t>& offsets,
                       std::vector<index_t>& entry, std::vector<index_t>& point)
{
    offsets.assign(static_cast<std::size_t>(n_nodes) + 1, 0);
    for (index_t I : op.nodes)
        ++offsets[I + 1];
    for (index_t i = 0; i < n_nodes; ++i)
        offsets[i + 1] += offsets[i];
    entry.resize(op.nodes.size());
    point.resize(op.nodes.size());
    std::vector<index_t> fill(offsets.begin(), offsets.end() - 1);
    for (index_t p = 0; p < op.n_points(); ++p)
        for (index_t a = op.offsets[p]; a < op.offsets[p + 1]; ++a)
        {
            const index_t s = fill[op.nodes[a]]++;
            entry[s] = a;
            point[s] = p;
        }
}

/// The lower triangle of K restricted to the dofs with map[dof] >= 0 (map ascending over them),
/// CSC to CSC: what CHOLMOD reads of a symmetric matrix.
SparseMatrix lower_restricted_to(const SparseMatrix& K, const std::vector<index_t>& map, index_t nf)
{
    std::vector<int> outer(static_cast<std::size_t>(nf) + 1, 0);
    std::vector<int> inner;
    std::vector<real_t> value;
    inner.reserve(static_cast<std::size_t>(K.nonZeros()));
    value.reserve(static_cast<std::size_t>(K.nonZeros()));
    for (int c = 0; c < K.outerSize(); ++c)
    {
        if (map[c] < 0)
            continue;
        for (SparseMatrix::InnerIterator it(K, c); it; ++it)
            if (map[it.row()] >= map[c])
            {
                inner.push_back(static_cast<int>(map[it.row()]));
                value.push_back(it.value());
            }
        outer[map[c] + 1] = static_cast<int>(inner.size());
    }
    SparseMatrix R(nf, nf);
    R.resizeNonZeros(static_cast<Eigen::Index>(inner.size()));
    std::copy(outer.begin(), outer.end(), R.outerIndexPtr());
    std::copy(inner.begin(), inner.end(), R.innerIndexPtr());
    std::copy(value.begin(), value.end(), R.valuePtr());
    return R;
}

/// map[dof] = index among the free dofs, -1 for the prescribed ones; returns the free count.
index_t free_dof_map(index_t n, const std::vector<index_t>& prescribed, std::vector<index_t>& map)
{
    map.assign(static_cast<std::size_t>(n), 0);
    for (index_t d : prescribed)
    {
        RKFEM_REQUIRE(d >= 0 && d < n, "static solve: prescribed dof " << d << " is outside 0.." << n - 1);
        map[d] = -1;
    }
    index_t nf = 0;
    for (index_t i = 0; i < n; ++i)
        map[i] = map[i] == 0 ? nf++ : -1;
    return nf;
}
} // namespace

SparseMatrix assemble_stiffness(const IntegrationOperator& op, const ElasticParams& mat, index_t n_nodes, real_t scale)
{
    // node-pair pattern: the nodes that share a point with node I, through the points that touch I
    std::vector<index_t> t_off, t_entry, t_point;
    transpose_entries(op, n_nodes, t_off, t_entry, t_point);
    std::vector<index_t> row_ptr(static_cast<std::size_t>(n_nodes) + 1, 0);
    std::vector<index_t> cols;
    std::vector<index_t> mark(static_cast<std::size_t>(n_nodes), -1);
    for (index_t I = 0; I < n_nodes; ++I)
    {
        const std::size_t first = cols.size();
        for (index_t s = t_off[I]; s < t_off[I + 1]; ++s)
        {
            const index_t p = t_point[s];
            for (index_t b = op.offsets[p]; b < op.offsets[p + 1]; ++b)
                if (mark[op.nodes[b]] != I)
                {
                    mark[op.nodes[b]] = I;
                    cols.push_back(op.nodes[b]);
                }
        }
        std::sort(cols.begin() + static_cast<std::ptrdiff_t>(first), cols.end());
        row_ptr[I + 1] = static_cast<index_t>(cols.size());
    }
    // 3x3 blocks, block (I, J) at slot s of row I: val[9 s + 3 i + j] = K(3I + i, 3J + j)
    std::vector<real_t> val(9 * cols.size(), 0.0);
    const real_t lam = mat.lambda, mu = mat.mu;
    for (index_t p = 0; p < op.n_points(); ++p)
    {
        const real_t w = scale * op.weight[p];
        for (index_t a = op.offsets[p]; a < op.offsets[p + 1]; ++a)
        {
            const index_t I = op.nodes[a];
            const Vec3 gI = op.gradient(a);
            const auto row_begin = cols.begin() + row_ptr[I], row_end = cols.begin() + row_ptr[I + 1];
            for (index_t b = op.offsets[p]; b < op.offsets[p + 1]; ++b)
            {
                const index_t J = op.nodes[b];
                const Vec3 gJ = op.gradient(b);
                const std::size_t slot =
                    static_cast<std::size_t>(std::lower_bound(row_begin, row_end, J) - cols.begin());
                const Mat3 k =
                    w * (lam * gI * gJ.transpose() + mu * gI.dot(gJ) * Mat3::Identity() + mu * gJ * gI.transpose());
                for (int i = 0; i < 3; ++i)
                    for (int j = 0; j < 3; ++j)
                        val[9 * slot + 3 * i + j] += k(i, j);
            }
        }
    }
    // CSC straight from the blocks: the pattern is symmetric and K(3I + i, 3J + j) is block (J, I)
    // transposed, so column 3J + j lists rows 3I + i for the I of row J, in order
    SparseMatrix K(3 * n_nodes, 3 * n_nodes);
    K.resizeNonZeros(static_cast<Eigen::Index>(val.size()));
    int* outer = K.outerIndexPtr();
    int* inner = K.innerIndexPtr();
    real_t* value = K.valuePtr();
    std::size_t nz = 0;
    outer[0] = 0;
    for (index_t J = 0; J < n_nodes; ++J)
        for (int j = 0; j < 3; ++j)
        {
            for (index_t s = row_ptr[J]; s < row_ptr[J + 1]; ++s)
                for (int i = 0; i < 3; ++i)
                {
                    inner[nz] = static_cast<int>(3 * cols[s] + i);
                    value[nz] = val[9 * static_cast<std::size_t>(s) + 3 * j + i];
                    ++nz;
                }
            outer[3 * J + j + 1] = static_cast<int>(nz);
        }
    return K;
}

std::vector<real_t> solve_static(const SparseMatrix& K, const std::vector<real_t>& f,
                                 const std::vector<index_t>& prescribed_dofs,
                                 const std::vector<real_t>& prescribed_values)
{
    const index_t n = static_cast<index_t>(K.rows());
    RKFEM_REQUIRE(static_cast<index_t>(f.size()) == n,
                  "solve_static: force has " << f.size() << " entries, K has " << n << " rows");
    RKFEM_REQUIRE(prescribed_dofs.size() == prescribed_values.size(),
                  "solve_static: prescribed dofs and values differ in length");
    std::vector<real_t> u(static_cast<std::size_t>(n), 0.0);
    std::vector<index_t> map;
    const index_t nf = free_dof_map(n, prescribed_dofs, map);
    for (std::size_t k = 0; k < prescribed_dofs.size(); ++k)
        u[prescribed_dofs[k]] = prescribed_values[k];
    Eigen::VectorXd rhs(nf);
    for (index_t i = 0; i < n; ++i)
        if (map[i] >= 0)
            rhs[map[i]] = f[i];
    // the prescribed values move to the right-hand side: rhs -= K_fp u_p
    for (index_t c = 0; c < n; ++c)
        if (map[c] < 0)
            for (SparseMatrix::InnerIterator it(K, static_cast<int>(c)); it; ++it)
                if (map[it.row()] >= 0)
                    rhs[map[it.row()]] -= it.value() * u[c];
    const SparseMatrix Kff = lower_restricted_to(K, map, nf);
    Eigen::CholmodSupernodalLLT<SparseMatrix, Eigen::Lower> chol;
    chol.compute(Kff);
    RKFEM_REQUIRE(chol.info() == Eigen::Success,
                  "static solve: the stiffness with "
                      << prescribed_dofs.size()
                      << " prescribed dofs is not positive definite "
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
    RKFEM_REQUIRE(lu.info() == Eigen::Success,
                  "constrained static solve: the saddle-point matrix with "
                      << m << " constraints is singular (free zero-energy mode or dependent constraints)");
    const Eigen::VectorXd x = lu.solve(rhs);
    return std::vector<real_t>(x.data(), x.data() + n);
}

MatrixFreeStiffness::MatrixFreeStiffness(std::vector<StiffnessTerm> terms, const ElasticParams& mat, index_t n_nodes)
    : terms_(std::move(terms)), mat_(mat), n_nodes_(n_nodes)
{
    for (const StiffnessTerm& t : terms_)
    {
        RKFEM_REQUIRE(t.op != nullptr, "matrix-free stiffness: a term has no operator");
        for (index_t I : t.op->nodes)
            RKFEM_REQUIRE(I >= 0 && I < n_nodes,
                          "matrix-free stiffness: an entry touches node " << I << " of " << n_nodes);
        Transposed tr;
        transpose_entries(*t.op, n_nodes, tr.offsets, tr.entry, tr.point);
        transposed_.push_back(std::move(tr));
        stress_.emplace_back(6 * static_cast<std::size_t>(t.op->n_points()));
    }
}

void MatrixFreeStiffness::apply(const real_t* u, real_t* out) const
{
    const real_t lam = mat_.lambda, mu = mat_.mu;
    for (std::size_t t = 0; t < terms_.size(); ++t)
    {
        const IntegrationOperator& op = *terms_[t].op;
        const real_t scale = terms_[t].scale;
        real_t* sig = stress_[t].data();
        parallel_for("stiffness_point_stress", op.n_points(),
                     [&](index_t p)
                     {
                         real_t G[9] = {}; // G(i, j) = du_i/dx_j
                         for (index_t a = op.offsets[p]; a < op.offsets[p + 1]; ++a)
                         {
                             const real_t* g = &op.grad[3 * static_cast<std::size_t>(a)];
                             const real_t* ua = u + 3 * static_cast<std::size_t>(op.nodes[a]);
                             for (int i = 0; i < 3; ++i)
                                 for (int j = 0; j < 3; ++j)
                                     G[3 * i + j] += ua[i] * g[j];
                         }
                         const real_t w = scale * op.weight[p];
                         const real_t tr = lam * (G[0] + G[4] + G[8]);
                         real_t* s = sig + 6 * static_cast<std::size_t>(p); // xx yy zz xy yz zx
                         s[0] = w * (tr + 2 * mu * G[0]);
                         s[1] = w * (tr + 2 * mu * G[4]);
                         s[2] = w * (tr + 2 * mu * G[8]);
                         s[3] = w * mu * (G[1] + G[3]);
                         s[4] = w * mu * (G[5] + G[7]);
                         s[5] = w * mu * (G[2] + G[6]);
                     });
    }
    parallel_for("stiffness_node_gather", n_nodes_,
                 [&](index_t I)
                 {
                     real_t f[3] = {0, 0, 0};
                     for (std::size_t t = 0; t < terms_.size(); ++t)
                     {
                         const IntegrationOperator& op = *terms_[t].op;
                         const Transposed& tr = transposed_[t];
                         const real_t* sig = stress_[t].data();
                         for (index_t k = tr.offsets[I]; k < tr.offsets[I + 1]; ++k)
                         {
                             const real_t* g = &op.grad[3 * static_cast<std::size_t>(tr.entry[k])];
                             const real_t* s = sig + 6 * static_cast<std::size_t>(tr.point[k]);
                             f[0] += s[0] * g[0] + s[3] * g[1] + s[5] * g[2];
                             f[1] += s[3] * g[0] + s[1] * g[1] + s[4] * g[2];
                             f[2] += s[5] * g[0] + s[4] * g[1] + s[2] * g[2];
                         }
                     }
                     for (int d = 0; d < 3; ++d)
                         out[3 * static_cast<std::size_t>(I) + d] = f[d];
                 });
}

PcgResult solve_static_pcg(const MatrixFreeStiffness& K, const std::vector<real_t>& f,
                           const std::vector<index_t>& pinned_dofs, const SparseMatrix& preconditioner, real_t rtol,
                           int max_iterations, const SparseMatrix* constraints)
{
    const index_t n = K.n_dofs();
    RKFEM_REQUIRE(static_cast<index_t>(f.size()) == n && preconditioner.rows() == n && preconditioner.cols() == n,
                  "solve_static_pcg: K has " << n << " dofs, f " << f.size() << ", the preconditioner "
                                             << preconditioner.rows() << " x " << preconditioner.cols());
    const bool constrained = constraints != nullptr && constraints->rows() > 0;
    RKFEM_REQUIRE(!constrained || constraints->cols() == n,
                  "solve_static_pcg: the constraints have " << constraints->cols() << " columns, K " << n << " dofs");
    std::vector<index_t> map;
    const index_t nf = free_dof_map(n, pinned_dofs, map);

    // the Euclidean projector onto C u = 0: v - C^T (C C^T)^-1 C v
    SparseMatrix Ct;
    Eigen::CholmodSupernodalLLT<SparseMatrix, Eigen::Lower> cct;
    Eigen::VectorXd lam;
    SparseMatrix M; // the preconditioner plus beta C^T C, with constraints only
    if (constrained)
    {
        Ct = constraints->transpose();
        const SparseMatrix CCt = (*constraints * Ct).pruned();
        cct.compute(CCt);
        RKFEM_REQUIRE(cct.info() == Eigen::Success, "static solve (PCG): the "
                                                        << constraints->rows()
                                                        << " constraints are linearly dependent (C C^T is singular)");
        // the preconditioner must be definite where K is, on C u = 0: add beta C^T C, which
        // removes the preconditioner's free motions as the constraints remove K's
        const SparseMatrix CtC = (Ct * *constraints).pruned();
        const real_t dp = preconditioner.diagonal().sum(), dc = CtC.diagonal().sum();
        M = preconditioner + (dp / std::max(dc, std::numeric_limits<real_t>::min())) * CtC;
    }
    const auto project = [&](std::vector<real_t>& v)
    {
        for (index_t d : pinned_dofs)
            v[d] = 0.0;
        if (!constrained)
            return;
        Eigen::Map<Eigen::VectorXd> vm(v.data(), n);
        lam = cct.solve(*constraints * vm);
        vm -= Ct * lam;
    };
    Eigen::CholmodSupernodalLLT<SparseMatrix, Eigen::Lower> chol;
    chol.compute(lower_restricted_to(constrained ? M : preconditioner, map, nf));
    RKFEM_REQUIRE(chol.info() == Eigen::Success, "static solve (PCG): the preconditioner with "
                                                     << pinned_dofs.size() << " pinned dofs is not positive definite");
    const auto dot = [n](const std::vector<real_t>& a, const std::vector<real_t>& b)
    { return parallel_reduce_sum("pcg_dot", n, [&](index_t i) { return a[i] * b[i]; }); };
    Eigen::VectorXd rf(nf), zf(nf);
    const auto precondition = [&](const std::vector<real_t>& r, std::vector<real_t>& z)
    {
        for (index_t i = 0; i < n; ++i)
            if (map[i] >= 0)
                rf[map[i]] = r[i];
        zf = chol.solve(rf);
        for (index_t i = 0; i < n; ++i)
            z[i] = map[i] >= 0 ? zf[map[i]] : 0.0;
        project(z);
    };
    // CG on the admissible dofs (zero at the pinned ones, C u = 0): every vector is projected
    PcgResult res;
    res.u.assign(static_cast<std::size_t>(n), 0.0);
    std::vector<real_t> r(f), z(static_cast<std::size_t>(n)), p(static_cast<std::size_t>(n)),
        q(static_cast<std::size_t>(n));
    project(r);
    const real_t f_norm = std::sqrt(dot(r, r));
    if (f_norm == 0.0)
        return res;
    precondition(r, z);
    p = z;
    real_t rz = dot(r, z);
    for (int it = 1; it <= max_iterations; ++it)
    {
        K.apply(p.data(), q.data());
        project(q);
        const real_t pq = dot(p, q);
        RKFEM_REQUIRE(pq > 0.0, "static solve (PCG): p.Kp = " << pq << " at iteration " << it
                                                              << "; K is not positive definite on the free dofs "
                                                                 "(a zero-energy mode is free)");
        const real_t alpha = rz / pq;
        parallel_for("pcg_update", n,
                     [&](index_t i)
                     {
                         res.u[i] += alpha * p[i];
                         r[i] -= alpha * q[i];
                     });
        res.iterations = it;
        res.relative_residual = std::sqrt(dot(r, r)) / f_norm;
        if (res.relative_residual <= rtol)
            return res;
        precondition(r, z);
        const real_t rz_new = dot(r, z);
        const real_t beta = rz_new / rz;
        rz = rz_new;
        parallel_for("pcg_direction", n, [&](index_t i) { p[i] = z[i] + beta * p[i]; });
    }
    throw Error("static solve (PCG): relative residual " + std::to_string(res.relative_residual) + " after " +
                std::to_string(max_iterations) + " iterations; expected at most " + std::to_string(rtol));
}
} // namespace rkfem
