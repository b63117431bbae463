// The per-frame dynamic-loading pipeline (paper section 4): region, loads and prefetch,
// per-block selective refinement with swap-in geomorphs, eviction, seams; see
// terrain_session.hpp.
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
}
}  // namespace

TerrainSession::TerrainSession(BlockSourceFactory source, const BlockGrid& grid, std::vector<BlockSummary> summaries,
                               const SessionOptions& options)
    : grid_(grid), sums_(std::move(summaries)), opt_(options), cache_(options.cache), predictor_(options.predictor) {
  check_options(opt_);
  if (sums_.size() != grid_.block_count())
    throw std::invalid_argument("TerrainSession: " + std::to_string(sums_.size()) + " block summaries for " +
                                std::to_string(grid_.block_count()) + " blocks");
  loader_ = std::make_unique<BlockLoader>(std::move(source), grid_);
}

TerrainSession::~TerrainSession() = default;

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

  // 3. Refinement of the resident inner blocks; swap-ins start at the base mesh and morph.
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
      if (ropt.morph_seconds > 0) {
        // The first update of a selection never morphs: settle it at the base mesh (every
        // collapse is acceptable at this tau), then refine with geomorphs from there.
        pm::RefinementOptions base = ropt;
        base.tolerance_px = 1e300;
        base.target_triangles = 0;
        r.sel = std::make_unique<pm::SelectiveRefinement>(*b->dag, base);
        r.sel->update(view, time_s);
        r.sel->set_options(ropt);
      } else {
        r.sel = std::make_unique<pm::SelectiveRefinement>(*b->dag, ropt);
      }
      it = refined_.emplace(k, std::move(r)).first;
      ++s.swapped_in;
    }
    const pm::FrameStats& fs = it->second.sel->update(view, time_s);
    s.tolerance_px = std::max(s.tolerance_px, fs.tolerance_px);
    if (it->second.sel->morphing()) ++s.morphing_blocks;
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
      const pm::SelectiveRefinement& sel = *it->second.sel;
      const pm::Heightfield& hf = sel.dag().heightfield();
      const pm::RenderMesh rm = sel.render_mesh();
      p.samples.reserve(rm.samples.size());
      for (std::size_t v = 0; v < rm.samples.size(); ++v) {
        const std::uint32_t ls = rm.samples[v];
        const int c = int(ls % std::uint32_t(hf.width())), r = int(ls / std::uint32_t(hf.width()));
        p.samples.push_back(std::uint64_t(d.row0 + r) * W + std::uint64_t(d.col0 + c));
        p.rest_z.push_back(hf[ls]);
        p.display_z.push_back(rm.positions[v].z);
      }
      p.triangles = rm.triangles;
      p.bound_px = sel.stats().bound_px;
    } else {
      const BlockSummary& b = sums_[grid_.index(k)];
      auto g = [&](int c, int r) { return std::uint64_t(r) * W + std::uint64_t(c); };
      p.samples = {g(d.col0, d.row0), g(d.col1, d.row0), g(d.col0, d.row1), g(d.col1, d.row1)};
      p.rest_z = {b.z00, b.z10, b.z01, b.z11};
      p.display_z = p.rest_z;
      p.triangles = {{0, 1, 3}, {0, 3, 2}};
      const pm::Box box = block_box(grid_, k, b);
      p.bound_px = view.outside(box) ? 0.0 : view.vertical_error_px(box, b.tm_error);
    }
    patches.push_back(std::move(p));
  }
  const detail::SeamResult sr =
      detail::assemble(grid_, patches, view, opt_.seams, opt_.skirt_depth_m, sums_, mesh_);
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
