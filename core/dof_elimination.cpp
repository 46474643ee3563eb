#include "core/dof_elimination.hpp"

#include "core/error.hpp"

namespace tetfsi {

void eliminate_dofs(SparseMatrix& A, const std::vector<std::uint8_t>& mask,
                    const std::function<double(Index)>& diag, VecX* b, const VecX* values) {
  const Index n = A.cols();
  TETFSI_CHECK(A.rows() == n && static_cast<Index>(mask.size()) == n && (!b || b->size() == n) &&
                   (!values || values->size() == n),
               "eliminate_dofs: A is {} x {}, mask {}, b {}, values {}", A.rows(), n, mask.size(),
               b ? b->size() : -1, values ? values->size() : -1);
  if (b && values)  // the prescribed columns move to the right-hand side
    for (Index c = 0; c < n; ++c) {
      if (!mask[c]) continue;
      for (SparseMatrix::InnerIterator it(A, c); it; ++it)
        if (!mask[it.row()]) (*b)[it.row()] -= it.value() * (*values)[c];
    }
  for (Index c = 0; c < n; ++c)
    for (SparseMatrix::InnerIterator it(A, c); it; ++it)
      if (mask[it.row()] || mask[c]) it.valueRef() = it.row() == c ? diag(c) : 0.0;
  if (b)
    for (Index i = 0; i < n; ++i)
      if (mask[i]) (*b)[i] = values ? diag(i) * (*values)[i] : 0.0;
}

}  // namespace tetfsi
