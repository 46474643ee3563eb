#include "solid/solid_body.hpp"

#include <algorithm>
#include <utility>

#include "core/error.hpp"

namespace tetfsi::solid {

namespace {

/// Validate before any member that depends on the mesh or material is built.
mesh::VolumeMesh validated_mesh(mesh::VolumeMesh m, const std::string& name) {
  mesh::validate_volume_mesh(m, name);
  return m;
}

const Material& validated_material(const Material& m, const std::string& name) {
  validate_material(m, name + ".material");
  return m;
}

}  // namespace

SolidBody::SolidBody(std::string name, mesh::VolumeMesh rest_mesh, const Material& material)
    : m_name(std::move(name)),
      m_mesh(validated_mesh(std::move(rest_mesh), m_name)),
      m_material(validated_material(material, m_name)),
      m_elasticity(m_mesh.vertices, m_mesh.tets, m_material) {
  const Index n = m_mesh.num_vertices();
  // Lumped mass: each tet gives ρ V0 / 4 to each of its nodes [OBrienHodgins99].
  m_mass = VecX::Zero(n);
  const VecX& v0 = m_elasticity.rest_volumes();
  for (Index t = 0; t < m_mesh.num_tets(); ++t)
    for (int a = 0; a < 4; ++a) m_mass[m_mesh.tets(t, a)] += 0.25 * m_material.density * v0[t];
  for (Index i = 0; i < n; ++i)
    TETFSI_REQUIRE(MeshError, m_mass[i] > 0.0,
                   "{}: node {} belongs to no tet (zero mass); remove unused vertices "
                   "(mesh::remove_unused_vertices)",
                   m_name, i);
  m_boundary = mesh::boundary_triangles(m_mesh);
  m_fixed.assign(static_cast<std::size_t>(3 * n), 0);
  displacement = MatX3::Zero(n, 3);
  velocity = MatX3::Zero(n, 3);
  applied_force = MatX3::Zero(n, 3);
}

void SolidBody::fix_dof(Index node, int axis) {
  TETFSI_REQUIRE(InputError, node >= 0 && node < num_nodes() && axis >= 0 && axis < 3,
                 "{}: cannot fix node {} axis {}: need 0 <= node < {} and 0 <= axis < 3", m_name,
                 node, axis, num_nodes());
  m_fixed[static_cast<std::size_t>(3 * node + axis)] = 1;
  velocity(node, axis) = 0.0;
}

void SolidBody::pin_node(Index node) {
  for (int k = 0; k < 3; ++k) fix_dof(node, k);
}

Index SolidBody::num_fixed_dofs() const {
  return static_cast<Index>(std::count(m_fixed.begin(), m_fixed.end(), std::uint8_t{1}));
}

void SolidBody::set_kinematic_state(double t) {
  TETFSI_CHECK(kinematic.has_value(), "{}: set_kinematic_state on a body that is not kinematic",
               m_name);
  displacement = kinematic->position(m_mesh.vertices, t) - m_mesh.vertices;
  velocity = kinematic->velocity(m_mesh.vertices, t);
}

VecX SolidBody::external_forces(const Vec3& gravity) const {
  MatX3 f = applied_force;
  for (Index i = 0; i < num_nodes(); ++i) f.row(i) += m_mass[i] * gravity.transpose();
  return flat(f);
}

double SolidBody::kinetic_energy() const {
  return 0.5 * (m_mass.array() * velocity.rowwise().squaredNorm().array()).sum();
}

double SolidBody::elastic_energy() const {
  return m_elasticity.energy(positions());
}

double SolidBody::gravity_potential(const Vec3& gravity) const {
  return -(m_mass.array() * (positions() * gravity).array()).sum();
}

}  // namespace tetfsi::solid
