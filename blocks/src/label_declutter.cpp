// Label decluttering (label_declutter.hpp): greedy placement in key order, overlap queries on a
// uniform grid of screen cells holding the labels already shown.
#include "terralod/blocks/label_declutter.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cassert>
#include <cmath>

namespace terralod::blocks {
namespace {

// Bits of a double whose unsigned order is the numeric order (-0 taken as +0).
std::uint64_t ordered_bits(double v) {
  const auto u = std::bit_cast<std::uint64_t>(v + 0.0);
  return (u >> 63) ? ~u : u | (std::uint64_t{1} << 63);
}
std::uint32_t ordered_bits(float v) {
  const auto u = std::bit_cast<std::uint32_t>(v + 0.0f);
  return (u >> 31) ? ~u : u | (std::uint32_t{1} << 31);
}

// The grid cells [lo, hi] that hold the interior of [a, b) along one axis, clamped to [0, n-1].
// Two intervals whose interiors meet share a cell: clamping is monotone.
void cell_span(float a, float b, float inv_cell, int n, int& lo, int& hi) {
  const float top = float(n - 1);
  lo = int(std::clamp(std::floor(a * inv_cell), 0.0f, top));
  hi = int(std::clamp(std::floor(b * inv_cell), 0.0f, top));
}

}  // namespace

LabelDeclutterer::LabelDeclutterer(Options options) : options_(options) {
  assert(options_.screen_width >= 1 && options_.screen_height >= 1 && options_.cell_px >= 1);
  cols_ = (options_.screen_width + options_.cell_px - 1) / options_.cell_px;
  rows_ = (options_.screen_height + options_.cell_px - 1) / options_.cell_px;
  cells_.resize(std::size_t(cols_) * std::size_t(rows_));
  remember({});
}

void LabelDeclutterer::reset() { remember({}); }

std::size_t LabelDeclutterer::slot_of(const LabelId& id) const {
  const std::uint64_t h = (std::uint64_t(id.layer) + 1) * 0x9E3779B97F4A7C15ull ^
                          std::uint64_t(id.feature) * 0xC2B2AE3D27D4EB4Full;
  return std::size_t(h ^ (h >> 29)) & (slots_.size() - 1);
}

bool LabelDeclutterer::was_shown(const LabelId& id) const {
  for (std::size_t k = slot_of(id);; k = (k + 1) & (slots_.size() - 1)) {  // linear probing
    if (!full_[k]) return false;
    if (slots_[k] == id) return true;
  }
}

void LabelDeclutterer::remember(std::span<const LabelId> ids) {
  std::size_t size = 16;  // a power of two, at least twice the ids: probes stay short
  while (size < 2 * ids.size()) size *= 2;
  slots_.resize(size);
  full_.assign(size, 0);  // no allocation once grown
  for (const LabelId& id : ids) {
    std::size_t k = slot_of(id);
    for (; full_[k]; k = (k + 1) & (size - 1)) assert(slots_[k] != id);  // ids unique
    slots_[k] = id;
    full_[k] = 1;
  }
}

void LabelDeclutterer::order(std::span<const LabelCandidate> candidates) {
  const std::size_t n = candidates.size();
  shown_before_.resize(n);
  bool packed = true;  // every priority a float and every depth >= 0: the key fits 64 bits
  for (std::size_t i = 0; i < n; ++i) {
    const LabelCandidate& c = candidates[i];
    assert(std::isfinite(c.x0) && std::isfinite(c.y0) && std::isfinite(c.x1) && std::isfinite(c.y1));
    assert(c.x0 < c.x1 && c.y0 < c.y1 && std::isfinite(c.priority) && std::isfinite(c.depth));
    shown_before_[i] = was_shown(c.id);
    packed = packed && double(float(c.priority)) == c.priority && c.depth >= 0.0f;
  }
  order_.resize(n);
  if (!packed) {  // the general key: 128 bits, compared
    keys_.clear();
    for (std::uint32_t i = 0; i < n; ++i)
      keys_.push_back({~ordered_bits(candidates[i].priority),
                       (shown_before_[i] ? 0 : std::uint64_t{1} << 63) | ordered_bits(candidates[i].depth),
                       i});
    std::sort(keys_.begin(), keys_.end(), [&](const Key& a, const Key& b) {
      if (a.major != b.major) return a.major < b.major;
      if (a.minor != b.minor) return a.minor < b.minor;
      return candidates[a.index].id < candidates[b.index].id;
    });
    for (std::size_t k = 0; k < n; ++k) order_[k] = keys_[k].index;
    return;
  }
  // The same order in one 64-bit key: priority (32 bits, decreasing), not shown before (1 bit),
  // depth (the 31 low bits of a float >= 0, increasing); an LSD radix sort, 8 bits a pass.
  packed_.resize(n);
  packed_tmp_.resize(n);
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::uint64_t p = ~ordered_bits(float(candidates[i].priority));
    const std::uint64_t d = std::bit_cast<std::uint32_t>(candidates[i].depth + 0.0f) & 0x7fffffffu;
    packed_[i] = {(p << 32) | (shown_before_[i] ? 0 : std::uint64_t{1} << 31) | d, i};
  }
  for (int shift = 0; shift < 64; shift += 8) {
    std::array<std::uint32_t, 257> count{};
    for (const Packed& e : packed_) ++count[((e.key >> shift) & 0xff) + 1];
    if (std::find(count.begin() + 1, count.end(), std::uint32_t(n)) != count.end()) continue;  // one bucket
    for (std::size_t b = 1; b < count.size(); ++b) count[b] += count[b - 1];
    for (const Packed& e : packed_) packed_tmp_[count[(e.key >> shift) & 0xff]++] = e;
    packed_.swap(packed_tmp_);
  }
  for (std::size_t k = 0; k < n;) {  // equal keys: the smaller id first
    std::size_t e = k + 1;
    while (e < n && packed_[e].key == packed_[k].key) ++e;
    if (e - k > 1)
      std::sort(
          packed_.begin() + std::ptrdiff_t(k), packed_.begin() + std::ptrdiff_t(e),
          [&](const Packed& a, const Packed& b) { return candidates[a.index].id < candidates[b.index].id; });
    for (; k < e; ++k) order_[k] = packed_[k].index;
  }
}

