// Private to the PM builder (pm_builder.cpp): std::vector on 2 MiB-aligned transparent huge pages.
#pragma once

#include <cstddef>
#include <cstdlib>
#include <memory>
#include <new>
#include <vector>
#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace terralod::pm::detail {
namespace {  // one translation unit (pm_builder.cpp): internal linkage, as when the code lived there

// Allocator for the builder's large, randomly accessed arrays (error cache, heap, per-vertex
// state): blocks of 2 MiB and more are 2 MiB-aligned and advised to use transparent huge
// pages, so that random accesses do not also miss the TLB. Elsewhere it is std::allocator.
template <class T>
struct HugeAllocator {
  using value_type = T;
  HugeAllocator() = default;
  template <class U>
  HugeAllocator(const HugeAllocator<U>&) {}
  static constexpr std::size_t kHuge = std::size_t(2) << 20;
  T* allocate(std::size_t n) {
    const std::size_t bytes = n * sizeof(T);
    if (bytes < kHuge) return std::allocator<T>().allocate(n);
    void* p = std::aligned_alloc(kHuge, (bytes + kHuge - 1) / kHuge * kHuge);
    if (!p) throw std::bad_alloc();
#ifdef MADV_HUGEPAGE
    madvise(p, (bytes + kHuge - 1) / kHuge * kHuge, MADV_HUGEPAGE);  // advice only: failure is harmless
#endif
    return static_cast<T*>(p);
  }
  void deallocate(T* p, std::size_t n) {
    if (n * sizeof(T) < kHuge)
      std::allocator<T>().deallocate(p, n);
    else
      std::free(p);
  }
  template <class U>
  bool operator==(const HugeAllocator<U>&) const {
    return true;
  }
};
template <class T>
using HugeVector = std::vector<T, HugeAllocator<T>>;

}  // namespace
}  // namespace terralod::pm::detail
