// Steps 4-5 of the terrain runtime's frame (terrain_runtime.hpp): the drawn mesh assembled from
// the frame's patches. Seams stitched between every pair of neighbours, one vertex per terrain
// sample, each drawn triangle's logical error (a stitched piece's from its source), geomorph
// offsets clamped so that every triangle stays within tau, and the bound of the mesh as drawn.
#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "grid_triangle.hpp"
#include "terrain_runtime_internal.hpp"
#include "terralod/blocks/terrain_runtime.hpp"

namespace terralod::blocks {

namespace {

bool on_border(const SampleRect& d, int col, int row) {
  return col == d.col0 || col == d.col1 || row == d.row0 || row == d.row1;
}

}  // namespace

void TerrainRuntime::assemble(const pm::View& view, double tau, std::size_t count, RuntimeFrameStats& s) {
  std::vector<Patch>& patches = patches_;
  Scratch& x = *scratch_;
  // The stitch runs on the patches' own StitchPatches (moved out and back: no copies).
  x.original_vertices.resize(count);
  x.sps.resize(count);
  for (std::size_t i = 0; i < count; ++i) {
    x.original_vertices[i] = patches[i].sp.vertices.size();
    x.sps[i] = std::move(patches[i].sp);
  }
  const StitchResult sr = stitch_seams(x.sps);
  for (std::size_t i = 0; i < count; ++i) patches[i].sp = std::move(x.sps[i]);
  const std::vector<std::size_t>& original_vertices = x.original_vertices;

  // One vertex per terrain sample: border samples through a map (first patch in node order
  // gives the displayed height), interior samples are their patch's own.
  std::unordered_map<std::uint64_t, std::uint32_t>& border = x.border;
  border.clear();
  mesh_.positions.clear();
  mesh_.samples.clear();
  mesh_.triangles.clear();
  mesh_.triangle_node.clear();
  std::vector<double>&rest = x.rest, &display = x.display;  // per drawn vertex
  rest.clear();
  display.clear();
  if (x.gidx.size() < count) x.gidx.resize(count);
  std::vector<std::vector<std::uint32_t>>& gidx = x.gidx;
  const std::uint64_t W = std::uint64_t(grid_.grid_width());
  for (std::size_t i = 0; i < count; ++i) {
    Patch& p = patches[i];
    const SampleRect& d = p.sp.domain;
    gidx[i].resize(p.sp.vertices.size());
    for (std::size_t v = 0; v < original_vertices[i]; ++v) {
      const pm::GridPoint g = p.sp.vertices[v];
      const std::uint64_t sample = std::uint64_t(g.y) * W + std::uint64_t(g.x);
      std::uint32_t gi;
      if (on_border(d, g.x, g.y)) {
        const auto [it, fresh] = border.try_emplace(sample, std::uint32_t(mesh_.samples.size()));
        gi = it->second;
        if (!fresh) {
          gidx[i][v] = gi;
          continue;
        }
      } else {
        gi = std::uint32_t(mesh_.samples.size());
      }
      mesh_.samples.push_back(sample);
      rest.push_back(p.rest_z[v]);
      display.push_back(p.display_z[v]);
      gidx[i][v] = gi;
    }
  }
  // Inserted vertices are another patch's border vertices: already in the map.
  for (std::size_t i = 0; i < count; ++i) {
    Patch& p = patches[i];
    for (std::size_t v = original_vertices[i]; v < p.sp.vertices.size(); ++v) {
      const pm::GridPoint g = p.sp.vertices[v];
      const auto it = border.find(std::uint64_t(g.y) * W + std::uint64_t(g.x));
      assert(it != border.end());
      gidx[i][v] = it->second;
    }
  }

  // Triangles, each with its logical error and whether it must be evaluated on its own.
  std::vector<Eval>& eval = x.eval;
  eval.clear();
  const std::size_t nv = mesh_.samples.size();
  std::vector<std::uint8_t>& moving = x.moving;
  moving.assign(nv, 0);
  for (std::size_t v = 0; v < nv; ++v) moving[v] = display[v] != rest[v];
  double bound = 0;
  std::vector<std::uint32_t>& piece = x.piece;  // per triangle: its index in new_triangles + 1, or 0
  for (std::size_t i = 0; i < count; ++i) {
    Patch& p = patches[i];
    const std::size_t T = p.sp.triangles.size();
    piece.assign(T, 0);
    for (std::size_t k = 0; k < sr.new_triangles[i].size(); ++k)
      piece[sr.new_triangles[i][k]] = std::uint32_t(k + 1);
    s.seam_triangles += sr.new_triangles[i].size();
    bool own_needed = false;
    for (std::size_t t = 0; t < T; ++t) {
      const auto& tl = p.sp.triangles[t];
      const std::array<std::uint32_t, 3> tg{gidx[i][tl[0]], gidx[i][tl[1]], gidx[i][tl[2]]};
      const std::uint32_t ti = std::uint32_t(mesh_.triangles.size());
      mesh_.triangles.push_back(tg);
      mesh_.triangle_node.push_back(p.node);
      double e = 0;
      if (piece[t]) {
        // Stitched piece: the source's error plus the largest difference between an inserted
        // corner's true height and the source plane there.
        const auto& src = sr.new_triangle_source_corners[i][piece[t] - 1];
        e = p.tri_error[sr.new_triangle_sources[i][piece[t] - 1]];
        std::array<std::array<double, 3>, 3> q;
        for (int c = 0; c < 3; ++c) {
          const pm::GridPoint g = p.sp.vertices[src[std::size_t(c)]];
          q[std::size_t(c)] = {double(g.x), double(g.y), p.rest_z[src[std::size_t(c)]]};
        }
        double delta = 0;
        std::array<double, 3> base;
        for (int c = 0; c < 3; ++c) {
          const std::uint32_t lv = tl[std::size_t(c)];
          const pm::GridPoint g = p.sp.vertices[lv];
          base[std::size_t(c)] = detail::plane_height(q, g.x, g.y);
          if (lv >= original_vertices[i])
            delta = std::max(delta, std::abs(rest[tg[std::size_t(c)]] - base[std::size_t(c)]));
        }
        eval.push_back({ti, e + delta, e, base, i});
      } else {
        e = p.tri_error[t];
        if (moving[tg[0]] || moving[tg[1]] || moving[tg[2]]) {
          eval.push_back({ti, e, e, {rest[tg[0]], rest[tg[1]], rest[tg[2]]}, i});
        } else {
          own_needed = true;
        }
      }
    }
    if (own_needed) bound = std::max(bound, p.bound_px);
  }

  // The prism of a drawn triangle: at each corner k the heights that a vertical segment from
  // the displayed surface to a sample under the triangle can reach there: the displayed height,
  // and base_k +- e0 (the samples lie within e0, the source's error, of the source's true plane,
  // whose height at the corner is base_k), clipped to the patch's sample range. Interpolated
  // over the triangle, these intervals hold every such segment; for a stitched piece the prism
  // lies inside its source's, as SelectiveRefinement's face prisms do (same construction).
  struct Prism {
    double x[3], y[3], lo[3], hi[3];
  };
  const double K = view.focal_px() * view.vertical_factor(), near = view.camera().near_m;
  auto prism_of = [&](const Eval& ev) {
    const auto& t = mesh_.triangles[ev.tri];
    const Patch& p = patches[ev.patch];
    Prism q;
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t v = t[std::size_t(k)];
      const std::uint64_t sm = mesh_.samples[v];
      const pm::Vec3 w = grid_.world(int(sm % W), int(sm / W), 0.0);
      q.x[k] = w.x, q.y[k] = w.y;
      q.lo[k] = std::min(display[v], std::max(ev.base[std::size_t(k)] - ev.source_error, p.zlo));
      q.hi[k] = std::max(display[v], std::min(ev.base[std::size_t(k)] + ev.source_error, p.zhi));
    }
    return q;
  };
  auto outside = [&](const Prism& q) {
    for (const pm::Plane& pl : view.planes()) {
      double top = -1e300;
      for (int k = 0; k < 3; ++k)
        top = std::max(
            top, pl.n.x * q.x[k] + pl.n.y * q.y[k] + std::max(pl.n.z * q.lo[k], pl.n.z * q.hi[k]) + pl.d);
      if (top < 0.0) return true;
    }
    return false;
  };
  const pm::Vec3 fwd = view.depth_gradient();
  const double eye_depth = pm::dot(view.eye(), fwd);
  auto min_depth = [&](const Prism& q) {
    double d = 1e300;
    for (int k = 0; k < 3; ++k)
      d = std::min(d,
                   fwd.x * q.x[k] + fwd.y * q.y[k] + std::min(fwd.z * q.lo[k], fwd.z * q.hi[k]) - eye_depth);
    return std::max(d, near);
  };
  // Clamp the offsets: each moving vertex stays within what every triangle around it allows.
  std::vector<double>& allowed = x.allowed;
  allowed.assign(nv, std::numeric_limits<double>::infinity());
  bool any_moving = false;
  for (std::size_t v = 0; v < nv; ++v) any_moving = any_moving || moving[v];
  if (any_moving) {
    for (const Eval& ev : eval) {
      const auto& t = mesh_.triangles[ev.tri];
      if (!moving[t[0]] && !moving[t[1]] && !moving[t[2]]) continue;
      const Prism q = prism_of(ev);
      if (outside(q)) continue;
      const double m = std::max(0.0, tau * min_depth(q) / K - ev.error);
      for (std::uint32_t v : t) allowed[v] = std::min(allowed[v], m);
    }
    // Unstitched, unmoving-cornered triangles of a patch were not evaluated, but a moving vertex
    // only belongs to evaluated triangles (every triangle with a moving corner is in eval).
    for (std::size_t v = 0; v < nv; ++v) {
      if (!moving[v]) continue;
      ++s.moving_vertices;
      const double o = display[v] - rest[v];
      if (std::abs(o) > allowed[v]) {
        display[v] = rest[v] + std::copysign(allowed[v] * (1 - 1e-9), o);  // margin for rounding
        ++s.clamped_vertices;
      }
    }
  }
  // The bound of the evaluated triangles as drawn.
  for (const Eval& ev : eval) {
    const auto& t = mesh_.triangles[ev.tri];
    double m = 0;
    for (std::uint32_t v : t) m = std::max(m, std::abs(display[v] - rest[v]));
    const Prism q = prism_of(ev);
    if (outside(q)) continue;
    bound = std::max(bound, (ev.error + m) * K / min_depth(q));
  }
  s.bound_px = bound;

  mesh_.positions.resize(nv);
  for (std::size_t v = 0; v < nv; ++v) {
    const std::uint64_t sm = mesh_.samples[v];
    mesh_.positions[v] = grid_.world(int(sm % W), int(sm / W), display[v]);
  }
  s.triangles = mesh_.triangles.size();
  s.vertices = nv;
}

}  // namespace terralod::blocks
