// Harmonic (Laplace) inpainting of DEM voids, one 4-connected void region at a time, solved by
// multigrid-preconditioned conjugate gradients and kept inside the region's border range exactly.
//
// Problem: for the samples V of one void region, find z with count_i z_i - sum_{j in N(i)} z_j = 0
// for i in V, where N(i) are the 4-neighbours of i inside the grid and valid samples are fixed
// (Dirichlet data; the grid edge is a natural Neumann boundary). Written as A x = b over V:
// A_ii = count_i, A_ij = -1 for void neighbours, b_i = sum of valid neighbours. A is symmetric
// positive definite because the region touches a valid sample. Regions do not interact, so each
// is solved alone on its box (bounding box + 1 ring, cut by the grid edge), in box coordinates:
// its bits depend only on that box, whichever window of the grid holds it (void_fill.hpp).
//
// Bound: by the discrete maximum principle the solution lies within [lo, hi], the range of the
// valid samples 4-adjacent to the region. The solver's iterates need not, so afterwards each
// value is clipped to [lo, hi] (a no-op up to rounding at convergence) and a few Gauss-Seidel
// sweeps follow; each update is a mean of values already in [lo, hi], clipped again against the
// last-bit rounding of the mean. So the bound holds exactly even if the solver stops early.
//
// Solver: conjugate gradients preconditioned by one multigrid V-cycle (aggregation multigrid:
// level k+1 merges the unknowns of 2 x 2 blocks of level k, coarse operator P^T A P, one forward
// Gauss-Seidel sweep before and one backward sweep after the coarse correction, so the
// preconditioner is symmetric; unknowns in red-black order; a dense Cholesky solve on the
// coarsest level). Iterations hardly grow with the void's size (measured: 17 for 8e3 voids, 24
// for 1.1e6 in a 1200-wide disc) where plain CG needs O(D) and Gauss-Seidel O(D^2) for a void D
// samples across. Time: about 0.8 us per void sample for large voids (1.1e6 voids: 0.9 s).
// Memory: about 115 bytes per void sample over all levels and the solver's vectors, plus 4
// bytes per sample of the window (labels) and of the region's box (unknown numbers) while it is
// solved.
#include "terralod/blocks/void_fill.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>

#include "terralod/pm/parallel.hpp"

