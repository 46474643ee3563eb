// ThreadSanitizer run of CGAL's parallel Delaunay insertion as tetfsi uses it
// (mesh::Delaunay::build(points, true)): three builds at 2 threads, each compared with the
// sequential build (the same cells; the containers' order differs). Built and run by
// scripts/tsan/run.sh, not by CMake (it needs -fsanitize=thread on these files).
#include <algorithm>
#include <array>
#include <cstdio>
#include <random>
#include <vector>

#include "core/parallel.hpp"
#include "core/ranks.hpp"
#include "mesh/delaunay.hpp"

namespace tetfsi {
// parallel.cpp's link to core/ranks (MPI) is not needed here: one process, no ranks.
RanksMode ranks_mode() {
  return RanksMode::Driver;
}
int ranks_on_this_node() {
  return 1;
}
}  // namespace tetfsi

/// The cells as sorted rows (the containers' order differs between the two builds).
std::vector<std::array<int, 4>> sorted_cells(const tetfsi::MatX4i& t) {
  std::vector<std::array<int, 4>> c(static_cast<size_t>(t.rows()));
  for (int i = 0; i < t.rows(); ++i) c[i] = {t(i, 0), t(i, 1), t(i, 2), t(i, 3)};
  std::sort(c.begin(), c.end());
  return c;
}

int main(int argc, char** argv) {
  using namespace tetfsi;
  const int n = argc > 1 ? std::atoi(argv[1]) : 40000;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Vec3> pts(n);
  for (auto& p : pts) p = Vec3(u(rng), u(rng), u(rng));
  set_thread_count(1);
  mesh::Delaunay seq;
  seq.build(pts, false);
  MatX4i ts, ns;
  seq.extract(ts, ns);
  set_thread_count(2);
  int bad = 0;
  for (int round = 0; round < 3; ++round) {
    mesh::Delaunay par;
    par.build(pts, true);
    MatX4i tp, np;
    par.extract(tp, np);
    bad += sorted_cells(tp) != sorted_cells(ts);
  }
  std::printf("%d points, %ld cells: %d of 3 parallel builds differ from the sequential\n", n,
              static_cast<long>(ts.rows()), bad);
  return bad;
}
