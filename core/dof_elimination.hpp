#pragma once
/// @file dof_elimination.hpp
/// The symmetric elimination of prescribed DOFs from a linear system A x = b: the one site
/// for pins (fixed DOFs) in the solid's trapezoidal systems, the static Newton solve and the
/// coupled solve's floor contacts.
#include <cstdint>
#include <functional>
#include <vector>

#include "core/types.hpp"

namespace tetfsi {

/// Eliminate every DOF i with mask[i] from the symmetric A x = b with the value x_i = v_i:
/// with `b`, the column moves to the right-hand side (b_r −= A_ri v_i for the other rows r,
/// in increasing i, from A's entries before the elimination) and b_i = diag(i) v_i; then every
/// entry in row or column i is zeroed except the diagonal, set to diag(i). A's sparsity
/// pattern must be symmetric and hold its diagonal.
/// @param A n × n, symmetric pattern
/// @param mask per DOF (size n): 1 to eliminate
/// @param diag the diagonal an eliminated DOF keeps (keep the matrix's scale: m/h, mean |K_ii|)
/// @param b n, or null (the matrix only)
/// @param values n prescribed values, or null: 0 (then b is not changed but b_i = 0)
void eliminate_dofs(SparseMatrix& A, const std::vector<std::uint8_t>& mask,
                    const std::function<double(Index)>& diag, VecX* b = nullptr,
                    const VecX* values = nullptr);

}  // namespace tetfsi