namespace terralod::blocks {

namespace {

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

// Residuals below this fraction of the height scale (max of the valid range and the largest
// |height|) stop the conjugate gradients; so does kMaxIterations.
constexpr double kResidualTolerance = 1e-10;
constexpr int kMaxIterations = 500;
// Gauss-Seidel sweeps after the clip, at most.
constexpr int kPolishSweeps = 20;
// Levels stop coarsening at this many unknowns; the coarsest is solved by dense Cholesky.
constexpr std::size_t kCoarsest = 48;
// Scale of the coarse-grid correction. Piecewise-constant aggregation makes P^T A P about twice
// as stiff as the operator smooth errors see, so the plain correction is about half as long as it
// should be; 1.9 restores it (measured: 17-24 CG iterations from 8e3 to 1.1e6 voids, against
// 30-103 at 1.0) and stays below 2, where the V-cycle could stop being positive definite.
constexpr double kOverCorrection = 1.9;
// 1 / n for the finest level's diagonal n = 0 .. 4, as 1.0 / double(n) computes it.
constexpr double kInverse[5] = {std::numeric_limits<double>::infinity(), 1.0 / 1.0, 1.0 / 2.0, 1.0 / 3.0,
                                1.0 / 4.0};

// One level of the multigrid hierarchy: a sparse symmetric matrix on a grid of w x h cells,
// row k = diag_k x_k - sum_d weight_k,d x_{nb_k,d} (d: west, east, north, south). A missing
// neighbour points at the sentinel entry size() of every vector, which holds 0, with weight 0:
// no branches in the inner loops. All entries are small integers, exact in float. The finest
// level's weights are all 1 (0 at the sentinel), so it stores none (`unit`): with the sentinel
// at 0, its sums are bit for bit those of stored weights, and its diagonal (the neighbours inside
// the grid, 0 to 4) is a byte: 31 bytes less a void sample.
struct Level {
  int w = 0, h = 0;
  bool unit = false;                             // every weight 1 where a neighbour exists; `weight` empty
  std::vector<std::uint32_t> pos;                // cell index in this level's grid; freed once coarsened
  std::vector<double> diag, inv_diag;            // empty when unit: `count` instead
  std::vector<std::uint8_t> count;               // unit: neighbours inside the grid, the diagonal
  std::vector<std::array<std::uint32_t, 4>> nb;  // size(): no unknown there
  std::vector<std::array<float, 4>> weight;
  std::vector<std::uint32_t> parent;  // unknown of the next level
  std::vector<double> e, r;           // V-cycle work space, size() + 1 entries
  std::size_t size() const { return nb.size(); }
  double diag_of(std::size_t k) const { return unit ? double(count[k]) : diag[k]; }
  double inv_diag_of(std::size_t k) const { return unit ? kInverse[count[k]] : inv_diag[k]; }
  float weight_of(std::size_t k, int d) const {
    return unit ? (nb[k][std::size_t(d)] == size() ? 0.0f : 1.0f) : weight[k][std::size_t(d)];
  }
  void allocate(std::size_t m, bool unit_weights = false) {
    unit = unit_weights;
    if (unit)
      count.assign(m, 0);
    else
      diag.assign(m, 0.0);
    nb.assign(m, {std::uint32_t(m), std::uint32_t(m), std::uint32_t(m), std::uint32_t(m)});
    if (!unit) weight.assign(m, {0.0f, 0.0f, 0.0f, 0.0f});
    e.assign(m + 1, 0.0);
    r.assign(m + 1, 0.0);
  }
  void finish() {
    if (unit) return;
    inv_diag.resize(diag.size());
    for (std::size_t k = 0; k < diag.size(); ++k) inv_diag[k] = 1.0 / diag[k];
  }
};

inline double neighbour_sum(const Level& L, std::size_t k, const std::vector<double>& x) {
  const auto& n = L.nb[k];
  if (L.unit) return x[n[0]] + x[n[1]] + x[n[2]] + x[n[3]];  // 1 * v is v; the sentinel holds 0
  const auto& wt = L.weight[k];
  return double(wt[0]) * x[n[0]] + double(wt[1]) * x[n[1]] + double(wt[2]) * x[n[2]] +
         double(wt[3]) * x[n[3]];
}

/// (A x)_k; x needs the sentinel entry.
inline double row_product(const Level& L, std::size_t k, const std::vector<double>& x) {
  return L.diag_of(k) * x[k] - neighbour_sum(L, k, x);
}

inline void gauss_seidel_step(const Level& L, std::size_t k, const std::vector<double>& rhs,
                              std::vector<double>& x) {
  x[k] = (rhs[k] + neighbour_sum(L, k, x)) * L.inv_diag_of(k);
}

/// Sorts grid cells red first (even col + row), then black, each row-major. Neighbours have
/// opposite colours, so a Gauss-Seidel pass in this order is red-black Gauss-Seidel: no update
/// waits for the one before it, and the reverse pass is its adjoint.
void red_black_order(std::vector<std::uint32_t>& cells, int w) {
  std::vector<std::uint64_t> keys(cells.size());
  for (std::size_t i = 0; i < cells.size(); ++i) {
    const std::uint64_t colour = (cells[i] % std::uint32_t(w) + cells[i] / std::uint32_t(w)) & 1u;
    keys[i] = (colour << 32) | cells[i];
  }
  std::sort(keys.begin(), keys.end());
  for (std::size_t i = 0; i < cells.size(); ++i) cells[i] = std::uint32_t(keys[i]);
}

/// Level k+1 from level k by merging 2 x 2 blocks: P^T A P for piecewise-constant P.
Level coarsen(Level& fine) {
  Level coarse;
  coarse.w = (fine.w + 1) / 2;
  coarse.h = (fine.h + 1) / 2;
  std::vector<std::uint32_t> index(std::size_t(coarse.w) * coarse.h, kNone);
  const std::size_t mf = fine.size();
  fine.parent.resize(mf);
  for (std::size_t k = 0; k < mf; ++k) {
    const std::uint32_t c = fine.pos[k] % std::uint32_t(fine.w) / 2,
                        r = fine.pos[k] / std::uint32_t(fine.w) / 2;
    const std::uint32_t cell = r * std::uint32_t(coarse.w) + c;
    if (index[cell] == kNone) {
      index[cell] = 0;
      coarse.pos.push_back(cell);
    }
    fine.parent[k] = cell;
  }
  red_black_order(coarse.pos, coarse.w);
  for (std::size_t K = 0; K < coarse.pos.size(); ++K) index[coarse.pos[K]] = std::uint32_t(K);
  for (std::size_t k = 0; k < mf; ++k) fine.parent[k] = index[fine.parent[k]];
  coarse.allocate(coarse.pos.size());
  for (std::size_t k = 0; k < mf; ++k) {
    const std::uint32_t I = fine.parent[k];
    coarse.diag[I] += fine.diag_of(k);
    for (int d = 0; d < 4; ++d) {
      const std::uint32_t j = fine.nb[k][d];
      if (j == mf) continue;
      const std::uint32_t J = fine.parent[j];
      if (J == I) {
        coarse.diag[I] -= fine.weight_of(k, d);  // an edge inside the block
      } else {
        coarse.nb[I][d] = J;  // blocks are 2 x 2, so J lies in the same direction d
        coarse.weight[I][d] += fine.weight_of(k, d);
      }
    }
  }
  coarse.finish();
  return coarse;
}

/// Dense Cholesky factor of the coarsest level (lower triangle, row-major).
std::vector<double> cholesky(const Level& L) {
  const std::size_t m = L.size();
  std::vector<double> a(m * m, 0.0);
  for (std::size_t k = 0; k < m; ++k) {
    a[k * m + k] = L.diag_of(k);
    for (int d = 0; d < 4; ++d) {
      if (L.nb[k][d] != m) a[k * m + L.nb[k][d]] -= L.weight_of(k, d);
    }
  }
  for (std::size_t j = 0; j < m; ++j) {
    double s = a[j * m + j];
    for (std::size_t p = 0; p < j; ++p) s -= a[j * m + p] * a[j * m + p];
    a[j * m + j] = std::sqrt(std::max(s, 1e-300));
    for (std::size_t i = j + 1; i < m; ++i) {
      double t = a[i * m + j];
      for (std::size_t p = 0; p < j; ++p) t -= a[i * m + p] * a[j * m + p];
      a[i * m + j] = t / a[j * m + j];
    }
  }
  return a;
}

class Multigrid {
 public:
  explicit Multigrid(Level finest) {
    levels_.push_back(std::move(finest));
    while (levels_.back().size() > kCoarsest && (levels_.back().w > 1 || levels_.back().h > 1)) {
      levels_.push_back(coarsen(levels_.back()));
      std::vector<std::uint32_t>().swap(levels_[levels_.size() - 2].pos);
    }
    factor_ = cholesky(levels_.back());
  }
  const Level& finest() const { return levels_.front(); }

