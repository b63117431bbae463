// Step 1 of the hybrid model's build (hybrid_builder.hpp): the TIN read into the lattice and
// checked (finite, inside the grid domain, non-degenerate, manifold), its boundary rings, and
// the intersection vertices where the rings cross the finest grid lines, with the TIN triangles
// split there; each ring then starts at a section end of the coarsest level.
// Memory: the TIN's directed edges in a hash, O(TIN triangles).
#include <algorithm>
#include <cmath>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "hybrid_builder.hpp"
#include "hybrid_geometry.hpp"

namespace terralod::blocks::hybrid {

using detail::kScale;
using detail::LPoint;
using detail::orient;

namespace {

std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) { return (std::uint64_t(a) << 32) | b; }

}  // namespace

void Builder::load_tin(const TinMesh& tin) {
  const std::int64_t W = std::int64_t(h.domain_w_) * kScale, H = std::int64_t(h.domain_h_) * kScale;
  if (tin.points.empty() || tin.triangles.empty()) throw HybridError(src + ": the TIN has no triangles");
  for (std::size_t i = 0; i < tin.points.size(); ++i) {
    const auto& p = tin.points[i];
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
      throw HybridError(src + ": TIN vertex " + std::to_string(i) + " is not finite");
    HybridTerrain::Vertex v{std::llround(p[0] * kScale), std::llround(p[1] * kScale), p[2]};
    if (v.x < 0 || v.y < 0 || v.x > W || v.y > H)
      throw HybridError(src + ": TIN vertex " + std::to_string(i) + " at (col,row) (" + std::to_string(p[0]) +
                        "," + std::to_string(p[1]) + ") lies outside the grid domain [0," +
                        std::to_string(h.domain_w_) + "]x[0," + std::to_string(h.domain_h_) + "]");
    h.vertices_.push_back(v);
  }
  for (std::size_t i = 0; i < tin.triangles.size(); ++i) {
    auto t = tin.triangles[i];
    for (auto v : t)
      if (v >= tin.points.size())
        throw HybridError(src + ": triangle " + std::to_string(i) + " has a bad index");
    const auto o = orient(P(t[0]), P(t[1]), P(t[2]));
    if (o == 0)
      throw HybridError(src + ": TIN triangle " + std::to_string(i) + " is degenerate in plan view");
    if (o < 0) std::swap(t[1], t[2]);
    h.tin_.push_back(t);
  }
  // Directed edges: each at most once (else the TIN overlaps itself or is not manifold).
  std::unordered_map<std::uint64_t, std::uint32_t> he;
  he.reserve(h.tin_.size() * 4);
  for (std::uint32_t i = 0; i < h.tin_.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = h.tin_[i][k], b = h.tin_[i][(k + 1) % 3];
      if (!he.emplace(edge_key(a, b), i).second)
        throw HybridError(src + ": TIN edge (" + std::to_string(a) + "," + std::to_string(b) +
                          ") is used twice in the same direction (overlapping or non-manifold TIN)");
    }
  std::unordered_map<std::uint32_t, std::uint32_t> next;  // boundary half-edge a -> b
  for (const auto& [key, tri] : he) {
    const std::uint32_t a = std::uint32_t(key >> 32), b = std::uint32_t(key);
    if (he.count(edge_key(b, a))) continue;
    if (!next.emplace(a, b).second)
      throw HybridError(src + ": the TIN boundary touches itself at vertex " + std::to_string(a) +
                        " (not a set of simple rings)");
  }
  // Rings, each started at its smallest vertex id for determinism.
  std::vector<std::uint32_t> starts;
  for (const auto& [a, b] : next) starts.push_back(a);
  std::sort(starts.begin(), starts.end());
  std::unordered_map<std::uint32_t, bool> done;
  std::vector<std::vector<std::uint32_t>> rings;
  for (std::uint32_t s : starts) {
    if (done.count(s)) continue;
    std::vector<std::uint32_t> ring;
    std::uint32_t v = s;
    do {
      done[v] = true;
      ring.push_back(v);
      auto it = next.find(v);
      if (it == next.end())
        throw HybridError(src + ": the TIN boundary is not closed at vertex " + std::to_string(v));
      v = it->second;
    } while (v != s && ring.size() <= next.size());
    rings.push_back(std::move(ring));
  }
  // Intersection vertices with the finest-level grid lines; split the triangle of each edge.
  // triangle -> (edge start, new vertices on that edge in order)
  std::unordered_map<std::uint32_t, std::vector<std::pair<std::uint32_t, std::uint32_t>>> extra;
  for (auto& ring : rings) {
    std::vector<std::uint32_t> out;
    for (std::size_t i = 0; i < ring.size(); ++i) {
      const std::uint32_t a = ring[i], b = ring[(i + 1) % ring.size()];
      out.push_back(a);
      const LPoint A = P(a), B = P(b);
      std::vector<std::pair<double, LPoint>> cuts;
      auto add_lines = [&](bool vertical) {
        const std::int64_t a0 = vertical ? A.x : A.y, b0 = vertical ? B.x : B.y;
        if (a0 == b0) return;
        const std::int64_t lo = std::min(a0, b0), hi = std::max(a0, b0);
        for (std::int64_t c = (lo / ks + 1) * ks; c < hi; c += ks) {
          const double t = double(c - a0) / double(b0 - a0);
          LPoint p = vertical ? LPoint{c, std::llround(double(A.y) + t * double(B.y - A.y))}
                              : LPoint{std::llround(double(A.x) + t * double(B.x - A.x)), c};
          cuts.push_back({t, p});
        }
      };
      add_lines(true);
      add_lines(false);
      std::sort(cuts.begin(), cuts.end(), [](const auto& u, const auto& v) { return u.first < v.first; });
      const std::uint32_t tri = he.at(edge_key(a, b));
      LPoint last = A;
      for (const auto& [t, p] : cuts) {
        if (p == last || p == B) continue;
        last = p;
        const double z = h.vertices_[a].z + t * (h.vertices_[b].z - h.vertices_[a].z);
        h.vertices_.push_back({p.x, p.y, z});
        const std::uint32_t id = std::uint32_t(h.vertices_.size() - 1);
        out.push_back(id);
        extra[tri].push_back({a, id});
      }
    }
    ring = std::move(out);
  }
  for (auto& [tri, ids] : extra) split_triangle(tri, ids);
  // Rotate every ring to start at a section end of the coarsest level.
  const std::int64_t cs = ks << (L - 1);
  for (auto& ring : rings) {
    const std::size_t n = ring.size();
    std::size_t start = n;
    for (std::size_t i = 0; i < n && start == n; ++i) {
      const std::int64_t c0 = edge_cell(P(ring[(i + n - 1) % n]), P(ring[i]), cs);
      const std::int64_t c1 = edge_cell(P(ring[i]), P(ring[(i + 1) % n]), cs);
      if (c0 < 0 || c1 < 0 || c0 != c1) start = i;
    }
    if (start == n)
      throw HybridError(src + ": a TIN boundary ring lies inside one coarsest grid cell (" +
                        std::to_string(h.step_ << (L - 1)) +
                        " samples); use fewer levels or a smaller grid step");
    std::rotate(ring.begin(), ring.begin() + std::ptrdiff_t(start), ring.end());
  }
  h.ring_begin_.push_back(0);
  for (const auto& ring : rings) {
    h.tb_.insert(h.tb_.end(), ring.begin(), ring.end());
    h.ring_begin_.push_back(std::uint32_t(h.tb_.size()));
  }
  h.conn_.assign(h.tb_.size(), 1);
}

void Builder::split_triangle(std::uint32_t tri,
                             const std::vector<std::pair<std::uint32_t, std::uint32_t>>& ids) {
  const auto t = h.tin_[tri];
  std::vector<std::uint32_t> poly;
  for (int k = 0; k < 3; ++k) {
    poly.push_back(t[k]);
    for (const auto& [a, id] : ids)
      if (a == t[k]) poly.push_back(id);  // new vertices of edge t[k] -> t[k+1], in order
  }
  std::vector<LPoint> pts(h.vertices_.size());
  for (std::uint32_t v : poly) pts[v] = P(v);
  std::vector<std::array<std::uint32_t, 3>> out;
  if (!detail::ear_clip(pts, poly, out))
    throw HybridError(src + ": TIN triangle " + std::to_string(tri) +
                      " is too thin to be split where its boundary edge crosses a grid line");
  h.tin_[tri] = out[0];
  for (std::size_t i = 1; i < out.size(); ++i) h.tin_.push_back(out[i]);
}

}  // namespace terralod::blocks::hybrid
