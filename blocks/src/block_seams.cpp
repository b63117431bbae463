// Watertight seams between the selected meshes of neighbouring blocks (paper section 4.3,
// Fig. 6) on top of the block-border stitch of seam_stitch.hpp: one height per shared
// vertex (geomorphs in step), the error the insertions add, and skirts; see block_seams.hpp
// and terrain_session.hpp.
#include "block_seams.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <map>
#include <unordered_map>

#include "terralod/blocks/seam_stitch.hpp"

namespace terralod::blocks::detail {

namespace {

// Sides of a block: 0 west (col == col0), 1 east (col == col1), 2 first row (row == row0),
// 3 last row (row == row1). The coordinate along a side is the row for 0/1, the col for 2/3.
constexpr int kDc[4] = {-1, 1, 0, 0}, kDr[4] = {0, 0, -1, 1};

struct BorderPoint {
  int coord;
  std::uint64_t sample;
  double rest_z;
  bool operator<(const BorderPoint& o) const { return coord < o.coord; }
};

}  // namespace

SeamResult assemble(const BlockGrid& grid, const std::vector<SeamPatch>& patches, const pm::View& view, SeamMode mode,
                    double skirt_depth_m, const std::vector<BlockSummary>& summaries, DrawnMesh& out) {
  out.positions.clear();
  out.samples.clear();
  out.triangles.clear();
  out.triangle_block.clear();
  SeamResult res;
  const std::uint64_t W = std::uint64_t(grid.grid_width());
  auto col_of = [&](std::uint64_t s) { return int(s % W); };
  auto row_of = [&](std::uint64_t s) { return int(s / W); };

  std::map<BlockKey, std::size_t> index;
  for (std::size_t i = 0; i < patches.size(); ++i) index[patches[i].key] = i;

  // Canonical displayed height of every sample: a side where it morphs wins, else rest.
  std::unordered_map<std::uint64_t, std::pair<double, bool>> zdisp;
  zdisp.reserve(patches.size() * 256);
  for (const SeamPatch& p : patches)
    for (std::size_t v = 0; v < p.samples.size(); ++v) {
      const bool morphing = p.display_z[v] != p.rest_z[v];
      auto [it, fresh] = zdisp.try_emplace(p.samples[v], p.display_z[v], morphing);
      if (!fresh && morphing && !it->second.second) it->second = {p.display_z[v], true};
    }
  std::unordered_map<std::uint64_t, std::uint32_t> vid;
  vid.reserve(zdisp.size());
  auto vertex = [&](std::uint64_t s) {
    auto [it, fresh] = vid.try_emplace(s, std::uint32_t(out.positions.size()));
    if (fresh) {
      out.positions.push_back(grid.world(col_of(s), row_of(s), zdisp.at(s).first));
      out.samples.push_back(s);
    }
    return it->second;
  };

  // Border vertices of every patch, per side, sorted along the side.
  std::vector<std::array<std::vector<BorderPoint>, 4>> border(patches.size());
  for (std::size_t i = 0; i < patches.size(); ++i) {
    const SeamPatch& p = patches[i];
    const SampleRect d = grid.domain(p.key);
    for (std::size_t v = 0; v < p.samples.size(); ++v) {
      const int c = col_of(p.samples[v]), r = row_of(p.samples[v]);
      if (c == d.col0) border[i][0].push_back({r, p.samples[v], p.rest_z[v]});
      if (c == d.col1) border[i][1].push_back({r, p.samples[v], p.rest_z[v]});
      if (r == d.row0) border[i][2].push_back({c, p.samples[v], p.rest_z[v]});
      if (r == d.row1) border[i][3].push_back({c, p.samples[v], p.rest_z[v]});
    }
    for (auto& s : border[i]) std::sort(s.begin(), s.end());
  }

  // Heights of every sample of the patches (true heights), for the inserted vertices.
  std::unordered_map<std::uint64_t, double> zrest;
  zrest.reserve(zdisp.size());
  for (const SeamPatch& p : patches)
    for (std::size_t v = 0; v < p.samples.size(); ++v) zrest.emplace(p.samples[v], p.rest_z[v]);

  std::vector<StitchPatch> sp(patches.size());
  for (std::size_t i = 0; i < patches.size(); ++i) {
    sp[i].domain = grid.domain(patches[i].key);
    for (std::uint64_t s : patches[i].samples) sp[i].vertices.push_back({col_of(s), row_of(s)});
    sp[i].triangles = patches[i].triangles;
  }
  StitchResult st;
  if (mode == SeamMode::Stitch) {
    st = stitch_seams(sp);  // A's re-triangulation (seam_stitch.hpp): fans, corners split in order
    res.seam_triangles = st.split_triangles;
  }

  for (std::size_t i = 0; i < patches.size(); ++i) {
    const SeamPatch& p = patches[i];
    const StitchPatch& q = sp[i];
    const SampleRect d = q.domain;
    const BlockSummary& sum = summaries[grid.index(p.key)];
    res.bound_px = std::max(res.bound_px, p.bound_px);
    auto sample = [&](std::uint32_t v) { return std::uint64_t(q.vertices[v].y) * W + std::uint64_t(q.vertices[v].x); };
    // delta of each inserted vertex: |z(v) - S(v)|, S the patch's surface before the stitch,
    // linear along the border between the patch's own neighbouring border vertices.
    std::vector<double> delta(q.vertices.size(), 0.0);
    for (std::size_t v = p.samples.size(); v < q.vertices.size(); ++v) {
      const pm::GridPoint g = q.vertices[v];
      const int s = g.x == d.col0 ? 0 : g.x == d.col1 ? 1 : g.y == d.row0 ? 2 : 3;
      const int c = s < 2 ? g.y : g.x;
      const auto& own = border[i][s];
      const auto hi = std::upper_bound(own.begin(), own.end(), BorderPoint{c, 0, 0});
      assert(hi != own.begin() && hi != own.end());  // the corners are always own vertices
      const auto lo = std::prev(hi);
      const double t = double(c - lo->coord) / double(hi->coord - lo->coord);
      delta[v] = std::abs(zrest.at(sample(std::uint32_t(v))) - (lo->rest_z + t * (hi->rest_z - lo->rest_z)));
      res.max_delta_m = std::max(res.max_delta_m, delta[v]);
    }
    // Bound of each new triangle: S' - S is linear on it with values delta at its corners.
    if (mode == SeamMode::Stitch)
      for (std::uint32_t ti : st.new_triangles[i]) {
        const auto& t = q.triangles[ti];
        const double dt = std::max({delta[t[0]], delta[t[1]], delta[t[2]]});
        if (dt == 0) continue;
        pm::Box box{{1e300, 1e300, 1e300}, {-1e300, -1e300, -1e300}};
        for (std::uint32_t v : t) {
          const std::uint64_t s = sample(v);
          const pm::Vec3 w = grid.world(col_of(s), row_of(s), zrest.at(s));
          box.lo = {std::min(box.lo.x, w.x), std::min(box.lo.y, w.y), std::min(box.lo.z, w.z - dt)};
          box.hi = {std::max(box.hi.x, w.x), std::max(box.hi.y, w.y), std::max(box.hi.z, w.z + dt)};
        }
        if (!view.outside(box)) res.bound_px = std::max(res.bound_px, p.bound_px + view.vertical_error_px(box, dt));
      }
    for (const auto& t : q.triangles) {
      out.triangles.push_back({vertex(sample(t[0])), vertex(sample(t[1])), vertex(sample(t[2]))});
      out.triangle_block.push_back(p.key);
    }
    if (mode != SeamMode::Skirts) continue;
    // Skirts: a wall below every border edge shared with an active neighbour.
    std::array<bool, 4> shared{};
    for (int s = 0; s < 4; ++s) shared[s] = index.count(BlockKey{p.key.col + kDc[s], p.key.row + kDr[s]}) != 0;
    const double depth = skirt_depth_m > 0 ? skirt_depth_m : sum.tm_error + 1.0;
    for (const auto& t : q.triangles)
      for (int e = 0; e < 3; ++e) {
        const pm::GridPoint a = q.vertices[t[e]], b = q.vertices[t[(e + 1) % 3]];
        int s = -1;
        if (a.x == b.x && a.x == d.col0) s = 0;
        if (a.x == b.x && a.x == d.col1) s = 1;
        if (a.y == b.y && a.y == d.row0) s = 2;
        if (a.y == b.y && a.y == d.row1) s = 3;
        if (s < 0 || !shared[s]) continue;
        const std::uint32_t va = vertex(sample(t[e])), vb = vertex(sample(t[(e + 1) % 3]));
        const auto ia = std::uint32_t(out.positions.size());
        pm::Vec3 pa = out.positions[va], pb = out.positions[vb];
        pa.z -= depth;
        pb.z -= depth;
        out.positions.push_back(pa);
        out.positions.push_back(pb);
        out.samples.push_back(DrawnMesh::kNoSample);
        out.samples.push_back(DrawnMesh::kNoSample);
        out.triangles.push_back({vb, va, ia});
        out.triangles.push_back({vb, ia, ia + 1});
        out.triangle_block.push_back(p.key);
        out.triangle_block.push_back(p.key);
      }
  }
  return res;
}

}  // namespace terralod::blocks::detail
