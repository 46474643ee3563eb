#pragma once
/// @file regions.hpp
/// The pressure regions of a fluid, whatever its discretisation: the fluid cells connected
/// through the faces the pressure couples (a region without a Dirichlet face — Open, or a free
/// surface — has its pressure level fixed by nothing and gets one pin). The flood fill is one
/// algorithm for every discretisation; each says which cells are fluid and which neighbours a
/// cell is joined to (the tet mesh: fluid_regions, tet/operators.hpp; the MAC grid: grid_regions,
/// grid/projection.hpp).
#include <vector>

#include "core/types.hpp"

namespace tetfsi::fluid {

/// Connected fluid regions: region id per cell (−1 for a cell that is not fluid) and whether
/// each region touches an Open face (has a Dirichlet condition).
struct Regions {
  VecXi cell_region;
  std::vector<bool> has_open;
  std::vector<Index> first_cell;  ///< lowest cell index of each region (its pin, if needed)
  Index count() const { return static_cast<Index>(has_open.size()); }
};

/// The regions of `num_cells` cells by flood fill: the fluid cells (`is_fluid(c)`) in order
/// of their lowest cell, each region grown through `for_each_joined(c, visit)`, which calls
/// visit(n) for every fluid cell n joined to c. has_open is left false for the caller to set.
template <class IsFluid, class ForEachJoined>
Regions connected_regions(Index num_cells, IsFluid&& is_fluid, ForEachJoined&& for_each_joined) {
  Regions r;
  r.cell_region = VecXi::Constant(num_cells, -1);
  std::vector<Index> stack;
  for (Index s = 0; s < num_cells; ++s) {
    if (!is_fluid(s) || r.cell_region[s] >= 0) continue;
    const Index id = r.count();
    r.has_open.push_back(false);
    r.first_cell.push_back(s);
    r.cell_region[s] = id;
    stack.assign(1, s);
    while (!stack.empty()) {
      const Index c = stack.back();
      stack.pop_back();
      for_each_joined(c, [&](Index n) {
        if (r.cell_region[n] >= 0) return;
        r.cell_region[n] = id;
        stack.push_back(n);
      });
    }
  }
  return r;
}

}  // namespace tetfsi::fluid
