#include "solid/contact.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

#include <Eigen/Eigenvalues>

#include "core/error.hpp"
#include "core/log.hpp"
#include "solid/contact_geometry.hpp"

namespace tetfsi::solid {

namespace {

/// A body's own primitives are neighbours through the material (not a contact) if they lie
/// closer than this many times its thinnest extent in the rest shape (and closer than d̂).
constexpr double k_self_reach = 1.5;
/// Releases of one pair per step (as the floors' k_releases).
constexpr int k_releases = 2;
/// A pair is released when it pulls by more than this fraction of the set's largest force.
constexpr double k_adhesion_tol = 1e-3;
/// Solves within which the friction viscosities are iterated to 1 %.
constexpr int k_friction_rounds = 4;
/// IPC's friction smoothing velocity ε (m/s) [Li20, Eq. (14)].
constexpr double k_eps_v = 1e-3;
/// An edge pair whose closest point is within this fraction of an edge's end is left to the
/// point–triangle pairs.
constexpr double k_end_fraction = 1e-6;
/// Solves of a step in which adhesive pairs are released; later solves only add (the set is
/// then monotone and settles; a pair added late holds at most until the step ends).
constexpr int k_release_rounds = 3;
/// The continuous detection reports a path that comes within this fraction of d̂.
constexpr double k_ccd_fraction = 0.1;
/// measure(): distances are looked for up to this many d̂.
constexpr double k_measure_reach = 4.0;
/// A resting pair of the set whose gap after a solve is below −this × d̂ gets its
/// augmented-Lagrangian offset raised by what it lacks, and the step solves again: a stiff or
/// heavy body presses harder than the penalty alone holds (λ/k deep: bar_fold's tips closed
/// to 0.024 d̂ without it).
constexpr double k_violation = 0.05;

/// The smallest extent of a body's rest shape along its principal axes (m): a sheet's
/// thickness whatever its orientation.
double thinnest(const SolidBody& b) {
  const MatX3& X = b.rest_positions();
  const Eigen::RowVector3d c = X.colwise().mean();
  const MatX3 Y = X.rowwise() - c;
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(Y.transpose() * Y);
  const MatX3 P = Y * eig.eigenvectors();
  return (P.colwise().maxCoeff() - P.colwise().minCoeff()).minCoeff();
}

Vec3 row(const MatX3& x, Index i) {
  return x.row(i).transpose();
}

/// f₁(y)/y of [Li20, Eq. (14)]: 2/ε − y/ε² below ε, 1/y above.
double f1_over_y(double y) {
  return y < k_eps_v ? 2.0 / k_eps_v - y / (k_eps_v * k_eps_v) : 1.0 / y;
}

}  // namespace

void validate(const ContactParams& p, const std::vector<SolidBody>& bodies,
              const std::string& where) {
  TETFSI_REQUIRE(InputError, std::isfinite(p.gap) && p.gap > 0.0,
                 "{}: contact.gap {} must be > 0 (m): the distance surfaces keep apart", where,
                 p.gap);
  for (const SolidBody& b : bodies) {
    const double t = thinnest(b);
    TETFSI_REQUIRE(InputError, p.gap < t,
                   "{}: contact.gap {} m is not smaller than body '{}' ({} m thin): give a gap "
                   "below its thinnest side",
                   where, p.gap, b.name(), t);
  }
  TETFSI_REQUIRE(InputError, std::isfinite(p.friction) && p.friction >= 0.0,
                 "{}: contact.friction {} must be >= 0 (Coulomb's coefficient)", where, p.friction);
  TETFSI_REQUIRE(InputError,
                 std::isfinite(p.restitution) && p.restitution >= 0.0 && p.restitution <= 1.0,
                 "{}: contact.restitution {} must be in [0, 1]", where, p.restitution);
  TETFSI_REQUIRE(InputError, std::isfinite(p.stiffness) && p.stiffness >= 10.0,
                 "{}: contact.stiffness {} must be >= 10 (the penalty relative to the pair's "
                 "inertia; 1e4 by default)",
                 where, p.stiffness);
}

double median_surface_edge(const std::vector<SolidBody>& bodies) {
  std::vector<double> len;
  for (const SolidBody& b : bodies) {
    const MatX3i& T = b.boundary_triangles();
    const MatX3& X = b.rest_positions();
    for (Index t = 0; t < T.rows(); ++t)
      for (int k = 0; k < 3; ++k)
        len.push_back((row(X, T(t, k)) - row(X, T(t, (k + 1) % 3))).norm());
  }
  if (len.empty()) return 0.0;
  std::nth_element(len.begin(), len.begin() + len.size() / 2, len.end());
  return len[len.size() / 2];
}

double default_contact_gap(const std::vector<SolidBody>& bodies, double size) {
  double g = 0.2 * size;
  for (const SolidBody& b : bodies) g = std::min(g, thinnest(b) / 3.0);
  return g;
}

// ---------------------------------------------------------------------------------------
// Surfaces and candidates
// ---------------------------------------------------------------------------------------

struct BodyContacts::Surface {
  std::vector<Index> points;                ///< surface nodes
  std::vector<std::array<Index, 2>> edges;  ///< unique surface edges
  MatX3i tris;
  bool free = false;               ///< deformable (its velocities are unknowns)
  std::vector<std::uint8_t> held;  ///< per node: every DOF fixed
};

BodyContacts::~BodyContacts() = default;

BodyContacts::BodyContacts(const std::vector<SolidBody>& bodies, const ContactParams& params,
                           const Vec3& gravity, double h)
    : m_bodies(bodies), m_params(params), m_h(h) {
  m_surf.resize(bodies.size());
  std::vector<MatX3> pred(bodies.size());
  for (size_t b = 0; b < bodies.size(); ++b) {
    const SolidBody& body = bodies[b];
    Surface& s = m_surf[b];
    s.tris = body.boundary_triangles();
    s.free = !body.is_kinematic();
    s.held.assign(body.num_nodes(), 0);
    for (Index i = 0; i < body.num_nodes(); ++i)
      s.held[i] =
          !s.free || (body.is_fixed(3 * i) && body.is_fixed(3 * i + 1) && body.is_fixed(3 * i + 2));
    std::set<std::array<Index, 2>> edges;
    std::set<Index> points;
    for (Index t = 0; t < s.tris.rows(); ++t)
      for (int k = 0; k < 3; ++k) {
        const Index a = s.tris(t, k), c = s.tris(t, (k + 1) % 3);
        edges.insert({std::min(a, c), std::max(a, c)});
        points.insert(a);
      }
    s.edges.assign(edges.begin(), edges.end());
    s.points.assign(points.begin(), points.end());
    // a body's own primitives closer than this at rest are neighbours through the material
    // (a sheet's two faces), not a contact
    const double thin = thinnest(body);
    m_self_reach.push_back(std::max(m_params.gap, k_self_reach * thin));
    // a point this far behind one of the body's faces at the start of a step is inside it
    // through that face (half the body's thickness: nearer that face than the opposite one)
    m_depth.push_back(0.5 * thin);
    m_x0.push_back(body.positions());
    m_u0.push_back(body.velocity);
    pred[b] = m_x0[b] + h * m_u0[b];
    if (!s.free) continue;
    for (Index i = 0; i < body.num_nodes(); ++i)
      for (int a = 0; a < 3; ++a)
        if (body.is_fixed(3 * i + a))
          pred[b](i, a) = m_x0[b](i, a);
        else
          pred[b](i, a) += 0.5 * h * h * gravity[a];
  }
  add_violated(pred);
}

void BodyContacts::candidates(const std::vector<MatX3>& x0, const std::vector<MatX3>& x1,
                              double pad, const Visit& visit) const {
  const Index nb = static_cast<Index>(m_surf.size());
  std::vector<BoxTree> pts(nb), edg(nb), tri(nb);
  auto box = [&](Index b, std::initializer_list<Index> nodes) {
    Box bx{row(x0[b], *nodes.begin()), row(x0[b], *nodes.begin())};
    for (Index i : nodes) {
      bx.extend(row(x0[b], i));
      bx.extend(row(x1[b], i));
    }
    bx.inflate(pad);
    return bx;
  };
  for (Index b = 0; b < nb; ++b) {
    const Surface& s = m_surf[b];
    std::vector<Box> bp, be, bt;
    for (Index p : s.points) bp.push_back(box(b, {p}));
    for (const auto& e : s.edges) be.push_back(box(b, {e[0], e[1]}));
    for (Index t = 0; t < s.tris.rows(); ++t)
      bt.push_back(box(b, {s.tris(t, 0), s.tris(t, 1), s.tris(t, 2)}));
    pts[b].build(bp);
    edg[b].build(be);
    tri[b].build(bt);
  }
  std::vector<std::pair<Index, Index>> found;
  for (Index a = 0; a < nb; ++a)
    for (Index b = 0; b < nb; ++b) {
      if (a == b && !m_params.self) continue;
      if (!m_surf[a].free && !m_surf[b].free) continue;
      found.clear();
      pts[a].pairs(tri[b], found);
      for (const auto& [p, t] : found) visit(false, a, m_surf[a].points[p], b, t);
      if (b < a) continue;
      found.clear();
      if (a == b)
        edg[a].self_pairs(found);
      else
        edg[a].pairs(edg[b], found);
      for (const auto& [e, f] : found) visit(true, a, e, b, f);
    }
}

bool BodyContacts::excluded(bool ee, Index ba, Index pa, Index bb, Index pb) const {
  if (ba != bb) return false;
  const Surface& s = m_surf[ba];
  const MatX3& X = m_bodies[ba].rest_positions();
  if (ee) {
    const auto &e = s.edges[pa], &f = s.edges[pb];
    if (e[0] == f[0] || e[0] == f[1] || e[1] == f[0] || e[1] == f[1]) return true;
    return edge_edge(row(X, e[0]), row(X, e[1]), row(X, f[0]), row(X, f[1])).distance <
           m_self_reach[ba];
  }
  for (int k = 0; k < 3; ++k)
    if (s.tris(pb, k) == pa) return true;
  return point_triangle(row(X, pa), row(X, s.tris(pb, 0)), row(X, s.tris(pb, 1)),
                        row(X, s.tris(pb, 2)))
             .distance < m_self_reach[ba];
}

// ---------------------------------------------------------------------------------------
// One pair
// ---------------------------------------------------------------------------------------

namespace {

/// A pair's four nodes (body, node) in the order of its weights.
struct Stencil {
  std::array<Index, 4> body{}, node{};
};

Stencil stencil(bool ee, Index ba, Index pa, Index bb, Index pb, const MatX3i& tris_b,
                const std::vector<std::array<Index, 2>>& edges_a,
                const std::vector<std::array<Index, 2>>& edges_b) {
  Stencil s;
  s.body = {ba, ee ? ba : bb, bb, bb};
  if (ee)
    s.node = {edges_a[pa][0], edges_a[pa][1], edges_b[pb][0], edges_b[pb][1]};
  else
    s.node = {pa, tris_b(pb, 0), tris_b(pb, 1), tris_b(pb, 2)};
  return s;
}

/// Weights c and the (unoriented) direction between the closest points at positions p[0..3]:
/// returns the distance.
double closest(bool ee, const std::array<Vec3, 4>& p, std::array<double, 4>& c, Vec3& dir) {
  if (ee) {
    const EdgeEdge r = edge_edge(p[0], p[1], p[2], p[3]);
    c = {1.0 - r.s, r.s, -(1.0 - r.t), -r.t};
    dir = (p[0] + r.s * (p[1] - p[0])) - (p[2] + r.t * (p[3] - p[2]));
    if (dir.norm() <= 1e-12 * (p[1] - p[0]).norm()) dir = (p[1] - p[0]).cross(p[3] - p[2]);
    return r.distance;
  }
  const PointTriangle r = point_triangle(p[0], p[1], p[2], p[3]);
  c = {1.0, -r.w[0], -r.w[1], -r.w[2]};
  dir = p[0] - r.closest;
  if (dir.norm() <= 1e-12 * (p[2] - p[1]).norm()) dir = (p[2] - p[1]).cross(p[3] - p[1]);
  return r.distance;
}

/// The nodes a constraint acts on (weight ≠ 0), sorted: two pairs with the same nodes are
/// the same contact (a point whose closest point is on a triangle's edge or vertex, found from
/// every triangle there and from the edges).
std::vector<std::array<Index, 2>> signature(const ContactPair& p) {
  std::vector<std::array<Index, 2>> s;
  for (int i = 0; i < p.nodes; ++i)
    if (std::abs(p.c[i]) > 1e-9) s.push_back({p.node_body[i], p.node[i]});
  std::sort(s.begin(), s.end());
  return s;
}

Vec3 combine(const std::array<double, 4>& c, const std::array<Vec3, 4>& p) {
  return c[0] * p[0] + c[1] * p[1] + c[2] * p[2] + c[3] * p[3];
}

}  // namespace

double BodyContacts::pair_distance(bool ee, Index ba, Index pa, Index bb, Index pb,
                                   const std::vector<MatX3>& x) const {
  const Stencil st =
      stencil(ee, ba, pa, bb, pb, m_surf[bb].tris, m_surf[ba].edges, m_surf[bb].edges);
  std::array<Vec3, 4> p;
  for (int i = 0; i < 4; ++i) p[i] = row(x[st.body[i]], st.node[i]);
  std::array<double, 4> c;
  Vec3 dir;
  return closest(ee, p, c, dir);
}

bool BodyContacts::try_pair(bool ee, Index ba, Index pa, Index bb, Index pb,
                            const std::vector<MatX3>& x1, ContactPair& cp, double& g1) const {
  const Stencil st =
      stencil(ee, ba, pa, bb, pb, m_surf[bb].tris, m_surf[ba].edges, m_surf[bb].edges);
  bool any_free = false;
  for (int i = 0; i < 4; ++i) any_free |= !m_surf[st.body[i]].held[st.node[i]];
  if (!any_free) return false;
  std::array<Vec3, 4> p0, p1;
  for (int i = 0; i < 4; ++i) {
    p0[i] = row(m_x0[st.body[i]], st.node[i]);
    p1[i] = row(x1[st.body[i]], st.node[i]);
  }
  cp = ContactPair{};
  if (!ee && inside_at_start(bb, p0)) {
    // The step began with the point just inside the other body (the last step's penalty
    // left it there): push it out through the triangle it is under, along the triangle's
    // outward normal, whatever its path does.
    Vec3 dir;
    closest(false, p1, cp.c, dir);
    cp.n = (p1[2] - p1[1]).cross(p1[3] - p1[1]).normalized();
    cp.crossed = true;
    return fill_pair(ee, {ba, bb}, {pa, pb}, st.node, st.body, p0, p1, cp, g1);
  }
  Vec3 dir;
  const double d1 = closest(ee, p1, cp.c, dir);
  // an edge pair whose closest point is an end is a point's contact (point–triangle)
  if (ee && (std::min({cp.c[0], cp.c[1], -cp.c[2], -cp.c[3]}) <= k_end_fraction)) return false;
  // Did the path come close (within a tenth of d̂: a crossing passes there)? Then the
  // constraint is taken where it did, before any crossing: its normal points to the side
  // the pair came from [Bridson02].
  const double tol = k_ccd_fraction * m_params.gap;
  const double t =
      ee ? ccd_edge_edge(p0[0], p0[1], p0[2], p0[3], p1[0], p1[1], p1[2], p1[3], tol)
         : ccd_point_triangle(p0[0], p0[1], p0[2], p0[3], p1[0], p1[1], p1[2], p1[3], tol);
  if (d1 >= m_params.gap && t < 0.0) return false;
  std::array<Vec3, 4> at = p1;  // where the constraint is taken
  if (t >= 0.0) {
    for (int i = 0; i < 4; ++i) at[i] = p0[i] + t * (p1[i] - p0[i]);
    closest(ee, at, cp.c, dir);
    if (ee && (std::min({cp.c[0], cp.c[1], -cp.c[2], -cp.c[3]}) <= k_end_fraction)) return false;
  }
  if (!(dir.norm() > 0.0)) return false;  // degenerate primitives
  cp.n = dir.normalized();
  // A point meets a triangle from outside its body (boundary triangles face outwards): a
  // touch from behind is the point leaving the other body through its far side on a path
  // that went through it (a long predicted step), not a contact.
  if (!ee && cp.n.dot((at[2] - at[1]).cross(at[3] - at[1])) < 0.0) return false;
  cp.crossed = t >= 0.0 && cp.n.dot(combine(cp.c, p1)) < 0.0;
  return fill_pair(ee, {ba, bb}, {pa, pb}, st.node, st.body, p0, p1, cp, g1);
}

bool BodyContacts::inside_at_start(Index bb, const std::array<Vec3, 4>& p0) const {
  const Vec3 n = (p0[2] - p0[1]).cross(p0[3] - p0[1]);
  if (!(n.norm() > 0.0)) return false;
  const double s = n.normalized().dot(p0[0] - p0[1]);  // < 0: behind the outward face
  if (s >= 0.0 || -s >= m_depth[bb]) return false;
  // under the triangle itself (the closest point is the projection), not beside it
  return point_triangle(p0[0], p0[1], p0[2], p0[3]).distance <= -s * (1.0 + 1e-9);
}

bool BodyContacts::fill_pair(bool ee, std::array<Index, 2> body, std::array<Index, 2> prim,
                             const std::array<Index, 4>& node,
                             const std::array<Index, 4>& node_body, const std::array<Vec3, 4>& p0,
                             const std::array<Vec3, 4>& p1, ContactPair& cp, double& g1) const {
  g1 = cp.n.dot(combine(cp.c, p1)) - m_params.gap;
  if (g1 >= 0.0) return false;  // satisfied there
  cp.edge_edge = ee;
  cp.body = body;
  cp.prim = prim;
  cp.nodes = 4;
  cp.node = node;
  cp.node_body = node_body;
  double inv_m = 0.0, g0 = -m_params.gap, approach = 0.0;
  for (int i = 0; i < 4; ++i) {
    const Index b = node_body[i], n = node[i];
    if (!m_surf[b].held[n]) inv_m += cp.c[i] * cp.c[i] / m_bodies[b].lumped_mass()[n];
    g0 += cp.c[i] * cp.n.dot(p0[i] + 0.5 * m_h * row(m_u0[b], n));
    approach -= cp.c[i] * cp.n.dot(row(m_u0[b], n));
  }
  cp.g0 = g0;
  cp.approach = approach;
  cp.k = m_params.stiffness / (inv_m * m_h * m_h);
  return true;
}

bool BodyContacts::add_violated(const std::vector<MatX3>& x1) {
  std::set<std::array<Index, 5>> in;
  std::set<std::vector<std::array<Index, 2>>> same;
  for (const ContactPair& p : m_pairs) {
    in.insert({p.edge_edge, p.body[0], p.prim[0], p.body[1], p.prim[1]});
    same.insert(signature(p));
  }
  // a point's most violated triangle of each body (its others would act on the same point
  // along other normals: redundant constraints that share its load unevenly), every edge pair
  std::map<std::array<Index, 3>, std::pair<double, ContactPair>> point_best;
  std::vector<ContactPair> edges;
  candidates(m_x0, x1, m_params.gap, [&](bool ee, Index ba, Index pa, Index bb, Index pb) {
    if (in.count({ee, ba, pa, bb, pb}) || excluded(ee, ba, pa, bb, pb)) return;
    ContactPair cp;
    double g1 = 0.0;
    if (!try_pair(ee, ba, pa, bb, pb, x1, cp, g1)) return;
    if (ee) {
      edges.push_back(cp);
      return;
    }
    auto [it, fresh] = point_best.try_emplace({ba, pa, bb}, g1, cp);
    if (!fresh && g1 < it->second.first) it->second = {g1, cp};
  });
  const size_t before = m_pairs.size();
  auto add = [&](const ContactPair& cp) {
    // the same contact found through another pair of primitives: one constraint
    if (!same.insert(signature(cp)).second) return;
    if (cp.crossed) ++m_report.crossings;
    m_pairs.push_back(cp);
  };
  for (const auto& [key, best] : point_best) add(best.second);
  // Edge pairs catch edges that meet away from any vertex (two sheets crossed in an X). Where
  // an end of one edge already has a point–triangle constraint against a triangle of the
  // other's end, the two faces are in contact and the edge pair would constrain the same
  // motion along another normal (redundant constraints that share a load unevenly).
  using Node = std::array<Index, 2>;
  std::set<std::pair<Node, Node>> faced;  // (point, a vertex of its triangle)
  for (const ContactPair& p : m_pairs)
    if (!p.edge_edge)
      for (int i = 1; i < 4; ++i)
        faced.insert({{p.node_body[0], p.node[0]}, {p.node_body[i], p.node[i]}});
  for (const ContactPair& cp : edges) {
    bool covered = false;
    for (int i = 0; i < 2; ++i)
      for (int j = 2; j < 4; ++j) {
        const Node a{cp.node_body[i], cp.node[i]}, b{cp.node_body[j], cp.node[j]};
        covered |= faced.count({a, b}) > 0 || faced.count({b, a}) > 0;
      }
    if (!covered) add(cp);
  }
  return m_pairs.size() > before;
}

// ---------------------------------------------------------------------------------------
// The system, the rounds, landing, the measure
// ---------------------------------------------------------------------------------------

ContactSystem BodyContacts::system(const std::vector<BodyDofs>& dofs, Index ns) const {
  ContactSystem cs;
  cs.A.resize(ns, ns);
  cs.b = VecX::Zero(ns);
  Triplets t;
  struct Dof {
    Index at;      // stacked index, −1 if known
    double value;  // known velocity
    double c;      // the node's weight
    int axis;
  };
  for (const ContactPair& p : m_pairs) {
    std::vector<Dof> d;
    for (int i = 0; i < p.nodes; ++i) {
      const BodyDofs& bd = dofs[p.node_body[i]];
      for (int a = 0; a < 3; ++a) {
        const Index j = 3 * p.node[i] + a;
        const bool known = bd.dof0 < 0 || (bd.fixed && (*bd.fixed)[j]);
        d.push_back(
            {known ? -1 : bd.dof0 + j, known && bd.known ? (*bd.known)[j] : 0.0, p.c[i], a});
      }
    }
    // penalty: (h/2) k a aᵀ on the free DOFs, (λ₀ − k (g₀ + (h/2) a_kᵀ u_k)) a on the right
    double gk = p.g0;
    for (const Dof& x : d)
      if (x.at < 0) gk += 0.5 * m_h * x.c * p.n[x.axis] * x.value;
    const Mat3 T = Mat3::Identity() - p.n * p.n.transpose();
    for (const Dof& x : d) {
      if (x.at < 0) continue;
      cs.b[x.at] += (p.lambda0 - p.k * gk) * x.c * p.n[x.axis];
      for (const Dof& y : d) {
        const double fr = p.eta * x.c * y.c * T(x.axis, y.axis);
        if (y.at < 0) {
          cs.b[x.at] -= fr * y.value;
          continue;
        }
        t.emplace_back(x.at, y.at, 0.5 * m_h * p.k * x.c * p.n[x.axis] * y.c * p.n[y.axis] + fr);
      }
    }
  }
  cs.A.setFromTriplets(t.begin(), t.end());
  return cs;
}

std::vector<MatX3> BodyContacts::ends(const std::vector<VecX>& u) const {
  std::vector<MatX3> x1(m_x0.size());
  for (size_t b = 0; b < m_x0.size(); ++b) {
    TETFSI_CHECK(u[b].size() == 3 * m_x0[b].rows(), "BodyContacts: body {} has {} velocities", b,
                 u[b].size());
    x1[b] = m_x0[b];
    for (Index i = 0; i < x1[b].rows(); ++i)
      for (int a = 0; a < 3; ++a) x1[b](i, a) += 0.5 * m_h * (m_u0[b](i, a) + u[b][3 * i + a]);
  }
  return x1;
}

bool BodyContacts::update(const std::vector<VecX>& u) {
  ++m_report.rounds;
  const bool closing = m_report.rounds >= max_rounds - 1;
  bool changed = false;
  std::vector<ContactPair> kept;
  // Adhesion below this is kept (redundant constraints share a load unevenly; releasing
  // their slightly adhesive members only makes the set churn): 1e-3 of the largest force.
  double scale = 0.0;
  for (ContactPair& p : m_pairs) {  // λ = −k g(uⁿ⁺¹)
    double g = p.g0;
    for (int i = 0; i < p.nodes; ++i)
      g += 0.5 * m_h * p.c[i] * p.n.dot(u[p.node_body[i]].segment<3>(3 * p.node[i]));
    p.force = p.lambda0 - p.k * g;
    scale = std::max(scale, p.force);
    // augmented Lagrangian: λ₀ ← max(0, λ₀ − k g) while the gap is off by more than the
    // tolerance (too deep, or pushed open by an offset it no longer needs); not for an impact
    // (closing more than d̂ in the step), which the penalty softens as the bodies would
    const bool resting = p.approach * m_h < m_params.gap;
    if (!closing && ((resting && g < -k_violation * m_params.gap) ||
                     (p.lambda0 > 0.0 && g > k_violation * m_params.gap))) {
      p.lambda0 = std::max(0.0, p.force);
      changed = true;
    }
  }
  const double adhesion_tol = k_adhesion_tol * scale;
  for (ContactPair p : m_pairs) {
    int& rel = m_released[{p.edge_edge, p.body[0], p.prim[0], p.body[1], p.prim[1]}];
    if (p.force < -adhesion_tol && rel < k_releases && m_report.rounds <= k_release_rounds) {
      changed = true;
      if (!closing) {
        ++rel;
        ++m_report.released;
        continue;
      }
    }
    if (m_params.friction > 0.0) {
      Vec3 v = Vec3::Zero();  // the relative velocity
      for (int i = 0; i < p.nodes; ++i) v += p.c[i] * u[p.node_body[i]].segment<3>(3 * p.node[i]);
      const Vec3 vt = v - p.n * p.n.dot(v);
      const double eta = m_params.friction * std::max(0.0, p.force) * f1_over_y(vt.norm());
      if (std::abs(eta - p.eta) > 1e-2 * std::max(eta, p.eta) &&
          m_report.rounds < k_friction_rounds)
        changed = true;
      if (!closing) p.eta = eta;
    }
    kept.push_back(p);
  }
  m_pairs = std::move(kept);
  const size_t before = m_pairs.size();
  const bool added = add_violated(ends(u));
  m_report.added += static_cast<Index>(m_pairs.size() - before);
  m_report.active = static_cast<Index>(m_pairs.size());
  m_report.force = m_report.max_force = 0.0;
  for (const ContactPair& p : m_pairs) {
    m_report.force += std::max(0.0, p.force);
    m_report.max_force = std::max(m_report.max_force, p.force);
  }
  if (!closing) return changed || added;
  if (added && m_report.rounds < max_rounds) return true;
  if (changed || added) {
    m_report.converged = false;
    logger().warn(
        "body contacts did not settle in {} solves ({} released, {} added); the last "
        "set is kept",
        m_report.rounds, m_report.released, m_report.added);
  }
  return false;
}

void BodyContacts::land(std::vector<SolidBody>& bodies) const {
  for (int sweep = 0; sweep < 60; ++sweep)
    for (const ContactPair& p : m_pairs) {
      double v = 0.0, w = 0.0;
      for (int i = 0; i < p.nodes; ++i) {
        const SolidBody& b = bodies[p.node_body[i]];
        v += p.c[i] * p.n.dot(b.velocity.row(p.node[i]).transpose());
        if (!m_surf[p.node_body[i]].held[p.node[i]])
          w += p.c[i] * p.c[i] / b.lumped_mass()[p.node[i]];
      }
      const double target = m_params.restitution * std::max(0.0, p.approach);
      if (v <= target || w <= 0.0) continue;
      const double lambda = (target - v) / w;  // < 0: an impulse that slows the separation
      for (int i = 0; i < p.nodes; ++i) {
        SolidBody& b = bodies[p.node_body[i]];
        const Index n = p.node[i];
        if (m_surf[p.node_body[i]].held[n]) continue;
        for (int a = 0; a < 3; ++a)
          if (!b.is_fixed(3 * n + a))
            b.velocity(n, a) += lambda * p.c[i] / b.lumped_mass()[n] * p.n[a];
      }
    }
}

void BodyContacts::measure(const std::vector<SolidBody>& bodies) {
  std::vector<MatX3> x;
  for (const SolidBody& b : bodies) x.push_back(b.positions());
  const double reach = k_measure_reach * m_params.gap;
  double gap = reach;
  candidates(x, x, 0.5 * reach, [&](bool ee, Index ba, Index pa, Index bb, Index pb) {
    if (excluded(ee, ba, pa, bb, pb)) return;
    const double d = pair_distance(ee, ba, pa, bb, pb, x);
    gap = std::min(gap, d);
  });
  m_report.min_gap = gap;
}

SparseMatrix stack_blocks(const std::vector<SparseMatrix>& A, const std::vector<Index>& dof0) {
  Triplets t;
  for (size_t b = 0; b < A.size(); ++b) {
    if (dof0[b + 1] == dof0[b]) continue;
    for (Index c = 0; c < A[b].outerSize(); ++c)
      for (SparseMatrix::InnerIterator it(A[b], c); it; ++it)
        t.emplace_back(dof0[b] + it.row(), dof0[b] + it.col(), it.value());
  }
  SparseMatrix K(dof0.back(), dof0.back());
  K.setFromTriplets(t.begin(), t.end());
  return K;
}

}  // namespace tetfsi::solid
