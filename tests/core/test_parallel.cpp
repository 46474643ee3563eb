// Tests of core/parallel.hpp / core/parallel.cpp: the thread count, its parsing, and loops
// whose chunks (and so their results) do not depend on it.
#include <doctest/doctest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "core/error.hpp"
#include "core/parallel.hpp"
#include "tests/test_util.hpp"

using namespace tetfsi;

namespace {

/// Restores the thread count in force at construction.
struct ThreadCountGuard {
  int saved = thread_count();
  ~ThreadCountGuard() { set_thread_count(saved); }
};

/// The chunks parallel_for_chunks hands out for (n, grain), sorted.
std::vector<std::pair<Index, Index>> chunks_of(Index n, Index grain) {
  std::mutex m;
  std::vector<std::pair<Index, Index>> c;
  parallel_for_chunks(n, grain, [&](Index b, Index e) {
    const std::lock_guard<std::mutex> lock(m);
    c.emplace_back(b, e);
  });
  std::sort(c.begin(), c.end());
  return c;
}

/// Σ sin(i) for i < n as per-chunk partial sums reduced in chunk order.
double chunked_sum(Index n, Index grain) {
  std::vector<double> partial(static_cast<size_t>(num_chunks(n, grain)), 0.0);
  parallel_for_chunks(n, grain, [&](Index b, Index e) {
    double s = 0.0;
    for (Index i = b; i < e; ++i) s += std::sin(static_cast<double>(i));
    partial[b / grain] = s;
  });
  double sum = 0.0;
  for (const double p : partial) sum += p;
  return sum;
}

}  // namespace

