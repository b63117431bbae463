// Non-regular grid of heightfield samples with an exact L-infinity error.
//
// Algorithm: the non-regular-grid strategy of the approximation tree (seeds/approximation-
// tree.txt, section 3.2, Fig. 4): start with the domain's boundary rows and columns; repeatedly
// find the point of largest error and add the row and the column through it; the approximating
// surface is made of the intersections of the selected rows and columns, each cell split along
// the diagonal (cols[i], rows[j]) - (cols[i+1], rows[j+1]). The errors are pm::LInfError's
// (samples, and under ErrorMetric::Continuous the crossings of the triangle edges with the
// full-resolution grid edges); when the worst point is such a crossing, the row and column of the
// nearer endpoint of the crossed grid edge are added. After an insertion only the cells of the
// split strips are re-measured.
//
// Memory: one 40-byte record per cell of the selected grid (rows * cols), plus the result.
// Time: per insertion O(area of the split strips + cells).
#include <algorithm>
#include <cassert>
#include <map>
#include <utility>

#include "terralod/blocks/greedy_tin.hpp"
#include "tin_error.hpp"

namespace terralod::blocks {
namespace {

using pm::GridPoint;

struct Cell {
  double error = 0.0;
  GridPoint worst{-1, -1};  ///< sample whose row and column fix the cell's worst point
};

class NonRegularBuilder {
 public:
  NonRegularBuilder(const pm::Heightfield& hf, const NonRegularGridOptions& o)
      : hf_(hf), opt_(o), linf_(hf, o.metric) {}

  /// Error of the cell with corners (c0,r0)-(c1,r1), and the sample to insert for it.
  Cell measure(int c0, int r0, int c1, int r1) const {
    const GridPoint a{c0, r0}, b{c1, r0}, c{c1, r1}, d{c0, r1};
    Cell cell;
    for (const auto& tri : {std::array<GridPoint, 3>{a, b, c}, std::array<GridPoint, 3>{a, c, d}}) {
      const detail::SampleScan s = detail::scan_triangle(hf_, tri[0], tri[1], tri[2]);
      if (s.error > cell.error || cell.worst.x < 0) {
        if (s.error > cell.error) cell.error = s.error;
        if (s.worst.x >= 0) cell.worst = s.worst;
      }
    }
    if (opt_.metric == pm::ErrorMetric::Continuous) {
      // The four sides run along grid lines: their crossings are samples, already scanned. The
      // diagonal a-c carries the other crossings; LInfError::segment gives the value.
      const double ce = detail::edge_error(linf_, hf_, a, c);
      if (ce > cell.error) {
        const detail::Crossing x = detail::worst_crossing(hf_, a, c);
        cell.error = ce;
        for (GridPoint s : {x.s0, x.s1})
          if (s.x >= 0 && hf_.valid(s.x, s.y) && !(s == a) && !(s == c)) {
            cell.worst = s;
            break;
          }
      }
    }
    return cell;
  }

  NonRegularGrid run(SampleRect d) {
    std::vector<int> cols = {d.col0, d.col1}, rows = {d.row0, d.row1};
    std::map<std::pair<int, int>, Cell> cells;  // keyed by (top-left column, top-left row)
    auto measure_strip_cols = [&](int c0, int c1) {
      for (std::size_t j = 0; j + 1 < rows.size(); ++j)
        cells[{c0, rows[j]}] = measure(c0, rows[j], c1, rows[j + 1]);
    };
    auto measure_strip_rows = [&](int r0, int r1) {
      for (std::size_t i = 0; i + 1 < cols.size(); ++i)
        cells[{cols[i], r0}] = measure(cols[i], r0, cols[i + 1], r1);
    };
    measure_strip_cols(d.col0, d.col1);
    double error = 0.0;
    for (;;) {
      error = 0.0;
      GridPoint worst{-1, -1};
      for (const auto& [key, cell] : cells)
        if (cell.error > error) error = cell.error, worst = cell.worst;
      if (error <= opt_.max_error || worst.x < 0) break;
      const bool new_col = !std::binary_search(cols.begin(), cols.end(), worst.x);
      const bool new_row = !std::binary_search(rows.begin(), rows.end(), worst.y);
      if (!new_col && !new_row) break;  // only rounding noise at a grid vertex is left
      if ((cols.size() + new_col) * (rows.size() + new_row) > opt_.max_points) break;
      if (new_col) {
        const auto it = std::upper_bound(cols.begin(), cols.end(), worst.x);
        const int c0 = *(it - 1), c1 = *it;
        cols.insert(it, worst.x);
        measure_strip_cols(c0, worst.x);
        measure_strip_cols(worst.x, c1);
      }
      if (new_row) {
        const auto it = std::upper_bound(rows.begin(), rows.end(), worst.y);
        const int r0 = *(it - 1), r1 = *it;
        rows.insert(it, worst.y);
        measure_strip_rows(r0, worst.y);
        measure_strip_rows(worst.y, r1);
      }
    }
    NonRegularGrid g;
    g.cols = cols, g.rows = rows, g.error = error;
    TinSurface& s = g.surface;
    const std::uint32_t nc = std::uint32_t(cols.size());
    for (int r : rows)
      for (int c : cols) s.points.push_back({c, r});
    for (std::uint32_t j = 0; j + 1 < rows.size(); ++j)
      for (std::uint32_t i = 0; i + 1 < nc; ++i) {
        const std::uint32_t a = j * nc + i, b = a + 1, c = a + nc + 1, dd = a + nc;
        s.triangles.push_back({a, b, c});
        s.triangles.push_back({a, c, dd});
      }
    s.error = error;
    return g;
  }

 private:
  const pm::Heightfield& hf_;
  const NonRegularGridOptions& opt_;
  pm::LInfError linf_;
};

}  // namespace

NonRegularGrid build_nonregular_grid(const pm::Heightfield& hf, SampleRect domain,
                                     const NonRegularGridOptions& options) {
  assert(domain.col0 >= 0 && domain.row0 >= 0 && domain.col1 < hf.width() && domain.row1 < hf.height());
  assert(domain.width() >= 2 && domain.height() >= 2);
  assert(options.max_error >= 0.0 && options.max_points >= 4);
  NonRegularBuilder b(hf, options);
  return b.run(domain);
}

}  // namespace terralod::blocks