  /// out = one V-cycle applied to r (an approximation of A^-1 r; symmetric in r).
  void precondition(const std::vector<double>& r, std::vector<double>& out) {
    std::copy(r.begin(), r.begin() + std::ptrdiff_t(levels_[0].size()), levels_[0].r.begin());
    cycle(0);
    std::copy(levels_[0].e.begin(), levels_[0].e.begin() + std::ptrdiff_t(levels_[0].size()), out.begin());
  }

 private:
  void cycle(std::size_t l) {
    Level& L = levels_[l];
    const std::size_t m = L.size();
    if (l + 1 == levels_.size()) {  // coarsest: L L^T e = r
      for (std::size_t i = 0; i < m; ++i) {
        double s = L.r[i];
        for (std::size_t p = 0; p < i; ++p) s -= factor_[i * m + p] * L.e[p];
        L.e[i] = s / factor_[i * m + i];
      }
      for (std::size_t i = m; i-- > 0;) {
        double s = L.e[i];
        for (std::size_t p = i + 1; p < m; ++p) s -= factor_[p * m + i] * L.e[p];
        L.e[i] = s / factor_[i * m + i];
      }
      return;
    }
    std::fill(L.e.begin(), L.e.end(), 0.0);
    for (std::size_t k = 0; k < m; ++k) gauss_seidel_step(L, k, L.r, L.e);
    Level& C = levels_[l + 1];
    std::fill(C.r.begin(), C.r.end(), 0.0);
    for (std::size_t k = 0; k < m; ++k) C.r[L.parent[k]] += L.r[k] - row_product(L, k, L.e);
    cycle(l + 1);
    for (std::size_t k = 0; k < m; ++k) L.e[k] += kOverCorrection * C.e[L.parent[k]];
    for (std::size_t k = m; k-- > 0;) gauss_seidel_step(L, k, L.r, L.e);
  }

