#pragma once
/// @file equilibrium.hpp
/// Iterative solution of nonlinear equilibrium equations g(x) = 0 by full Newton, modified
/// Newton or BFGS [BatheSonnad80, Eqs. (8)–(13)], the BFGS inverse in the product form of
/// Matthies & Strang (1979).
///
/// The caller supplies the out-of-balance force g(x) (the seed's R − F − M Ü, zero on fixed
/// DOFs) and a way to factor a coefficient matrix K̂ ≈ −∂g/∂x at a point. Iteration i:
///
///   Δx⁽ⁱ⁾ = (K̂⁻¹)⁽ⁱ⁻¹⁾ g⁽ⁱ⁻¹⁾                                              [Eq. (8)]
///   x⁽ⁱ⁾ = x⁽ⁱ⁻¹⁾ + β Δx⁽ⁱ⁾,  |Δx⁽ⁱ⁾ᵀ g(x⁽ⁱ⁾)| ≤ STOL |Δx⁽ⁱ⁾ᵀ g⁽ⁱ⁻¹⁾|         [Eqs. (9), (10)]
///   (K̂⁻¹)⁽ⁱ⁾ = A⁽ⁱ⁾ᵀ (K̂⁻¹)⁽ⁱ⁻¹⁾ A⁽ⁱ⁾,  A⁽ⁱ⁾ = I + v⁽ⁱ⁾ w⁽ⁱ⁾ᵀ                     [Eq. (11)]
///
/// with, for δ = x⁽ⁱ⁾ − x⁽ⁱ⁻¹⁾ and γ = g⁽ⁱ⁻¹⁾ − g⁽ⁱ⁾ (Matthies & Strang; Bathe, *Finite
/// Element Procedures*, §8.4.2),
///
///   w = δ / (δᵀγ),  v = −c K̂⁽ⁱ⁻¹⁾ δ − γ,  c = (δᵀγ / δᵀ K̂⁽ⁱ⁻¹⁾ δ)^½,  K̂⁽ⁱ⁻¹⁾ δ = β g⁽ⁱ⁻¹⁾,
///
/// so that the updated inverse meets the secant condition (K̂⁻¹)⁽ⁱ⁾ γ = δ and equals the
/// classical BFGS inverse update; it is applied as a product (two rank-one sweeps around one
/// solve with the starting matrix), never formed. An update is skipped when δᵀγ ≤ 0 or when
/// the condition number of A⁽ⁱ⁾ (computed exactly, rank_one_condition) exceeds
/// `max_condition`; after `max_updates` updates the matrix is re-formed at the current point.
///
/// Convergence [Eqs. (12), (13)], checked once Δx⁽ⁱ⁾ is known (i ≥ 2):
///   ||g⁽ⁱ⁻¹⁾||₂ ≤ RTOL · max ||g||₂ (the largest out-of-balance force at the start of any
///   step so far, EquilibriumHistory), and |Δx⁽ⁱ⁾ᵀ g⁽ⁱ⁻¹⁾| ≤ ETOL · |Δx⁽¹⁾ᵀ g⁽⁰⁾|;
/// the solution is then x⁽ⁱ⁻¹⁾ (whose residual was checked) and the step took i iterations:
/// a linear problem with the exact matrix takes 2, as in the seed's Table I.
///
/// The line search belongs to BFGS, as in the seed (Newton and modified Newton are plain
/// iterations unless `line_search_newton`). It uses |·| on both sides of Eq. (10): the literal
/// inequality would accept any overshoot (a large negative Δxᵀg). It tries β = 1, doubles β while
/// Δxᵀg keeps its sign (up to `max_step`), then closes a sign change by regula falsi (Illinois);
/// after `max_line_search` extra evaluations it keeps the best β found.
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/enum_names.hpp"
#include "core/types.hpp"

