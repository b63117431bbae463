// Seam stitching by fan-splitting border triangles at the neighbours' border vertices (the
// error argument is in seam_stitch.hpp). Memory: border vertex sets + one map per patch.
#include "terralod/blocks/seam_stitch.hpp"

#include <algorithm>
#include <cassert>
#include <unordered_map>

namespace terralod::blocks {
namespace {

std::uint64_t key(pm::GridPoint p) { return (std::uint64_t(std::uint32_t(p.x)) << 32) | std::uint32_t(p.y); }

}  // namespace

StitchResult stitch_seams(std::vector<StitchPatch>& patches) {
  // Border vertices per grid line: columns -> rows on that vertical line, rows -> columns.
  std::unordered_map<int, std::vector<int>> vline, hline;
  for (const StitchPatch& p : patches)
    for (const pm::GridPoint& v : p.vertices) {
      assert(p.domain.contains(v.x, v.y));
      if (v.x == p.domain.col0 || v.x == p.domain.col1) vline[v.x].push_back(v.y);
      if (v.y == p.domain.row0 || v.y == p.domain.row1) hline[v.y].push_back(v.x);
    }
  for (auto* lines : {&vline, &hline})
    for (auto& [line, vs] : *lines) {
      std::sort(vs.begin(), vs.end());
      vs.erase(std::unique(vs.begin(), vs.end()), vs.end());
    }

  StitchResult res;
  res.new_triangles.resize(patches.size());
  res.new_triangle_sources.resize(patches.size());
  res.new_triangle_source_corners.resize(patches.size());
  for (std::size_t pi = 0; pi < patches.size(); ++pi) {
    StitchPatch& p = patches[pi];
    const SampleRect& d = p.domain;
    std::unordered_map<std::uint64_t, std::uint32_t> index;
    auto vertex = [&](pm::GridPoint g) {
      auto [it, inserted] = index.try_emplace(key(g), std::uint32_t(p.vertices.size()));
      if (inserted) {
        p.vertices.push_back(g);
        ++res.inserted_vertices;
      }
      return it->second;
    };
    bool indexed = false;
    // Points of the neighbours strictly inside border edge a-b, ordered from a to b.
    std::vector<pm::GridPoint> inside;
    auto find_inside = [&](pm::GridPoint a, pm::GridPoint b) {
      inside.clear();
      const std::vector<int>* vs = nullptr;
      int lo, hi;
      bool vertical;
      if (a.x == b.x && (a.x == d.col0 || a.x == d.col1)) {
        const auto it = vline.find(a.x);
        if (it == vline.end()) return;
        vs = &it->second, lo = std::min(a.y, b.y), hi = std::max(a.y, b.y), vertical = true;
      } else if (a.y == b.y && (a.y == d.row0 || a.y == d.row1)) {
        const auto it = hline.find(a.y);
        if (it == hline.end()) return;
        vs = &it->second, lo = std::min(a.x, b.x), hi = std::max(a.x, b.x), vertical = false;
      } else {
        return;
      }
      for (auto it = std::upper_bound(vs->begin(), vs->end(), lo); it != vs->end() && *it < hi; ++it)
        inside.push_back(vertical ? pm::GridPoint{a.x, *it} : pm::GridPoint{*it, a.y});
      if (vertical ? a.y > b.y : a.x > b.x) std::reverse(inside.begin(), inside.end());
    };

    auto on_border = [&](pm::GridPoint a, pm::GridPoint b) {
      return (a.x == b.x && (a.x == d.col0 || a.x == d.col1)) ||
             (a.y == b.y && (a.y == d.row0 || a.y == d.row1));
    };
    std::vector<std::array<std::uint32_t, 3>> work, done;
    const std::size_t original = p.triangles.size();
    for (std::size_t ti = 0; ti < original; ++ti) {
      const std::array<std::uint32_t, 3> t0 = p.triangles[ti];
      const pm::GridPoint g0 = p.vertices[t0[0]], g1 = p.vertices[t0[1]], g2 = p.vertices[t0[2]];
      if (!on_border(g0, g1) && !on_border(g1, g2) && !on_border(g2, g0)) continue;  // nothing to split
      work.assign(1, t0);
      done.clear();
      bool split_any = false;
      while (!work.empty()) {
        const auto t = work.back();
        work.pop_back();
        bool split = false;
        for (int e = 0; e < 3 && !split; ++e) {
          const std::uint32_t ia = t[e], ib = t[(e + 1) % 3], ic = t[(e + 2) % 3];
          find_inside(p.vertices[ia], p.vertices[ib]);
          if (inside.empty()) continue;
          if (!indexed) {  // inserted points lie on the border: only border vertices can match
            for (std::uint32_t v = 0; v < p.vertices.size(); ++v) {
              const pm::GridPoint g = p.vertices[v];
              if (g.x == d.col0 || g.x == d.col1 || g.y == d.row0 || g.y == d.row1) index.emplace(key(g), v);
            }
            indexed = true;
          }
          std::uint32_t prev = ia;
          for (const pm::GridPoint& g : inside) {
            const std::uint32_t iv = vertex(g);
            work.push_back({prev, iv, ic});
            prev = iv;
          }
          work.push_back({prev, ib, ic});
          split = true;
        }
        if (!split) done.push_back(t);
        split_any = split_any || split;
      }
      if (!split_any) continue;
      ++res.split_triangles;
      p.triangles[ti] = done[0];
      res.new_triangles[pi].push_back(std::uint32_t(ti));
      res.new_triangle_sources[pi].push_back(std::uint32_t(ti));
      res.new_triangle_source_corners[pi].push_back(t0);
      for (std::size_t k = 1; k < done.size(); ++k) {
        res.new_triangles[pi].push_back(std::uint32_t(p.triangles.size()));
        res.new_triangle_sources[pi].push_back(std::uint32_t(ti));
        res.new_triangle_source_corners[pi].push_back(t0);
        p.triangles.push_back(done[k]);
      }
    }
  }
  return res;
}

}  // namespace terralod::blocks
