#pragma once
/// @file grid_coupled.hpp
/// The simultaneous solve [Chentanez06, Eq. (7)] on the MAC grid (fluid/grid*.hpp) and the
/// grid fluid behind the schemes' seam (fluid_seam.hpp). The system is coupled_system.hpp's,
/// filled from the grid: one pressure unknown per fluid cell, C = diag(h/ρ) L with the grid's
/// 7-point L (grid_pressure_matrix), the second block row's interface operator V D1 H
/// (fluid::GridInterface), and the first row's pressure forces J in one of two forms
/// [Chentanez06, §3.4, last paragraph]:
///  - paper (the default): the pressure interpolated side-aware at quadrature points of every
///    body triangle and integrated (GridInterface::J_paper), built apart from H as in the
///    paper. Exact for a linear pressure (the released sphere's added mass within 2 % at 40³),
///    but the system is not symmetric: schur_amg runs BiCGSTAB on the Schur complement (LU if
///    it fails), and the interface creates or absorbs the power
///    CoupledReport::interface_imbalance;
///  - consistent: J = (V D1 H)ᵀ. The system is symmetric quasi-definite like the tet fluid's
///    (CG on the Schur complement), and the pressure does on the bodies exactly the power the
///    bodies do on the fluid; its staircase forces leave ~6 % in the sphere's added mass.
/// The hydrostatic part of a liquid's pressure pushes the bodies through the paper's J in both
/// forms (it integrates a linear field exactly: a neutrally buoyant body floats), as on the
/// tet mesh, where it is exact at the face centroids. Enclosed regions keep their
/// volume as on the tet mesh; a cavity is every triangle of the body surface components the
/// region's Solid faces cross.
#include <memory>
#include <string>
#include <vector>

#include "core/enum_names.hpp"
#include "coupling/fluid_seam.hpp"
#include "coupling/scheme.hpp"
#include "fluid/grid/grid.hpp"
#include "fluid/grid/interface.hpp"
#include "fluid/grid/simulation.hpp"

namespace tetfsi::coupling {

enum class GridPressureForces { Consistent, Paper };
inline constexpr EnumNames<GridPressureForces, 2> k_grid_pressure_forces_names{
    "fluid.grid.pressure_forces",
    {{{GridPressureForces::Consistent, "consistent"}, {GridPressureForces::Paper, "paper"}}}};

struct GridCoupledInput {
  const fluid::GridCells* cells = nullptr;
  const VecX* u_star = nullptr;  ///< #F v*, prescribed faces set
  const VecX* p_open = nullptr;  ///< #F dynamic pressure on Open faces (Pa)
  const VecX* rho = nullptr;     ///< #C fluid density per cell
  double h = 0.0;
  Vec3 gravity = Vec3::Zero(), hydrostatic_origin = Vec3::Zero();
  const fluid::GridInterface* interface = nullptr;
  const SparseMatrix* J = nullptr;   ///< 3N × #C, the first row's pressure forces
  const SparseMatrix* Jc = nullptr;  ///< 3N × #C, (V D1 H)ᵀ
  /// 3N × #C, the paper's J: the hydrostatic part's forces (exact for a linear pressure;
  /// may be null without gravity)
  const SparseMatrix* Jh = nullptr;
  const std::vector<CoupledBody>* bodies = nullptr;
  VolumeTargets* volume_targets = nullptr;  ///< null: no volume correction
};

/// Assemble (CoupledSystem), solve, keep enclosed volumes, finish with Eq. (8): the grid's
/// counterpart of solve_coupled. @throws InputError for inconsistent sizes; SolverError as
/// solve_coupled.
CoupledSolution solve_grid_coupled(const GridCoupledInput& in, const CoupledOptions& opt);

/// The grid fluid's prediction of a step: the classified grid with v*, H, J.
class GridPredicted final : public PredictedFluid {
 public:
  GridPredicted(fluid::GridPrediction pred, const fluid::FluidParams& params,
                const std::vector<BodyInterface>& bodies, GridPressureForces forces);

  const VecX& u_star() const override { return m_pred.u_star; }
  CoupledSolution solve(const std::vector<CoupledBody>& bodies, const CoupledOptions& opt,
                        const SolveVariant& variant = {}) const override;
  void apply_H(const std::vector<VecX>& u, VecX& u_face) const override {
    m_iface.apply_H(u, u_face);
  }
  void refuse_sealed_regions(const solid::SolidWorld& world, const char* scheme) const override;

