#pragma once
/// @file solid_test_utils.hpp
/// Small helpers shared by the solid tests.
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "mesh/generate.hpp"
#include "solid/obstacles.hpp"
#include "solid/solid_body.hpp"

namespace tetfsi::solid::testing {

inline Material make_material(double rho, double E, double nu, double alpha = 0.0,
                              double beta = 0.0) {
  Material m;
  m.density = rho;
  m.youngs_modulus = E;
  m.poisson_ratio = nu;
  m.rayleigh_alpha = alpha;
  m.rayleigh_beta = beta;
  return m;
}

/// A box body [lo, hi] with cells.x × cells.y × cells.z Kuhn-split hexahedra.
inline SolidBody make_box_body(const std::string& name, const Vec3& lo, const Vec3& hi,
                               const Vec3i& cells, const Material& mat) {
  return SolidBody(name, mesh::make_box(lo, hi, cells), mat);
}

/// Nodes whose rest coordinate `axis` equals `value` (to 1e-12 relative to the box size).
inline std::vector<Index> nodes_at(const SolidBody& b, int axis, double value, double scale) {
  std::vector<Index> out;
  for (Index i = 0; i < b.num_nodes(); ++i)
    if (std::abs(b.rest_positions()(i, axis) - value) <= 1e-12 * scale) out.push_back(i);
  return out;
}

/// Node closest to point p in the rest configuration.
inline Index closest_node(const SolidBody& b, const Vec3& p) {
  Index best = 0;
  double best_d = 1e300;
  for (Index i = 0; i < b.num_nodes(); ++i) {
    const double d = (b.rest_positions().row(i).transpose() - p).norm();
    if (d < best_d) {
      best_d = d;
      best = i;
    }
  }
  return best;
}

/// A floor: the plane z = `z`, normal +z, restitution e and Coulomb μ.
inline Obstacle floor_plane(double z, double e, double mu) {
  Obstacle o;
  o.kind = Obstacle::Kind::Plane;
  o.name = "floor";
  o.point = Vec3(0, 0, z);
  o.normal = Vec3::UnitZ();
  o.restitution = e;
  o.friction = mu;
  return o;
}

/// Centre of mass (m) and its velocity (m/s).
inline Vec3 com(const SolidBody& b) {
  return (b.positions().transpose() * b.lumped_mass()) / b.total_mass();
}
inline Vec3 com_velocity(const SolidBody& b) {
  return (b.velocity.transpose() * b.lumped_mass()) / b.total_mass();
}

/// Kinetic + elastic + gravitational energy (J).
inline double mechanical_energy(const SolidBody& b, const Vec3& gravity) {
  return b.kinetic_energy() + b.elastic_energy() + b.gravity_potential(gravity);
}

inline Mat3 rotation(const Vec3& axis, double angle) {
  return Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
}

}  // namespace tetfsi::solid::testing
