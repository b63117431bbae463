// Watertight seams between the selected meshes of neighbouring blocks (paper section 4.3,
// Fig. 6) on top of the block-border stitch of seam_stitch.hpp: sliver merging of close
// unmatched border vertices, one height per shared vertex (geomorphs in step), the error the
// merge and the insertions add, and skirts; see block_seams.hpp and terrain_session.hpp.
#include "block_seams.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <map>
#include <span>
#include <unordered_map>

#include "terralod/blocks/seam_stitch.hpp"
#include "terralod/pm/linf_error.hpp"

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

pm::Box empty_box() { return {{1e300, 1e300, 1e300}, {-1e300, -1e300, -1e300}}; }

// The sliver merge of block_seams.hpp over all shared borders. Moves vertices of `sp` in
// place, adds the heights of new samples to zrest / zdisp, raises base_px[i] to the bound of
// patch i's moved triangles (never above patches[i].bound_px, condition (iii)).
class SliverMerge {
 public:
  SliverMerge(const BlockGrid& grid, const std::vector<SeamPatch>& patches, const pm::View& view,
              std::vector<StitchPatch>& sp, std::unordered_map<std::uint64_t, double>& zrest,
              std::unordered_map<std::uint64_t, std::pair<double, bool>>& zdisp, std::vector<double>& base_px,
              SeamResult& res)
      : grid_(grid),
        patches_(patches),
        view_(view),
        sp_(sp),
        zrest_(zrest),
        zdisp_(zdisp),
        base_px_(base_px),
        res_(res),
        around_(patches.size()) {}

  void run(double tolerance, const std::map<BlockKey, std::size_t>& index) {
    // Border vertices (coord, vertex) of every patch, per side, sorted along the side. A merge
    // on one border moves only non-corner vertices of that border, so the lists of the other
    // borders stay valid.
    std::vector<std::array<std::vector<std::pair<int, std::uint32_t>>, 4>> side(sp_.size());
    for (std::size_t i = 0; i < sp_.size(); ++i) {
      const SampleRect& d = sp_[i].domain;
      for (std::uint32_t v = 0; v < sp_[i].vertices.size(); ++v) {
        const pm::GridPoint g = sp_[i].vertices[v];
        if (g.x == d.col0) side[i][0].push_back({g.y, v});
        if (g.x == d.col1) side[i][1].push_back({g.y, v});
        if (g.y == d.row0) side[i][2].push_back({g.x, v});
        if (g.y == d.row1) side[i][3].push_back({g.x, v});
      }
      for (auto& l : side[i]) std::sort(l.begin(), l.end());
    }
    struct Entry {
      int coord;
      std::int64_t a = -1, b = -1;  // vertex of either side at coord
    };
    std::vector<Entry> line;
    for (std::size_t i = 0; i < sp_.size(); ++i)
      for (int s : {1, 3}) {  // each shared border once: east and last-row sides
        const auto it = index.find(BlockKey{patches_[i].key.col + kDc[s], patches_[i].key.row + kDr[s]});
        if (it == index.end()) continue;
        const std::size_t j = it->second;
        const auto &la = side[i][s], &lb = side[j][s - 1];
        const int at = s == 1 ? sp_[i].domain.col1 : sp_[i].domain.row1;  // the border line
        auto point = [&](int c) { return s == 1 ? pm::GridPoint{at, c} : pm::GridPoint{c, at}; };
        line.clear();
        for (std::size_t ka = 0, kb = 0; ka < la.size() || kb < lb.size();) {
          if (kb == lb.size() || (ka < la.size() && la[ka].first < lb[kb].first)) {
            line.push_back({la[ka].first, la[ka].second, -1}), ++ka;
          } else if (ka == la.size() || lb[kb].first < la[ka].first) {
            line.push_back({lb[kb].first, -1, lb[kb].second}), ++kb;
          } else {
            line.push_back({la[ka].first, la[ka].second, lb[kb].second}), ++ka, ++kb;
          }
        }
        const bool a_finer = la.size() >= lb.size();
        for (std::size_t k = 0; k + 1 < line.size(); ++k) {
          const Entry &e0 = line[k], &e1 = line[k + 1];
          const bool unmatched0 = (e0.a < 0) != (e0.b < 0), unmatched1 = (e1.a < 0) != (e1.b < 0);
          if (!unmatched0 || !unmatched1 || (e0.a < 0) == (e1.a < 0)) continue;  // need one of each side
          if (double(e1.coord - e0.coord) >= tolerance) continue;
          const Entry& ea = e0.a >= 0 ? e0 : e1;
          const Entry& eb = e0.a >= 0 ? e1 : e0;
          int targets[3], nt = 0;
          if (e1.coord - e0.coord >= 2) targets[nt++] = (e0.coord + e1.coord) / 2;
          targets[nt++] = a_finer ? ea.coord : eb.coord;
          targets[nt++] = a_finer ? eb.coord : ea.coord;
          bool merged = false;
          for (int q = 0; q < nt && !merged; ++q) {
            const pm::GridPoint g = point(targets[q]);
            Move ma, mb;
            if (!try_move(i, std::uint32_t(ea.a), g, ma) || !try_move(j, std::uint32_t(eb.b), g, mb))
              continue;
            apply(i, std::uint32_t(ea.a), g, ma, j, std::uint32_t(eb.b), mb);
            merged = true;
          }
          if (merged) {
            ++res_.merged_pairs;
            ++k;  // both vertices are used up
          } else {
            ++res_.refused_pairs;
          }
        }
      }
  }

