#pragma once
/// @file raster.hpp
/// A small RGB picture drawn pixel by pixel, with a built-in 5 × 8 bitmap font, written as
/// PNG. For charts made without an X server or OpenGL (Debian's VTK renders only through X,
/// docs/dev/architecture.md, measured facts). VTK (vtkPNGWriter) stays inside raster.cpp.
///
/// Coordinates are pixels, x to the right and y *down*, (0, 0) the top-left pixel. Every
/// drawing call clips to the picture.
#include <cstdint>
#include <filesystem>
#include <string_view>
#include <vector>

namespace tetfsi::app {

/// An 8-bit sRGB colour.
struct Rgb {
  std::uint8_t r = 0, g = 0, b = 0;
  bool operator==(const Rgb&) const = default;
};

/// Horizontal placement of text relative to the given x.
enum class Align { Left, Center, Right };

class Image {
 public:
  /// A width × height picture (px) filled with `background`.
  /// @throws InternalError if a size is < 1
  Image(int width, int height, Rgb background);

  int width() const { return m_width; }
  int height() const { return m_height; }
  /// The colour at (x, y); both must be inside the picture.
  Rgb pixel(int x, int y) const;
  /// Row-major RGB bytes, top row first (width × height × 3).
  const std::vector<std::uint8_t>& rgb() const { return m_rgb; }

  void set(int x, int y, Rgb c);
  /// Fill [x0, x1) × [y0, y1).
  void fill_rect(int x0, int y0, int x1, int y1, Rgb c);
  /// The outline of [x0, x1) × [y0, y1), `thickness` px inwards.
  void frame_rect(int x0, int y0, int x1, int y1, Rgb c, int thickness = 1);
  /// Pixels x0..x1 (inclusive) of row y; with dash > 0, dash px on, dash px off.
  void hline(int x0, int x1, int y, Rgb c, int dash = 0);
  /// Pixels y0..y1 (inclusive) of column x; with dash > 0, dash px on, dash px off.
  void vline(int x, int y0, int y1, Rgb c, int dash = 0);

  /// Draw `s` (printable ASCII; other bytes show as '?') with each font pixel a
  /// scale × scale block. y is the top of the text (cap height 7·scale px, descenders to
  /// 8·scale); x is its left end, centre or right end as `align` says.
  void text(int x, int y, std::string_view s, int scale, Rgb c, Align align = Align::Left);
  /// Like text(), turned 90° counter-clockwise (reads bottom to top, for a y-axis label).
  /// x is the left side of the turned text (the tops of its letters); `align` follows the
  /// reading direction: Left puts the start of the text at y (its lower end), Center its
  /// centre, Right its end (upper end).
  void text_up(int x, int y, std::string_view s, int scale, Rgb c, Align align = Align::Left);

  /// Width of `s` drawn at `scale` (px): 6·scale per character less the last gap.
  static int text_width(std::string_view s, int scale);
  /// Height of a line of text at `scale` (px), descenders included: 8·scale.
  static int text_height(int scale) { return 8 * scale; }

 private:
  int m_width, m_height;
  std::vector<std::uint8_t> m_rgb;
};

/// Write `image` as an 8-bit RGB PNG, to `<path>.tmp` then renamed over `path`.
/// @throws InputError naming the file if it cannot be written.
void write_png(const std::filesystem::path& path, const Image& image);

}  // namespace tetfsi::app
