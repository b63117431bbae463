// The two run-time primitives of the hybrid grid + TIN scheme (Boo, Amor, Doellner, "Unified
// hybrid terrain representation based on local convexifications"): the cavity decoder of the
// paper's Fig. 7, which rebuilds a cell's convexification triangles from one connectivity index
// per TIN-boundary vertex, and the corner tessellation of section 2.1, which joins the uncovered
// cell corners to the convex hull chain by the sign of cross products.
//
// Usage (the paper's Table 1: up-left cell of Fig. 4, TB = {4(9), 5(6), 6(1), 7(2), 8(1), ...}):
//   std::vector<std::uint32_t> conn(100, 1);
//   conn[4] = 9; conn[5] = 6; conn[7] = 2;
//   std::vector<std::uint32_t> seq = {4, 5, 6, 7, 8, 9, 10, 11, 12};
//   auto d = terralod::blocks::hybrid::decode_cavities(seq, conn);
//   // d.triangles = (5,6,7) (7,8,9) (5,7,9) (5,9,10) (5,10,11) (4,5,11) (4,11,12); d.hull = {4, 12}
//
//   auto tris = terralod::blocks::hybrid::corner_tessellation(hull_points, corner_points);
//
// Contract of decode_cavities(sequence, connectivity):
//   sequence      TIN-boundary (TB) indices of the vertices of one boundary cycle inside one
//                 cell, in ring order (the concatenated sections of the cell's VC entry); no
//                 index repeats. Empty is allowed (no output).
//   connectivity  one entry per TB vertex (the whole TB array): c >= 1; c == 1 means "connected
//                 to the next vertex only"; c > 1 opens a cavity that ends at TB index
//                 (t + c) mod connectivity.size(). A cavity whose end is not in `sequence` after
//                 t lies partly outside the cell (it belongs to a coarser level): it is fanned
//                 up to the end of the sequence and never closed (the paper's Table 1: vertex 4).
//   gaps          sorted positions p whose vertex ends a section of a multi-section cycle (a border
//                 gap follows): such a vertex (a section's exit) never opens a cavity here, its
//                 connectivity belongs to the neighbouring cell where it is an entry.
//   Output: fan triangles (apex S_k, previous, current) in the order the decoder emits them, the
//   convex hull vertices (TB indices, in order): a vertex is on the hull when no cavity that
//   closes inside the sequence is open at it, and, while only cavities reaching beyond the cell
//   are open, when it opens such a cavity itself or is the last vertex. With trace = true, one
//   DecodeStep per row of the paper's Table 1.
//   Cost: O(|sequence|) time and memory (a hash of positions for the cavity ends).
//
// Contract of corner_tessellation(hull, corners): `hull` is the convex hull chain h_0..h_m in
// ring order (TIN side on its left, the cell's uncovered part on its right), in (col,row); h_0
// and h_m lie on the cell border. `corners` are the uncovered cell corners in positive (col,row)
// order starting from the corner next to h_0 along the border (the paper's (C, I) list). Returns
// triangles as indices: values < hull.size() index `hull`, values >= hull.size() index
// corners[value - hull.size()]; every triangle is CCW in (col,row) (orient2d > 0). Corner c_k is
// joined to consecutive hull edges while it lies strictly on their uncovered side (cross
// product < 0), then the next corner takes over (the paper's corner shift). Throws
// std::runtime_error if a hull edge is seen by no remaining corner (not a convex chain).
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace terralod::blocks::hybrid {

/// One decoded convexification triangle, vertices as TB indices in the paper's order.
struct FanTriangle {
  std::uint32_t apex = 0, previous = 0, current = 0;
  bool operator==(const FanTriangle&) const = default;
};

/// One row of the paper's Table 1: the vertex read, the starting vertex after it was read, the
/// triangle completed (if any) and the S list after the row.
struct DecodeStep {
  std::uint32_t vertex = 0;
  std::int64_t starting_vertex = -1;  ///< -1 when no cavity is open
  bool has_triangle = false;
  FanTriangle triangle;
  std::vector<std::uint32_t> s_list;
};

struct CavityDecode {
  std::vector<FanTriangle> triangles;
  std::vector<std::uint32_t> hull;  ///< convex hull vertices (TB indices) in ring order
  std::vector<DecodeStep> steps;    ///< filled when trace = true
};

CavityDecode decode_cavities(std::span<const std::uint32_t> sequence,
                             std::span<const std::uint32_t> connectivity, bool trace = false,
                             std::span<const std::size_t> gaps = {});

/// A point in (col,row) plan coordinates.
using PlanPoint = std::array<double, 2>;

std::vector<std::array<std::uint32_t, 3>> corner_tessellation(std::span<const PlanPoint> hull,
                                                              std::span<const PlanPoint> corners);

}  // namespace terralod::blocks::hybrid
