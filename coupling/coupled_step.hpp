#pragma once
/// @file coupled_step.hpp
/// One two-way coupled step of the fluid and the solid bodies by any scheme (scheme.hpp):
/// the part every scheme shares — the world is left at tⁿ if the step fails, the fluid is
/// committed from the scheme's solution, the step's report is completed.
#include <memory>
#include <vector>

#include "core/timer.hpp"
#include "coupling/scheme.hpp"
#include "solid/world.hpp"

namespace tetfsi::coupling {

class CoupledStepper {
 public:
  CoupledStepper(CouplingParams params, const solid::SolidWorld& world);

  /// Advance the world and the fluid by h together. The fluid must be around the bodies at
  /// tⁿ (their surfaces, body_surface numbering). Phases: remesh (the tet fluid's), transfer,
  /// forces, coupled_assembly, coupled_solve, solid (splitting and the iterated schemes: the
  /// bodies' own work), update.
  /// @throws SolverError if a solve fails or the state becomes non-finite; MeshError from
  ///   the fluid's predict. The world and the fluid are then left at tⁿ.
  CoupledStepReport step(solid::SolidWorld& world, CoupledFluid& fluid, double h,
                         PhaseTimes& phases);

  const CouplingParams& params() const { return m_params; }
  /// The scheme's state carried across steps (CouplingScheme::save_state / load_state).
  void save_state(CheckpointWriter& w, const std::string& prefix) const {
    m_scheme->save_state(w, prefix);
  }
  void load_state(const CheckpointReader& r, const std::string& prefix) {
    m_scheme->load_state(r, prefix);
  }
  const std::vector<BodySurface>& surfaces() const { return m_surfaces; }

 private:
  CouplingParams m_params;
  std::vector<BodySurface> m_surfaces;
  std::unique_ptr<CouplingScheme> m_scheme;
};

}  // namespace tetfsi::coupling
