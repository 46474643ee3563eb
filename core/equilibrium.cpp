#include "core/equilibrium.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/checkpoint.hpp"
#include "core/error.hpp"
#include "core/linear_solver.hpp"

namespace tetfsi {

IterationMethod parse_iteration_method(const std::string& name) {
  return k_iteration_method_names.parse(name);
}

const char* to_string(IterationMethod m) {
  return k_iteration_method_names.name(m);
}

double rank_one_condition(const VecX& v, const VecX& w) {
  const double s = w.dot(v);
  const double sum = 2.0 + 2.0 * s + v.squaredNorm() * w.squaredNorm();  // σ₁² + σ₂²
  const double prod = (1.0 + s) * (1.0 + s);                             // σ₁² σ₂²
  if (prod == 0.0) return std::numeric_limits<double>::infinity();
  const double disc = std::max(0.0, sum * sum - 4.0 * prod);
  const double big = 0.5 * (sum + std::sqrt(disc));
  const double small = prod / big;
  return std::sqrt(std::max(big, 1.0) / std::min(small, 1.0));
}

VecX BfgsInverse::apply(const VecX& r) const {
  // (K̂⁻¹)⁽ⁱ⁾ r = A⁽ⁱ⁾ᵀ … A⁽¹⁾ᵀ (K̂⁻¹)⁽⁰⁾ A⁽¹⁾ … A⁽ⁱ⁾ r, A = I + v wᵀ  [BatheSonnad80, Eq. (11)]
  VecX s = r;
  for (auto it = m_vw.rbegin(); it != m_vw.rend(); ++it) s += it->first * it->second.dot(s);  // A s
  s = m_h0(s);
  for (const auto& [v, w] : m_vw) s += w * v.dot(s);  // Aᵀ s
  return s;
}

bool BfgsInverse::update(const VecX& delta, const VecX& gamma, const VecX& k_delta,
                         double max_condition) {
  const double dg = delta.dot(gamma), dk = delta.dot(k_delta);
  if (!(dg > 0.0) || !(dk > 0.0)) {
    m_last_condition = std::numeric_limits<double>::infinity();
    return false;
  }
  const double c = std::sqrt(dg / dk);
  VecX v = -c * k_delta - gamma;
  VecX w = delta / dg;
  m_last_condition = rank_one_condition(v, w);
  if (!(m_last_condition <= max_condition)) return false;
  m_vw.emplace_back(std::move(v), std::move(w));
  return true;
}

void BfgsInverse::reset(InverseOperator k0_inverse) {
  m_vw.clear();
  if (k0_inverse) m_h0 = std::move(k0_inverse);
}

LineSearchResult line_search(const std::function<VecX(const VecX&)>& residual, const VecX& x,
                             const VecX& dx, const VecX& g, const EquilibriumOptions& opt) {
  const double phi0 = dx.dot(g);
  const double target = opt.stol * std::abs(phi0);  // [BatheSonnad80, Eq. (10)], |·| both sides
  LineSearchResult best;
  double best_phi = std::numeric_limits<double>::infinity();
  auto at = [&](double beta) {
    VecX xb = x + beta * dx;  // [BatheSonnad80, Eq. (9)]
    VecX gb = residual(xb);
    ++best.evaluations;
    const double phi = gb.allFinite() ? dx.dot(gb) : std::numeric_limits<double>::quiet_NaN();
    if (std::isfinite(phi) && std::abs(phi) < best_phi) {
      best_phi = std::abs(phi);
      best.beta = beta;
      best.x = std::move(xb);
      best.g = std::move(gb);
    }
    return phi;
  };
  auto done = [&] {
    best.satisfied = best_phi <= target;
    return best;
  };
  double b_hi = 1.0, f_hi = at(1.0);
  if (!best.x.size()) {  // non-finite at β = 1: return it as it is, the caller fails
    best.x = x + dx;
    best.g = residual(best.x);
    return best;
  }
  if (std::abs(f_hi) <= target) return done();
  // Same sign as φ₀: the step is too short; extend until the sign changes.
  double b_lo = 0.0, f_lo = phi0;
  while (f_hi > 0.0 && b_hi < opt.max_step && best.evaluations <= opt.max_line_search) {
    b_lo = b_hi;
    f_lo = f_hi;
    b_hi = std::min(2.0 * b_hi, opt.max_step);
    f_hi = at(b_hi);
    if (std::abs(f_hi) <= target) return done();
  }
  if (!(f_hi < 0.0)) return done();  // no sign change (or not finite): the best β so far
  // Regula falsi, Illinois variant, on [b_lo (φ > 0), b_hi (φ < 0)].
  int side = 0;
  while (best.evaluations <= opt.max_line_search) {
    const double b = b_hi - f_hi * (b_hi - b_lo) / (f_hi - f_lo);
    const double f = at(b);
    if (!std::isfinite(f) || std::abs(f) <= target) break;
    if (f > 0.0) {
      b_lo = b;
      f_lo = f;
      if (side == -1) f_hi *= 0.5;
      side = -1;
    } else {
      b_hi = b;
      f_hi = f;
      if (side == 1) f_lo *= 0.5;
      side = 1;
    }
  }
  return done();
}

namespace {

/// @throws InputError unless the options are in their ranges.
void check_options(const EquilibriumOptions& opt) {
  TETFSI_REQUIRE(InputError,
                 opt.rtol > 0 && opt.etol > 0 && opt.stol > 0 && opt.stol < 1 &&
                     opt.max_iterations >= 1 && opt.max_updates >= 1 && opt.max_condition > 1,
                 "equilibrium iteration: need rtol > 0, etol > 0, 0 < stol < 1, max_iterations "
                 ">= 1, max_updates >= 1, max_condition > 1 (got {}, {}, {}, {}, {}, {})",
                 opt.rtol, opt.etol, opt.stol, opt.max_iterations, opt.max_updates,
                 opt.max_condition);
}

/// The iterate after x: x + dx, or with `search` the line search's x + β dx [BatheSonnad80,
/// Eqs. (9), (10)], and its out-of-balance force; the evaluations counted in `rep`.
struct Step {
  VecX x, g;
  double beta = 1.0;
};
Step take_step(const EquilibriumProblem& problem, const VecX& x, const VecX& dx, const VecX& g,
               const EquilibriumOptions& opt, bool search, EquilibriumReport& rep) {
  Step st;
  if (search) {
    LineSearchResult ls = line_search(problem.residual, x, dx, g, opt);
    rep.evaluations += ls.evaluations;
    st.beta = ls.beta;
    st.x = std::move(ls.x);
    st.g = std::move(ls.g);
    if (st.beta != 1.0) ++rep.line_searches;
  } else {
    st.x = x + dx;
    ++rep.evaluations;
    st.g = problem.residual(st.x);
  }
  return st;
}

}  // namespace

EquilibriumReport solve_equilibrium(const EquilibriumProblem& problem, VecX& x,
                                    const EquilibriumOptions& opt, EquilibriumHistory& history) {
  check_options(opt);
  EquilibriumReport rep;
  auto evaluate = [&](const VecX& y) {
    ++rep.evaluations;
    return problem.residual(y);
  };
  auto factor = [&](const VecX& y) {
    ++rep.factorizations;
    return problem.factor(y);
  };
  VecX g = evaluate(x);
  if (!g.allFinite()) {
    rep.failure = "the out-of-balance force is not finite at the start";
    return rep;
  }
  history.max_force = std::max(history.max_force, g.norm());
  if (history.max_force == 0.0) {  // nothing to balance
    rep.converged = true;
    return rep;
  }
  const bool newton = opt.method == IterationMethod::Newton;
  const bool bfgs = opt.method == IterationMethod::Bfgs;
  InverseOperator start;
  if (!newton && opt.keep_matrix && history.kept) {
    start = history.kept.inverse;
  } else {
    FactoredMatrix k = factor(x);
    start = k.inverse;
    if (!newton && opt.keep_matrix) history.kept = std::move(k);
  }
  BfgsInverse H(start);
  const bool carry = bfgs && opt.keep_matrix;  // updates carried from solve to solve
  if (carry && !history.updates.empty() && history.updates.front().first.size() == x.size())
    H.set_factors(history.updates);
  history.updates.clear();  // set again on convergence
  // Re-form the matrix at y and drop the updates; with keep_matrix it is the one kept.
  auto reform = [&](const VecX& y) {
    FactoredMatrix k = factor(y);
    H.reset(k.inverse);
    if (!newton && opt.keep_matrix) history.kept = std::move(k);
  };
  double e1 = 0.0;
  for (int i = 1; i <= opt.max_iterations; ++i) {
    rep.iterations = i;
    if ((newton && i > 1) || (bfgs && H.updates() >= opt.max_updates)) reform(x);
    VecX dx = H.apply(g);  // Δx⁽ⁱ⁾ = (K̂⁻¹)⁽ⁱ⁻¹⁾ g⁽ⁱ⁻¹⁾  [BatheSonnad80, Eq. (8)]
    double phi0 = dx.dot(g);
    if (bfgs && H.updates() > 0 && !(phi0 > 0.0)) {
      // The updated matrix lost positive definiteness along g: start again from the tangent.
      reform(x);
      dx = H.apply(g);
      phi0 = dx.dot(g);
    }
    if (!dx.allFinite()) {
      rep.failure = fmt::format("the increment of iteration {} is not finite (singular matrix)", i);
      return rep;
    }
    if (i == 1) e1 = std::abs(phi0);
    rep.force_ratio = g.norm() / history.max_force;
    rep.energy_ratio = e1 > 0.0 ? std::abs(phi0) / e1 : 0.0;
    // [BatheSonnad80, Eqs. (12), (13)] on g⁽ⁱ⁻¹⁾ and Δx⁽ⁱ⁾: x⁽ⁱ⁻¹⁾ is the solution.
    if (i > 1 && rep.force_ratio <= opt.rtol && rep.energy_ratio <= opt.etol) {
      rep.converged = true;
      if (carry) history.updates = H.factors();
      return rep;
    }
    const bool search = bfgs ? opt.line_search : opt.line_search_newton;
    auto [xn, gn, beta] = take_step(problem, x, dx, g, opt, search && phi0 > 0.0, rep);
    if (!gn.allFinite()) {
      rep.failure = fmt::format("the out-of-balance force became non-finite at iteration {}", i);
      return rep;
    }
    if (bfgs) {  // K̂⁽ⁱ⁻¹⁾ δ = β g⁽ⁱ⁻¹⁾, see [BatheSonnad80, Eq. (11)]
      if (H.update(xn - x, g - gn, beta * g, opt.max_condition))
        ++rep.updates;
      else
        ++rep.skipped_updates;
    }
    x = std::move(xn);
    g = std::move(gn);
    if (g.norm() > 1e12 * history.max_force) {
      rep.force_ratio = g.norm() / history.max_force;
      rep.failure = fmt::format(
          "diverged: the out-of-balance force grew to {:.3g} times the "
          "largest seen, at iteration {}",
          rep.force_ratio, i);
      return rep;
    }
  }
  rep.force_ratio = g.norm() / history.max_force;
  rep.failure = fmt::format(
      "did not converge in {} iterations (force ratio {:.3g}, RTOL {:.3g}; energy ratio {:.3g}, "
      "ETOL {:.3g})",
      opt.max_iterations, rep.force_ratio, opt.rtol, rep.energy_ratio, opt.etol);
  return rep;
}

FactoredMatrix factor_blocks(std::vector<std::shared_ptr<const SparseMatrix>> blocks,
                             std::vector<Index> offsets) {
  TETFSI_CHECK(offsets.size() == blocks.size() + 1, "factor_blocks: {} offsets for {} blocks",
               offsets.size(), blocks.size());
  std::vector<std::shared_ptr<LinearSolver>> solvers(blocks.size());
  for (size_t b = 0; b < blocks.size(); ++b) {
    if (!blocks[b]) continue;
    TETFSI_CHECK(
        blocks[b]->rows() == offsets[b + 1] - offsets[b] && blocks[b]->cols() == blocks[b]->rows(),
        "factor_blocks: block {} is {} x {} for {} unknowns", b, blocks[b]->rows(),
        blocks[b]->cols(), offsets[b + 1] - offsets[b]);
    solvers[b] = factor_symmetric(*blocks[b]);  // refers to *blocks[b], which the operator keeps
  }
  FactoredMatrix f;
  f.inverse = [blocks, solvers, offsets](const VecX& r) -> VecX {
    VecX dx = VecX::Zero(r.size());
    for (size_t b = 0; b < solvers.size(); ++b) {
      if (!solvers[b]) continue;
      const Index n = offsets[b + 1] - offsets[b];
      VecX x = VecX::Zero(n);
      solvers[b]->solve(r.segment(offsets[b], n), x);
      dx.segment(offsets[b], n) = x;
    }
    return dx;
  };
  f.blocks = std::move(blocks);
  f.offsets = std::move(offsets);
  return f;
}

void save_history(const EquilibriumHistory& h, CheckpointWriter& w, const std::string& prefix) {
  w.put(prefix + "max_force", h.max_force);
  w.put(prefix + "kept", static_cast<bool>(h.kept));
  if (h.kept) {
    TETFSI_CHECK(!h.kept.blocks.empty(), "save_history: the kept matrix has no blocks to save");
    w.put(prefix + "kept_offsets", h.kept.offsets);
    std::vector<std::uint8_t> present;
    for (size_t b = 0; b < h.kept.blocks.size(); ++b) {
      present.push_back(h.kept.blocks[b] ? 1 : 0);
      if (h.kept.blocks[b]) w.put(fmt::format("{}kept_block/{}", prefix, b), *h.kept.blocks[b]);
    }
    w.put(prefix + "kept_present", present);
  }
  w.put(prefix + "updates", static_cast<std::int64_t>(h.updates.size()));
  for (size_t i = 0; i < h.updates.size(); ++i) {
    w.put(fmt::format("{}update/{}/v", prefix, i), h.updates[i].first);
    w.put(fmt::format("{}update/{}/w", prefix, i), h.updates[i].second);
  }
}

EquilibriumHistory load_history(const CheckpointReader& r, const std::string& prefix) {
  EquilibriumHistory h;
  h.max_force = r.get_double(prefix + "max_force");
  if (r.get_bool(prefix + "kept")) {
    std::vector<Index> offsets = r.get_vector<Index>(prefix + "kept_offsets");
    const std::vector<std::uint8_t> present = r.get_vector<std::uint8_t>(prefix + "kept_present");
    if (offsets.size() != present.size() + 1)
      r.fail(fmt::format("record '{}kept_offsets' has {} entries for {} blocks", prefix,
                         offsets.size(), present.size()));
    std::vector<std::shared_ptr<const SparseMatrix>> blocks(present.size());
    for (size_t b = 0; b < present.size(); ++b) {
      if (!present[b]) continue;
      const std::string key = fmt::format("{}kept_block/{}", prefix, b);
      SparseMatrix a = r.get_sparse(key);
      if (a.rows() != offsets[b + 1] - offsets[b] || a.cols() != a.rows())
        r.fail(fmt::format("record '{}' is {} x {} for {} unknowns", key, a.rows(), a.cols(),
                           offsets[b + 1] - offsets[b]));
      blocks[b] = std::make_shared<const SparseMatrix>(std::move(a));
    }
    h.kept = factor_blocks(std::move(blocks), std::move(offsets));
  }
  const std::size_t n = r.get_count(prefix + "updates");
  for (std::size_t i = 0; i < n; ++i)
    h.updates.emplace_back(r.get<VecX>(fmt::format("{}update/{}/v", prefix, i)),
                           r.get<VecX>(fmt::format("{}update/{}/w", prefix, i)));
  return h;
}

}  // namespace tetfsi
