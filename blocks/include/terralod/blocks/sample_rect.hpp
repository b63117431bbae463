// SampleRect: an axis-aligned rectangle of samples of a terrain grid, the domain of blocks,
// tree nodes and TINs.
//
// Usage:
//   terralod::blocks::SampleRect r{/*col0=*/0, /*row0=*/0, /*col1=*/256, /*row1=*/256};
//   r.width();   // 257 samples
//
// Contract: bounds are inclusive sample indices of the whole terrain grid (col = column,
// row = row as in pm::Heightfield), col0 <= col1 and row0 <= row1. Neighbouring domains share
// their border samples (a 257-sample block spans 256 cells).
#pragma once

#include <cstddef>

namespace terralod::blocks {

struct SampleRect {
  int col0 = 0, row0 = 0, col1 = 0, row1 = 0;

  int width() const { return col1 - col0 + 1; }   ///< samples per row
  int height() const { return row1 - row0 + 1; }  ///< samples per column
  std::size_t samples() const { return std::size_t(width()) * std::size_t(height()); }
  bool contains(int col, int row) const { return col >= col0 && col <= col1 && row >= row0 && row <= row1; }
  bool operator==(const SampleRect&) const = default;
};

}  // namespace terralod::blocks