  std::vector<Level> levels_;
  std::vector<double> factor_;
};

double dot(const std::vector<double>& a, const std::vector<double>& b, std::size_t m) {
  double s = 0.0;
  for (std::size_t i = 0; i < m; ++i) s += a[i] * b[i];
  return s;
}

// One void region: its samples are cells[first, first + count) (window indices), its bounding
// box bbox (window coordinates).
struct Region {
  std::size_t first = 0, count = 0;
  SampleRect bbox;
};

// What solving one region did.
struct RegionSolve {
  bool filled = false;
  int iterations = 0;
  double residual = 0.0;
  int sweeps = 0;
  double last_change = 0.0;
};

/// Fills region `id` on `box` (its bounding box plus one ring, cut by the grid edge; window
/// coordinates, inside the window). Everything is computed in the box's own coordinates and in
/// an order fixed by them, and only the region's samples and the valid samples 4-adjacent to
/// them are read (label[j] == id: the region; kNone: valid), so the result depends on nothing
/// else. Writes only the region's samples of z.
RegionSolve solve_region(std::vector<double>& z, std::size_t ww, const std::vector<std::uint32_t>& label,
                         std::uint32_t id, const std::uint32_t* region_cells, std::size_t m, SampleRect box) {
  RegionSolve out;
  const std::size_t bw = std::size_t(box.width()), bh = std::size_t(box.height());
  const auto window_index = [&](std::size_t local) {
    return (local / bw + std::size_t(box.row0)) * ww + local % bw + std::size_t(box.col0);
  };
  // The region's samples as box indices, red-black order (see red_black_order).
  std::vector<std::uint32_t> order(m);
  for (std::size_t k = 0; k < m; ++k) {
    const std::size_t i = region_cells[k];
    order[k] = std::uint32_t((i / ww - std::size_t(box.row0)) * bw + i % ww - std::size_t(box.col0));
  }
  red_black_order(order, int(bw));

  // Neighbours of sample k: d = west, east, north, south; -1 outside the box (= outside the grid).
  const auto neighbours = [&](std::size_t local, std::array<std::ptrdiff_t, 4>& at) {
    const std::size_t c = local % bw, r = local / bw;
    at = {c > 0 ? std::ptrdiff_t(local - 1) : -1, c + 1 < bw ? std::ptrdiff_t(local + 1) : -1,
          r > 0 ? std::ptrdiff_t(local - bw) : -1, r + 1 < bh ? std::ptrdiff_t(local + bw) : -1};
  };
  std::array<std::ptrdiff_t, 4> at{};

  // The region's bounds [lo, hi]: the range of its valid 4-neighbours.
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (std::size_t k = 0; k < m; ++k) {
    neighbours(order[k], at);
    for (int d = 0; d < 4; ++d) {
      if (at[d] < 0) continue;
      const std::size_t j = window_index(std::size_t(at[d]));
      if (label[j] == id) continue;
      assert(label[j] == kNone && std::isfinite(z[j]));
      lo = std::min(lo, z[j]);
      hi = std::max(hi, z[j]);
    }
  }
  assert(lo <= hi && "a void region with no valid neighbour: the grid is all void");
  if (!(lo <= hi)) return out;
  out.filled = true;

  // The system A x = b: A_kk = neighbours in the grid, A_kj = -1 for void neighbours, b_k = sum
  // of valid neighbours.
  std::vector<std::uint32_t> slot(bw * bh, kNone);
  for (std::size_t k = 0; k < m; ++k) slot[order[k]] = std::uint32_t(k);
  Level finest;
  finest.w = int(bw);
  finest.h = int(bh);
  finest.pos = order;
  finest.allocate(m, /*unit_weights=*/true);
  std::vector<double> b(m, 0.0), x(m + 1, 0.0);  // x[m]: the sentinel
  for (std::size_t k = 0; k < m; ++k) {
    neighbours(order[k], at);
    int valid = 0;
    for (int d = 0; d < 4; ++d) {
      if (at[d] < 0) continue;
      ++finest.count[k];
      const std::uint32_t s = slot[std::size_t(at[d])];
      if (s != kNone) {
        finest.nb[k][d] = s;  // weight 1 (unit)
      } else {
        b[k] += z[window_index(std::size_t(at[d]))];
        ++valid;
      }
    }
    // First guess: the mean of the valid neighbours, or the middle of the bounds.
    x[k] = valid > 0 ? b[k] / valid : 0.5 * (lo + hi);
  }
  std::vector<std::uint32_t>().swap(slot);
  finest.finish();

  // Preconditioned conjugate gradients (the multigrid is built only when needed).
  const double tolerance = kResidualTolerance * std::max({hi - lo, std::abs(hi), std::abs(lo), 1e-300});
  std::vector<double> r(m);
  double rmax = 0.0;
  for (std::size_t k = 0; k < m; ++k) {
    r[k] = b[k] - row_product(finest, k, x);
    rmax = std::max(rmax, std::abs(r[k]));
  }
  std::optional<Multigrid> mg;
  const Level* A = &finest;
  int it = 0;
  if (rmax > tolerance) {
    mg.emplace(std::move(finest));
    A = &mg->finest();
    // q (the preconditioned residual) and A p share one vector: A p is dead once r is updated.
    std::vector<double> p(m + 1, 0.0), q(m);
    std::vector<double>& ap = q;
    mg->precondition(r, q);
    std::copy(q.begin(), q.end(), p.begin());
    double rq = dot(r, q, m);
    while (it < kMaxIterations && rq > 0.0) {
      for (std::size_t k = 0; k < m; ++k) ap[k] = row_product(*A, k, p);
      const double pap = dot(p, ap, m);
      if (!(pap > 0.0)) break;
      const double alpha = rq / pap;
      rmax = 0.0;
      for (std::size_t k = 0; k < m; ++k) {
        x[k] += alpha * p[k];
        r[k] -= alpha * ap[k];
        rmax = std::max(rmax, std::abs(r[k]));
      }
      ++it;
      if (rmax <= tolerance) break;
      mg->precondition(r, q);
      const double rq_next = dot(r, q, m);
      const double beta = rq_next / rq;
      rq = rq_next;
      for (std::size_t k = 0; k < m; ++k) p[k] = q[k] + beta * p[k];
    }
  }
  out.iterations = it;
  out.residual = rmax;

  // Clip to the bounds, then Gauss-Seidel sweeps that keep them (see the top).
  for (std::size_t k = 0; k < m; ++k) x[k] = std::clamp(x[k], lo, hi);
  double change = 0.0;
  int sweeps = 0;
  do {
    change = 0.0;
    for (std::size_t k = 0; k < m; ++k) {
      const double next = std::clamp((b[k] + neighbour_sum(*A, k, x)) / A->diag_of(k), lo, hi);
      change = std::max(change, std::abs(next - x[k]));
      x[k] = next;
    }
    ++sweeps;
  } while (change > tolerance && sweeps < kPolishSweeps);
  out.sweeps = sweeps;
  out.last_change = change;
  for (std::size_t k = 0; k < m; ++k) z[window_index(order[k])] = x[k];
  return out;
}

}  // namespace

VoidFillStats fill_voids_in_window(std::vector<double>& z, SampleRect window, int grid_width, int grid_height,
                                   const VoidFillOptions& options) {
  assert(grid_width >= 1 && grid_height >= 1);
  assert(window.col0 >= 0 && window.row0 >= 0 && window.col0 <= window.col1 && window.row0 <= window.row1);
  assert(window.col1 < grid_width && window.row1 < grid_height);
  assert(z.size() == window.samples() && z.size() < std::size_t(kNone));
  VoidFillStats stats;
  const std::size_t n = z.size(), ww = std::size_t(window.width()), wh = std::size_t(window.height());

  // 4-connected void regions, breadth-first from the first sample of each in row-major order.
  std::vector<std::uint32_t> label(n, kNone);
  std::vector<std::uint32_t> cells;
  std::vector<Region> regions;
  for (std::size_t seed = 0; seed < n; ++seed) {
    if (std::isfinite(z[seed]) || label[seed] != kNone) continue;
    const std::uint32_t id = std::uint32_t(regions.size());
    Region g;
    g.first = cells.size();
    g.bbox = SampleRect{int(seed % ww), int(seed / ww), int(seed % ww), int(seed / ww)};
    cells.push_back(std::uint32_t(seed));
    label[seed] = id;
    for (std::size_t q = g.first; q < cells.size(); ++q) {
      const std::size_t i = cells[q], c = i % ww, r = i / ww;
      g.bbox = SampleRect{std::min(g.bbox.col0, int(c)), std::min(g.bbox.row0, int(r)),
                          std::max(g.bbox.col1, int(c)), std::max(g.bbox.row1, int(r))};
      const bool has[4] = {c > 0, c + 1 < ww, r > 0, r + 1 < wh};
      const std::size_t at[4] = {i - 1, i + 1, i - ww, i + ww};
      for (int d = 0; d < 4; ++d) {
        if (has[d] && !std::isfinite(z[at[d]]) && label[at[d]] == kNone) {
          label[at[d]] = id;
          cells.push_back(std::uint32_t(at[d]));
        }
      }
    }
    g.count = cells.size() - g.first;
    regions.push_back(g);
  }
  stats.voids = cells.size();
  stats.regions = regions.size();

  // Which regions this window can close; the rest stay void.
  const bool cut_w = window.col0 > 0, cut_e = window.col1 + 1 < grid_width;
  const bool cut_n = window.row0 > 0, cut_s = window.row1 + 1 < grid_height;
  std::vector<std::uint32_t> closed;
  for (std::uint32_t id = 0; id < regions.size(); ++id) {
    const Region& g = regions[id];
    const SampleRect& b = g.bbox;
    if (b.samples() > options.max_region_cells) {
      ++stats.capped_regions;
      stats.capped_samples += g.count;
    } else if ((cut_w && b.col0 == 0) || (cut_e && std::size_t(b.col1) + 1 == ww) || (cut_n && b.row0 == 0) ||
               (cut_s && std::size_t(b.row1) + 1 == wh)) {
      stats.open.push_back(OpenVoidRegion{
          SampleRect{b.col0 + window.col0, b.row0 + window.row0, b.col1 + window.col0, b.row1 + window.row0},
          g.count});
    } else {
      closed.push_back(id);
    }
  }
  // Largest first, so that one big region does not finish alone at the end.
  std::stable_sort(closed.begin(), closed.end(),
                   [&](std::uint32_t a, std::uint32_t b) { return regions[a].count > regions[b].count; });

  std::vector<RegionSolve> solved(closed.size());
  pm::parallel_for(closed.size(), options.threads, [&](std::size_t k) {
    const std::uint32_t id = closed[k];
    const Region& g = regions[id];
    const SampleRect box{std::max(g.bbox.col0 - 1, 0), std::max(g.bbox.row0 - 1, 0),
                         std::min(g.bbox.col1 + 1, int(ww) - 1), std::min(g.bbox.row1 + 1, int(wh) - 1)};
    const bool tell = options.on_solve && g.count >= options.notify_from;
    const VoidSolveNotice notice{SampleRect{g.bbox.col0 + window.col0, g.bbox.row0 + window.row0,
                                            g.bbox.col1 + window.col0, g.bbox.row1 + window.row0},
                                 g.count, -1.0};
    if (tell) options.on_solve(notice);
    const auto t0 = std::chrono::steady_clock::now();
    solved[k] = solve_region(z, ww, label, id, cells.data() + g.first, g.count, box);
    if (tell) {
      VoidSolveNotice done = notice;
      done.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      options.on_solve(done);
    }
  });
  for (std::size_t k = 0; k < closed.size(); ++k) {
    const RegionSolve& s = solved[k];
    if (!s.filled) continue;
    ++stats.filled_regions;
    stats.filled += regions[closed[k]].count;
    stats.iterations = std::max(stats.iterations, s.iterations);
    stats.residual = std::max(stats.residual, s.residual);
    stats.sweeps = std::max(stats.sweeps, s.sweeps);
    stats.last_change = std::max(stats.last_change, s.last_change);
    const Region& g = regions[closed[k]];
    if (options.keep_filled_from == 0 || g.count < options.keep_filled_from) continue;
    FilledVoidRegion& kept = stats.kept.emplace_back();
    std::vector<std::uint32_t> at(cells.begin() + std::ptrdiff_t(g.first),
                                  cells.begin() + std::ptrdiff_t(g.first + g.count));
    std::sort(at.begin(), at.end());
    kept.runs = runs_of(at, window);
    kept.values.reserve(at.size());
    for (const std::uint32_t i : at) kept.values.push_back(z[i]);
  }
  return stats;
}

SampleRuns runs_of(const std::vector<std::uint32_t>& cells, SampleRect window) {
  const std::uint32_t w = std::uint32_t(window.width());
  SampleRuns runs;
  for (const std::uint32_t i : cells) {
    const int c = window.col0 + int(i % w), r = window.row0 + int(i / w);
    if (!runs.empty() && runs.back()[0] == r && runs.back()[2] + 1 == c) {
      runs.back()[2] = c;
    } else {
      runs.push_back({r, c, c});
    }
  }
  return runs;
}

VoidFillStats fill_voids(std::vector<double>& z, int width, int height, const VoidFillOptions& options) {
  return fill_voids_in_window(z, SampleRect{0, 0, width - 1, height - 1}, width, height, options);
}

}  // namespace terralod::blocks
