// Heap bytes held by standard containers, for the memory accounts that budgets are checked
// against (CollapseDag::memory_bytes, SelectiveRefinement::memory_bytes, the terrain runtime's
// resident bytes): what a container has reserved (its capacity), not what it uses, since that
// is what the process holds.
//
// Usage:
//   std::size_t n = capacity_bytes(positions) + capacity_bytes(per_sample_lists) + capacity_bytes(index);
//
// Node-based containers are counted with glibc malloc's per-chunk cost: the node rounded up,
// with its 8-byte header, to a multiple of 16 bytes (at least 32).
#pragma once

#include <algorithm>
#include <cstddef>
#include <map>
#include <set>
#include <unordered_map>
#include <vector>

namespace terralod::pm {

/// One malloc chunk for `bytes` requested (glibc, 64-bit).
constexpr std::size_t malloc_chunk_bytes(std::size_t bytes) {
  return std::max<std::size_t>(32, (bytes + 8 + 15) / 16 * 16);
}

template <class T, class A>
std::size_t capacity_bytes(const std::vector<T, A>& v) {
  return v.capacity() * sizeof(T);
}

/// A vector of vectors: its own array and every inner one's.
template <class T, class A, class B>
std::size_t capacity_bytes(const std::vector<std::vector<T, A>, B>& v) {
  std::size_t n = v.capacity() * sizeof(std::vector<T, A>);
  for (const auto& inner : v) n += capacity_bytes(inner);
  return n;
}

namespace detail {
// One node of an unordered_map<K, V>: one chunk for the value and the next pointer (and the
// cached hash, which libstdc++ keeps unless the hash is marked fast, as std::hash of integers is).
template <class K, class V>
constexpr std::size_t hash_node_bytes() {
  return malloc_chunk_bytes(sizeof(void*) + sizeof(std::pair<const K, V>));
}
// Buckets plus one chunk per node.
template <class K, class V, class H, class E, class A>
std::size_t hash_map_bytes(const std::unordered_map<K, V, H, E, A>& m) {
  return m.bucket_count() * sizeof(void*) + m.size() * hash_node_bytes<K, V>();
}
}  // namespace detail

/// Buckets plus one chunk per node.
template <class K, class V, class H, class E, class A>
std::size_t capacity_bytes(const std::unordered_map<K, V, H, E, A>& m) {
  return detail::hash_map_bytes(m);
}

/// The same, with each value's list (a map of lists).
template <class K, class T, class VA, class H, class E, class A>
std::size_t capacity_bytes(const std::unordered_map<K, std::vector<T, VA>, H, E, A>& m) {
  std::size_t n = detail::hash_map_bytes(m);
  for (const auto& [k, v] : m) n += capacity_bytes(v);
  return n;
}

/// Red-black tree nodes: three pointers and a colour before the value.
template <class K, class C, class A>
std::size_t capacity_bytes(const std::set<K, C, A>& s) {
  return s.size() * malloc_chunk_bytes(4 * sizeof(void*) + sizeof(K));
}
template <class K, class V, class C, class A>
std::size_t capacity_bytes(const std::map<K, V, C, A>& m) {
  return m.size() * malloc_chunk_bytes(4 * sizeof(void*) + sizeof(std::pair<const K, V>));
}

}  // namespace terralod::pm
