// Private to the PM builder (cached_linf_error.hpp): the direct-mapped cache of triangle errors.
#pragma once

#include <cassert>
#include <cstddef>
#include <cstdint>

#include "huge_vector.hpp"

namespace terralod::pm::detail {
namespace {  // one translation unit (pm_builder.cpp): internal linkage, as when the code lived there

// Direct-mapped cache of triangle errors: exact values, or lower bounds from evaluations that
// stopped early (those exceed a cutoff >= 0, so they are > 0 and stored negated). A colliding
// insert simply overwrites the slot.
class TriangleCache {
 public:
  TriangleCache() = default;
  /// Empties the cache and gives it 2^log2_slots slots.
  void reset(int log2_slots) {
    mask_ = (std::size_t(1) << log2_slots) - 1;
    slots_.assign(mask_ + 1, Slot{});
  }
  struct Slot {
    std::uint32_t a = UINT32_MAX, b = 0, c = 0;
    double value = 0;  // the exact error when >= 0, else minus a lower bound (always > 0)
  };
  // Returns true and sets value/exact when the triangle {a,b,c} (sorted) is cached.
  bool find(std::uint32_t a, std::uint32_t b, std::uint32_t c, double& value, bool& exact) const {
    const Slot& s = slots_[hash(a, b, c)];
    if (s.a != a || s.b != b || s.c != c) return false;
    exact = s.value >= 0;
    value = exact ? s.value : -s.value;
    return true;
  }
  void store(std::uint32_t a, std::uint32_t b, std::uint32_t c, double value, bool exact) {
    Slot& s = slots_[hash(a, b, c)];
    s.a = a, s.b = b, s.c = c;
    assert(exact || value > 0);  // a lower bound exceeds a cutoff >= 0
    s.value = exact ? value : -value;
  }

 private:
  std::size_t hash(std::uint64_t a, std::uint64_t b, std::uint64_t c) const {
    std::uint64_t h = a * 0x9E3779B97F4A7C15ull ^ (b + 0x632BE59BD9B4E019ull) * 0xC2B2AE3D27D4EB4Full ^
                      (c + 0x165667B19E3779F9ull) * 0x94D049BB133111EBull;
    h ^= h >> 29;
    return std::size_t(h) & mask_;
  }
  std::size_t mask_ = 0;
  HugeVector<Slot> slots_ = HugeVector<Slot>(1);
};

}  // namespace
}  // namespace terralod::pm::detail
