#include "solid/stvk.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include "core/error.hpp"
#include "core/parallel.hpp"

namespace tetfsi::solid {

namespace {

/// Deformation gradient, Green strain, 2nd Piola–Kirchhoff and 1st Piola–Kirchhoff stress of
/// one tet [OBrienHodgins99], [Chentanez06, §3.2].
struct TetState {
  Mat3 F;  ///< F = Ds Dm⁻¹
  Mat3 E;  ///< E = ½(FᵀF − I)
  Mat3 S;  ///< S = λ tr(E) I + 2μ E
  Mat3 P;  ///< P = F S
};

inline TetState tet_state(const MatX3& x, const Vec4i& tet, const Mat3& dm_inv,
                          const LameParameters& lame) {
  TetState s;
  const Vec3 x0 = x.row(tet[0]).transpose();
  Mat3 ds;
  for (int c = 0; c < 3; ++c) ds.col(c) = x.row(tet[c + 1]).transpose() - x0;
  s.F = ds * dm_inv;
  s.E = 0.5 * (s.F.transpose() * s.F - Mat3::Identity());
  s.S = lame.lambda * s.E.trace() * Mat3::Identity() + 2.0 * lame.mu * s.E;
  s.P = s.F * s.S;
  return s;
}

/// Shape-function gradients g_a = ∂F/∂x_a acting as dF = δx_a g_aᵀ (columns of a 3 × 4):
/// g_1..3 = rows of Dm⁻¹, g_0 = −(g_1 + g_2 + g_3).
inline Eigen::Matrix<double, 3, 4> shape_gradients(const Mat3& dm_inv) {
  Eigen::Matrix<double, 3, 4> g;
  for (int a = 1; a < 4; ++a) g.col(a) = dm_inv.row(a - 1).transpose();
  g.col(0) = -(g.col(1) + g.col(2) + g.col(3));
  return g;
}

using Mat12 = Eigen::Matrix<double, 12, 12>;
using Mat34 = Eigen::Matrix<double, 3, 4>;

/// Tets per block of local results and per chunk of the parallel loop over a block.
constexpr Index kBlock = 4096, kGrain = 256;

/// compute(t, local) for the tets of each block of kBlock in parallel, each into its own
/// slot, then scatter(t, local) serially in tet order: the sums are the serial loop's, bit for
/// bit, at any thread count.
template <class Local, class Compute, class Scatter>
void compute_then_scatter(Index nt, Compute&& compute, Scatter&& scatter) {
  std::vector<Local> buffer(static_cast<std::size_t>(std::min(nt, kBlock)));
  for (Index b0 = 0; b0 < nt; b0 += kBlock) {
    const Index n = std::min(kBlock, nt - b0);
    parallel_for_each(n, kGrain, [&](Index i) { compute(b0 + i, buffer[i]); });
    for (Index i = 0; i < n; ++i) scatter(b0 + i, buffer[i]);
  }
}

/// Element Jacobian K'_e = ∂²W_e/∂x² (12 × 12, rows/cols 3a + k), from
/// dP = dF S + F dS, dS = λ tr(dE) I + 2μ dE, dE = ½(dFᵀF + FᵀdF), with dF = e_k g_aᵀ.
/// The initial-stress term dF S uses S₊ (the tensile part of S) with Tangent::Definite.
inline Mat12 tet_jacobian(const TetState& s, const Eigen::Matrix<double, 3, 4>& g, double v0,
                          const LameParameters& lame, Tangent tangent) {
  Mat12 K;
  Mat3 S = s.S;
  if (tangent == Tangent::Definite) {
    const Eigen::SelfAdjointEigenSolver<Mat3> eig(s.S);
    if (eig.eigenvalues().minCoeff() < 0.0)
      S = eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).asDiagonal() *
          eig.eigenvectors().transpose();
  }
  for (int a = 0; a < 4; ++a) {
    const Vec3 ga = g.col(a);
    const Vec3 sga = S * ga;
    for (int k = 0; k < 3; ++k) {
      const Vec3 fk = s.F.row(k).transpose();  // Fᵀ e_k
      // dE = ½(g_a (Fᵀe_k)ᵀ + (Fᵀe_k) g_aᵀ)
      const Mat3 dE = 0.5 * (ga * fk.transpose() + fk * ga.transpose());
      const Mat3 dS = lame.lambda * ga.dot(fk) * Mat3::Identity() + 2.0 * lame.mu * dE;
      Mat3 dP = s.F * dS;
      dP.row(k) += sga.transpose();  // dF S = e_k (S g_a)ᵀ
      // Force on node b is V0 P g_b, so column (a, k) of K'_e holds V0 dP g_b.
      const Eigen::Matrix<double, 3, 4> dPg = v0 * dP * g;
      for (int b = 0; b < 4; ++b) K.block<3, 1>(3 * b, 3 * a + k) = dPg.col(b);
    }
  }
  return 0.5 * (K + K.transpose());  // exact symmetry (differences are round-off only)
}

}  // namespace

