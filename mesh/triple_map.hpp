#pragma once
/// @file triple_map.hpp
/// Triples of vertex ids as hash keys, and an open-addressing map from them (the remesher's
/// surface facets, Delaunay's hole facets). Internal to the mesh layer.
#include <algorithm>
#include <bit>
#include <cstddef>
#include <vector>

#include "mesh/geometry.hpp"

namespace tetfsi::mesh::detail {

struct TripleKey {
  int a, b, c;
  bool operator==(const TripleKey&) const = default;
};
struct TripleHash {
  std::size_t operator()(const TripleKey& k) const { return hash_triple(k.a, k.b, k.c); }
};

/// A map from triples of vertex ids (the first ≥ 0; the remesher's are sorted, a removal's
/// hole facets rotated to start at the smallest) to V, by open addressing with linear
/// probing: several times faster than std::unordered_map for the recovery's facet table,
/// which is looked up for every surface facet of every cell it sees. No iteration (so no
/// order to depend on).
template <class V>
class TripleMap {
 public:
  /// The value of k, inserted value-initialised if absent.
  V& operator[](const TripleKey& k) {
    if (2 * (m_used + 1) > m_keys.size()) grow();
    std::size_t free = m_keys.size();
    for (std::size_t i = slot(k);; i = (i + 1) & m_mask) {
      if (m_keys[i] == k) return m_values[i];
      if (m_keys[i].a == kGone && free == m_keys.size()) free = i;
      if (m_keys[i].a == kEmpty) {
        if (free == m_keys.size()) free = i, ++m_used;
        m_keys[free] = k;
        m_values[free] = V{};
        ++m_size;
        return m_values[free];
      }
    }
  }
  /// The value of k, or null.
  V* find(const TripleKey& k) {
    return const_cast<V*>(static_cast<const TripleMap*>(this)->find(k));
  }
  const V* find(const TripleKey& k) const {
    if (m_keys.empty()) return nullptr;
    for (std::size_t i = slot(k);; i = (i + 1) & m_mask) {
      if (m_keys[i] == k) return &m_values[i];
      if (m_keys[i].a == kEmpty) return nullptr;
    }
  }
  bool contains(const TripleKey& k) const { return find(k) != nullptr; }
  void erase(const TripleKey& k) {
    if (V* v = find(k)) {
      m_keys[static_cast<std::size_t>(v - m_values.data())].a = kGone;
      --m_size;
    }
  }
  void clear() {
    std::fill(m_keys.begin(), m_keys.end(), TripleKey{kEmpty, 0, 0});
    m_size = m_used = 0;
  }
  std::size_t size() const { return m_size; }

 private:
  static constexpr int kEmpty = -1, kGone = -2;
  std::size_t slot(const TripleKey& k) const {
    std::uint64_t h = hash_triple(k.a, k.b, k.c);
    h ^= h >> 33;
    h *= 0xFF51AFD7ED558CCDULL;
    h ^= h >> 33;
    return static_cast<std::size_t>(h) & m_mask;
  }
  void grow() {
    std::vector<TripleKey> keys;
    std::vector<V> values;
    keys.swap(m_keys);
    values.swap(m_values);
    const std::size_t n = std::bit_ceil(std::max<std::size_t>(1024, 4 * (m_size + 1)));
    m_keys.assign(n, TripleKey{kEmpty, 0, 0});
    m_values.resize(n);
    m_mask = n - 1;
    m_size = m_used = 0;
    for (std::size_t i = 0; i < keys.size(); ++i)
      if (keys[i].a >= 0) (*this)[keys[i]] = values[i];
  }
  std::vector<TripleKey> m_keys;
  std::vector<V> m_values;
  std::size_t m_mask = 0, m_size = 0, m_used = 0;  ///< m_used: keys and tombstones
};

}  // namespace tetfsi::mesh::detail
