// Private to the PM builder (pm_builder.cpp): the indexed priority queue of collapse candidates.
#pragma once

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "huge_vector.hpp"

namespace terralod::pm::detail {
namespace {  // one translation unit (pm_builder.cpp): internal linkage, as when the code lived there

// Indexed priority queue over vertices, keyed by (error, tie, vertex): a 4-ary min-heap for
// the keys near the top and unsorted buckets for the rest. Bucket b holds the keys whose
// error lies in the b-th range of a geometric scale (8 per octave); the heap holds exactly
// the keys of buckets <= active_, so its top is the smallest key of all. When the heap runs
// empty, the next non-empty bucket is poured into it. Most updates move a vertex far above
// the top (a popped lower bound that grows, a neighbour of a collapse measured up to the
// top's keys); in a bucket that costs one store, where sifting through a heap of all
// vertices (tens of MB on a full tile) cost a cache miss per level. The heap stays small,
// usually in cache. Pops come in the order of the keys, which are unique (the vertex is
// part of them), so the collapse order is the one of a single heap.
//
// The heap: keys live inside the 16-byte entries, so sifting touches only the heap array.
// Node i is stored at slot i + 3, so the four children of node i (4i+1 .. 4i+4, slots
// 4(i+1) .. 4(i+1)+3) fill exactly one cache line when the array is large (2 MiB aligned). A vertex's
// position lives in the caller's per-vertex record (reset()), beside what the caller reads
// with it: a heap slot, or kInBucket | index in its bucket, with the bucket in a 16-bit field.
class VertexHeap {
 public:
  /// Empties the queue for vertices 0 .. n-1; vertex v's position is pos[v * stride] and its
  /// bucket bucket[v * 2 * stride] (a 16-bit field of the same record).
  void reset(std::size_t n, std::uint32_t* pos, std::uint16_t* bucket, std::size_t stride) {
    slots_.assign(kPad, Entry{});
    pos_ = pos, bucket_ = bucket, stride_ = stride, size_ = 0;
    for (std::size_t v = 0; v < n; ++v) pos_[v * stride_] = kAbsent;
    buckets_.assign(kBuckets, {});
    active_ = 0;
    in_buckets_ = 0;
  }
  /// True when no vertex is queued. Pours the next bucket into the heap when it ran empty.
  bool empty() {
    if (size_ == 0 && in_buckets_ > 0) pour();
    return size_ == 0;
  }
  std::uint32_t top() const { return at(0).v(); }
  double top_error() const { return at(0).err(); }
  /// Largest key among the top's children, or, with fewer than four, the smallest error a
  /// key outside the heap can have.
  double children_max_error() const {
    if (size_ < 5) {
      for (std::uint32_t b = active_ + 1; b < kBuckets; ++b)
        if (!buckets_[b].empty()) return bucket_floor(b);
      return 1e300;
    }
    double e = 0;
    for (std::uint32_t c = 1; c <= 4; ++c) e = std::max(e, at(c).err());
    return e;
  }
  /// The vertex that would be on top of the heap without the current top (UINT32_MAX when none).
  std::uint32_t second() const {
    if (size_ < 2) return UINT32_MAX;
    std::uint32_t best = 1;
    for (std::uint32_t c = 2; c <= 4 && c < size_; ++c)
      if (less(at(c), at(best))) best = c;
    return at(best).v();
  }
  /// Starts loading v's heap entry and the line of its children.
  void prefetch_entry(std::uint32_t v) const {
    const std::uint32_t p = pos(v);
    if (p >= kInBucket) return;
    __builtin_prefetch(&at(p));
    if (4 * std::size_t(p) + 1 < size_) __builtin_prefetch(&at(4 * p + 1));
  }
  void set(std::uint32_t v, double err, std::uint32_t tie) {
    assert(err >= 0 && !std::signbit(err));  // the key order is the order of the bits
    const Entry e = Entry::make(err, tie, v);
    const std::uint32_t b = bucket_of(err);
    std::uint32_t p = pos(v);
    if (p < kInBucket) {  // in the heap
      if (b > active_) {
        heap_remove(p);
        bucket_push(b, e);
      } else if (less(e, at(p))) {
        up(p, e);
      } else {
        down(p, e);
      }
      return;
    }
    if (p != kAbsent) {  // in a bucket
      if (b == bucket(v)) {
        buckets_[b][p - kInBucket] = e;
        return;
      }
      bucket_remove(v, p);
    }
    if (b > active_) {
      bucket_push(b, e);
    } else {
      p = size_++;
      if (slots_.size() < size_ + kPad) slots_.resize(size_ + kPad);
      up(p, e);
    }
  }
  void remove(std::uint32_t v) {
    const std::uint32_t p = pos(v);
    if (p == kAbsent) return;
    if (p >= kInBucket)
      bucket_remove(v, p);
    else
      heap_remove(p);
  }
  /// Renames every vertex v in the queue to map[v]; map must keep the order of the vertices
  /// in it, so that the key order (and every tie) stays. Positions stay where they are.
  void renumber(const HugeVector<std::uint32_t>& map) {
    const auto rename = [&](Entry& e) { e.key = (e.key >> 32 << 32) | map[e.v()]; };
    for (std::uint32_t i = 0; i < size_; ++i) rename(at(i));
    for (auto& b : buckets_)
      for (Entry& e : b) rename(e);
  }

