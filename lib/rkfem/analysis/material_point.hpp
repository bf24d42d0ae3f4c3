#pragma once
/// @file material_point.hpp
/// Drives one material point along a strain path with mixed stress/strain control (the
/// material-point driver of `rkfem material-point DECK --out DIR`). Paths (x is axial):
///   uniaxial-stress  axial strain rate, lateral stresses held at 0
///   uniaxial-strain  axial strain rate, lateral strains 0
///   hydrostatic      equal strain rates in x, y, z (strain = volumetric strain)
///   pure-shear       engineering shear strain gamma_xy
///   triaxial         isotropic compression to the confinement (first quarter of the steps),
///                    then axial strain with the lateral stresses held at -confinement
///   rotation         uniaxial strain, then a rigid rotation by `angle` about z
/// Stress-controlled components are solved each step by Newton iterations with the elastic
/// lateral stiffness, each from the committed state, to 1e-10 of the stress scale.
#include <string>
#include <vector>

#include "rkfem/core/types.hpp"

namespace rkfem
{
struct MaterialPointDeck;
struct MaterialPointRecord
{
    real_t time = 0.0;
    real_t strain[6] = {}; ///< accumulated d dt (tensor shear)
    real_t stress[6] = {};
    real_t plastic_strain = 0.0;
    real_t failed = 0.0; ///< failed flag (j2); damage function lambda (kcc); damage d (cscm)
    real_t work = 0.0;   ///< accumulated plastic work density (kcc, cscm) [J/m^3]
};

std::vector<MaterialPointRecord> run_material_point(const MaterialPointDeck& deck);

/// Writes DIR/stress_strain.csv and the same columns in DIR/stress_strain.h5 (time, strain n x 6,
/// stress n x 6, plastic_strain, failed, work).
void write_material_point(const std::vector<MaterialPointRecord>& h, const std::string& out_dir);
} // namespace rkfem
