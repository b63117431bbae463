// The per-frame dynamic-loading pipeline (paper section 4): region, loads and prefetch,
// stand-ins, per-block selective refinement with swap-in blends from the old surface,
// eviction, seams; see terrain_session.hpp.
#include "terralod/blocks/terrain_session.hpp"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "block_seams.hpp"

namespace terralod::blocks {

namespace {
void check_options(const SessionOptions& o) {
  if (o.refinement.morph_mode != pm::MorphMode::Vertical)
    throw std::invalid_argument("SessionOptions: refinement.morph_mode must be Vertical (seams keep plan positions)");
  if (!(o.region.theta_deg > 0 && o.region.theta_deg < 90))
    throw std::invalid_argument("SessionOptions: region.theta_deg must be in (0, 90)");
  if (o.region.p < 0) throw std::invalid_argument("SessionOptions: region.p must be >= 0");
  if (o.region.n_min < 0 || o.region.n_min > o.region.n_max)
    throw std::invalid_argument("SessionOptions: need 0 <= region.n_min <= region.n_max");
  if (!(o.prefetch_horizon_s >= 0) || !(o.prefetch_step_s > 0))
    throw std::invalid_argument("SessionOptions: need prefetch_horizon_s >= 0 and prefetch_step_s > 0");
  if (!(o.skirt_depth_m >= 0)) throw std::invalid_argument("SessionOptions: skirt_depth_m must be >= 0");
  if (!(o.merge_tolerance_samples >= 0))
    throw std::invalid_argument("SessionOptions: merge_tolerance_samples must be >= 0");
}
}  // namespace

TerrainSession::TerrainSession(BlockSourceFactory source, const BlockGrid& grid, std::vector<BlockSummary> summaries,
                               const SessionOptions& options)
    : grid_(grid), sums_(std::move(summaries)), opt_(options), cache_(options.cache), predictor_(options.predictor) {
  check_options(opt_);
  if (sums_.size() != grid_.block_count())
    throw std::invalid_argument("TerrainSession: " + std::to_string(sums_.size()) + " block summaries for " +
                                std::to_string(grid_.block_count()) + " blocks");
  for (std::size_t i = 0; i < sums_.size(); ++i) {
    if (sums_[i].triangles.empty()) {
      const SampleRect d = grid_.domain(grid_.key(i));
      set_two_triangle_standin(sums_[i], d.width(), d.height());
    }
    if (sums_[i].triangle_errors.size() != sums_[i].triangles.size())
      throw std::invalid_argument("TerrainSession: block summary " + std::to_string(i) + " has " +
                                  std::to_string(sums_[i].triangles.size()) + " stand-in triangles but " +
                                  std::to_string(sums_[i].triangle_errors.size()) + " triangle errors");
  }
  loader_ = std::make_unique<BlockLoader>(std::move(source), grid_);
}

TerrainSession::~TerrainSession() = default;

std::vector<TerrainSession::OldTriangle> TerrainSession::old_surface(BlockKey k) const {
  // The triangles drawn for k last frame (stand-in plus stitched pieces; walls left out), or
  // its bare stand-in when it was not drawn.
  std::vector<OldTriangle> out;
  const SampleRect d = grid_.domain(k);
  const std::uint64_t W = std::uint64_t(grid_.grid_width());
  for (std::size_t t = 0; t < mesh_.triangles.size(); ++t) {
    if (mesh_.triangle_block[t] != k) continue;
    OldTriangle o;
    bool wall = false;
    for (int i = 0; i < 3; ++i) {
      const std::uint32_t v = mesh_.triangles[t][std::size_t(i)];
      const std::uint64_t s = mesh_.samples[v];
      if (s == DrawnMesh::kNoSample) wall = true;
      else o.p[std::size_t(i)] = {double(std::int64_t(s % W) - d.col0), double(std::int64_t(s / W) - d.row0), mesh_.positions[v].z};
    }
    if (!wall) out.push_back(o);
  }
  if (!out.empty()) return out;
  const BlockSummary& b = sums_[grid_.index(k)];
  for (const auto& t : b.triangles) {
    OldTriangle o;
    for (int i = 0; i < 3; ++i) {
      const StandinPoint& q = b.points[t[std::size_t(i)]];
      o.p[std::size_t(i)] = {double(q.col), double(q.row), q.z};
    }
    out.push_back(o);
  }
  return out;
}

double TerrainSession::old_height(Refined& r, BlockKey k, std::uint32_t local_sample, int width) const {
  const auto [it, fresh] = r.old_z.try_emplace(local_sample, 0.0);
  if (!fresh) return it->second;
  const double c = double(local_sample % std::uint32_t(width)), w = double(local_sample / std::uint32_t(width));
  // The containing old triangle (barycentric, inclusive); the least-outside one absorbs rounding.
  double best = sums_[grid_.index(k)].z00, best_in = -1e300;
  for (const OldTriangle& t : r.old) {
    const auto &a = t.p[0], &b = t.p[1], &e = t.p[2];
    if (c < std::min({a[0], b[0], e[0]}) || c > std::max({a[0], b[0], e[0]}) || w < std::min({a[1], b[1], e[1]}) ||
        w > std::max({a[1], b[1], e[1]}))
      continue;
    const double det = (b[0] - a[0]) * (e[1] - a[1]) - (b[1] - a[1]) * (e[0] - a[0]);
    const double l1 = ((c - a[0]) * (e[1] - a[1]) - (w - a[1]) * (e[0] - a[0])) / det;
    const double l2 = ((b[0] - a[0]) * (w - a[1]) - (b[1] - a[1]) * (c - a[0])) / det;
    const double l0 = 1 - l1 - l2, in = std::min({l0, l1, l2});
    if (in > best_in) {
      best_in = in;
      best = l0 * a[2] + l1 * b[2] + l2 * e[2];
      if (in >= 0) break;
    }
  }
  if (best_in == -1e300) best = standin_height(sums_[grid_.index(k)], c, w);  // not covered (cannot happen)
  it->second = best;
  return best;
}

const pm::SelectiveRefinement* TerrainSession::selection(BlockKey k) const {
  const auto it = refined_.find(k);
  return it == refined_.end() ? nullptr : it->second.sel.get();
}

void TerrainSession::queue_loads(const pm::View& view) {
  std::vector<BlockLoader::Request> req;
  const pm::Vec3 eye = view.eye();
  auto dist = [&](BlockKey k) {
    const pm::Box b = block_box(grid_, k, sums_[grid_.index(k)]);
    const double dx = std::max({b.lo.x - eye.x, 0.0, eye.x - b.hi.x}), dy = std::max({b.lo.y - eye.y, 0.0, eye.y - b.hi.y});
    return std::hypot(dx, dy);
  };
  const double scale = 1.0 / (grid_.block_extent_m() * (2 * opt_.region.n_max + 3));  // keeps distance terms < 1
  for (BlockKey k : region_.inner) {
    if (cache_.contains(k)) continue;
    const bool in_view = std::binary_search(needed_.begin(), needed_.end(), k);
    req.push_back({k, (in_view ? 0.0 : 1.0) + std::min(0.99, dist(k) * scale)});
  }
  if (opt_.prefetch) {
    // Room in the budget for prefetched blocks: what the inner blocks leave, at the mean size.
    std::size_t mean = 0, n = 0;
    for (BlockKey k : cache_.keys()) mean += cache_.find(k)->memory_bytes, ++n;
    mean = n ? mean / n : 0;
    std::size_t room = ~std::size_t(0);
    if (mean > 0) {
      const std::size_t inner_bytes = region_.inner.size() * mean;
      room = inner_bytes >= opt_.cache.budget_bytes ? 0 : (opt_.cache.budget_bytes - inner_bytes) / mean;
    }
    std::set<BlockKey> seen(region_.inner.begin(), region_.inner.end());
    std::size_t queued = 0;
    for (const PredictedPoint& pt : predictor_.predict(opt_.prefetch_horizon_s, opt_.prefetch_step_s)) {
      if (pt.dt == 0) continue;
      const ActiveRegion r = active_region(grid_, sums_, pt.position, opt_.region);
      for (BlockKey k : r.inner) {
        if (!seen.insert(k).second) continue;
        if (queued >= room) break;
        ++queued;
        if (cache_.contains(k)) {
          cache_.touch(k, frame_);  // keep what the path needs
          continue;
        }
        req.push_back({k, 2.0 + pt.dt + std::min(0.99, dist(k) * scale) * opt_.prefetch_step_s});
      }
    }
  }
  loader_->set_queue(std::move(req));
}

const SessionFrameStats& TerrainSession::update(const pm::View& view, double time_s) {
  const auto t0 = std::chrono::steady_clock::now();
  if (started_ && time_s < time_)
    throw std::invalid_argument("TerrainSession::update: time went backwards (" + std::to_string(time_s) + " s after " +
                                std::to_string(time_) + " s)");
  started_ = true;
  time_ = time_s;
  ++frame_;
  SessionFrameStats s;
  s.frame = frame_;
  s.time_s = time_s;
  s.evicted_total = stats_.evicted_total;
  s.prefetch_hits_total = stats_.prefetch_hits_total;
  s.prefetch_misses_total = stats_.prefetch_misses_total;

  predictor_.observe(time_s, view.eye());
  region_ = active_region(grid_, sums_, view.eye(), opt_.region);
  s.centre = region_.centre;
  s.n = region_.n;
  s.p = region_.p;
  s.inner = region_.inner.size();
  s.active = region_.inner.size() + region_.outer.size();

  // 1. Finished loads (never waits).
  for (LoadResult& r : loader_->take_results()) {
    if (!r.block) throw std::runtime_error(r.error);
    cache_.insert(std::move(r.block), frame_);
  }
  // 2. What is needed in view, prefetch hits and misses.
  needed_.clear();
  for (BlockKey k : region_.inner)
    if (!view.outside(block_box(grid_, k, sums_[grid_.index(k)]))) needed_.push_back(k);
  std::set<BlockKey> needed_now(needed_.begin(), needed_.end());
  for (BlockKey k : needed_) {
    if (cache_.contains(k)) {
      if (!needed_prev_.count(k) && !missing_.count(k)) ++s.prefetch_hits_total;
      missing_.erase(k);
    } else {
      ++s.missing_in_view;
      if (missing_.insert(k).second) ++s.prefetch_misses_total;
    }
  }
  for (auto it = missing_.begin(); it != missing_.end();) it = needed_now.count(*it) ? std::next(it) : missing_.erase(it);
  needed_prev_ = std::move(needed_now);
  s.needed_in_view = needed_.size();
  queue_loads(view);

  // 3. Refinement of the resident inner blocks; swap-ins blend from the old surface.
  for (auto it = refined_.begin(); it != refined_.end();)
    it = region_.is_inner(it->first) ? std::next(it) : refined_.erase(it);
  pm::RefinementOptions ropt = opt_.refinement;
  for (BlockKey k : region_.inner) {
    cache_.touch(k, frame_);
    auto it = refined_.find(k);
    if (it == refined_.end()) {
      std::shared_ptr<const LoadedBlock> b = cache_.find(k);
      if (!b) {
        ++s.stand_ins;
        continue;
      }
      Refined r;
      r.block = b;
      // The first update of a selection never morphs: it is at tau at once; with geomorphs
      // the display blends from the block's old surface instead (header, step 3).
      r.sel = std::make_unique<pm::SelectiveRefinement>(*b->dag, ropt);
      if (ropt.morph_seconds > 0) {
        r.blending = true;
        r.blend_t0 = time_s;
        r.old = old_surface(k);
      }
      it = refined_.emplace(k, std::move(r)).first;
      ++s.swapped_in;
    }
    const pm::FrameStats& fs = it->second.sel->update(view, time_s);
    s.tolerance_px = std::max(s.tolerance_px, fs.tolerance_px);
    if (it->second.sel->morphing() || it->second.blending) ++s.morphing_blocks;
  }
  if (s.tolerance_px == 0) s.tolerance_px = ropt.tolerance_px;
  s.refined = refined_.size();

  // 4. Eviction beyond the budget; the inner blocks in use are pinned.
  const std::vector<BlockKey> gone = cache_.evict([&](BlockKey k) { return region_.is_inner(k); });
  s.evicted = gone.size();
  s.evicted_total += gone.size();

  // 5-6. Seams, geomorph heights, the drawn mesh and the bound.
  std::vector<detail::SeamPatch> patches;
  patches.reserve(s.active);
  std::vector<BlockKey> active = region_.inner;
  active.insert(active.end(), region_.outer.begin(), region_.outer.end());
  std::sort(active.begin(), active.end());
  const std::uint64_t W = std::uint64_t(grid_.grid_width());
  for (BlockKey k : active) {
    detail::SeamPatch p;
    p.key = k;
    const SampleRect d = grid_.domain(k);
    const auto it = refined_.find(k);
    if (it != refined_.end()) {
      Refined& ref = it->second;
      const pm::SelectiveRefinement& sel = *ref.sel;
      const double w = ref.blending ? std::clamp((time_s - ref.blend_t0) / ropt.morph_seconds, 0.0, 1.0) : 1.0;
      const pm::Heightfield& hf = sel.dag().heightfield();
      const pm::RenderMesh rm = sel.render_mesh();
      p.samples.reserve(rm.samples.size());
      for (std::size_t v = 0; v < rm.samples.size(); ++v) {
        const std::uint32_t ls = rm.samples[v];
        const int c = int(ls % std::uint32_t(hf.width())), r = int(ls / std::uint32_t(hf.width()));
        p.samples.push_back(std::uint64_t(d.row0 + r) * W + std::uint64_t(d.col0 + c));
        p.rest_z.push_back(hf[ls]);
        const double z = rm.positions[v].z;
        p.display_z.push_back(w < 1 ? old_height(ref, k, ls, hf.width()) * (1 - w) + z * w : z);
      }
      if (w >= 1 && ref.blending) {
        ref.blending = false;
        ref.old = {};
        ref.old_z = {};
      }
      p.triangles = rm.triangles;
      p.bound_px = sel.stats().bound_px;
      p.heights = &hf;  // lives in the resident block, which refined_ holds
    } else {
      const BlockSummary& b = sums_[grid_.index(k)];
      p.samples.reserve(b.points.size());
      p.rest_z.reserve(b.points.size());
      for (const StandinPoint& q : b.points) {
        p.samples.push_back(std::uint64_t(d.row0 + q.row) * W + std::uint64_t(d.col0 + q.col));
        p.rest_z.push_back(q.z);
      }
      p.display_z = p.rest_z;
      p.triangles = b.triangles;
      p.bound_px = standin_bound_px(grid_, k, b, view);
    }
    patches.push_back(std::move(p));
  }
  // A border sample of a block blending in is drawn, on every side, at the height of the
  // latest swap's blend: that blend started from what was drawn, so the shared height never
  // switches between two blends (continuous display; one height per sample stays true).
  {
    std::unordered_map<std::uint64_t, std::pair<double, double>> lead;  // sample -> (t_swap, z)
    auto on_border = [&](const detail::SeamPatch& p, std::uint64_t sample) {
      const SampleRect d = grid_.domain(p.key);
      const int c = int(sample % W), r = int(sample / W);
      return c == d.col0 || c == d.col1 || r == d.row0 || r == d.row1;
    };
    for (const detail::SeamPatch& p : patches) {
      const auto it = refined_.find(p.key);
      if (it == refined_.end() || !it->second.blending) continue;
      for (std::size_t v = 0; v < p.samples.size(); ++v) {
        if (!on_border(p, p.samples[v])) continue;
        auto [e, fresh] = lead.try_emplace(p.samples[v], it->second.blend_t0, p.display_z[v]);
        if (!fresh && it->second.blend_t0 > e->second.first) e->second = {it->second.blend_t0, p.display_z[v]};
      }
    }
    if (!lead.empty())
      for (detail::SeamPatch& p : patches)
        for (std::size_t v = 0; v < p.samples.size(); ++v)
          if (const auto e = lead.find(p.samples[v]); e != lead.end()) p.display_z[v] = e->second.second;
  }
  const detail::SeamResult sr =
      detail::assemble(grid_, patches, view, opt_.seams, opt_.skirt_depth_m, sums_, mesh_,
                       opt_.merge_tolerance_samples);
  s.bound_px = sr.bound_px;
  s.max_stitch_delta_m = sr.max_delta_m;
  s.seam_triangles = sr.seam_triangles;
  s.triangles = mesh_.triangles.size();
  s.vertices = mesh_.positions.size();

  s.resident = cache_.size();
  s.loading = loader_->pending();
  s.bytes_read_total = loader_->bytes_read();
  s.bytes_read = s.bytes_read_total - stats_.bytes_read_total;
  s.resident_bytes = cache_.bytes();
  s.peak_resident_bytes = cache_.peak_bytes();
  s.update_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  stats_ = s;
  return stats_;
}

}  // namespace terralod::blocks
