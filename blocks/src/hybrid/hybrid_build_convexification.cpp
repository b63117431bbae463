// Step 2 of the hybrid model's build (hybrid_builder.hpp), per cycle: the local convexification
// of an uncovered region, i.e. the convex hull chain of the cycle and the triangulation of each
// pocket between the chain and the boundary, in the fan-with-nested-cavities form that one
// connectivity index per TIN-boundary vertex encodes (the paper's section 3 and appendix).
// Memory: per pocket of N hull vertices, O(N^2) diagonals and the search's memo.
#include <algorithm>
#include <cmath>
#include <string>
#include <unordered_map>
#include <vector>

#include "hybrid_builder.hpp"
#include "hybrid_geometry.hpp"

namespace terralod::blocks::hybrid {

using detail::kScale;
using detail::LPoint;
using detail::orient;

// Triangulation of one reduced pocket polygon in the fan-with-nested-cavities form that one
// connectivity index per vertex encodes, preferring triangulations that every finer level still
// decodes exactly (see the note on constraints R1/R2 below). Memoised search, O(N^4) worst case.
struct Builder::Pocket {
  std::vector<LPoint> pt;
  std::vector<std::int64_t> last;  // reduced index of the finer group's last vertex; -1 free; N+1 beyond
  std::vector<char> fixed;         // section exits: may not open a cavity here
  std::vector<std::vector<char>> diag;
  bool constrained = true;
  std::unordered_map<std::uint64_t, int> memo;  // -> chosen s' + 1, or 0 = impossible
};

namespace {

std::uint64_t key(std::size_t a, std::size_t s, std::size_t j, bool need) {
  return (std::uint64_t(a) << 40) | (std::uint64_t(s) << 20) | (std::uint64_t(j) << 1) | (need ? 1 : 0);
}

}  // namespace

/// Hull chain of a cycle: convex hull of the cycle's vertices and the corners not in its arc,
/// walked CCW from the first to the last vertex of the sequence (collinear points kept).
std::vector<std::size_t> Builder::hull_chain(int l, std::uint32_t cell, int cx, const Cycle& cyc,
                                             std::int64_t x0, std::int64_t y0, std::int64_t cs) {
  struct Pt {
    LPoint p;
    long pos;  // sequence position, or -1 for a corner
  };
  std::vector<Pt> pts;
  for (std::size_t i = 0; i < cyc.seq.size(); ++i) pts.push_back({TP(cyc.seq[i]), long(i)});
  const LPoint corner[4] = {{x0, y0}, {x0 + cs, y0}, {x0 + cs, y0 + cs}, {x0, y0 + cs}};
  for (const LPoint& c : corner) {
    const bool in_arc = std::find(cyc.corners.begin(), cyc.corners.end(), c) != cyc.corners.end();
    const bool is_vertex = std::any_of(pts.begin(), pts.end(), [&](const Pt& q) { return q.p == c; });
    if (!in_arc && !is_vertex) pts.push_back({c, -1});
  }
  // Andrew's monotone chain, strict.
  std::vector<Pt> s = pts;
  std::sort(s.begin(), s.end(),
            [](const Pt& a, const Pt& b) { return a.p.x != b.p.x ? a.p.x < b.p.x : a.p.y < b.p.y; });
  std::vector<LPoint> hull;
  for (int pass = 0; pass < 2; ++pass) {
    const std::size_t base = hull.size();
    for (const Pt& q : s) {
      while (hull.size() >= base + 2 && orient(hull[hull.size() - 2], hull.back(), q.p) <= 0) hull.pop_back();
      hull.push_back(q.p);
    }
    hull.pop_back();
    std::reverse(s.begin(), s.end());
  }
  // Boundary walk with collinear points: for each hull edge, every point on it in order.
  std::vector<Pt> ring;
  for (std::size_t k = 0; k < hull.size(); ++k) {
    const LPoint a = hull[k], b = hull[(k + 1) % hull.size()];
    std::vector<std::pair<double, Pt>> on;
    for (const Pt& q : pts)
      if (detail::on_segment(a, b, q.p) && !(q.p == b))
        on.push_back({std::hypot(double(q.p.x - a.x), double(q.p.y - a.y)), q});
    std::sort(on.begin(), on.end(), [](const auto& u, const auto& v) {
      return u.first != v.first ? u.first < v.first : u.second.pos < v.second.pos;
    });
    for (const auto& [d, q] : on) ring.push_back(q);
  }
  const long last = long(cyc.seq.size() - 1);
  std::size_t start = ring.size();
  for (std::size_t k = 0; k < ring.size(); ++k)
    if (ring[k].pos == 0) start = k;
  auto fail = [&](const std::string& why) {
    return HybridError(src + ": " + cell_name(l, cell, cx) + ": " + why);
  };
  if (start == ring.size()) throw fail("the first vertex of a section is not on the convex hull");
  std::vector<std::size_t> chain;
  for (std::size_t k = 0; k < ring.size(); ++k) {
    const Pt& q = ring[(start + k) % ring.size()];
    if (q.pos < 0) throw fail("the convex hull chain passes a cell corner (unsupported configuration)");
    if (!chain.empty() && std::size_t(q.pos) <= chain.back()) continue;  // duplicate position
    chain.push_back(std::size_t(q.pos));
    if (q.pos == last) break;
  }
  if (chain.back() != std::size_t(last)) throw fail("the convex hull chain does not reach the section's end");
  return chain;
}

void Builder::convexify(int l, std::uint32_t cell, int cx, Cycle& cyc) {
  const std::int64_t cs = ks << l;
  const std::int64_t x0 = std::int64_t(cell % std::uint32_t(cx)) * cs,
                     y0 = std::int64_t(cell / std::uint32_t(cx)) * cs;
  const std::vector<std::size_t> chain = hull_chain(l, cell, cx, cyc, x0, y0, cs);
  for (std::size_t p : chain) cyc.hull.push_back(cyc.seq[p]);
  std::unordered_map<std::uint32_t, std::size_t> pos;
  for (std::size_t i = 0; i < cyc.seq.size(); ++i) pos.emplace(cyc.seq[i], i);
  const std::uint32_t n = std::uint32_t(h.tb_.size());
  for (std::size_t k = 0; k + 1 < chain.size(); ++k) {
    const std::size_t p = chain[k], q = chain[k + 1];
    if (q == p + 1) continue;
    // Reduced polygon: finer cavities collapsed to their lids.
    std::vector<std::size_t> R{p};
    std::size_t r = p;
    while (r < q) {
      const std::uint32_t t = cyc.seq[r];
      std::size_t nx = r + 1;
      if (h.conn_[t] > 1 && !std::binary_search(cyc.gaps.begin(), cyc.gaps.end(), r)) {
        auto it = pos.find((t + h.conn_[t]) % n);
        if (it == pos.end() || it->second <= r || it->second > q)
          throw HybridError(
              src + ": " + cell_name(l, cell, cx) +
              ": a finer level's cavity crosses this level's convex hull (unsupported configuration)");
        nx = it->second;
      }
      r = nx;
      R.push_back(r);
    }
    if (R.size() == 2) continue;  // already filled at a finer level
    triangulate_pocket(l, cell, cx, cyc, R);
  }
}

// R1: a new cavity of k must end beyond the finer group that k belongs to (else the finer level
// would decode it as its own). R2: then k's finer successor must open such a cavity too, unless
// it is the group's last vertex (else the finer level would fan k too far).
bool Builder::cave(Pocket& pk, std::size_t k, std::size_t j) {
  if (!pk.diag[k][j] || pk.fixed[k]) return false;
  bool need = false;
  if (pk.constrained && pk.last[k] >= 0) {
    if (std::int64_t(j) <= pk.last[k]) return false;
    need = std::int64_t(k + 1) != pk.last[k];
  }
  return fan(pk, k, k + 1, j, need);
}

bool Builder::fan(Pocket& pk, std::size_t a, std::size_t s, std::size_t j, bool need) {
  if (s == j) return !need;
  const std::uint64_t kk = key(a, s, j, need);
  if (auto it = pk.memo.find(kk); it != pk.memo.end()) return it->second > 0;
  pk.memo[kk] = 0;
  for (std::size_t s2 = s + 1; s2 <= j; ++s2) {
    if (need && s2 == s + 1) continue;
    if (orient(pk.pt[a], pk.pt[s], pk.pt[s2]) == 0) continue;
    if (s2 != j && !pk.diag[a][s2]) continue;
    if (s2 > s + 1 && !cave(pk, s, s2)) continue;
    if (!fan(pk, a, s2, j, false)) continue;
    pk.memo[kk] = int(s2) + 1;
    return true;
  }
  return false;
}

void Builder::emit(Pocket& pk, const std::vector<std::uint32_t>& tbs, std::size_t a, std::size_t s,
                   std::size_t j, bool need, int l, std::uint32_t cell) {
  while (s != j) {
    const std::size_t s2 = std::size_t(pk.memo.at(key(a, s, j, need)) - 1);
    std::array<std::uint32_t, 3> tri{tbs[a], tbs[s2], tbs[s]};
    if (orient(pk.pt[a], pk.pt[s2], pk.pt[s]) < 0) std::swap(tri[1], tri[2]);
    h.direct_.push_back({l, cell, tri});
    if (s2 > s + 1) {
      h.conn_[tbs[s]] = dist(tbs[s], tbs[s2]);
      bool need2 = false;
      if (pk.constrained && pk.last[s] >= 0) need2 = std::int64_t(s + 1) != pk.last[s];
      emit(pk, tbs, s, s + 1, s2, need2, l, cell);
    }
    s = s2;
    need = false;
  }
}

void Builder::triangulate_pocket(int l, std::uint32_t cell, int cx, const Cycle& cyc,
                                 const std::vector<std::size_t>& R) {
  const std::size_t N = R.size() - 1;
  if (N > 400)
    throw HybridError(src + ": " + cell_name(l, cell, cx) + ": a cavity of " + std::to_string(N + 1) +
                      " hull vertices is too large (limit 401)");
  Pocket pk;
  std::vector<std::uint32_t> tbs;
  for (std::size_t r : R) {
    tbs.push_back(cyc.seq[r]);
    pk.pt.push_back(TP(cyc.seq[r]));
  }
  pk.fixed.assign(N + 1, 0);
  for (std::size_t k = 0; k <= N; ++k)
    pk.fixed[k] = std::binary_search(cyc.gaps.begin(), cyc.gaps.end(), R[k]);
  if (pk.fixed[0])
    throw HybridError(
        src + ": " + cell_name(l, cell, cx) +
        ": a cavity starts at a section's exit point (unsupported configuration); use fewer levels");
  // Finer-level groups.
  pk.last.assign(N + 1, -1);
  for (std::size_t k = 0; k <= N; ++k) {
    const std::int64_t g = prev_group_last_.empty() ? -1 : prev_group_last_[tbs[k]];
    if (g < 0) continue;
    pk.last[k] = std::int64_t(N + 1);
    for (std::size_t m = k + 1; m <= N; ++m)
      if (tbs[m] == std::uint32_t(g)) {
        pk.last[k] = std::int64_t(m);
        break;
      }
  }
  // Valid diagonals of the polygon R_0..R_N closed by the lid.
  pk.diag.assign(N + 1, std::vector<char>(N + 1, 0));
  // CCW order of the pocket: R_0, R_N, R_{N-1}, ..., R_1.
  auto ccw_next = [&](std::size_t k) { return k == 0 ? N : k - 1; };
  auto ccw_prev = [&](std::size_t k) { return k == N ? 0 : k + 1; };
  auto in_cone = [&](std::size_t a, std::size_t b) {
    const LPoint& A = pk.pt[a];
    const LPoint& B = pk.pt[b];
    const LPoint& A0 = pk.pt[ccw_prev(a)];
    const LPoint& A1 = pk.pt[ccw_next(a)];
    if (orient(A, A1, A0) >= 0) return orient(A, B, A0) > 0 && orient(B, A, A1) > 0;
    return !(orient(A, B, A1) >= 0 && orient(B, A, A0) >= 0);
  };
  for (std::size_t a = 0; a <= N; ++a)
    for (std::size_t b = a + 2; b <= N; ++b) {
      if (a == 0 && b == N) {
        pk.diag[a][b] = 1;
        continue;
      }
      bool ok = in_cone(a, b) && in_cone(b, a);
      for (std::size_t e = 0; e <= N && ok; ++e) {
        const std::size_t f = (e == N) ? 0 : e + 1;  // edge e -> f (the lid for e == N)
        if (e == a || e == b || f == a || f == b) {
          // Adjacent edge: only a collinear overlap is a problem.
          const std::size_t other = (e == a || e == b) ? f : e;
          if (other != a && other != b && detail::on_segment(pk.pt[a], pk.pt[b], pk.pt[other])) ok = false;
          continue;
        }
        if (detail::segments_meet(pk.pt[a], pk.pt[b], pk.pt[e], pk.pt[f])) ok = false;
      }
      pk.diag[a][b] = ok ? 1 : 0;
    }
  bool need0 = false, ok = true;
  if (pk.last[0] >= 0) {
    ok = std::int64_t(N) > pk.last[0];
    need0 = std::int64_t(1) != pk.last[0];
  }
  if (!(ok && fan(pk, 0, 1, N, need0))) {
    pk.constrained = false;
    pk.memo.clear();
    need0 = false;
    if (!fan(pk, 0, 1, N, false))
      throw HybridError(src + ": " + cell_name(l, cell, cx) +
                        ": a cavity of the convexification cannot be triangulated");
  }
  h.conn_[tbs[0]] = dist(tbs[0], tbs[N]);
  emit(pk, tbs, 0, 1, N, need0, l, cell);
}

}  // namespace terralod::blocks::hybrid