TEST_SUITE("unit") {
  TEST_CASE("parse_thread_count: an integer >= 1 - else one line naming the source") {
    CHECK(parse_thread_count("1", "--threads") == 1);
    CHECK(parse_thread_count("12", "TETFSI_THREADS") == 12);
    for (const char* bad : {"0", "-2", "abc", "2x", "", "1.5", " 2"}) {
      CAPTURE(bad);
      const std::string m =
          test::message_of<InputError>([&] { parse_thread_count(bad, "TETFSI_THREADS"); });
      CHECK(m == fmt::format("TETFSI_THREADS: expected an integer >= 1 (threads), got '{}'", bad));
    }
    CHECK_THROWS_AS(set_thread_count(0), InputError);
    CHECK(default_thread_count() >= 1);
  }

  TEST_CASE("set_thread_count: thread_count reports it - loops use at most that many threads") {
    const ThreadCountGuard guard;
    for (const int n : {1, 2, 3}) {
      CAPTURE(n);
      set_thread_count(n);
      CHECK(thread_count() == n);
      std::mutex m;
      std::set<std::thread::id> ids;
      parallel_for_each(4000, 10, [&](Index) {
        volatile double x = 0;
        for (int k = 0; k < 2000; ++k) x = x + std::sqrt(static_cast<double>(k));
        const std::lock_guard<std::mutex> lock(m);
        ids.insert(std::this_thread::get_id());
      });
      CHECK(ids.size() >= 1);
      CHECK(static_cast<int>(ids.size()) <= n);
      if (n == 1) CHECK(*ids.begin() == std::this_thread::get_id());
    }
  }

  TEST_CASE("parallel_for_chunks: the chunks depend on n and the grain only") {
    const ThreadCountGuard guard;
    for (const Index n : {0, 1, 7, 100, 1001}) {
      for (const Index grain : {1, 3, 64, 5000}) {
        CAPTURE(n);
        CAPTURE(grain);
        set_thread_count(1);
        const auto one = chunks_of(n, grain);
        CHECK(static_cast<Index>(one.size()) == num_chunks(n, grain));
        Index next = 0;
        for (const auto& [b, e] : one) {  // they tile [0, n) in order
          CHECK(b == next);
          CHECK(e > b);
          CHECK(e - b <= grain);
          next = e;
        }
        CHECK(next == n);
        for (const int threads : {2, 3}) {
          set_thread_count(threads);
          CHECK(chunks_of(n, grain) == one);
        }
      }
    }
    CHECK_THROWS_AS(parallel_for_chunks(10, 0, [](Index, Index) {}), InternalError);
  }

  TEST_CASE("per-chunk sums reduced in chunk order are the same bits at 1 and 2 and 3 threads") {
    const ThreadCountGuard guard;
    set_thread_count(1);
    const double one = chunked_sum(1000003, 4096);
    double serial = 0.0;  // ... and differ from the plain serial sum only by the grouping
    for (Index i = 0; i < 1000003; ++i) serial += std::sin(static_cast<double>(i));
    CHECK(one == doctest::Approx(serial).epsilon(1e-9));
    for (const int threads : {2, 3}) {
      set_thread_count(threads);
      CHECK(chunked_sum(1000003, 4096) == one);
    }
  }

  TEST_CASE("parallel_for_chunks: an exception in a chunk reaches the caller") {
    const ThreadCountGuard guard;
    for (const int threads : {1, 2}) {
      set_thread_count(threads);
      CHECK_THROWS_WITH_AS(parallel_for_each(1000, 7,
                                             [](Index i) {
                                               if (i == 500) throw InputError("item 500");
                                             }),
                           "item 500", InputError);
    }
  }

  TEST_CASE("run_alongside: at 2 threads side runs while main waits for it; at 1 thread after") {
    const ThreadCountGuard guard;
    set_thread_count(2);
    // main blocks until side has started: only a side on another thread can release it (a
    // minute's bound, so that a wrong implementation fails instead of hanging)
    std::mutex m;
    std::condition_variable cv;
    bool side_started = false, released = false;
    double side_sum = 0;
    run_alongside(
        [&] {
          std::unique_lock<std::mutex> lock(m);
          released = cv.wait_for(lock, std::chrono::seconds(60), [&] { return side_started; });
        },
        [&] {
          {
            const std::lock_guard<std::mutex> lock(m);
            side_started = true;
          }
          cv.notify_all();
          side_sum = chunked_sum(10000, 64);  // a parallel loop inside the side task
        });
    CHECK(released);
    CHECK(side_sum == chunked_sum(10000, 64));

    set_thread_count(1);
    std::string order;
    run_alongside([&] { order += "main "; }, [&] { order += "side"; });
    CHECK(order == "main side");
  }

  TEST_CASE("run_alongside: exceptions reach the caller after both ended, main's first") {
    const ThreadCountGuard guard;
    for (const int threads : {1, 2}) {
      CAPTURE(threads);
      set_thread_count(threads);
      std::atomic<bool> side_done{false};
      CHECK_THROWS_WITH_AS(
          run_alongside([] { throw InputError("main failed"); }, [&] { side_done = true; }),
          "main failed", InputError);
      CHECK(side_done);
      CHECK_THROWS_WITH_AS(run_alongside([] {}, [] { throw SolverError("side failed"); }),
                           "side failed", SolverError);
      CHECK_THROWS_WITH_AS(run_alongside([] { throw InputError("main failed"); },
                                         [] { throw SolverError("side failed"); }),
                           "main failed", InputError);
    }
  }

  TEST_CASE(
      "group_by_key: every key's items in increasing order, the same at 1, 2, 3 and 9 threads") {
    const ThreadCountGuard guard;
    // Items emit 0-3 keys (a key twice sometimes), by a hash: the plain serial grouping is
    // the reference.
    const Index n = 100003, nkeys = 5003;
    const auto keys_of = [](Index i, auto&& emit) {
      const auto h = static_cast<std::uint32_t>(i) * 2654435761u;
      const int count = static_cast<int>(h >> 30);
      for (int c = 0; c < count; ++c) emit(static_cast<Index>((h >> (3 * c)) % 5003));
      if (i % 7 == 0) emit(static_cast<Index>(i % 5003));
    };
    std::vector<std::vector<Index>> expected(static_cast<size_t>(nkeys));
    for (Index i = 0; i < n; ++i) keys_of(i, [&](Index k) { expected[k].push_back(i); });
    for (const int threads : {1, 2, 3, 9}) {
      CAPTURE(threads);
      set_thread_count(threads);
      std::vector<Index> start, items;
      group_by_key(n, nkeys, keys_of, start, items);
      REQUIRE(start.size() == static_cast<size_t>(nkeys) + 1);
      CHECK(start.front() == 0);
      CHECK(start.back() == static_cast<Index>(items.size()));
      int wrong = 0;
      for (Index k = 0; k < nkeys; ++k)
        wrong += std::vector<Index>(items.begin() + start[k], items.begin() + start[k + 1]) !=
                 expected[k];
      CHECK(wrong == 0);
    }
    std::vector<Index> start{7}, items{7};  // nothing to group
    group_by_key(0, 3, keys_of, start, items);
    CHECK(start == std::vector<Index>{0, 0, 0, 0});
    CHECK(items.empty());
  }

  TEST_CASE("parallel_count and parallel_fill: every item once, the count at 1, 2 and 3 threads") {
    const ThreadCountGuard guard;
    const Index n = 100003;
    for (const int threads : {1, 2, 3}) {
      CAPTURE(threads);
      set_thread_count(threads);
      std::vector<int> visits(static_cast<size_t>(n), 0);
      const Index multiples_of_7 = parallel_count(n, 4096, [&](Index i) {
        ++visits[i];
        return i % 7 == 0;
      });
      CHECK(multiples_of_7 == (n + 6) / 7);
      CHECK(std::count(visits.begin(), visits.end(), 1) == n);
      CHECK(parallel_count(0, 4096, [](Index) { return true; }) == 0);
      UnfilledVector<std::pair<double, Index>> v(static_cast<size_t>(n));
      parallel_fill(v, std::pair<double, Index>{2.5, -1});
      CHECK(std::count(v.begin(), v.end(), std::pair<double, Index>{2.5, -1}) == n);
      v.resize(static_cast<size_t>(n) + 5);  // grows without filling, keeps what was there
      CHECK(v[static_cast<size_t>(n) - 1] == std::pair<double, Index>{2.5, -1});
    }
  }
}
