// Private to the PM builder (pm_builder.cpp): the order in which the builder numbers the grid's
// samples as vertices, tiles of 64 x 64 samples row by row and Z-order (Morton) inside a tile.
//
// The collapse order is global by error, so every collapse works at a random place of the
// mesh; what it touches there (the rings of u and its neighbours: halfedges, edge errors,
// positions, heights, heap positions) should lie in a few cache lines and one page, which this
// order gives. In it a cell's left, upper and upper-left neighbours always come before it, so
// cells created in this order extend connected fans at their corners and OpenMesh accepts every
// face of a hole-free grid. The order depends on the grid (and `used`) only, so the PM stays a
// function of the heightfield; leaving samples out keeps the order of the others, and with it
// every tie-break by vertex id. Memory: 4 bytes per sample numbered, 16 KiB of Morton table.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace terralod::pm::detail {
namespace {  // one translation unit (pm_builder.cpp): internal linkage, as when the code lived there

/// The samples (row-major indices in a grid of `width` x `height`) of the columns [x0, x1] in
/// tile order, leaving out those with (*used)[s] == 0 when `used` is given: vertex id -> sample.
inline std::vector<std::uint32_t> tile_order(int x0, int x1, int width, int height,
                                             const std::vector<std::uint8_t>* used) {
  constexpr int kTile = 64;
  std::vector<std::uint32_t> sample_of;  // vertex id -> sample index
  sample_of.reserve(used ? std::size_t(std::count(used->begin(), used->end(), 1))
                         : std::size_t(x1 + 1 - x0) * std::size_t(height));
  std::vector<std::uint32_t> z_order(std::size_t(kTile) * kTile);  // Morton code -> dx + kTile * dy
  for (std::uint32_t m = 0; m < z_order.size(); ++m) {
    std::uint32_t dx = 0, dy = 0;
    for (int b = 0; 2 * b < 32 && (m >> (2 * b)) != 0; ++b)
      dx |= ((m >> (2 * b)) & 1u) << b, dy |= ((m >> (2 * b + 1)) & 1u) << b;
    z_order[m] = dx + kTile * dy;
  }
  for (int ty = 0; ty < height; ty += kTile)
    for (int tx = x0; tx <= x1; tx += kTile) {
      const int tw = std::min(kTile, x1 + 1 - tx), th = std::min(kTile, height - ty);
      for (std::uint32_t c : z_order) {  // a partial tile skips the codes outside it
        const int dx = int(c % kTile), dy = int(c / kTile);
        if (dx >= tw || dy >= th) continue;
        const std::uint32_t s = std::uint32_t(std::size_t(ty + dy) * width + tx + dx);
        if (!used || (*used)[s]) sample_of.push_back(s);
      }
    }
  return sample_of;
}

}  // namespace
}  // namespace terralod::pm::detail
