/// @file parallel.cpp
/// Thread control and fixed-chunk parallel loops (parallel.hpp) on oneTBB.
#include "core/parallel.hpp"

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <exception>
#include <memory>
#include <mutex>
#include <thread>

#include <fmt/format.h>

#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>
#include <tbb/task_group.h>

#include "core/ranks.hpp"

#include "core/error.hpp"

namespace tetfsi {

namespace {

/// The process's limit: one global_control alive at a time (TBB applies the smallest of
/// those alive, so the previous one is destroyed before the next is made), and an arena of
/// exactly that many threads — so that N threads are N even beyond the cores (the default
/// arena stops at the cores), e.g. 3 on this 2-core machine for the tests of uneven splits.
struct ThreadLimit {
  std::mutex mutex;
  std::unique_ptr<tbb::global_control> control;
  std::unique_ptr<tbb::task_arena> arena;
  std::atomic<int> count{0};  ///< 0: never set
};

ThreadLimit& thread_limit() {
  static ThreadLimit limit;
  return limit;
}

}  // namespace

int default_thread_count() {
  const unsigned n = std::thread::hardware_concurrency();
  const int cores = n == 0 ? 1 : static_cast<int>(n);
  // Replicated ranks share the node's cores; a driver rank 0 has them all (its workers sleep
  // between the solves).
  return std::max(1, cores / (ranks_mode() == RanksMode::Replicated ? ranks_on_this_node() : 1));
}

void set_thread_count(int n) {
  TETFSI_REQUIRE(InputError, n >= 1, "the thread count must be at least 1, got {}", n);
  ThreadLimit& l = thread_limit();
  const std::lock_guard<std::mutex> lock(l.mutex);
  l.arena.reset();
  l.control.reset();
  l.control = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                    static_cast<std::size_t>(n));
  l.arena = std::make_unique<tbb::task_arena>(n);
  l.count = n;
}

int thread_count() {
  const int n = thread_limit().count.load();
  return n > 0 ? n : default_thread_count();
}

int parse_thread_count(const std::string& text, const std::string& source) {
  const bool digits =
      !text.empty() && text.size() <= 7 &&
      std::all_of(text.begin(), text.end(), [](char c) { return c >= '0' && c <= '9'; });
  if (digits && std::stoi(text) >= 1) return std::stoi(text);
  throw InputError(fmt::format("{}: expected an integer >= 1 (threads), got '{}'", source, text));
}

int requested_thread_count(const std::string& option) {
  if (!option.empty()) return parse_thread_count(option, "--threads");
  if (const char* env = std::getenv("TETFSI_THREADS"))
    return parse_thread_count(env, "TETFSI_THREADS");
  return default_thread_count();
}

void parallel_for_chunks(Index n, Index grain, const std::function<void(Index, Index)>& fn) {
  TETFSI_CHECK(grain >= 1, "parallel_for_chunks: grain {} < 1", grain);
  const Index chunks = num_chunks(n, grain);
  auto chunk = [&](Index k) { fn(k * grain, std::min(n, (k + 1) * grain)); };
  if (chunks <= 1 || thread_count() == 1) {
    for (Index k = 0; k < chunks; ++k) chunk(k);
    return;
  }
  auto loop = [&] {
    tbb::parallel_for(
        tbb::blocked_range<Index>(0, chunks, 1),
        [&](const tbb::blocked_range<Index>& r) {
          for (Index k = r.begin(); k != r.end(); ++k) chunk(k);
        },
        tbb::simple_partitioner());
  };
  tbb::task_arena* arena = thread_limit().arena.get();
  if (arena)
    arena->execute(loop);
  else
    loop();
}

namespace {

/// fn(), an exception it throws kept in `error`.
void capture(const std::function<void()>& fn, std::exception_ptr& error) {
  try {
    fn();
  } catch (...) {
    error = std::current_exception();
  }
}

}  // namespace

void run_alongside(const std::function<void()>& main, const std::function<void()>& side) {
  std::exception_ptr main_error, side_error;
  auto both = [&] {
    tbb::task_group group;
    group.run([&] { capture(side, side_error); });
    capture(main, main_error);
    group.wait();
  };
  tbb::task_arena* arena = thread_limit().arena.get();
  if (thread_count() == 1) {
    capture(main, main_error);
    capture(side, side_error);
  } else if (arena) {
    arena->execute(both);
  } else {
    both();
  }
  if (main_error) std::rethrow_exception(main_error);
  if (side_error) std::rethrow_exception(side_error);
}

}  // namespace tetfsi