 private:
  static constexpr std::uint32_t kAbsent = UINT32_MAX;
  static constexpr std::uint32_t kInBucket = 0x80000000u;
  static constexpr std::size_t kPad = 3;
  // Buckets: 8 per octave of the error, from 2^-20 m (and 0) to 2^20 m; the first and the
  // last also take what lies below and above. Any monotone map of the error would do.
  static constexpr int kSubBits = 3;
  static constexpr std::uint64_t kLowBits = (std::uint64_t(1023 - 20) << 52) >> (52 - kSubBits);
  static constexpr std::uint32_t kBuckets = 40u << kSubBits;
  static std::uint32_t bucket_of(double err) {
    const std::uint64_t q = std::bit_cast<std::uint64_t>(err) >> (52 - kSubBits);
    return q <= kLowBits ? 0 : std::uint32_t(std::min<std::uint64_t>(q - kLowBits, kBuckets - 1));
  }
  // The smallest error of bucket b > 0.
  static double bucket_floor(std::uint32_t b) {
    return std::bit_cast<double>((std::uint64_t(b) + kLowBits) << (52 - kSubBits));
  }
  // Key (err, tie, v) as one unsigned 128-bit number: the bits of err (>= +0, so they order
  // as the values do) above tie above v. One comparison, no unpredictable branches.
  struct Entry {
    unsigned __int128 key = 0;
    static Entry make(double err, std::uint32_t tie, std::uint32_t v) {
      return Entry{(static_cast<unsigned __int128>(std::bit_cast<std::uint64_t>(err)) << 64) |
                   (static_cast<unsigned __int128>(tie) << 32) | v};
    }
    double err() const { return std::bit_cast<double>(std::uint64_t(key >> 64)); }
    std::uint32_t v() const { return std::uint32_t(key); }
  };
  Entry& at(std::uint32_t i) { return slots_[i + kPad]; }
  const Entry& at(std::uint32_t i) const { return slots_[i + kPad]; }
  static bool less(const Entry& a, const Entry& b) { return a.key < b.key; }
  // Moves e (destined for slot i) up/down to its place.
  void up(std::uint32_t i, const Entry& e) {
    while (i > 0) {
      const std::uint32_t p = (i - 1) / 4;
      if (!less(e, at(p))) break;
      at(i) = at(p), pos(at(i).v()) = i, i = p;
    }
    at(i) = e, pos(e.v()) = i;
  }
  void down(std::uint32_t i, const Entry& e) {
    const std::uint32_t n = size_;
    for (;;) {
      const std::uint32_t c0 = 4 * i + 1;
      if (c0 >= n) break;
      std::uint32_t c = c0;
      const std::uint32_t end = std::min(c0 + 4, n);
      for (std::uint32_t k = c0 + 1; k < end; ++k)
        if (less(at(k), at(c))) c = k;
      if (!less(at(c), e)) break;
      at(i) = at(c), pos(at(i).v()) = i, i = c;
    }
    at(i) = e, pos(e.v()) = i;
  }
  void heap_remove(std::uint32_t p) {
    pos(at(p).v()) = kAbsent;
    const Entry last = at(--size_);
    if (p == size_) return;
    if (p > 0 && less(last, at((p - 1) / 4)))
      up(p, last);
    else
      down(p, last);
  }
  void bucket_push(std::uint32_t b, const Entry& e) {
    auto& q = buckets_[b];
    pos(e.v()) = kInBucket | std::uint32_t(q.size());
    bucket(e.v()) = std::uint16_t(b);
    q.push_back(e);
    ++in_buckets_;
  }
  void bucket_remove(std::uint32_t v, std::uint32_t p) {
    auto& q = buckets_[bucket(v)];
    const std::uint32_t i = p - kInBucket;
    if (i + 1 != q.size()) {
      q[i] = q.back();
      pos(q[i].v()) = p;
    }
    q.pop_back();
    pos(v) = kAbsent;
    --in_buckets_;
  }
  // Makes the next non-empty bucket the heap (the heap is empty): Floyd's heap construction.
  void pour() {
    std::uint32_t b = active_ + 1;
    while (buckets_[b].empty()) ++b;
    active_ = b;
    auto& q = buckets_[b];
    size_ = std::uint32_t(q.size());
    if (slots_.size() < size_ + kPad) slots_.resize(size_ + kPad);
    std::copy(q.begin(), q.end(), slots_.begin() + kPad);
    in_buckets_ -= q.size();
    q.clear();
    if (size_ > 1)
      for (std::uint32_t i = (size_ - 2) / 4 + 1; i-- > 0;) {
        const Entry e = at(i);
        down(i, e);
      }
    for (std::uint32_t i = 0; i < size_; ++i) pos(at(i).v()) = i;
  }
  std::uint32_t& pos(std::uint32_t v) { return pos_[v * stride_]; }
  std::uint32_t pos(std::uint32_t v) const { return pos_[v * stride_]; }
  std::uint16_t& bucket(std::uint32_t v) { return bucket_[v * 2 * stride_]; }
  HugeVector<Entry> slots_;  // the heap, from slot kPad
  std::vector<HugeVector<Entry>> buckets_;
  std::uint32_t* pos_ = nullptr;
  std::uint16_t* bucket_ = nullptr;
  std::size_t stride_ = 1;
  std::uint32_t size_ = 0;      // entries in the heap
  std::uint32_t active_ = 0;    // the heap holds the keys of buckets 0 .. active_
  std::size_t in_buckets_ = 0;  // entries in buckets
};

}  // namespace
}  // namespace terralod::pm::detail
