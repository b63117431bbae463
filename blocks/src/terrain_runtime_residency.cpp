// Step 3 of the terrain runtime's frame (terrain_runtime.hpp): residency. Loads taken from the
// background loader, the loader's queue by priority (needed blocks, the active region around
// the eye, then along the predicted flight path) within the memory budget, eviction of the
// least recently used blocks, and the memory estimates behind them.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <stdexcept>
#include <thread>
#include <unordered_map>

#include "grid_triangle.hpp"
#include "terrain_runtime_internal.hpp"
#include "terralod/blocks/terrain_runtime.hpp"
#include "terralod/pm/memory_bytes.hpp"

namespace terralod::blocks {

using detail::refinement_options;

namespace {

// The height of the surface `tris` (whole-grid (col, row, z), corners on samples) at every
// block-local sample inside one of them, into `out`: one pass over each triangle's samples
// (exact on the integer grid), so that a blend from a large mesh (a coarser copy of the
// block: thousands of triangles) does not search every triangle for every vertex.
void old_surface_at_samples(const std::vector<detail::Tri3>& tris, const SampleRect& d, std::uint32_t bw,
                            std::unordered_map<std::uint32_t, double>& out) {
  out.reserve(out.size() + 2 * tris.size());
  for (const detail::Tri3& t : tris) {
    const int c0 = int(std::min({t[0][0], t[1][0], t[2][0]})),
              c1 = int(std::max({t[0][0], t[1][0], t[2][0]}));
    const int r0 = int(std::min({t[0][1], t[1][1], t[2][1]})),
              r1 = int(std::max({t[0][1], t[1][1], t[2][1]}));
    for (int r = r0; r <= r1; ++r)
      for (int c = c0; c <= c1; ++c) {
        const detail::Barycentric w = detail::barycentric(t, double(c), double(r));
        if (w.det == 0 || w.l0 < 0 || w.l1 < 0 || w.l2 < 0) continue;
        out.try_emplace(std::uint32_t(r - d.row0) * bw + std::uint32_t(c - d.col0),
                        detail::plane_height(t, w));
      }
  }
}

}  // namespace

bool TerrainRuntime::loading() const { return loader_->pending() > 0 || loader_->finished() > 0; }

bool TerrainRuntime::wait_for_loader(double timeout_s) const {
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  const std::size_t before = loader_->pending();
  while (loader_->pending() > 0 && loader_->pending() >= before && std::chrono::steady_clock::now() < until)
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  return loader_->pending() > 0;
}

std::size_t TerrainRuntime::estimate_bytes(BlockKey k) const {
  const double per_vertex = loaded_vertices_ > 0 ? loaded_bytes_ / loaded_vertices_ : 600.0;
  return std::size_t(double(block_vertices_[grid_.index(k)]) * per_vertex);
}

std::size_t TerrainRuntime::block_bytes(const Block& b) const {
  using pm::capacity_bytes;
  // The DAG and refinement as measured now, or the reservation the block was admitted with
  // (LoadedBlock::memory_bytes: its refinement at full resolution) while that is larger, so
  // that a block never needs more room than it was given when it refines further.
  const std::size_t data = std::max(b.data->memory_bytes, sizeof(LoadedBlock) + b.data->dag->memory_bytes() +
                                                              (b.sel ? b.sel->memory_bytes() : 0));
  return data + pm::malloc_chunk_bytes(sizeof(Block)) + capacity_bytes(b.rm.samples) +
         capacity_bytes(b.rm.positions) + capacity_bytes(b.rm.triangles) + capacity_bytes(b.rm.errors) +
         capacity_bytes(b.old) + capacity_bytes(b.old_z);
}

std::size_t TerrainRuntime::frame_bytes() const {
  using pm::capacity_bytes;
  std::size_t n = mesh_.memory_bytes() + capacity_bytes(patches_);
  for (const Patch& p : patches_)
    n += capacity_bytes(p.sp.vertices) + capacity_bytes(p.sp.triangles) + capacity_bytes(p.rest_z) +
         capacity_bytes(p.display_z) + capacity_bytes(p.tri_error);
  const HeightIndex& ix = height_index_;
  n += capacity_bytes(ix.start) + capacity_bytes(ix.tris) + capacity_bytes(ix.box) + capacity_bytes(ix.fill);
  const Scratch& sc = *scratch_;
  n += capacity_bytes(sc.original_vertices) + capacity_bytes(sc.sps) + capacity_bytes(sc.border) +
       capacity_bytes(sc.rest) + capacity_bytes(sc.display) + capacity_bytes(sc.allowed) +
       capacity_bytes(sc.gidx) + capacity_bytes(sc.eval) + capacity_bytes(sc.moving) +
       capacity_bytes(sc.piece);
  for (const StitchPatch& p : sc.sps) n += capacity_bytes(p.vertices) + capacity_bytes(p.triangles);
  return n + capacity_bytes(blocks_) + capacity_bytes(needed_prev_) + capacity_bytes(missing_) +
         capacity_bytes(drawn_as_) + capacity_bytes(standins_prev_);
}

std::size_t TerrainRuntime::resident_bytes() const {
  std::size_t n = fixed_bytes_ + sums_->held_bytes() + frame_bytes() + loader_->held_bytes();
  for (const auto& [k, b] : blocks_) n += block_bytes(*b);
  return n;
}

void TerrainRuntime::make_room(std::size_t bytes, const std::set<BlockKey>& keep) {
  std::size_t resident = resident_bytes();
  while (resident + bytes > opt_.budget_bytes) {
    auto victim = blocks_.end();
    for (auto it = blocks_.begin(); it != blocks_.end(); ++it) {
      if (keep.count(it->first)) continue;
      if (victim == blocks_.end() || it->second->last_used < victim->second->last_used) victim = it;
    }
    if (victim == blocks_.end()) return;
    resident -= block_bytes(*victim->second);
    blocks_.erase(victim);
    ++stats_.blocks_evicted;
  }
}

void TerrainRuntime::take_loads() {
  std::vector<LoadResult> results = loader_->take_results();
  if (results.empty()) return;
  std::set<BlockKey> keep;
  for (const auto& [k, b] : blocks_)
    if (b->last_drawn == frame_ - 1 || b->last_used == frame_ - 1) keep.insert(k);
  for (LoadResult& r : results) {
    if (!r.block) throw std::runtime_error(r.error);
    const BlockKey k = r.key;
    auto old = blocks_.find(k);
    // A copy no finer than the resident one (asked for before the resident one arrived) is
    // not needed.
    if (old != blocks_.end() && !(r.block->dag->floor_error() < old->second->data->dag->floor_error()))
      continue;
    const std::uint64_t nv = r.block->dag->full_vertex_count();
    if (nv > 0 && r.block->dag->skipped() == 0)  // whole blocks only: estimate_bytes is for them
      loaded_bytes_ += double(r.block->memory_bytes), loaded_vertices_ += double(nv);
    // A finer copy replaces the resident one: only the difference needs room.
    const std::size_t old_bytes = old != blocks_.end() ? block_bytes(*old->second) : 0;
    keep.insert(k);
    make_room(r.block->memory_bytes > old_bytes ? r.block->memory_bytes - old_bytes : 0, keep);
    if (resident_bytes() - old_bytes + r.block->memory_bytes > opt_.budget_bytes) {
      ++stats_.dropped_total;
      continue;
    }
    auto b = std::make_unique<Block>();
    b->data = std::move(r.block);
    b->sel = r.selection
                 ? std::move(r.selection)
                 : std::make_unique<pm::SelectiveRefinement>(*b->data->dag, refinement_options(opt_, tau_));
    b->last_used = frame_;
    if (old != blocks_.end()) {
      // The finer copy blends in from what the coarser one drew last (or goes on with the
      // blend that one was in), as a block arriving over its stand-in does.
      Block& o = *old->second;
      b->last_drawn = o.last_drawn;
      if (opt_.morph_seconds > 0 && o.last_drawn + 1 >= frame_) {
        if (o.blending) {
          b->old = std::move(o.old);
          b->old_z = std::move(o.old_z);  // heights of the same old surface, at any sample
          b->blend_t0 = o.blend_t0;
        } else if (o.rm_valid) {
          const SampleRect d = grid_.domain(k);
          const std::uint32_t bw = std::uint32_t(o.data->dag->heightfield().width());
          for (const auto& t : o.rm.triangles) {
            detail::Tri3 q;
            for (int c = 0; c < 3; ++c) {
              const std::uint32_t v = t[std::size_t(c)], ls = o.rm.samples[v];
              q[std::size_t(c)] = {double(d.col0 + int(ls % bw)), double(d.row0 + int(ls / bw)),
                                   o.rm.positions[v].z};
            }
            b->old.push_back(q);
          }
          old_surface_at_samples(b->old, d, bw, b->old_z);
          b->blend_t0 = time_;
        }
        b->blending = !b->old.empty();
      }
      ++stats_.reloads_total;
    }
    blocks_[k] = std::move(b);
  }
}

void TerrainRuntime::queue_loads(const pm::View& view, const std::vector<Need>& needed) {
  // Requests in priority order (lower first): needed blocks by screen error, then the active
  // region around the eye, then the regions around the predicted path. The queue stops where
  // the estimated memory would pass the budget.
  std::vector<BlockLoader::Request> req;
  std::map<BlockKey, std::size_t> queued;  // index in req
  std::set<BlockKey> seen;                 // counted in `planned`
  // What the loader holds (blocks being read or waiting to be taken) is already spent.
  std::size_t planned = fixed_bytes_ + sums_->held_bytes() + frame_bytes() + loader_->held_bytes();
  for (const auto& [k, b] : blocks_)
    if (b->last_used == frame_) planned += block_bytes(*b), seen.insert(k);
  // The floor a block is loaded at when `need` is the coarsest its view can use (see
  // RuntimeOptions::partial_load_factor).
  const auto load_floor = [&](double need) {
    return opt_.partial_load_factor > 0 ? need / opt_.partial_load_factor : 0.0;
  };
  // Wants block k at priority `priority` with leaves no coarser than `need`: resident and fine
  // enough, it is kept; otherwise it is queued (a resident coarser copy stays until the finer
  // one replaces it). False once the plan would pass the budget.
  auto want = [&](BlockKey k, double priority, double need) {
    if (const auto q = queued.find(k); q != queued.end()) {
      req[q->second].floor_m = std::min(req[q->second].floor_m, load_floor(need));
      return true;
    }
    const auto it = blocks_.find(k);
    const bool resident = it != blocks_.end(), covered = resident && covers(*it->second, need);
    if (covered && seen.count(k)) return true;
    std::size_t bytes = !resident || seen.count(k) ? 0 : block_bytes(*it->second);
    // Whole-block estimate, an upper bound of any copy; a block the loader holds is counted.
    const std::size_t estimate = covered ? 0 : estimate_bytes(k);
    if (!covered && !loader_->holds(k)) bytes += estimate;
    if (planned + bytes > opt_.budget_bytes) return false;
    planned += bytes;
    seen.insert(k);
    if (resident) it->second->last_used = frame_;  // keep what the policy wants
    if (!covered) {
      queued[k] = req.size();
      req.push_back({k, priority, load_floor(need), estimate});
    }
    return true;
  };
  std::vector<Want> order;
  for (const Need& nd : needed) order.push_back({-nd.parent_px, *tree_.node(nd.id).block, nd.floor_m});
  std::sort(order.begin(), order.end());
  bool room = true;
  for (std::size_t i = 0; i < order.size() && room; ++i)
    room = want(order[i].key, double(i) / double(order.size() + 1), order[i].floor_m);
  const pm::Vec3 eye = view.eye();
  const double scale = 1.0 / (grid_.block_extent_m() * double(2 * opt_.region.n_max + 3));
  auto dist = [&](BlockKey k) {  // in plan view: the box flattened to the eye's height
    pm::Box b = block_box(grid_, k, sums_->fields()[grid_.index(k)]);
    b.lo.z = b.hi.z = eye.z;
    return std::min(0.99, pm::distance_to_box(eye, b) * scale);
  };
  // The floor a view from `centre` (this view's lens) needs over block k at its nearest.
  const double limit = detail::kSelectShare * tau_;
  const double seen_scale = view.camera().ground.min_distance_scale();
  auto need_from = [&](const pm::Vec3& centre, BlockKey k) {
    const pm::Box b = block_box(grid_, k, sums_->fields()[grid_.index(k)]);
    return limit / view.vertical_error_px_at_depth(seen_scale * pm::distance_to_box(centre, b), 1.0);
  };
  // The inner blocks of the active region around `centre`, nearest the eye first, at
  // priorities base + spread * distance (distance scaled into [0, 0.99]), with the floor a view
  // from `centre` needs.
  auto want_region = [&](const pm::Vec3& centre, double base, double spread) {
    const ActiveRegion r = active_region(grid_, sums_->fields(), centre, opt_.region);
    std::vector<std::pair<double, BlockKey>> around;
    for (BlockKey k : r.inner) around.push_back({dist(k), k});
    std::sort(around.begin(), around.end());
    for (std::size_t i = 0; i < around.size() && room; ++i)
      room = want(around[i].second, base + spread * around[i].first, need_from(centre, around[i].second));
  };
  if (room) want_region(eye, 1.0, 1.0);
  if (room && opt_.prefetch) {
    // Along the predicted path, nearest in time first: the blocks the view from there will need
    // (the camera moved to the predicted point, turned along the motion, same lens), then the
    // region around that point.
    pm::Vec3 prev = eye;
    for (const PredictedPoint& pt : predictor_.predict(opt_.prefetch_horizon_s, opt_.prefetch_step_s)) {
      if (pt.dt == 0 || !room) continue;
      pm::Camera c = view.camera();
      c.x = pt.position.x, c.y = pt.position.y, c.z = pt.position.z;
      const double dx = pt.position.x - prev.x, dy = pt.position.y - prev.y;
      if (std::hypot(dx, dy) > 1e-6) c.yaw_deg = std::atan2(dx, dy) * 180.0 / std::numbers::pi;
      prev = pt.position;
      std::vector<Want> ahead;
      needed_at(pm::View(c), tau_, 0, std::numeric_limits<double>::infinity(), ahead);
      std::sort(ahead.begin(), ahead.end());
      for (std::size_t i = 0; i < ahead.size() && room; ++i)
        room = want(ahead[i].key, 2.0 + pt.dt, ahead[i].floor_m);
      if (room)
        want_region(pt.position, 2.0 + pt.dt + 0.5 * opt_.prefetch_step_s, 0.25 * opt_.prefetch_step_s);
    }
  }
  loader_->set_queue(std::move(req));
}

}  // namespace terralod::blocks
