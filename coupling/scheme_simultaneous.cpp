/// @file scheme_simultaneous.cpp
/// The simultaneous scheme [Chentanez06, §3.3] (scheme.hpp): Eq. (4) per body at dⁿ, the mesh
/// around x*, one coupled solve of Eq. (7) per round of the floors' active set, Eq. (8), Eq. (5),
/// collisions.
#include <optional>

#include "core/error.hpp"
#include "coupling/scheme.hpp"
#include "solid/contact.hpp"
#include "solid/floor_contact.hpp"
#include "solid/integrator.hpp"
#include "solid/obstacles.hpp"

namespace tetfsi::coupling {

namespace {

/// The free bodies' DOFs stacked in body order (as the coupled solve stacks them), their
/// fixed and prescribed velocities; the others' known uⁿ⁺¹.
std::vector<solid::BodyDofs> stacked_dofs(const solid::SolidWorld& world,
                                          const std::vector<CoupledBody>& cb,
                                          const std::vector<VecX>& known) {
  std::vector<solid::BodyDofs> dofs(cb.size());
  Index at = 0;
  for (size_t b = 0; b < cb.size(); ++b) {
    if (!cb[b].free) {
      dofs[b] = {-1, nullptr, &known[b]};
      continue;
    }
    dofs[b] = {at, &cb[b].fixed, &cb[b].prescribed};
    at += world.bodies[b].num_dofs();
  }
  return dofs;
}

class SimultaneousScheme final : public CouplingScheme {
 public:
  explicit SimultaneousScheme(CouplingParams p) : m_params(std::move(p)) {}
  Scheme kind() const override { return Scheme::Simultaneous; }

  CoupledSolution advance(StepContext& ctx, std::unique_ptr<PredictedFluid>& pred,
                          CoupledStepReport& rep) override {
    solid::SolidWorld& world = ctx.world;
    const Index nb = static_cast<Index>(world.bodies.size());
    std::vector<CoupledBody> cb(nb);
    std::vector<solid::TrapezoidalSystem> sys(nb);
    std::vector<std::unique_ptr<solid::FloorContacts>> contacts(nb);
    std::optional<solid::BodyContacts> touching;  // contact between the bodies
    {  // 1. each deformable body's Eq. (4) at dⁿ; kinematic bodies to tⁿ⁺¹
      ScopedTimer timer(ctx.phases, "coupled_assembly");
      for (Index b = 0; b < nb; ++b) {
        solid::SolidBody& body = world.bodies[b];
        if (body.is_kinematic()) continue;
        sys[b] = solid::assemble_trapezoidal(body, ctx.h, body.external_forces(world.gravity),
                                             world.trapezoid);
        contacts[b] =
            std::make_unique<solid::FloorContacts>(body, world.obstacles, world.gravity, ctx.h);
        cb[b].free = true;
        cb[b].x = body.positions();
        cb[b].u = flat(body.velocity);
      }
      if (world.contact.enabled) {  // at xⁿ, uⁿ: before the kinematic bodies move
        ScopedTimer contact_timer(ctx.phases, "contact");
        touching.emplace(world.bodies, world.contact, world.gravity, ctx.h);
      }
      for (solid::SolidBody& body : world.bodies)
        if (body.is_kinematic()) body.set_kinematic_state(world.time + ctx.h);
    }
    // the kinematic bodies' uⁿ⁺¹ (the free bodies' entries are the rounds' solutions)
    std::vector<VecX> known(nb);
    Index ns = 0;
    for (Index b = 0; b < nb; ++b) {
      known[b] = flat(world.bodies[b].velocity);
      if (cb[b].free) ns += world.bodies[b].num_dofs();
    }
    // 2. the mesh around x* = X + dⁿ + h uⁿ (or xⁿ), 3. transfer, forces: v*
    pred = predict_around_predicted(ctx, rep);
    // 4. the coupled solve, see [Chentanez06, Eq. (7)], once per round of the floors' active
    // set (solid/floor_contact.hpp): its multipliers are the fluid-aware floor forces
    SolveVariant variant;
    variant.targets = &m_targets;
    // The rounds' P = C + Jᵀ diag(A)⁻¹ J differ only at the contact DOFs: the first round's
    // AMG preconditions the later ones (measured on paddle below).
    CoupledOptions opt = m_params.solve;
    SolveCache rounds_amg;
    opt.reuse = &rounds_amg;
    CoupledSolution sol;
    solid::ContactSystem between;  // the contacts' part of the solid block
    for (bool again = true; again;) {
      for (Index b = 0; b < nb; ++b)
        if (cb[b].free)
          contacts[b]->constrain(sys[b], cb[b].A, cb[b].b, cb[b].fixed, cb[b].prescribed);
      if (touching) {
        ScopedTimer timer(ctx.phases, "contact");
        between = touching->system(stacked_dofs(world, cb, known), ns);
        opt.contact = &between;
      }
      sol = pred->solve(cb, opt, variant);
      add_solve_phases(ctx.phases, sol.report);
      again = false;
      for (Index b = 0; b < nb; ++b)
        if (cb[b].free && contacts[b]->update(sol.u[b], &sol.fluid_force[b])) again = true;
      if (touching) {
        ScopedTimer timer(ctx.phases, "contact");
        for (Index b = 0; b < nb; ++b)
          if (cb[b].free) known[b] = sol.u[b];
        if (touching->update(known)) again = true;
      }
    }
    // 5. Eq. (5), landing, the other obstacles
    ScopedTimer timer(ctx.phases, "update");
    for (Index b = 0; b < nb; ++b) {
      solid::SolidBody& body = world.bodies[b];
      if (!cb[b].free) continue;
      solid::advance_trapezoidal(body, sol.u[b], ctx.h);
      rep.contacts += contacts[b]->land(body);
      rep.contact_rounds = std::max(rep.contact_rounds, contacts[b]->report().rounds);
      rep.contacts_settled = rep.contacts_settled && contacts[b]->report().converged;
      check_finite(body, ctx.h);
    }
    if (touching) {
      ScopedTimer contact_timer(ctx.phases, "contact");
      touching->land(world.bodies);
      touching->measure(world.bodies);
      rep.body_contact = touching->report();
    }
    return sol;
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
