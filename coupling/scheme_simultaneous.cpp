/// @file scheme_simultaneous.cpp
/// The simultaneous scheme [Chentanez06, §3.3] (scheme.hpp): Eq. (4) per body at dⁿ, the mesh
/// around x*, one coupled solve of Eq. (7), Eq. (8), Eq. (5), collisions.
#include "core/dof_elimination.hpp"
#include "core/error.hpp"
#include "coupling/contacts.hpp"
#include "coupling/scheme.hpp"
#include "solid/integrator.hpp"
#include "solid/obstacles.hpp"

namespace tetfsi::coupling {

namespace {

class SimultaneousScheme final : public CouplingScheme {
 public:
  explicit SimultaneousScheme(CouplingParams p) : m_params(std::move(p)) {}
  Scheme kind() const override { return Scheme::Simultaneous; }

  CoupledSolution advance(StepContext& ctx, std::unique_ptr<PredictedFluid>& pred,
                          CoupledStepReport& rep) override {
    solid::SolidWorld& world = ctx.world;
    const Index nb = static_cast<Index>(world.bodies.size());
    std::vector<CoupledBody> cb(nb);
    std::vector<std::vector<Contact>> contacts(nb);
    {  // 1. each deformable body's Eq. (4) at dⁿ; kinematic bodies to tⁿ⁺¹
      ScopedTimer timer(ctx.phases, "coupled_assembly");
      for (Index b = 0; b < nb; ++b) contacts[b] = assemble_body(world, b, ctx.h, cb[b]);
    }
    // 2. the mesh around x* = X + dⁿ + h uⁿ (or xⁿ), 3. transfer, forces: v*
    pred = predict_around_predicted(ctx, rep);
    // 4. the coupled solve, see [Chentanez06, Eq. (7)]
    SolveVariant variant;
    variant.targets = &m_targets;
    CoupledSolution sol = pred->solve(cb, m_params.solve, variant);
    add_solve_phases(ctx.phases, sol.report);
    // 5. Eq. (5), collisions
    ScopedTimer timer(ctx.phases, "update");
    for (Index b = 0; b < nb; ++b) {
      solid::SolidBody& body = world.bodies[b];
      if (!cb[b].free) continue;
      solid::advance_trapezoidal(body, sol.u[b], ctx.h);
      land_contacts(body, contacts[b], world.gravity, ctx.h);
      rep.contacts += static_cast<Index>(contacts[b].size());
      rep.contacts += solid::resolve_collisions(body, world.obstacles);
      check_finite(body, ctx.h);
    }
    return sol;
  }

 private:
  /// Body b's Eq. (4) with its floor contacts eliminated (a kinematic body: moved to tⁿ⁺¹).
  static std::vector<Contact> assemble_body(solid::SolidWorld& world, Index b, double h,
                                            CoupledBody& cb) {
    solid::SolidBody& body = world.bodies[b];
    if (body.is_kinematic()) {
      body.set_kinematic_state(world.time + h);
      return {};
    }
    solid::TrapezoidalSystem sys =
        solid::assemble_trapezoidal(body, h, body.external_forces(world.gravity), world.trapezoid);
    cb.free = true;
    cb.A = std::move(sys.A);
    cb.b = std::move(sys.b);
    cb.fixed = body.fixed_dofs();
    cb.prescribed = VecX::Zero(body.num_dofs());
    std::vector<Contact> contacts =
        floor_contacts(body, world.obstacles, world.gravity, h, cb.prescribed, cb.fixed);
    std::vector<std::uint8_t> mask(body.num_dofs(), 0);
    for (const Contact& c : contacts) mask[3 * c.node + c.axis] = 1;
    if (!contacts.empty())
      eliminate_dofs(
          cb.A, mask, [&](Index i) { return body.lumped_mass()[i / 3] / h; }, &cb.b,
          &cb.prescribed);
    cb.x = body.positions();
    cb.u = flat(body.velocity);
    return contacts;
  }

 public:
  void save_state(CheckpointWriter& w, const std::string& prefix) const override {
    std::vector<std::int64_t> keys;
    std::vector<double> volumes;
    for (const auto& [k, v] : m_targets) {
      keys.push_back(k);
      volumes.push_back(v);
    }
    w.put(prefix + "volume_target_keys", keys);
    w.put(prefix + "volume_targets", volumes);
  }

  void load_state(const CheckpointReader& r, const std::string& prefix) override {
    const auto keys = r.get_vector<std::int64_t>(prefix + "volume_target_keys");
    const auto volumes = r.get_vector<double>(prefix + "volume_targets");
    if (keys.size() != volumes.size())
      r.fail(fmt::format("it has {} volume targets for {} keys", volumes.size(), keys.size()));
    m_targets.clear();
    for (size_t i = 0; i < keys.size(); ++i) m_targets[keys[i]] = volumes[i];
  }

 private:
  CouplingParams m_params;
  VolumeTargets m_targets;  ///< the enclosed regions' volumes when first seen
};

}  // namespace

std::unique_ptr<CouplingScheme> make_simultaneous_scheme(const CouplingParams& params) {
  return std::make_unique<SimultaneousScheme>(params);
}

}  // namespace tetfsi::coupling
