// Private to the two PM builders (pm_builder.cpp, openmesh_build.cpp): how both make the
// full-resolution mesh of a heightfield, so that their PMs describe the same M^n - the checks
// of the input, and the grid's faces in ProgressiveMesh::full_face's numbering, with the faces
// the mesh refuses around holes recorded as the PM's dropped faces.
//
// Around holes, which faces an OpenMesh mesh accepts depends on the order they come in;
// ProgressiveMesh::dropped_faces() is defined by adding the cells row by row
// (add_faces_row_by_row). A hole-free grid accepts every face in any order in which a cell's
// left, upper and upper-left neighbours come before it (row by row, or tile_order.hpp's).
// Memory: none.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "terralod/pm/grid_triangle.hpp"
#include "terralod/pm/heightfield.hpp"

namespace terralod::pm::detail {

/// Throws std::invalid_argument (naming the problem and, for a sample, the source) unless the
/// heightfield can have a PM: at least 2 x 2 samples, fewer than 2^31 of them, every valid
/// sample finite.
inline void check_buildable(const Heightfield& hf) {
  if (hf.width() < 2 || hf.height() < 2)
    throw std::invalid_argument("progressive mesh: grid is " + std::to_string(hf.width()) + " x " +
                                std::to_string(hf.height()) + "; at least 2 x 2 samples are needed");
  if (hf.size() >= (std::size_t(1) << 31))
    throw std::invalid_argument("progressive mesh: grid of " + std::to_string(hf.size()) +
                                " samples is too large for one PM; cut it into blocks");
  for (std::size_t i = 0; i < hf.size(); ++i)
    if (hf.valid(i) && !std::isfinite(hf[i]))
      throw std::invalid_argument("progressive mesh: sample " + std::to_string(i) + " of " + hf.source +
                                  " is not finite; fill or mask voids first");
}

/// Adds the two faces of cell (i, j) (0 <= i < width - 1, 0 <= j < height - 1) that have three
/// valid samples, face 2c then 2c + 1 (c = j * (width - 1) + i, ProgressiveMesh::full_face):
/// add(samples, corners) gets a face's samples (row * width + col) and grid points, CCW in
/// (col,row), and returns whether the mesh took it. The numbers of refused faces are appended
/// to `dropped`; a grid without holes refuses none (std::logic_error otherwise: the order of
/// the cells broke the rule in the header).
template <class AddFace>
void add_cell_faces(const Heightfield& hf, int i, int j, AddFace&& add, std::vector<std::uint32_t>& dropped) {
  const std::uint32_t W = std::uint32_t(hf.width());
  const std::uint32_t s00 = std::uint32_t(j) * W + std::uint32_t(i), s10 = s00 + 1, s01 = s00 + W,
                      s11 = s01 + 1;
  const std::uint32_t samples[2][3] = {{s00, s10, s11}, {s00, s11, s01}};
  const GridPoint corners[2][3] = {{{i, j}, {i + 1, j}, {i + 1, j + 1}},
                                   {{i, j}, {i + 1, j + 1}, {i, j + 1}}};
  for (int k = 0; k < 2; ++k) {
    if (hf.has_holes() && !(hf.valid(samples[k][0]) && hf.valid(samples[k][1]) && hf.valid(samples[k][2])))
      continue;
    if (add(samples[k], corners[k])) continue;
    if (!hf.has_holes()) throw std::logic_error("progressive mesh: the full-resolution grid is not manifold");
    dropped.push_back(2 * (std::uint32_t(j) * (W - 1) + std::uint32_t(i)) + std::uint32_t(k));
  }
}

/// add_cell_faces for every cell whose column lies in [x0, x1), row by row: the order that
/// defines the dropped faces (appended in increasing order).
template <class AddFace>
void add_faces_row_by_row(const Heightfield& hf, int x0, int x1, AddFace&& add,
                          std::vector<std::uint32_t>& dropped) {
  for (int j = 0; j + 1 < hf.height(); ++j)
    for (int i = x0; i < x1; ++i) add_cell_faces(hf, i, j, add, dropped);
}

}  // namespace terralod::pm::detail
