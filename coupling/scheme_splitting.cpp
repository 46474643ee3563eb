/// @file scheme_splitting.cpp
/// Time splitting, the paper's baseline [Chentanez06, §4, Fig. 6] (scheme.hpp): the bodies
/// with the fluid's last nodal forces held, then the fluid with the bodies' velocities held.
#include "core/linear_solver.hpp"
#include "coupling/scheme.hpp"
#include "solid/floor_contact.hpp"
#include "solid/integrator.hpp"
#include "solid/obstacles.hpp"

namespace tetfsi::coupling {

namespace {

class SplittingScheme final : public CouplingScheme {
 public:
  explicit SplittingScheme(CouplingParams p) : m_params(std::move(p)) {}
  Scheme kind() const override { return Scheme::Splitting; }

  CoupledSolution advance(StepContext& ctx, std::unique_ptr<PredictedFluid>& pred,
                          CoupledStepReport& rep) override {
    solid::SolidWorld& world = ctx.world;
    const Index nb = static_cast<Index>(world.bodies.size());
    // The first step's held forces: those of the fluid's pressure at t = 0 (its dynamic
    // part through J, the hydrostatic part exactly).
    if (!m_have_force)
      m_held_force = ctx.fluid.current_forces(body_interfaces(world, ctx.surfaces));
    {  // 1. the bodies with the fluid's last nodal forces held
      ScopedTimer timer(ctx.phases, "solid");
      for (Index b = 0; b < nb; ++b) step_body(world, b, ctx.h, rep);
    }
    // 2. the mesh around the bodies at tⁿ⁺¹, the fluid with their velocities held
    pred = predict_around_current(ctx);
    const std::vector<CoupledBody> held(nb);  // every body prescribed
    CoupledSolution sol = pred->solve(held, m_params.solve);
    add_solve_phases(ctx.phases, sol.report);
    m_held_force = sol.fluid_force;
    m_have_force = true;
    return sol;
  }

 private:
  /// Body b's trapezoidal step with the held forces (a kinematic body: moved to tⁿ⁺¹).
  void step_body(solid::SolidWorld& world, Index b, double h, CoupledStepReport& rep) const {
    solid::SolidBody& body = world.bodies[b];
    if (body.is_kinematic()) {
      body.set_kinematic_state(world.time + h);
      return;
    }
    VecX fe = body.external_forces(world.gravity) + m_held_force[b];
    for (Index l = 0; l < fe.size(); ++l)
      if (body.is_fixed(l)) fe[l] = 0.0;
    const solid::TrapezoidalSystem sys = solid::assemble_trapezoidal(body, h, fe, world.trapezoid);
    VecX u = flat(body.velocity);
    const solid::BodySolve solve = [&](const SparseMatrix& A, const VecX& rhs, VecX& x) {
      rep.solid_iterations += factor_symmetric(A)->solve(rhs, x).iterations;
    };
    solid::FloorContactReport fr;
    PhaseTimes within_solid;  // the whole body step is the phase "solid"
    rep.contacts += solid::step_with_floor_contacts(body, sys, world.obstacles, world.gravity, h,
                                                    solve, u, within_solid, &fr);
    rep.contact_rounds = std::max(rep.contact_rounds, fr.rounds);
    rep.contacts_settled = rep.contacts_settled && fr.converged;
    check_finite(body, h);
  }

 public:
  void save_state(CheckpointWriter& w, const std::string& prefix) const override {
    w.put(prefix + "have_force", m_have_force);
    w.put(prefix + "held_forces", static_cast<std::int64_t>(m_held_force.size()));
    for (size_t b = 0; b < m_held_force.size(); ++b)
      w.put(fmt::format("{}held_force/{}", prefix, b), m_held_force[b]);
  }

  void load_state(const CheckpointReader& r, const std::string& prefix) override {
    const std::size_t n = r.get_count(prefix + "held_forces");
    std::vector<VecX> f;
    for (std::size_t b = 0; b < n; ++b)
      f.push_back(r.get<VecX>(fmt::format("{}held_force/{}", prefix, b)));
    m_have_force = r.get_bool(prefix + "have_force");
    m_held_force = std::move(f);
  }

 private:
  CouplingParams m_params;
  std::vector<VecX> m_held_force;  ///< the fluid's nodal forces of the last step
  bool m_have_force = false;
};

}  // namespace

std::unique_ptr<CouplingScheme> make_splitting_scheme(const CouplingParams& params) {
  return std::make_unique<SplittingScheme>(params);
}

}  // namespace tetfsi::coupling
