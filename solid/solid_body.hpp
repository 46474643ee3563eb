#pragma once
/// @file solid_body.hpp
/// One deformable body: rest mesh, material, state (d, u), loads and fixed DOFs; or a
/// kinematic body, whose state follows a prescribed rigid motion (kinematic.hpp).
#include <optional>
#include <string>
#include <vector>

#include "core/types.hpp"
#include "mesh/volume_mesh.hpp"
#include "solid/kinematic.hpp"
#include "solid/material.hpp"
#include "solid/stvk.hpp"

namespace tetfsi::solid {

class SolidBody {
 public:
  /// @param rest_mesh validated tet mesh in the rest configuration (m)
  /// @throws InputError for a bad material, MeshError for a bad mesh (naming `name`).
  SolidBody(std::string name, mesh::VolumeMesh rest_mesh, const Material& material);

  const std::string& name() const { return m_name; }
  Index num_nodes() const { return m_mesh.num_vertices(); }
  Index num_dofs() const { return 3 * num_nodes(); }
  Index num_tets() const { return m_mesh.num_tets(); }
  const mesh::VolumeMesh& rest_mesh() const { return m_mesh; }
  const MatX3& rest_positions() const { return m_mesh.vertices; }
  const MatX4i& tets() const { return m_mesh.tets; }
  /// Outward-oriented boundary triangles (#B × 3, node indices): what the fluid sees.
  const MatX3i& boundary_triangles() const { return m_boundary; }
  const Material& material() const { return m_material; }
  const StvkElasticity& elasticity() const { return m_elasticity; }
  /// The Jacobian the integrators use (StvkElasticity::set_tangent).
  void set_tangent(Tangent t) { m_elasticity.set_tangent(t); }
  /// Lumped mass per node (#V, kg): each tet gives ρ V0 / 4 to each of its nodes.
  const VecX& lumped_mass() const { return m_mass; }
  /// Total mass (kg) = ρ · rest volume.
  double total_mass() const { return m_mass.sum(); }

  /// Current positions x = X + d (#V × 3).
  MatX3 positions() const { return m_mesh.vertices + displacement; }

  // ---- fixed degrees of freedom (pins) ----
  /// Fix component `axis` (0, 1, 2) of node `node` at its current displacement (zero velocity).
  void fix_dof(Index node, int axis);
  /// Fix all three components of a node.
  void pin_node(Index node);
  /// Per DOF (3#V, interleaved): 1 if fixed.
  const std::vector<std::uint8_t>& fixed_dofs() const { return m_fixed; }
  bool is_fixed(Index dof) const { return m_fixed[dof] != 0; }
  Index num_fixed_dofs() const;

  // ---- state ----
  MatX3 displacement;   ///< d (#V × 3, m)
  MatX3 velocity;       ///< u (#V × 3, m/s)
  MatX3 applied_force;  ///< loads set by the scene, gravity excluded (#V × 3, N)
  /// Set: the body is kinematic. SolidWorld::step does not integrate it (no assembly, solve
  /// or collisions) but sets d = x(t) − X and u = u(t) from the motion at the new time, so
  /// pins and loads make no sense on it (step rejects them). Its material is still validated:
  /// mass and energies use it.
  std::optional<KinematicMotion> kinematic;
  bool is_kinematic() const { return kinematic.has_value(); }
  /// Kinematic bodies: d and u from the motion at time t (s). @pre is_kinematic()
  void set_kinematic_state(double t);

  /// f_e = applied_force + m_i g for every node (3#V, interleaved, N).
  VecX external_forces(const Vec3& gravity) const;
  /// ½ uᵀ M u (J).
  double kinetic_energy() const;
  /// W(X + d) (J).
  double elastic_energy() const;
  /// −Σ m_i g · x_i (J), zero at the origin.
  double gravity_potential(const Vec3& gravity) const;

 private:
  std::string m_name;
  mesh::VolumeMesh m_mesh;
  Material m_material;
  StvkElasticity m_elasticity;
  VecX m_mass;
  MatX3i m_boundary;
  std::vector<std::uint8_t> m_fixed;
};

}  // namespace tetfsi::solid
