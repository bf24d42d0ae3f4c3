#pragma once
/// @file formulation.hpp
/// How a part's weak form is integrated and approximated (deck key `formulation`).

namespace rkfem
{
enum class Formulation
{
    Fem1pt,   ///< 1-point uniform-strain hex (Flanagan-Belytschko) + hourglass control
    Fem2x2x2, ///< fully integrated hex, 8 Gauss points
    FemNodal, ///< trilinear FE functions, nodal integration, state at nodes (total Lagrangian)
    Rkpm,     ///< RK particles at the mesh nodes, nodal integration (total Lagrangian)
};

inline bool is_nodal(Formulation f)
{
    return f == Formulation::FemNodal || f == Formulation::Rkpm;
}
} // namespace rkfem