  fluid::GridPrediction& prediction() { return m_pred; }
  const fluid::GridPrediction& prediction() const { return m_pred; }
  const fluid::GridInterface& interface() const { return m_iface; }
  /// Move (V D1 H)ᵀ and the paper's J out (after the solve, for a GridForceCache).
  void release_forces(SparseMatrix& Jc, SparseMatrix& Jp) {
    Jc = std::move(m_Jc);
    Jp = std::move(m_Jp);
  }

 private:
  fluid::GridPrediction m_pred;
  const fluid::FluidParams& m_params;
  fluid::GridInterface m_iface;
  SparseMatrix m_Jp, m_Jc;  ///< the paper's J (paper form, or for gravity), (V D1 H)ᵀ
  GridPressureForces m_forces;
};

/// The hydrostatic pressure ρ_c g·(x_c − origin) at every cell centre (#C, Pa).
VecX grid_hydrostatic_pressure(const fluid::GridCells& gc, const VecX& rho,
                               const fluid::FluidParams& params);

/// The fluid's nodal forces (3n per body, N): the dynamic pressure p_dyn (#C) through J, the
/// hydrostatic p_hydro (#C) through Jh (the paper's J: exact for a linear field), 3N × #C.
std::vector<VecX> grid_fluid_forces(const fluid::GridInterface& iface, const SparseMatrix& J,
                                    const VecX& p_dyn, const SparseMatrix* Jh = nullptr,
                                    const VecX* p_hydro = nullptr);

/// The pressure-force matrices of the grid the fluid last committed (a step's J, kept for the
/// forces the output and the next step read on that same grid instead of rebuilding them).
struct GridForceCache {
  bool valid = false;
  double time = 0;      ///< GridFluid::time() of the committed grid
  SparseMatrix Jc, Jp;  ///< (V D1 H)ᵀ; the paper's J (empty if the step did not need it)
};

/// The J matrices a two-way step keeps for a classified grid `gc` (Jc always, Jp when
/// `forces` is Paper or there is gravity), put in `cache` for the fluid time `time` (the
/// one-way step builds them beside its pressure solve for the output's forces).
void fill_grid_force_cache(const fluid::GridCells& gc, const std::vector<BodyInterface>& bodies,
                           GridPressureForces forces, const fluid::FluidParams& params, double time,
                           GridForceCache& cache);

/// The fluid's nodal forces on the bodies on the fluid's current grid (3n per body, N): the
/// dynamic pressure through the J of `forces`, the hydrostatic one through the paper's J; the
/// matrices from `cache` when it holds this grid's.
std::vector<VecX> grid_current_forces(const fluid::GridFluid& fluid,
                                      const std::vector<BodyInterface>& bodies,
                                      GridPressureForces forces, const GridForceCache* cache);

class GridCoupledFluid final : public CoupledFluid {
 public:
  /// @param surfaces, names, bodies per body (body_surface, SolidBody::name, body_interfaces)
  /// @param cache filled by commit, read by current_forces (may be null)
  GridCoupledFluid(fluid::GridFluid& fluid, const mesh::FluidDomain& domain,
                   const std::vector<BodySurface>& surfaces, const std::vector<std::string>& names,
                   std::vector<BodyInterface> bodies, GridPressureForces forces,
                   GridForceCache* cache = nullptr);

  const fluid::FluidParams& params() const override { return m_fluid.params(); }
  std::unique_ptr<PredictedFluid> predict(const std::vector<MatX3>& positions,
                                          const std::vector<fluid::SolidSurfaceMotion>& motions,
                                          double h, PhaseTimes& phases) override;
  fluid::FluidStepReport commit(std::unique_ptr<PredictedFluid> pred,
                                CoupledSolution& sol) override;
  std::vector<VecX> current_forces(const std::vector<BodyInterface>& bodies) const override;

 private:
  fluid::GridFluid& m_fluid;
  const mesh::FluidDomain& m_domain;
  const std::vector<BodySurface>& m_surfaces;
  const std::vector<std::string>& m_names;
  std::vector<BodyInterface> m_bodies;
  GridPressureForces m_forces;
  GridForceCache* m_cache;
};

}  // namespace tetfsi::coupling
