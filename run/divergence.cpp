#include "run/divergence.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "coupling/simulation.hpp"
#include "io/state_io.hpp"
#include "scene/scene.hpp"
#include "solid/world.hpp"

namespace tetfsi::app {

namespace {

/// The largest buoyancy acceleration (m/s²) the sources and inflow patches can cause:
/// |−α ρ_smoke + β (T − T_ambient)| at their densities and temperatures [Fedkiw01, Eq. (8)].
double buoyancy_acceleration(const fluid::FluidParams& p) {
  double rho = 0.0, dt = 0.0;
  for (const fluid::SmokeSource& s : p.sources) {
    rho = std::max(rho, s.smoke_density);
    if (s.emits_temperature) dt = std::max(dt, std::abs(s.temperature - p.ambient_temperature));
  }
  for (const fluid::PatchConditions& c : p.patches) {
    rho = std::max(rho, c.smoke_density);
    if (c.emits_temperature) dt = std::max(dt, std::abs(c.temperature - p.ambient_temperature));
  }
  return std::abs(p.buoyancy_alpha) * rho + std::abs(p.buoyancy_beta) * dt;
}

/// The mass centroid of a body (m).
Vec3 centroid(const solid::SolidBody& b) {
  const double m = b.total_mass();
  if (!(m > 0.0)) return Vec3::Zero();
  return (b.positions().transpose() * b.lumped_mass()) / m;
}

/// The volume of the body's rest bounding box (m³): at least the body and any cavity in it.
double box_volume(const solid::SolidBody& b) {
  if (b.num_nodes() == 0) return 0.0;
  const MatX3& x = b.rest_positions();
  return (x.colwise().maxCoeff() - x.colwise().minCoeff()).prod();
}

}  // namespace

DivergenceScales divergence_scales(const Scene& scene) {
  DivergenceScales s;
  s.gravity = scene.gravity;
  if (!scene.fluid) return s;
  const fluid::FluidParams& p = scene.fluid->params;
  const double a = scene.gravity.norm() + p.gravity.norm() + buoyancy_acceleration(p);
  const double L = (scene.fluid->domain.hi - scene.fluid->domain.lo).norm();
  s.fluid_speed = std::sqrt(2.0 * a * L);
  for (const fluid::PatchConditions& c : p.patches)
    s.fluid_speed = std::max(s.fluid_speed, c.inflow_speed);
  // The displaced fluid's weight acts on the bodies only where the fluid has gravity.
  if (p.gravity.norm() > 0.0) s.fluid_density = std::max(p.density, p.enclosed_density);
  return s;
}

DivergenceGuard::DivergenceGuard(const solid::SolidWorld& world, const DivergenceScales& scales)
    : m_scales(scales) {
  m_energy0 = mechanical_energy(world);
  m_potential0 = gravity_potential(world);
  for (const solid::SolidBody& b : world.bodies) {
    m_centroid0.push_back(centroid(b));
    if (b.is_kinematic() || !(b.material().density > 0.0)) continue;
    m_mass += b.total_mass();
    m_floor += 1e-4 * b.material().youngs_modulus * b.total_mass() / b.material().density;
  }
}

double DivergenceGuard::mechanical_energy(const solid::SolidWorld& world) const {
  double e = 0.0;
  for (const solid::SolidBody& b : world.bodies)
    if (!b.is_kinematic()) e += b.kinetic_energy() + b.elastic_energy();
  return e;
}

double DivergenceGuard::gravity_potential(const solid::SolidWorld& world) const {
  double v = 0.0;
  for (const solid::SolidBody& b : world.bodies)
    if (!b.is_kinematic()) v += b.gravity_potential(world.gravity);
  return v;
}

double DivergenceGuard::buoyancy_work(const solid::SolidWorld& world) const {
  if (!(m_scales.fluid_density > 0.0)) return 0.0;
  const Vec3 up =
      m_scales.gravity.norm() > 0.0 ? Vec3(-m_scales.gravity.normalized()) : Vec3::UnitZ();
  double w = 0.0;
  for (size_t i = 0; i < world.bodies.size(); ++i) {
    const solid::SolidBody& b = world.bodies[i];
    if (b.is_kinematic()) continue;
    const double dz = std::abs((centroid(b) - m_centroid0[i]).dot(up));
    w += m_scales.fluid_density * box_volume(b) * m_scales.gravity.norm() * dz;
  }
  return w;
}

double DivergenceGuard::budget() const {
  return m_energy0 + m_release + m_work + m_buoyancy;
}

void DivergenceGuard::before_step(const solid::SolidWorld& world) {
  m_before.clear();
  for (const solid::SolidBody& b : world.bodies) m_before.push_back(b.displacement);
}

std::optional<std::string> DivergenceGuard::check_fluid(const coupling::FsiStepReport& rep) const {
  const fluid::FluidStepReport* f =
      rep.coupled ? &rep.coupled->fluid : (rep.fluid ? &*rep.fluid : nullptr);
  if (!f) return std::nullopt;
  // The fluid keeps the motion the bodies gave it after they slow down (a swing's turning
  // point): the bodies' peak speed so far, and the speed of the bodies' whole energy budget.
  const double budget_speed = m_mass > 0.0 ? std::sqrt(2.0 * budget() / m_mass) : 0.0;
  const double scale = std::max({m_scales.fluid_speed, m_body_speed, budget_speed});
  const double limit = kFactor * kFactor * scale;
  if (std::isfinite(f->max_speed) && f->max_speed <= limit) return std::nullopt;
  return fmt::format(
      "the fluid diverged: its largest speed {:.3g} m/s is beyond {:.3g} m/s, {:g} × what the "
      "scene can drive ({:.3g} m/s from the inflows, gravity, buoyancy and the bodies' peak speed "
      "and energy); "
      "reduce time.dt",
      f->max_speed, limit, kFactor * kFactor, scale);
}

namespace {

template <class S, class F>
void visit_guard(S& energy0, S& potential0, S& floor, S& work, S& release, S& buoyancy,
                 S& body_speed, S& mass, F&& f) {
  f("energy0", energy0);
  f("potential0", potential0);
  f("floor", floor);
  f("work", work);
  f("release", release);
  f("buoyancy", buoyancy);
  f("body_speed", body_speed);
  f("mass", mass);
}

}  // namespace

void DivergenceGuard::save_state(CheckpointWriter& w) const {
  visit_guard(m_energy0, m_potential0, m_floor, m_work, m_release, m_buoyancy, m_body_speed, m_mass,
              RecordSaver{w, "run/guard/"});
  MatX3 c(static_cast<Index>(m_centroid0.size()), 3);
  for (size_t i = 0; i < m_centroid0.size(); ++i) c.row(static_cast<Index>(i)) = m_centroid0[i];
  w.put("run/guard/centroid0", c);
}

void DivergenceGuard::load_state(const CheckpointReader& r) {
  visit_guard(m_energy0, m_potential0, m_floor, m_work, m_release, m_buoyancy, m_body_speed, m_mass,
              RecordLoader{r, "run/guard/"});
  const MatX3 c = r.get<MatX3>("run/guard/centroid0");
  if (static_cast<size_t>(c.rows()) != m_centroid0.size())
    r.fail(fmt::format("run/guard/centroid0: {} bodies, this scene has {}", c.rows(),
                       m_centroid0.size()));
  for (size_t i = 0; i < m_centroid0.size(); ++i)
    m_centroid0[i] = c.row(static_cast<Index>(i)).transpose();
}

std::optional<std::string> DivergenceGuard::after_step(const solid::SolidWorld& world,
                                                       const coupling::FsiStepReport& rep) {
  double w = 0.0;  // the loads' work over the step, f · Δd
  for (size_t i = 0; i < world.bodies.size() && i < m_before.size(); ++i) {
    const solid::SolidBody& b = world.bodies[i];
    if (b.is_kinematic()) continue;
    w += flat(b.applied_force).dot(flat(b.displacement) - flat(m_before[i]));
  }
  m_work += std::max(0.0, w);
  if (rep.coupled) m_work += std::max(0.0, rep.coupled->fluid_work);
  m_release = std::max(0.0, m_potential0 - gravity_potential(world));
  m_buoyancy = buoyancy_work(world);
  for (const solid::SolidBody& b : world.bodies)
    if (b.num_nodes() > 0)
      m_body_speed = std::max(m_body_speed, b.velocity.rowwise().norm().maxCoeff());
  if (auto fluid = check_fluid(rep)) return fluid;
  const double e = mechanical_energy(world);
  const double limit = kFactor * budget() + m_floor;
  if (std::isfinite(e) && e <= limit) return std::nullopt;
  return fmt::format(
      "the bodies diverged: their kinetic + elastic energy {:.3g} J is beyond {:.3g} J, {:g} × "
      "what the start, gravity, the loads and the fluid supplied ({:.3g} J) + {:.3g} J; reduce "
      "time.dt, or use solid.trapezoid \"paper\" or solid.integrator \"bfgs\"",
      e, limit, kFactor, budget(), m_floor);
}

}  // namespace tetfsi::app
