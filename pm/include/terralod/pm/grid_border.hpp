// The grid border rules of L-infinity collapses, shared by ProgressiveMesh::build and ModLInfT
// (linf_decimater_module.hpp) so that both keep a grid mesh's outline the same way.
//
// Usage:
//   const terralod::pm::GridBorder border{hf.width(), hf.height()};
//   if (border.corner(p)) { /* p never moves */ }
//   const terralod::pm::BorderLine line = border.line(p);   // BorderLine::None: not on the border
//   if (line != terralod::pm::BorderLine::None && border.on(line, q)) { /* p may move to q */ }
//
// The rules (every collapse u -> w of either builder obeys them): a grid corner never moves; a
// vertex on the grid border moves only along its border line, into a neighbour joined to it by
// a boundary edge, and only when all of its boundary neighbours lie on that line too (otherwise
// a hole touches the border there); a vertex on the boundary of a hole never moves (the hole
// keeps its shape). Points are (column, row) in a grid of width x height samples, both >= 1.
// Memory: none.
#pragma once

#include <cstdint>

#include "terralod/pm/linf_error.hpp"

namespace terralod::pm {

/// The border lines of the grid; a point on two of them is a corner.
enum class BorderLine : std::uint8_t {
  None = 0,
  FirstColumn = 1,  ///< x = 0
  LastColumn = 2,   ///< x = width - 1
  FirstRow = 3,     ///< y = 0
  LastRow = 4,      ///< y = height - 1
};

struct GridBorder {
  int width = 0;   ///< samples per row
  int height = 0;  ///< rows

  /// Whether p is one of the grid's four corners (which never move).
  bool corner(GridPoint p) const { return (p.x == 0 || p.x == width - 1) && (p.y == 0 || p.y == height - 1); }

  /// The border line p lies on: the first of x = 0, x = width - 1, y = 0, y = height - 1
  /// (for a corner, the column line); BorderLine::None inside the grid.
  BorderLine line(GridPoint p) const {
    if (p.x == 0) return BorderLine::FirstColumn;
    if (p.x == width - 1) return BorderLine::LastColumn;
    if (p.y == 0) return BorderLine::FirstRow;
    if (p.y == height - 1) return BorderLine::LastRow;
    return BorderLine::None;
  }

  /// Whether p lies on border line l (never on BorderLine::None).
  bool on(BorderLine l, GridPoint p) const {
    switch (l) {
      case BorderLine::FirstColumn:
        return p.x == 0;
      case BorderLine::LastColumn:
        return p.x == width - 1;
      case BorderLine::FirstRow:
        return p.y == 0;
      case BorderLine::LastRow:
        return p.y == height - 1;
      case BorderLine::None:
        break;
    }
    return false;
  }
};

}  // namespace terralod::pm