 private:
  struct Move {
    bool moves = false;
    double px = 0, error_m = 0;
    std::size_t triangles = 0;
  };

  // Can vertex v of patch pi move to g (conditions (i)-(iii))? Fills the move's bound.
  bool try_move(std::size_t pi, std::uint32_t v, pm::GridPoint g, Move& m) {
    StitchPatch& q = sp_[pi];
    const SeamPatch& p = patches_[pi];
    const pm::GridPoint from = q.vertices[v];
    m = {};
    if (from == g) return true;
    const SampleRect& d = q.domain;
    if (p.heights == nullptr) return false;  // (ii) stand-in
    if ((from.x == d.col0 || from.x == d.col1) && (from.y == d.row0 || from.y == d.row1))
      return false;  // (ii)
    assert(p.heights->width() == d.width() && p.heights->height() == d.height());
    Around& ar = around_[pi];
    if (ar.first.empty()) {  // vertex -> triangles, compressed rows: first[v]..first[v+1] in tri
      ar.first.assign(q.vertices.size() + 1, 0);
      for (const auto& t : q.triangles)
        for (std::uint32_t c : t) ++ar.first[c + 1];
      for (std::size_t k = 1; k < ar.first.size(); ++k) ar.first[k] += ar.first[k - 1];
      ar.tri.resize(ar.first.back());
      std::vector<std::uint32_t> fill(ar.first.begin(), ar.first.end() - 1);
      for (std::uint32_t t = 0; t < q.triangles.size(); ++t)
        for (std::uint32_t c : q.triangles[t]) ar.tri[fill[c]++] = t;
    }
    const std::span<const std::uint32_t> star(ar.tri.data() + ar.first[v], ar.first[v + 1] - ar.first[v]);
    auto local = [&](pm::GridPoint x) { return pm::GridPoint{x.x - d.col0, x.y - d.row0}; };
    auto moved = [&](std::uint32_t t, pm::GridPoint* c) {
      for (int k = 0; k < 3; ++k) c[k] = q.triangles[t][k] == v ? g : q.vertices[q.triangles[t][k]];
    };
    for (std::uint32_t t : star) {  // (i), before any error is measured
      pm::GridPoint c[3];
      moved(t, c);
      if (pm::orient2d(c[0], c[1], c[2]) <= 0) return false;
    }
    const pm::LInfError err(*p.heights, pm::ErrorMetric::Continuous);
    m.moves = true;
    for (std::uint32_t t : star) {
      pm::GridPoint c[3];
      moved(t, c);
      pm::Box box = empty_box();  // the corners; widened by e below
      for (const pm::GridPoint& x : c) {
        const pm::GridPoint l = local(x);
        const pm::Vec3 w = grid_.world(x.x, x.y, p.heights->at(l.x, l.y));
        box.lo = {std::min(box.lo.x, w.x), std::min(box.lo.y, w.y), std::min(box.lo.z, w.z)};
        box.hi = {std::max(box.hi.x, w.x), std::max(box.hi.y, w.y), std::max(box.hi.z, w.z)};
      }
      // Widening the box only brings it nearer, so px(e) >= e * vertical_error_px(corner box,
      // 1 m): an error above bound_px / that can stop the measurement early, refused.
      const double per_m = view_.outside(box) ? 0.0 : view_.vertical_error_px(box, 1.0);
      const double cutoff = per_m > 0 ? p.bound_px / per_m : pm::LInfError::kNoCutoff;
      const double e = err.triangle(local(c[0]), local(c[1]), local(c[2]), cutoff);
      if (e > cutoff) return false;  // (iii)
      box.lo.z -= e;
      box.hi.z += e;
      const double px = view_.outside(box) ? 0.0 : view_.vertical_error_px(box, e);
      if (px > p.bound_px) return false;  // (iii)
      m.px = std::max(m.px, px);
      m.error_m = std::max(m.error_m, e);
      ++m.triangles;
    }
    return true;
  }

