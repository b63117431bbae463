// The per-frame terrain runtime: opening a database (tree, stand-ins, memory estimates, the
// loader), its options, and the frame itself, update(): tree selection with PM blocks below,
// residency by priority within a memory budget, the refinements with their swap-in blends, the
// frame's patches, then stitched seams, geomorphs clamped to the bound and the bound of the mesh
// as drawn (see terrain_runtime.hpp for the argument; terrain_runtime_internal.hpp lists the
// files that hold each step).
#include "terralod/blocks/terrain_runtime.hpp"

#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include "grid_triangle.hpp"
#include "terrain_runtime_internal.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/memory_bytes.hpp"
#include "terralod/pm/timing.hpp"

namespace terralod::blocks {

namespace {

using detail::Barycentric;
using detail::barycentric;
using detail::outside_box;
using detail::plane_height;
using detail::refinement_options;
using detail::Tri3;

using pm::thread_cpu_ms;

void check_options(const RuntimeOptions& o) {
  if (!(o.tolerance_px > 0) || !std::isfinite(o.tolerance_px))
    throw std::invalid_argument("RuntimeOptions: tolerance_px must be > 0 and finite");
  if (!(o.min_tolerance_px > 0) || !(o.min_tolerance_px <= o.max_tolerance_px) ||
      !std::isfinite(o.max_tolerance_px))
    throw std::invalid_argument("RuntimeOptions: need 0 < min_tolerance_px <= max_tolerance_px (finite)");
  if (!(o.morph_seconds >= 0) || !std::isfinite(o.morph_seconds))
    throw std::invalid_argument("RuntimeOptions: morph_seconds must be >= 0 and finite");
  if (o.budget_bytes == 0) throw std::invalid_argument("RuntimeOptions: budget_bytes must be > 0");
  if (!(o.partial_load_factor == 0 || (o.partial_load_factor >= 1 && std::isfinite(o.partial_load_factor))))
    throw std::invalid_argument("RuntimeOptions: partial_load_factor must be 0 or finite and >= 1");
  if (o.loader_threads < 1) throw std::invalid_argument("RuntimeOptions: loader_threads must be >= 1");
  if (!(o.prefetch_horizon_s >= 0) || !(o.prefetch_step_s > 0))
    throw std::invalid_argument("RuntimeOptions: need prefetch_horizon_s >= 0 and prefetch_step_s > 0");
  if (!(o.region.theta_deg > 0 && o.region.theta_deg < 90))
    throw std::invalid_argument("RuntimeOptions: region.theta_deg must be in (0, 90)");
  if (o.region.n_min < 0 || o.region.n_min > o.region.n_max)
    throw std::invalid_argument("RuntimeOptions: need 0 <= region.n_min <= region.n_max");
}

// Height at (c, r) of the first triangle of `tris` (whole-grid (col, row, z)) containing it;
// the least-outside one absorbs rounding. NaN when `tris` is empty.
double surface_height(const std::vector<Tri3>& tris, double c, double r) {
  double best = std::numeric_limits<double>::quiet_NaN(), best_in = -1e300;
  for (const Tri3& t : tris) {
    if (outside_box(t, c, r)) continue;
    const Barycentric w = barycentric(t, c, r);
    if (w.det == 0) continue;
    const double in = std::min({w.l0, w.l1, w.l2});
    if (in > best_in) {
      best_in = in;
      best = plane_height(t, w);
      if (in >= 0) break;
    }
  }
  return best;
}

}  // namespace

TerrainRuntime::TerrainRuntime(const std::string& db_path, const RuntimeOptions& options,
                               BlockSourceFactory blocks)
    : path_(db_path), opt_(options), predictor_(options.predictor), scratch_(std::make_unique<Scratch>()) {
  check_options(opt_);
  tau_ = opt_.tolerance_px;
  const BlockDatabase db = BlockDatabase::open(db_path);
  if (db.info().block_size <= 0)
    throw DatabaseError(db_path,
                        "not a blocked database (kind '" + db.info().kind + "'): no PM blocks to draw");
  require_complete_build(db);
  grid_ = BlockGrid::from_info(db.info());
  const auto tree_blob = db.read_blob("tree");
  if (!tree_blob) throw DatabaseError(db_path, "no approximation tree (blob 'tree')");
  tree_ = decode_tree(*tree_blob, db_path + ": tree");
  if (tree_.size() == 0) throw DatabaseError(db_path, "the approximation tree is empty");
  // Block summaries, when the build stored them (databases built before blocks with holes had
  // stand-ins may lack them): every block's fields are held, its stand-in is read when a frame
  // first looks at it (summary_store.hpp). Without them no block is drawn as its stand-in, and
  // a missing PmBlock root leaves nothing to draw until it arrives. An empty block (no valid
  // sample) has no stand-in.
  sums_ = std::make_unique<detail::SummaryStore>(db_path, grid_);
  // Beyond the terrain the scale at its nearest point: the frame is known to hold there.
  if (const auto geo = db.georeference())
    ground_ = GroundScaleMap(db.info().crs_wkt, geo->crs_transform, db.info().transform, terrain_box());
  for (const TreeNode& n : tree_.nodes()) {
    if (n.strategy == Strategy::PmBlock && (!n.block || !grid_.contains(*n.block)))
      throw DatabaseError(db_path,
                          "tree node " + std::to_string(n.id) + " is a PM block outside the block grid");
    // Seams are stitched in sample coordinates: every coarse node's points must be samples of
    // its domain (hybrid nodes built over blocks are; a hybrid database's own tree, whose TIN
    // vertices lie between samples, is drawn by 'terralod view' instead).
    for (const auto& p : n.surface.points)
      if (p[0] != std::floor(p[0]) || p[1] != std::floor(p[1]) || !n.domain.contains(int(p[0]), int(p[1])))
        throw DatabaseError(db_path, "tree node " + std::to_string(n.id) + " (" + strategy_name(n.strategy) +
                                         ") has a point off its domain's samples");
  }
  // PM vertex counts from the build's per-block records ("<error> <vertices> <bytes>"), for the
  // memory estimate of blocks not yet read.
  block_vertices_.assign(grid_.block_count(), 0);
  for (std::size_t i = 0; i < grid_.block_count(); ++i) {
    const BlockKey k = grid_.key(i);
    const auto v = db.get_meta("block/" + std::to_string(k.col) + "," + std::to_string(k.row));
    double e = 0;
    unsigned long long nv = 0, nb = 0;
    if (v && std::sscanf(v->c_str(), "%lf %llu %llu", &e, &nv, &nb) == 3)
      block_vertices_[i] = nv;
    else
      block_vertices_[i] = std::uint64_t(grid_.domain(k).width()) * std::uint64_t(grid_.domain(k).height());
  }
  // The tree and the summaries' fields stay resident. A budget they already pass leaves no room
  // for any block, and resident_bytes <= budget_bytes would be false from the first frame.
  fixed_bytes_ = tree_.memory_bytes() + sums_->fixed_bytes() + pm::capacity_bytes(block_vertices_);
  if (fixed_bytes_ > opt_.budget_bytes) {
    char what[200];
    std::snprintf(what, sizeof what,
                  "its approximation tree and block summaries need %.3g MB resident, more than the memory "
                  "budget of %.3g MB: give a larger budget",
                  double(fixed_bytes_) / 1e6, double(opt_.budget_bytes) / 1e6);
    throw DatabaseError(db_path, what);
  }
  stats_.resident_bytes = stats_.peak_resident_bytes = fixed_bytes_;  // what stats() says before a frame
  prep_options_ = refinement_options(opt_, tau_);
  loader_ = std::make_unique<BlockLoader>(
      blocks ? std::move(blocks) : database_source(db_path), grid_,
      [this](const LoadedBlock& b) {
        std::optional<pm::View> view;
        double t = 0;
        pm::RefinementOptions o;
        {
          std::lock_guard lock(prep_mutex_);
          view = prep_view_, t = prep_time_, o = prep_options_;
        }
        auto sel = std::make_unique<pm::SelectiveRefinement>(*b.dag, o);
        if (view) sel->update(*view, t);  // a first update never morphs
        return sel;
      },
      opt_.loader_threads);
}

TerrainRuntime::~TerrainRuntime() { loader_.reset(); }

void TerrainRuntime::set_options(const RuntimeOptions& options) {
  check_options(options);
  if (options.loader_threads != opt_.loader_threads)
    throw std::invalid_argument("RuntimeOptions: loader_threads is fixed when the runtime opens");
  const bool refine_changed = options.tolerance_px != opt_.tolerance_px ||
                              options.morph_seconds != opt_.morph_seconds ||
                              options.target_triangles != opt_.target_triangles;
  // The flight history is kept unless the predictor itself changes (a new tau must not make
  // the next frames predict from nothing).
  if (!(options.predictor == opt_.predictor)) predictor_ = FlightPredictor(options.predictor);
  opt_ = options;
  if (refine_changed) tau_ = opt_.tolerance_px;
}

void TerrainRuntime::fit_camera(pm::Camera& cam) const {
  cam.ground = ground_scale(cam.x, cam.y);
  pm::fit_clip_planes(cam, terrain_box());
}

RuntimeFrameStats TerrainRuntime::update_until_loaded(const pm::View& view, double time_s, double timeout_s) {
  const RuntimeFrameStats first = update(view, time_s);
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  for (int quiet = 0;;) {
    quiet = loading() ? 0 : quiet + 1;
    if (quiet == 2) return first;
    if (std::chrono::steady_clock::now() > until)
      throw std::runtime_error(path_ + ": block loads did not finish in " + std::to_string(timeout_s) + " s");
    wait_for_loader(0.05);
    update(view, time_s);
  }
}

const RuntimeFrameStats& TerrainRuntime::update(const pm::View& view, double time_s) {
  const auto t0 = std::chrono::steady_clock::now();
  const double cpu0 = thread_cpu_ms();
  if (started_ && time_s < time_)
    throw std::invalid_argument("TerrainRuntime::update: time went backwards (" + std::to_string(time_s) +
                                " s after " + std::to_string(time_) + " s)");
  started_ = true;
  time_ = time_s;
  ++frame_;
  const RuntimeFrameStats prev = stats_;
  // The frame's statistics start from zero but for the cumulative counters (and the peak).
  stats_ = RuntimeFrameStats{.frame = frame_,
                             .time_s = time_s,
                             .nodes_resident = tree_.size(),
                             .evicted_total = prev.evicted_total,
                             .dropped_total = prev.dropped_total,
                             .reloads_total = prev.reloads_total,
                             .prefetch_hits_total = prev.prefetch_hits_total,
                             .prefetch_misses_total = prev.prefetch_misses_total,
                             .peak_resident_bytes = prev.peak_resident_bytes};
  RuntimeFrameStats& s = stats_;

  // Budget mode: tau follows the triangle count of the last frame.
  if (opt_.target_triangles > 0 && prev.triangles > 0) {
    const double f = std::clamp(double(prev.triangles) / double(opt_.target_triangles), 0.5, 2.0);
    tau_ = std::clamp(tau_ * f, opt_.min_tolerance_px, opt_.max_tolerance_px);
  } else if (opt_.target_triangles == 0) {
    tau_ = opt_.tolerance_px;
  }
  const double tau = tau_;
  s.tolerance_px = tau;
  predictor_.observe(time_s, view.eye());
  // Blocks the loader decodes from now on are refined first for this view, before step 3
  // queues them: set at the end of the frame instead, a block asked for in this frame and
  // decoded before its end would be prepared for the previous view and geomorph from it when
  // taken, and whether it was depended on the loader's timing (headless replays differed).
  {
    std::lock_guard lock(prep_mutex_);
    prep_view_ = view, prep_time_ = time_s, prep_options_ = refinement_options(opt_, tau);
  }

  auto lap = [last = std::chrono::steady_clock::now()]() mutable {
    const auto now = std::chrono::steady_clock::now();
    const double ms = std::chrono::duration<double, std::milli>(now - last).count();
    last = now;
    return ms;
  };
  // 1. Finished loads.
  take_loads();

  // 2. Selection.
  Selection sel;
  const bool root_ok = visit(view, tau, 0, sel, std::numeric_limits<double>::infinity());
  const std::vector<std::int64_t>&coarse = sel.coarse, &pms = sel.pms;
  const std::vector<Need>& needed = sel.needed;
  // A PmBlock root that is missing is drawn as its stand-in (no ancestor exists).
  const bool root_standin = !root_ok && sums_->has_standin(grid_.index(*tree_.root().block));
  s.needed_in_view = needed.size();
  std::set<BlockKey> needed_now;
  for (const Need& nd : needed) {
    const BlockKey k = *tree_.node(nd.id).block;
    needed_now.insert(k);
    const auto it = blocks_.find(k);
    if (it != blocks_.end()) it->second->last_used = frame_;
    if (it != blocks_.end() && covers(*it->second, nd.floor_m)) {
      if (!needed_prev_.count(k) && !missing_.count(k)) ++s.prefetch_hits_total;
      missing_.erase(k);
    } else {
      ++s.missing_in_view;
      if (missing_.insert(k).second) ++s.prefetch_misses_total;
    }
  }
  for (auto it = missing_.begin(); it != missing_.end();)
    it = needed_now.count(*it) ? std::next(it) : missing_.erase(it);
  needed_prev_ = std::move(needed_now);

  s.select_ms = lap();
  // 3. Residency: the loader's queue.
  queue_loads(view, needed);

  s.residency_ms = lap();
  // Refinement of the drawn PM blocks; what was drawn over a block before it arrived.
  const std::set<std::int64_t> coarse_set(coarse.begin(), coarse.end()), pm_set(pms.begin(), pms.end());
  std::map<std::int64_t, std::int64_t> drawn_as;
  for (const Need& nd : needed) {
    const std::int64_t id = nd.id;
    std::int64_t a = id;
    if (!pm_set.count(id)) {
      a = tree_.node(id).parent;
      while (a >= 0 && !coarse_set.count(a)) a = tree_.node(a).parent;
      if (a < 0) a = root_standin ? id : -1;
    }
    if (a >= 0) drawn_as[id] = a;
  }
  // The frame's patches, in a pool kept from frame to frame (their vectors keep their storage).
  std::vector<Patch>& patches = patches_;
  std::size_t used = 0;
  auto next_patch = [&]() -> Patch& {
    if (used == patches.size()) patches.emplace_back();
    Patch& p = patches[used++];
    p.sp.vertices.clear();
    p.sp.triangles.clear();
    p.rest_z.clear();
    p.display_z.clear();
    p.tri_error.clear();
    p.heights = nullptr;
    return p;
  };
  const pm::RefinementOptions ropt = refinement_options(opt_, tau);
  for (std::int64_t id : pms) {
    const TreeNode& n = tree_.node(id);
    Block& b = *blocks_.at(*n.block);
    if (b.sel->options().tolerance_px != ropt.tolerance_px ||
        b.sel->options().morph_seconds != ropt.morph_seconds) {
      b.sel->set_options(ropt);
      b.rm_valid = false;
    }
    const bool fresh = b.last_drawn == 0 || b.last_drawn + 1 < frame_;
    if (fresh && opt_.morph_seconds > 0) {
      // Swap-in blend from the surface drawn over the block last frame: its stand-in, or an
      // ancestor's surface.
      b.blending = false;
      b.old.clear();
      b.old_z.clear();
      const auto it = drawn_as_.find(id);
      if (it != drawn_as_.end() && (it->second != id || standins_prev_.count(id))) {
        const TreeNode& a = tree_.node(it->second);
        NodeSurface standin;
        if (a.strategy == Strategy::PmBlock) {  // the stand-in, in whole-grid coordinates
          const BlockSummary& sum = sums_->summary(grid_.index(*a.block), frame_);
          for (const StandinPoint& q : sum.points)
            standin.points.push_back({double(a.domain.col0 + q.col), double(a.domain.row0 + q.row), q.z});
          standin.triangles = sum.triangles;
        }
        const NodeSurface& old = a.strategy == Strategy::PmBlock ? standin : a.surface;
        for (const auto& t : old.triangles) {
          Tri3 q;
          for (int c = 0; c < 3; ++c) q[std::size_t(c)] = old.points[t[std::size_t(c)]];
          const double cmin = std::min({q[0][0], q[1][0], q[2][0]}),
                       cmax = std::max({q[0][0], q[1][0], q[2][0]});
          const double rmin = std::min({q[0][1], q[1][1], q[2][1]}),
                       rmax = std::max({q[0][1], q[1][1], q[2][1]});
          if (cmax < n.domain.col0 || cmin > n.domain.col1 || rmax < n.domain.row0 || rmin > n.domain.row1)
            continue;
          b.old.push_back(q);
        }
        if (!b.old.empty()) {
          b.blending = true;
          b.blend_t0 = time_s;
        }
      }
    }
    b.last_drawn = frame_;
    b.last_used = frame_;
    const pm::FrameStats& fs = b.sel->update(view, time_s);
    if (!b.rm_valid || fs.vsplits > 0 || fs.ecols > 0 || b.sel->morphing() || fs.morphing > 0) {
      b.sel->render_mesh_into(b.rm);
      b.rm_valid = true;
    }
    if (b.sel->morphing() || b.blending) ++s.morphing_blocks;
    const double w = b.blending ? std::clamp((time_s - b.blend_t0) / opt_.morph_seconds, 0.0, 1.0) : 1.0;
    Patch& p = next_patch();
    p.node = id;
    p.sp.domain = n.domain;
    const pm::Heightfield& hf = b.data->dag->heightfield();
    const int bw = hf.width();
    p.sp.vertices.reserve(b.rm.samples.size());
    p.rest_z.reserve(b.rm.samples.size());
    p.display_z.reserve(b.rm.samples.size());
    for (std::size_t v = 0; v < b.rm.samples.size(); ++v) {
      const std::uint32_t ls = b.rm.samples[v];
      const int c = int(ls % std::uint32_t(bw)), r = int(ls / std::uint32_t(bw));
      p.sp.vertices.push_back({n.domain.col0 + c, n.domain.row0 + r});
      p.rest_z.push_back(hf[ls]);
      double z = b.rm.positions[v].z;
      if (w < 1) {
        auto [e, inserted] = b.old_z.try_emplace(ls, 0.0);
        if (inserted) {
          const double h = surface_height(b.old, double(n.domain.col0 + c), double(n.domain.row0 + r));
          e->second = std::isnan(h) ? hf[ls] : h;
        }
        z = e->second * (1 - w) + z * w;
      }
      p.display_z.push_back(z);
    }
    if (w >= 1 && b.blending) {
      b.blending = false;
      b.old = {};
      b.old_z = {};
    }
    p.sp.triangles.assign(b.rm.triangles.begin(), b.rm.triangles.end());
    p.tri_error.assign(b.rm.errors.begin(), b.rm.errors.end());
    p.bound_px = fs.bound_px;
    p.heights = &hf;
    p.metric = b.data->metric;
    p.zlo = n.bbox.lo.z;
    p.zhi = n.bbox.hi.z;
    ++s.pm_blocks;
  }
  auto add_surface_patch = [&](std::int64_t id, const SampleRect& domain,
                               const std::vector<std::array<double, 3>>& pts,
                               const std::vector<std::array<std::uint32_t, 3>>& tris,
                               const std::vector<double>& errs, double bound_px, const pm::Box& box) {
    Patch& p = next_patch();
    p.node = id;
    p.zlo = box.lo.z;
    p.zhi = box.hi.z;
    p.sp.domain = domain;
    for (const auto& q : pts) {
      p.sp.vertices.push_back({int(q[0]), int(q[1])});
      p.rest_z.push_back(q[2]);
    }
    p.display_z.assign(p.rest_z.begin(), p.rest_z.end());
    p.sp.triangles.assign(tris.begin(), tris.end());
    p.tri_error.assign(errs.begin(), errs.end());
    p.bound_px = bound_px;
  };
  for (std::int64_t id : coarse) {
    const TreeNode& n = tree_.node(id);
    add_surface_patch(id, n.domain, n.surface.points, n.surface.triangles,
                      std::vector<double>(n.surface.triangles.size(), n.error),
                      view.vertical_error_px(n.bbox, n.error), n.bbox);
  }
  s.coarse_nodes = coarse.size();
  auto add_standin = [&](const TreeNode& n) {
    const BlockSummary& sum = sums_->summary(grid_.index(*n.block), frame_);
    std::vector<std::array<double, 3>> pts;
    pts.reserve(sum.points.size());
    for (const StandinPoint& q : sum.points)
      pts.push_back({double(n.domain.col0 + q.col), double(n.domain.row0 + q.row), q.z});
    add_surface_patch(n.id, n.domain, pts, sum.triangles, sum.triangle_errors,
                      standin_bound_px(grid_, *n.block, sum, view), n.bbox);
  };
  for (std::int64_t id : sel.standins) add_standin(tree_.node(id));
  s.standin_blocks = sel.standins.size();
  if (root_standin) {  // a missing PmBlock root: its stand-in, with its true bound
    add_standin(tree_.root());
    s.fallback_nodes += 1;
  }
  for (std::int64_t id : sel.standins) drawn_as[id] = id;
  drawn_as_ = std::move(drawn_as);
  standins_prev_ = std::set<std::int64_t>(sel.standins.begin(), sel.standins.end());
  std::sort(patches.begin(), patches.begin() + std::ptrdiff_t(used),
            [](const Patch& a, const Patch& b) { return a.node < b.node; });

  s.refine_ms = lap();
  // 4-5. Seams, offsets clamped to the bound, the drawn mesh.
  assemble(view, tau, used, s);
  s.seams_ms = lap();

  // Eviction: within the budget at the end of every frame; blocks drawn this frame go last.
  // Stand-ins this frame and the last kKeepFrames did not look at go first.
  sums_->trim(frame_);
  {
    std::set<BlockKey> keep;
    for (const auto& [k, b] : blocks_)
      if (b->last_drawn == frame_) keep.insert(k);
    make_room(0, keep);
    make_room(0, {});
  }
  s.evicted_total += s.blocks_evicted;
  s.blocks_resident = blocks_.size();
  for (const auto& [k, b] : blocks_) s.partial_blocks += b->data->dag->skipped() > 0;
  s.blocks_loading = loader_->pending();
  s.bytes_read_total = loader_->bytes_read();
  s.bytes_read = s.bytes_read_total - prev.bytes_read_total;
  s.standins_held = sums_->held_count();
  s.standin_reads_total = sums_->reads();
  s.resident_bytes = resident_bytes();
  s.peak_resident_bytes = std::max(s.peak_resident_bytes, s.resident_bytes);
  s.update_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  s.update_cpu_ms = thread_cpu_ms() - cpu0;
  return stats_;
}

}  // namespace terralod::blocks
