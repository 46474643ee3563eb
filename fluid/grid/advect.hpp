#pragma once
/// @file grid/advect.hpp
/// Semi-Lagrangian advection on the MAC grid [Stam99]: every face centre and cell centre is
/// traced back through the velocity (RK2), the trace stopped just before the first body
/// triangle it would cross and at the box, and the value read there with side-aware
/// trilinear interpolation (only values the end point sees, grid_cell_stencil) — so nothing
/// is read through a thin sheet or into a sealed shell.
#include "core/types.hpp"
#include "fluid/grid/grid.hpp"

namespace tetfsi::fluid {

/// The velocity at x from face velocities u (#F): each component interpolated from its own
/// faces (side-aware; faces with no fluid cell are skipped).
Vec3 grid_velocity_at(const GridCells& gc, const VecX& u, const Vec3& x);

/// The RK2 back-trace x − h u(x − ½ h u(x)), stopped before a body triangle or the box.
/// @param clamped set to true if the trace was stopped
Vec3 grid_trace_back(const GridCells& gc, const VecX& u, const Vec3& x, double h, bool& clamped);

struct GridAdvected {
  VecX u;  ///< #F: the face component at the traced point (Interior and Open faces; 0
           ///< elsewhere — the caller sets prescribed faces)
  Eigen::MatrixXd scalars;  ///< #C × k: each scalar at the traced cell centre
  Index traces_clamped = 0;
};

/// Advect the face velocities and k cell scalars (columns of `scalars`, #C × k) by u over h.
/// `old` is the classification the values live on, `now` the one they are advected onto
/// (the bodies may have moved); cells that are not fluid in `now` get `fill`.
GridAdvected grid_advect(const GridCells& old, const GridCells& now, const VecX& u,
                         const Eigen::MatrixXd& scalars, double h, const Eigen::VectorXd& fill);

}  // namespace tetfsi::fluid