std::span<const LabelId> LabelDeclutterer::update(std::span<const LabelCandidate> candidates) {
  assert(candidates.size() < std::size_t{UINT32_MAX});
  stats_ = {};
  stats_.candidates = candidates.size();
  order(candidates);

  for (const std::uint32_t c : used_cells_) cells_[c].clear();
  used_cells_.clear();
  shown_.clear();
  const float inv_cell = 1.0f / float(options_.cell_px);
  constexpr std::size_t kAhead = 16;  // candidates are read in key order, far apart in memory
  for (std::size_t k = 0; k < order_.size(); ++k) {
    if (k + kAhead < order_.size()) __builtin_prefetch(&candidates[order_[k + kAhead]]);
    const std::uint32_t index = order_[k];
    const LabelCandidate& c = candidates[index];
    int cx0, cx1, cy0, cy1;
    cell_span(c.x0, c.x1, inv_cell, cols_, cx0, cx1);
    cell_span(c.y0, c.y1, inv_cell, rows_, cy0, cy1);
    bool free = true;
    for (int y = cy0; y <= cy1 && free; ++y)
      for (int x = cx0; x <= cx1 && free; ++x)
        for (const Box& other : cells_[std::size_t(y) * std::size_t(cols_) + std::size_t(x)]) {
          ++stats_.overlap_tests;
          if (c.x0 < other.x1 && other.x0 < c.x1 && c.y0 < other.y1 && other.y0 < c.y1) {  // labels_overlap
            free = false;
            break;
          }
        }
    if (!free) continue;
    for (int y = cy0; y <= cy1; ++y)
      for (int x = cx0; x <= cx1; ++x) {
        const std::uint32_t cell = std::uint32_t(y * cols_ + x);
        if (cells_[cell].empty()) used_cells_.push_back(cell);
        cells_[cell].push_back({c.x0, c.y0, c.x1, c.y1});
      }
    shown_.push_back(c.id);
    if (shown_before_[index]) ++stats_.kept;
  }
  stats_.shown = shown_.size();
  remember(shown_);
  return shown_;
}

}  // namespace terralod::blocks
