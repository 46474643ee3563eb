#pragma once
/// @file parallel.hpp
/// Threads for the per-face, per-cell and per-element loops (TBB underneath; TBB stays out of
/// this header). The process has one thread count, set once by the driver
/// (`set_thread_count`, from `--threads N` or TETFSI_THREADS; default: every core).
///
/// Determinism. `parallel_for_chunks` cuts [0, n) into chunks of a fixed `grain` that
/// depend on n and the grain only, never on the thread count. A loop whose items each write
/// only their own output slot, or whose per-chunk partial results are reduced afterwards in
/// chunk order, therefore gives the same bits at 1 and at N threads; at 1 thread the chunks
/// run in order on the calling thread, exactly the serial loop.
#include <algorithm>
#include <functional>
#include <memory>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "core/types.hpp"

namespace tetfsi {

/// The cores this machine offers (std::thread::hardware_concurrency, at least 1), shared
/// among the ranks of an mpirun job on this machine with replicated ranks (ranks_on_this_node,
/// core/ranks.hpp); all of them for rank 0 of driver ranks.
int default_thread_count();

/// Let every parallel loop of the process use at most `n` threads (≥ 1) from now on (a
/// tbb::global_control kept alive until the next call). Call it from the driver, not from
/// inside a parallel loop.
/// @throws InputError if n < 1
void set_thread_count(int n);

/// The thread count in force: the last `set_thread_count`, else default_thread_count().
int thread_count();

/// "N" (an integer ≥ 1, nothing else) as a thread count; `source` names where it came from
/// in the message (e.g. "--threads" or "TETFSI_THREADS").
/// @throws InputError "<source>: expected an integer >= 1 (threads), got '<text>'"
int parse_thread_count(const std::string& text, const std::string& source);

/// The thread count the command line and environment ask for: `option` (the text of
/// `--threads`, empty if not given) wins, else the environment variable TETFSI_THREADS if
/// set, else default_thread_count().
/// @throws InputError as parse_thread_count, naming --threads or TETFSI_THREADS
int requested_thread_count(const std::string& option);

/// fn(begin, end) for the chunks [k g, min(n, (k + 1) g)) of [0, n), g = grain (≥ 1), on up to
/// thread_count() threads; the chunks depend on n and grain only. Each call must write only
/// what its own items own. Exceptions thrown by fn reach the caller (one of them if several
/// chunks throw). At one thread (or one chunk) this is the plain loop on the calling thread.
void parallel_for_chunks(Index n, Index grain, const std::function<void(Index, Index)>& fn);

/// fn(i) for every i in [0, n), in chunks of `grain` as parallel_for_chunks.
template <class F>
void parallel_for_each(Index n, Index grain, F&& fn) {
  parallel_for_chunks(n, grain, [&fn](Index begin, Index end) {
    for (Index i = begin; i < end; ++i) fn(i);
  });
}

/// Every item of `v` (a vector, e.g. an UnfilledVector) set to `value`, in parallel chunks:
/// the first touch of a new buffer's pages is spread over the threads.
template <class Vector, class T>
void parallel_fill(Vector& v, const T& value) {
  parallel_for_chunks(static_cast<Index>(v.size()), 16384, [&](Index begin, Index end) {
    std::fill(v.begin() + begin, v.begin() + end, value);
  });
}

/// main() on the calling thread and side() as a task beside it (on another thread of the
/// pool when there is one: work that does not use the pool, such as a serial solver, leaves
/// the other threads free for it), returning when both are done. The two must not write
/// what the other reads. At one thread: main() then side(). An exception from either
/// reaches the caller (main's first) after both have ended.
void run_alongside(const std::function<void()>& main, const std::function<void()>& side);

/// An allocator whose value-construction (`resize(n)`, `vector(n)`) writes nothing: the items
/// of an `UnfilledVector` hold garbage until written, so a buffer that a parallel loop fills
/// whole (parallel_fill, or a loop that assigns every item) is not first filled serially.
/// For plain structs of numbers (trivially destructible).
template <class T>
struct NoFillAllocator : std::allocator<T> {
  static_assert(std::is_trivially_destructible_v<T>, "NoFillAllocator is for plain structs");
  NoFillAllocator() noexcept = default;
  template <class U>
  NoFillAllocator(const NoFillAllocator<U>&) noexcept {}  // NOLINT: the standard's form
  template <class U>
  struct rebind {
    using other = NoFillAllocator<U>;
  };
  template <class U>
  void construct(U*) noexcept {}
  template <class U, class... A>
  void construct(U* p, A&&... a) {
    ::new (static_cast<void*>(p)) U(std::forward<A>(a)...);
  }
};

/// A vector whose `resize` leaves the new items unwritten (see NoFillAllocator).
template <class T>
using UnfilledVector = std::vector<T, NoFillAllocator<T>>;

/// The number of chunks parallel_for_chunks cuts [0, n) into (0 for n ≤ 0).
inline Index num_chunks(Index n, Index grain) {
  return n <= 0 ? 0 : (n + grain - 1) / grain;
}

/// fn(i) for every i in [0, n) as parallel_for_each, and the number of items for which it
/// returned true (counted per chunk, then added).
template <class F>
Index parallel_count(Index n, Index grain, F&& fn) {
  std::vector<Index> count(static_cast<std::size_t>(num_chunks(n, grain)), 0);
  parallel_for_chunks(n, grain, [&](Index begin, Index end) {
    Index c = 0;
    for (Index i = begin; i < end; ++i) c += fn(i) ? 1 : 0;
    count[static_cast<std::size_t>(begin / grain)] = c;
  });
  Index total = 0;
  for (Index c : count) total += c;
  return total;
}

/// The items of [0, n) grouped by key, the same at any thread count: for every key k in
/// [0, nkeys), items[start[k] .. start[k + 1]) lists in increasing order the items i for which
/// `keys_of(i, emit)` calls emit(k) (as often as it calls it). keys_of is called twice per item,
/// in parallel, and must emit the same keys both times. Up to 8 parts of [0, n) count their
/// keys apart (8 × nkeys counters), then each part fills its slots of every key.
template <class KeysOf>
void group_by_key(Index n, Index nkeys, KeysOf&& keys_of, std::vector<Index>& start,
                  std::vector<Index>& items) {
  const Index parts =
      std::max<Index>(1, std::min<Index>(std::min<Index>(thread_count(), 8), num_chunks(n, 4096)));
  const Index grain = std::max<Index>(1, num_chunks(n, parts));
  std::vector<std::vector<Index>> count(static_cast<std::size_t>(parts));
  parallel_for_chunks(n, grain, [&](Index begin, Index end) {
    std::vector<Index>& c = count[static_cast<std::size_t>(begin / grain)];
    c.assign(static_cast<std::size_t>(nkeys), 0);
    for (Index i = begin; i < end; ++i) keys_of(i, [&c](Index k) { ++c[k]; });
  });
  count.resize(static_cast<std::size_t>(num_chunks(n, grain)));
  start.assign(static_cast<std::size_t>(nkeys) + 1, 0);
  parallel_for_chunks(nkeys, 16384, [&](Index begin, Index end) {
    for (Index k = begin; k < end; ++k) {
      Index sum = 0;  // each part's first slot within key k
      for (std::vector<Index>& c : count) sum += std::exchange(c[k], sum);
      start[static_cast<std::size_t>(k) + 1] = sum;
    }
  });
  for (Index k = 0; k < nkeys; ++k) start[k + 1] += start[k];
  items.resize(static_cast<std::size_t>(start[nkeys]));
  parallel_for_chunks(n, grain, [&](Index begin, Index end) {
    std::vector<Index>& c = count[static_cast<std::size_t>(begin / grain)];
    for (Index i = begin; i < end; ++i)
      keys_of(i, [&](Index k) { items[static_cast<std::size_t>(start[k] + c[k]++)] = i; });
  });
}

}  // namespace tetfsi
