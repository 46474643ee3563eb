#pragma once
/// @file render.hpp
/// `tetfsi render`: headless pictures of a run's frames, drawn by VTK's own OpenGL renderer
/// off screen (through an X display, HeadlessDisplay: Xvfb when DISPLAY is unset).
///
/// A picture shows, in a fixed oblique view of the fluid box (the bodies' box without a
/// fluid), so that the frames of `--all` line up:
///  - the bodies' surfaces, coloured by a body array (default `von_mises_stress`), with a
///    horizontal colour bar at the bottom;
///  - the fluid, by default as
///     - the smoke (a scene that emits smoke): a volume rendering of `smoke_density`, grey to
///       white smoke on a dark background, its opacity rising from 0 to the largest smoke
///       density the scene emits. A tet frame (.vtu) is sampled onto voxels of the scene's
///       fluid.mesh.surface_size (io/export.hpp's voxelize) and smoothed by one voxel; a grid
///       frame's (.vti) cells are the voxels;
///     - a liquid (liquid.pvd): its surface, water blue and semi-opaque, closed along the
///       box's walls (the contour of the grid frame's φ);
///     - otherwise a plane slice coloured by a fluid array (default `pressure`);
///  - on request (`RenderOptions::slice_view` or `slice`, or `color` naming another fluid
///    array than `smoke_density`) the slice instead: a plane (default normal z through the
///    centre of the inflow patches, or the box centre; with a liquid normal y through the box
///    centre) coloured by a fluid array (default `smoke_density` if the scene emits smoke,
///    else `pressure`; a vector array by its magnitude), with a colour bar on the right; tet
///    frames (.vtu) and grid frames (.vti) alike;
///  - the box's outline, the obstacles (planes within the box, boxes), the scene's name, the
///    time and step, and what the fluid shows.
/// Colour ranges are the same for every frame of a run: `smoke_density` (the slice's colours
/// and the volume's opacity) from 0 to the largest smoke density the scene emits; any other
/// array from its 0.5th to 99.5th percentile over the *last* frame (from 0 when it is
/// non-negative there with its 0.5th percentile below a quarter of its 99.5th: stresses,
/// speeds); `RenderOptions::range` overrides.
///
/// VTK stays in render.cpp; this header only has plain types.
#include <array>
#include <filesystem>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/types.hpp"

namespace tetfsi::app {

/// A slice plane normal to a coordinate axis: `axis` (0 x, 1 y, 2 z) = `value` (m).
struct SlicePlane {
  int axis = 2;
  double value = 0.0;
};

/// "z=0.45" (also "x = 1", "Y=0.5") → SlicePlane.
/// @throws InputError naming the text and the expected form.
SlicePlane parse_slice(const std::string& text);

struct RenderOptions {
  std::optional<int> step;          ///< the frame of this step; default: the last frame
  bool all = false;                 ///< every frame (then `output` is a folder)
  std::optional<SlicePlane> slice;  ///< the slice's plane (implies slice_view)
  /// The slice picture instead of the smoke's volume or the liquid's surface alone.
  bool slice_view = false;
  std::string color;                           ///< fluid array of the slice ("": the default); the
                                               ///< bodies' array instead if only they have it
  std::string body_color;                      ///< bodies' array ("": von_mises_stress)
  std::optional<std::array<double, 2>> range;  ///< the slice's colour range or the volume's
                                               ///< opacity range (else fixed per run)
  /// One frame: the PNG (default OUT/pictures/<scene>_<step>.png); `all`: the folder of the
  /// PNGs (default OUT/pictures), named <scene>_<step>.png.
  std::filesystem::path output;
  /// `all` only: also assemble the PNGs into this .mp4 with ffmpeg, if it is installed.
  std::filesystem::path movie;
  int width = 1280, height = 720;  ///< pixels
  double body_opacity = 1.0;       ///< in (0, 1]: < 1 shows the slice through the bodies
  double zoom = 1.0;  ///< in [0.1, 20]: > 1 magnifies the picture's centre (the box fits at 1)
};

/// One picture written.
struct RenderedFrame {
  int step = 0;
  double time = 0.0;  ///< s
  std::filesystem::path png;
  /// World (m, homogeneous) → normalised device coordinates (x, y in [−1, 1], y up) of the
  /// picture: pixel column (x + 1) W / 2, row from the top (1 − y) H / 2 (pixel_of).
  Eigen::Matrix4d world_to_ndc = Eigen::Matrix4d::Identity();
};

struct RenderReport {
  std::string scene_name;
  std::vector<RenderedFrame> frames;  ///< in step order
  int width = 0, height = 0;
  SlicePlane slice;
  bool has_slice = false;   ///< a slice of the fluid was drawn
  bool has_volume = false;  ///< the smoke's volume was drawn (color: smoke_density)
  std::string color;        ///< the slice's or the volume's array ("" without either)
  std::array<double, 2> color_range = {0, 1};
  std::string body_color;  ///< the bodies' array ("" without bodies)
  std::array<double, 2> body_range = {0, 1};
  double seconds = 0.0;         ///< wall time, the display's start-up included
  std::filesystem::path movie;  ///< written .mp4 ("" if none)
  std::string note;             ///< one line for the user (e.g. ffmpeg missing), or ""
};

/// Render frames of the run in `out_dir` (a folder `tetfsi run` wrote: scene.resolved.json
/// and the `.pvd` collections of io/output.hpp).
/// @throws InputError for a missing folder or collection (naming it and what to do), a step
///   that was not written (naming the steps that were), an array that does not exist (listing
///   those that do), a PNG that cannot be written, or no X display (HeadlessDisplay).
RenderReport render_output(const std::filesystem::path& out_dir, const RenderOptions& options);

/// The pixel (column, row from the top) of world point `x` in `frame` of a `width` × `height`
/// picture.
std::array<double, 2> pixel_of(const RenderedFrame& frame, const Vec3& x, int width, int height);

/// `tetfsi render`: render_output, then one line per picture (or a count with `all`), the
/// movie or the note, on `out`. Returns 0.
int render_command(const std::filesystem::path& out_dir, const RenderOptions& options,
                   std::ostream& out);

}  // namespace tetfsi::app
