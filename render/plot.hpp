#pragma once
/// @file plot.hpp
/// `tetfsi plot OUT [-o FILE.png]`: a run's stats.csv as a page of plots over time, drawn by
/// scripts/plot_stats.py with Debian's matplotlib (`/usr/bin/python3`: a python3 found
/// earlier on the PATH may not see Debian's modules). The script is found in the source tree
/// tetfsi was configured from (TETFSI_SOURCE_DIR), or where `TETFSI_PLOT_SCRIPT` points.
#include <filesystem>
#include <iosfwd>

namespace tetfsi::app {

/// The plotting script run by plot_command (exists or not).
std::filesystem::path plot_script_path();

/// Plot `out_dir`/stats.csv into `png` (default `out_dir`/stats.png); prints the script's
/// one-line report (the PNG, its panels and those left out) on `out`. Returns 0.
/// @throws InputError for a missing folder or stats.csv, a missing Python, matplotlib or
///   script (naming what to install), or the script's own one-line error.
int plot_command(const std::filesystem::path& out_dir, std::filesystem::path png,
                 std::ostream& out);

}  // namespace tetfsi::app