StvkElasticity::StvkElasticity(const MatX3& rest, const MatX4i& tets, const Material& material)
    : m_num_nodes(static_cast<Index>(rest.rows())),
      m_tets(tets),
      m_lame(lame_parameters(material)) {
  const Index nt = num_tets();
  m_dm_inv.resize(nt);
  m_rest_volume.resize(nt);
  Triplets pattern;
  pattern.reserve(static_cast<std::size_t>(nt) * 144);
  for (Index t = 0; t < nt; ++t) {
    const Vec4i tet = m_tets.row(t).transpose();
    for (int a = 0; a < 4; ++a)
      TETFSI_REQUIRE(MeshError, tet[a] >= 0 && tet[a] < m_num_nodes,
                     "tet {} has vertex index {} out of range [0, {})", t, tet[a], m_num_nodes);
    Mat3 dm;
    for (int c = 0; c < 3; ++c) dm.col(c) = (rest.row(tet[c + 1]) - rest.row(tet[0])).transpose();
    const double v0 = dm.determinant() / 6.0;
    TETFSI_REQUIRE(MeshError, std::isfinite(v0) && v0 > 0.0,
                   "tet {} (vertices {} {} {} {}) has rest volume {:.3g} m^3; need positively "
                   "oriented, non-degenerate tets",
                   t, tet[0], tet[1], tet[2], tet[3], v0);
    m_rest_volume[t] = v0;
    m_dm_inv[t] = dm.inverse();
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b)
        for (int k = 0; k < 3; ++k)
          for (int l = 0; l < 3; ++l) pattern.emplace_back(3 * tet[b] + l, 3 * tet[a] + k, 0.0);
  }
  const Index ndof = 3 * m_num_nodes;
  m_pattern.resize(ndof, ndof);
  m_pattern.setFromTriplets(pattern.begin(), pattern.end());
  m_pattern.makeCompressed();
  // Map each local entry (row 3b+l, col 3a+k) of every tet to its slot in the value array.
  m_slot.resize(static_cast<std::size_t>(nt) * 144);
  const Index* outer = m_pattern.outerIndexPtr();
  const Index* inner = m_pattern.innerIndexPtr();
  for (Index t = 0; t < nt; ++t) {
    for (int j = 0; j < 12; ++j) {
      const Index col = 3 * m_tets(t, j / 3) + j % 3;
      const Index* begin = inner + outer[col];
      const Index* end = inner + outer[col + 1];
      for (int i = 0; i < 12; ++i) {
        const Index row = 3 * m_tets(t, i / 3) + i % 3;
        const Index* it = std::lower_bound(begin, end, row);
        m_slot[static_cast<std::size_t>(t) * 144 + 12 * i + j] = static_cast<Index>(it - inner);
      }
    }
  }
}

double StvkElasticity::energy(const MatX3& x) const {
  TETFSI_CHECK(x.rows() == m_num_nodes, "x has {} rows, expected {}", x.rows(), m_num_nodes);
  double w = 0.0;
  compute_then_scatter<double>(
      num_tets(),
      [&](Index t, double& wt) {
        const TetState s = tet_state(x, m_tets.row(t).transpose(), m_dm_inv[t], m_lame);
        const double tr = s.E.trace();
        // W = V0 (μ E:E + ½ λ (tr E)²)  [OBrienHodgins99]
        wt = m_rest_volume[t] * (m_lame.mu * s.E.squaredNorm() + 0.5 * m_lame.lambda * tr * tr);
      },
      [&](Index, double wt) { w += wt; });
  return w;
}