namespace tetfsi {

enum class IterationMethod {
  Newton,          ///< the tangent matrix re-formed every iteration
  ModifiedNewton,  ///< the starting matrix kept (for the step, or the run)
  Bfgs,            ///< the starting matrix with BFGS updates [BatheSonnad80, Eq. (11)]
};
inline constexpr EnumNames<IterationMethod, 3> k_iteration_method_names{
    "iteration method",
    {{{IterationMethod::Newton, "newton"},
      {IterationMethod::ModifiedNewton, "modified_newton"},
      {IterationMethod::Bfgs, "bfgs"}}}};
/// The coupled iterations' starting matrix (modified Newton and BFGS;
/// coupling/scheme_iterated.cpp).
enum class StartingMatrix {
  Bodies,     ///< [BatheSonnad80, Eq. (15)]: the bodies' own K̂, no fluid
  AddedMass,  ///< plus a lumped (3×3 per node) estimate of the fluid's added mass
  Coupled,    ///< plus the fluid itself: the coupled system on the increment (the whole added mass)
};
inline constexpr EnumNames<StartingMatrix, 3> k_starting_matrix_names{
    "starting matrix",
    {{{StartingMatrix::Bodies, "bodies"},
      {StartingMatrix::AddedMass, "added_mass"},
      {StartingMatrix::Coupled, "coupled"}}}};

/// "newton" | "modified_newton" | "bfgs". @throws InputError naming the value.
IterationMethod parse_iteration_method(const std::string& name);
const char* to_string(IterationMethod m);

/// Applies an approximate inverse of the coefficient matrix: returns Δx = K̂⁻¹ r.
using InverseOperator = std::function<VecX(const VecX&)>;

/// A factored coefficient matrix: its inverse and, when it is block diagonal of sparse
/// symmetric blocks (every matrix the bodies factor), those blocks, so that a checkpoint can
/// re-form the kept starting matrix exactly (factor_blocks of the same blocks).
struct FactoredMatrix {
  FactoredMatrix() = default;
  FactoredMatrix(InverseOperator op) : inverse(std::move(op)) {}  // NOLINT: implicit on purpose
  InverseOperator inverse;
  /// The diagonal blocks (null: that block's unknowns get Δx = 0, e.g. a kinematic body);
  /// empty if the operator is not one of these.
  std::vector<std::shared_ptr<const SparseMatrix>> blocks;
  std::vector<Index> offsets;  ///< first unknown of each block, then the total
  explicit operator bool() const { return static_cast<bool>(inverse); }
};

/// The block-diagonal inverse of `blocks` (each factored by factor_symmetric) at `offsets`
/// (blocks.size() + 1 entries). @throws SolverError if a block cannot be factored.
FactoredMatrix factor_blocks(std::vector<std::shared_ptr<const SparseMatrix>> blocks,
                             std::vector<Index> offsets);

struct EquilibriumOptions {
  IterationMethod method = IterationMethod::Bfgs;
  double rtol = 1e-3;       ///< out-of-balance force tolerance, Eq. (12)
  double etol = 1e-5;       ///< energy tolerance, Eq. (13)
  double stol = 0.5;        ///< line-search tolerance, Eq. (10)
  int max_iterations = 30;  ///< iterations per solve before it is declared failed
  /// The line search of Eqs. (9)–(10) in BFGS (off: β = 1 always).
  bool line_search = true;
  /// Also in Newton and modified Newton (the seed's are plain iterations; a line search keeps
  /// Newton from overshooting far from the solution, e.g. a static solve from d = 0).
  bool line_search_newton = false;
  int max_line_search = 8;     ///< residual evaluations per line search after β = 1
  double max_step = 16.0;      ///< largest β the line search tries
  int max_updates = 20;        ///< BFGS: re-form the matrix after this many updates
  double max_condition = 1e5;  ///< BFGS: skip an update whose A is worse conditioned
  /// Modified Newton and BFGS: form the starting matrix once per run (the first solve's,
  /// kept in EquilibriumHistory) instead of at the start of every solve. BFGS then also
  /// carries its updates from solve to solve (the next step starts with what the last one
  /// learnt, e.g. the fluid's added mass left out of Eq. (15)) until `max_updates`, when the
  /// matrix is re-formed at the current point and the updates dropped.
  bool keep_matrix = false;
  /// Coupled iterations (modified Newton, BFGS): Eq. (15)'s bodies-only matrix, or with the
  /// fluid's added mass in it — lumped, or whole through the coupled system
  /// (coupling/scheme_iterated.cpp): the incompressible analogues of the seed keeping the
  /// fluid's mass in M. `Coupled` is formed on one step's fluid mesh: not with keep_matrix.
  StartingMatrix starting_matrix = StartingMatrix::Bodies;
};

/// cond₂(I + v wᵀ), exactly: its singular values are 1 (n − 2 times) and the two roots of
/// σ⁴ − (2 + 2wᵀv + |v|²|w|²) σ² + (1 + wᵀv)² = 0. Infinite if I + v wᵀ is singular.
double rank_one_condition(const VecX& v, const VecX& w);

/// The product-form BFGS inverse (K̂⁻¹)⁽ᵏ⁾ = A⁽ᵏ⁾ᵀ … A⁽¹⁾ᵀ K̂₀⁻¹ A⁽¹⁾ … A⁽ᵏ⁾.
class BfgsInverse {
 public:
  explicit BfgsInverse(InverseOperator k0_inverse) : m_h0(std::move(k0_inverse)) {}
  /// (K̂⁻¹)⁽ᵏ⁾ r: r ← A⁽ᵏ⁾ … A⁽¹⁾ r, one solve with K̂₀, then the transposes in reverse.
  VecX apply(const VecX& r) const;
  /// The update from δ = x_new − x_old, γ = g_old − g_new and k_delta = K̂⁽ᵏ⁾ δ (β g_old
  /// after a step β Δx from g_old). @return false if skipped (δᵀγ ≤ 0, δᵀK̂δ ≤ 0, or
  /// cond(A) > max_condition); the inverse is then unchanged.
  bool update(const VecX& delta, const VecX& gamma, const VecX& k_delta, double max_condition);
  int updates() const { return static_cast<int>(m_vw.size()); }
  /// cond(A) of the last update tried (made or skipped).
  double last_condition() const { return m_last_condition; }
  /// (v, w) of each update, oldest first.
  const std::vector<std::pair<VecX, VecX>>& factors() const { return m_vw; }
  /// Drop every update; with a new starting inverse if given.
  void reset(InverseOperator k0_inverse = nullptr);
  /// Replace the updates (e.g. by those an earlier solve made on the same starting matrix).
  void set_factors(std::vector<std::pair<VecX, VecX>> vw) { m_vw = std::move(vw); }

