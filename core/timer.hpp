#pragma once
/// @file timer.hpp
/// Wall-clock timers. A `ScopedTimer` adds its elapsed seconds to one named phase of a
/// `PhaseTimes` table, which the step driver writes into stats.csv each step.
#include <chrono>
#include <string>
#include <utility>
#include <vector>

namespace tetfsi {

/// Seconds since an arbitrary fixed point (steady clock).
inline double now_seconds() {
  using namespace std::chrono;
  return duration<double>(steady_clock::now().time_since_epoch()).count();
}

/// Seconds per named phase, in first-use order (so CSV columns are stable).
class PhaseTimes {
 public:
  /// Add `seconds` to `phase` (created at 0 on first use).
  void add(const std::string& phase, double seconds);
  /// Seconds of `phase`, 0 if never used.
  double get(const std::string& phase) const;
  /// Set every phase to 0, keeping the names and their order.
  void reset();
  const std::vector<std::pair<std::string, double>>& entries() const { return m_entries; }

 private:
  std::vector<std::pair<std::string, double>> m_entries;
};

/// Adds the time from construction to destruction (or `stop()`) to a phase.
class ScopedTimer {
 public:
  ScopedTimer(PhaseTimes& table, std::string phase)
      : m_table(&table), m_phase(std::move(phase)), m_start(now_seconds()) {}
  ScopedTimer(const ScopedTimer&) = delete;
  ScopedTimer& operator=(const ScopedTimer&) = delete;
  ~ScopedTimer() { stop(); }
  /// Stop now and return the elapsed seconds (later calls return 0).
  double stop() {
    if (!m_table) return 0.0;
    const double dt = now_seconds() - m_start;
    m_table->add(m_phase, dt);
    m_table = nullptr;
    return dt;
  }

 private:
  PhaseTimes* m_table;
  std::string m_phase;
  double m_start;
};

}  // namespace tetfsi