VecX StvkElasticity::forces(const MatX3& x) const {
  TETFSI_CHECK(x.rows() == m_num_nodes, "x has {} rows, expected {}", x.rows(), m_num_nodes);
  VecX f = VecX::Zero(3 * m_num_nodes);
  compute_then_scatter<Mat34>(
      num_tets(),
      [&](Index t, Mat34& h) {
        const TetState s = tet_state(x, m_tets.row(t).transpose(), m_dm_inv[t], m_lame);
        // K(d) = ∂W/∂x: node a gets V0 P g_a  [Chentanez06, Eq. (3)], [OBrienHodgins99]
        h = m_rest_volume[t] * s.P * shape_gradients(m_dm_inv[t]);
      },
      [&](Index t, const Mat34& h) {
        for (int a = 0; a < 4; ++a) f.segment<3>(3 * m_tets(t, a)) += h.col(a);
      });
  return f;
}

SparseMatrix StvkElasticity::jacobian(const MatX3& x) const {
  VecX f;
  SparseMatrix K;
  forces_and_jacobian(x, f, K);
  return K;
}

void StvkElasticity::forces_and_jacobian(const MatX3& x, VecX& forces,
                                         SparseMatrix& jacobian) const {
  TETFSI_CHECK(x.rows() == m_num_nodes, "x has {} rows, expected {}", x.rows(), m_num_nodes);
  forces.setZero(3 * m_num_nodes);
  jacobian = m_pattern;
  double* values = jacobian.valuePtr();
  std::fill(values, values + jacobian.nonZeros(), 0.0);
  struct Local {
    Mat34 h;   ///< the element's nodal forces
    Mat12 ke;  ///< its Jacobian
  };
  compute_then_scatter<Local>(
      num_tets(),
      [&](Index t, Local& l) {
        const TetState s = tet_state(x, m_tets.row(t).transpose(), m_dm_inv[t], m_lame);
        const Mat34 g = shape_gradients(m_dm_inv[t]);
        const double v0 = m_rest_volume[t];
        l.h = v0 * s.P * g;
        // K' = ∂K/∂d, see [Chentanez06, Eq. (16)]
        l.ke = tet_jacobian(s, g, v0, m_lame, m_tangent);
      },
      [&](Index t, const Local& l) {
        for (int a = 0; a < 4; ++a) forces.segment<3>(3 * m_tets(t, a)) += l.h.col(a);
        const Index* slot = m_slot.data() + static_cast<std::size_t>(t) * 144;
        for (int i = 0; i < 12; ++i)
          for (int j = 0; j < 12; ++j) values[slot[12 * i + j]] += l.ke(i, j);
      });
}

TetFields StvkElasticity::tet_fields(const MatX3& x) const {
  TETFSI_CHECK(x.rows() == m_num_nodes, "x has {} rows, expected {}", x.rows(), m_num_nodes);
  const Index nt = num_tets();
  TetFields out;
  out.green_strain_norm.resize(nt);
  out.von_mises_stress.resize(nt);
  out.volume_ratio.resize(nt);
  parallel_for_each(nt, kGrain, [&](Index t) {
    const TetState s = tet_state(x, m_tets.row(t).transpose(), m_dm_inv[t], m_lame);
    const double J = s.F.determinant();
    out.green_strain_norm[t] = s.E.norm();
    out.volume_ratio[t] = J;
    // Cauchy stress σ = F S Fᵀ / J; von Mises = sqrt(3/2 dev σ : dev σ).
    const Mat3 sigma = s.F * s.S * s.F.transpose() / J;
    const Mat3 dev = sigma - sigma.trace() / 3.0 * Mat3::Identity();
    out.von_mises_stress[t] = std::sqrt(1.5 * dev.squaredNorm());
  });
  return out;
}

}  // namespace tetfsi::solid
