#include "core/timer.hpp"

namespace tetfsi {

void PhaseTimes::add(const std::string& phase, double seconds) {
  for (auto& [name, s] : m_entries) {
    if (name == phase) {
      s += seconds;
      return;
    }
  }
  m_entries.emplace_back(phase, seconds);
}

double PhaseTimes::get(const std::string& phase) const {
  for (const auto& [name, s] : m_entries)
    if (name == phase) return s;
  return 0.0;
}

void PhaseTimes::reset() {
  for (auto& e : m_entries) e.second = 0.0;
}

}  // namespace tetfsi