 private:
  InverseOperator m_h0;
  std::vector<std::pair<VecX, VecX>> m_vw;
  double m_last_condition = 1.0;
};

/// What the iteration needs from the problem.
struct EquilibriumProblem {
  /// g(x): the out-of-balance force (the seed's R − F − M Ü), zero on fixed DOFs.
  std::function<VecX(const VecX& x)> residual;
  /// A factorization of the coefficient matrix at x (the tangent, or the seed's Eq. (15)).
  std::function<FactoredMatrix(const VecX& x)> factor;
};

/// State kept across the solves of a run.
struct EquilibriumHistory {
  double max_force = 0.0;  ///< the denominator of Eq. (12): largest ||g⁽⁰⁾|| so far
  FactoredMatrix kept;     ///< EquilibriumOptions::keep_matrix: the starting matrix
  std::vector<std::pair<VecX, VecX>> updates;  ///< keep_matrix, BFGS: the updates so far
};

class CheckpointWriter;
class CheckpointReader;
/// The history's records under `prefix` (max_force, the kept matrix's blocks and offsets,
/// the BFGS updates), and back: the kept matrix is re-formed by factor_blocks from the same
/// blocks, so the next solve is the one that would have followed.
/// @throws InternalError (save) if the kept matrix has no blocks; CheckpointError (load).
void save_history(const EquilibriumHistory& h, CheckpointWriter& w, const std::string& prefix);
EquilibriumHistory load_history(const CheckpointReader& r, const std::string& prefix);

struct EquilibriumReport {
  bool converged = false;
  int iterations = 0;         ///< directions Δx computed (the seed's Table I counts these)
  int evaluations = 0;        ///< residual evaluations, the line searches' included
  int factorizations = 0;     ///< coefficient matrices formed and factored
  int updates = 0;            ///< BFGS updates made
  int skipped_updates = 0;    ///< BFGS updates skipped (δᵀγ ≤ 0 or ill-conditioned)
  int line_searches = 0;      ///< iterations that took β ≠ 1
  double force_ratio = 0.0;   ///< ||g||₂ / max ||g⁽⁰⁾||₂ at the end, Eq. (12)
  double energy_ratio = 0.0;  ///< the last |Δxᵀg| / |Δx⁽¹⁾ᵀ g⁽⁰⁾|, Eq. (13)
  std::string failure;        ///< empty if converged, else why not
};

struct LineSearchResult {
  double beta = 1.0;
  VecX x, g;  ///< x + β Δx and its residual
  int evaluations = 0;
  bool satisfied = false;  ///< |Δxᵀ g| ≤ STOL |Δxᵀ g₀| at β
};

/// The line search of [BatheSonnad80, Eqs. (9), (10)] along dx from x (residual g there),
/// see the file comment. @pre dxᵀ g > 0
LineSearchResult line_search(const std::function<VecX(const VecX&)>& residual, const VecX& x,
                             const VecX& dx, const VecX& g, const EquilibriumOptions& opt);

/// Iterate from x (updated in place) until Eqs. (12) and (13) hold or `max_iterations`
/// pass. Never throws for non-convergence (the report says why); exceptions of the
/// problem's callbacks pass through.
EquilibriumReport solve_equilibrium(const EquilibriumProblem& problem, VecX& x,
                                    const EquilibriumOptions& opt, EquilibriumHistory& history);

}  // namespace tetfsi