  void apply(std::size_t pa, std::uint32_t va, pm::GridPoint g, const Move& ma, std::size_t pb,
             std::uint32_t vb, const Move& mb) {
    const std::uint64_t W = std::uint64_t(grid_.grid_width());
    auto sample = [&](pm::GridPoint x) { return std::uint64_t(x.y) * W + std::uint64_t(x.x); };
    const std::uint64_t to = sample(g);
    // Displayed height of a new sample: its rest height plus the mean morph offset of the
    // vertices that move onto it (an existing sample keeps its canonical height).
    double offset = 0;
    int moved = 0;
    for (auto [pi, v, m] : {std::tuple{pa, va, &ma}, std::tuple{pb, vb, &mb}}) {
      if (!m->moves) continue;
      const SeamPatch& p = patches_[pi];
      const std::uint64_t from = sample(sp_[pi].vertices[v]);
      offset += zdisp_.at(from).first - zrest_.at(from);
      ++moved;
      const SampleRect& d = sp_[pi].domain;
      zrest_.try_emplace(to, p.heights->at(g.x - d.col0, g.y - d.row0));
      sp_[pi].vertices[v] = g;
      base_px_[pi] = std::max(base_px_[pi], m->px);
      res_.moved_triangles += m->triangles;
      res_.max_merge_error_m = std::max(res_.max_merge_error_m, m->error_m);
    }
    assert(moved > 0);
    zdisp_.try_emplace(to, zrest_.at(to) + offset / moved, false);
  }

  const BlockGrid& grid_;
  const std::vector<SeamPatch>& patches_;
  const pm::View& view_;
  std::vector<StitchPatch>& sp_;
  std::unordered_map<std::uint64_t, double>& zrest_;
  std::unordered_map<std::uint64_t, std::pair<double, bool>>& zdisp_;
  std::vector<double>& base_px_;
  SeamResult& res_;
  struct Around {
    std::vector<std::uint32_t> first, tri;
  };
  std::vector<Around> around_;  // per patch, built on its first candidate
};

}  // namespace

SeamResult assemble(const BlockGrid& grid, const std::vector<SeamPatch>& patches, const pm::View& view,
                    SeamMode mode, double skirt_depth_m, const std::vector<BlockSummary>& summaries,
                    DrawnMesh& out, double merge_tolerance_samples) {
  assert(merge_tolerance_samples >= 0);
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
  // Sliver merge (block_seams.hpp): base_px[i] bounds patch i's merged surface.
  std::vector<double> base_px(patches.size());
  for (std::size_t i = 0; i < patches.size(); ++i) base_px[i] = patches[i].bound_px;
  if (mode == SeamMode::Stitch && merge_tolerance_samples > 0)
    SliverMerge(grid, patches, view, sp, zrest, zdisp, base_px, res).run(merge_tolerance_samples, index);

  // Border vertices of every (merged) patch, per side, sorted along the side.
  std::vector<std::array<std::vector<BorderPoint>, 4>> border(patches.size());
  for (std::size_t i = 0; i < patches.size(); ++i) {
    const SampleRect d = sp[i].domain;
    for (const pm::GridPoint& g : sp[i].vertices) {
      const std::uint64_t s = std::uint64_t(g.y) * W + std::uint64_t(g.x);
      const double z = zrest.at(s);
      if (g.x == d.col0) border[i][0].push_back({g.y, s, z});
      if (g.x == d.col1) border[i][1].push_back({g.y, s, z});
      if (g.y == d.row0) border[i][2].push_back({g.x, s, z});
      if (g.y == d.row1) border[i][3].push_back({g.x, s, z});
    }
    for (auto& side : border[i]) std::sort(side.begin(), side.end());
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
    res.bound_px = std::max(res.bound_px, base_px[i]);
    auto sample = [&](std::uint32_t v) {
      return std::uint64_t(q.vertices[v].y) * W + std::uint64_t(q.vertices[v].x);
    };
    // delta of each inserted vertex: |z(v) - S(v)|, S the patch's (merged) surface before the stitch,
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
        pm::Box box = empty_box();
        for (std::uint32_t v : t) {
          const std::uint64_t s = sample(v);
          const pm::Vec3 w = grid.world(col_of(s), row_of(s), zrest.at(s));
          box.lo = {std::min(box.lo.x, w.x), std::min(box.lo.y, w.y), std::min(box.lo.z, w.z - dt)};
          box.hi = {std::max(box.hi.x, w.x), std::max(box.hi.y, w.y), std::max(box.hi.z, w.z + dt)};
        }
        if (!view.outside(box))
          res.bound_px = std::max(res.bound_px, base_px[i] + view.vertical_error_px(box, dt));
      }
    for (const auto& t : q.triangles) {
      out.triangles.push_back({vertex(sample(t[0])), vertex(sample(t[1])), vertex(sample(t[2]))});
      out.triangle_block.push_back(p.key);
    }
    if (mode != SeamMode::Skirts) continue;
    // Skirts: a wall below every border edge shared with an active neighbour.
    std::array<bool, 4> shared{};
    for (int s = 0; s < 4; ++s)
      shared[s] = index.count(BlockKey{p.key.col + kDc[s], p.key.row + kDr[s]}) != 0;
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
