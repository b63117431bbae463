// The per-frame terrain runtime: tree selection with PM blocks below, residency by priority
// within a memory budget, stitched seams between patches of any kind, geomorphs clamped to the
// bound, and the bound of the mesh as drawn (see terrain_runtime.hpp for the argument).
#include "terralod/blocks/terrain_runtime.hpp"

#include <time.h>

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <thread>
#include <unordered_map>

#include "terralod/blocks/seam_stitch.hpp"
#include "terralod/blocks/tree_builder.hpp"

namespace terralod::blocks {

namespace {

double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) * 1e3 + double(ts.tv_nsec) * 1e-6;
}

void check_options(const RuntimeOptions& o) {
  if (!(o.tolerance_px > 0) || !std::isfinite(o.tolerance_px))
    throw std::invalid_argument("RuntimeOptions: tolerance_px must be > 0 and finite");
  if (!(o.min_tolerance_px > 0) || !(o.min_tolerance_px <= o.max_tolerance_px) ||
      !std::isfinite(o.max_tolerance_px))
    throw std::invalid_argument("RuntimeOptions: need 0 < min_tolerance_px <= max_tolerance_px (finite)");
  if (!(o.morph_seconds >= 0) || !std::isfinite(o.morph_seconds))
    throw std::invalid_argument("RuntimeOptions: morph_seconds must be >= 0 and finite");
  if (o.budget_bytes == 0) throw std::invalid_argument("RuntimeOptions: budget_bytes must be > 0");
  if (!(o.prefetch_horizon_s >= 0) || !(o.prefetch_step_s > 0))
    throw std::invalid_argument("RuntimeOptions: need prefetch_horizon_s >= 0 and prefetch_step_s > 0");
  if (!(o.region.theta_deg > 0 && o.region.theta_deg < 90))
    throw std::invalid_argument("RuntimeOptions: region.theta_deg must be in (0, 90)");
  if (o.region.n_min < 0 || o.region.n_min > o.region.n_max)
    throw std::invalid_argument("RuntimeOptions: need 0 <= region.n_min <= region.n_max");
}

// The share of tau every patch is selected at: half, since the stitch can at most double the
// error of a border face (terrain_runtime.hpp, "The bound"), less a relative 1e-9 so that the
// rounding of the separately computed bounds (~1e-15) can never carry a frame over tau.
constexpr double kSelectShare = 0.5 * (1.0 - 1e-9);

// PM blocks, like coarse nodes, are selected at kSelectShare of tau.
pm::RefinementOptions refinement_options(const RuntimeOptions& o, double tau) {
  pm::RefinementOptions r;
  r.tolerance_px = kSelectShare * tau;
  r.morph_seconds = o.morph_seconds;
  r.morph_mode = pm::MorphMode::Vertical;  // plan positions stay on the samples: seams hold
  return r;
}

bool on_border(const SampleRect& d, int col, int row) {
  return col == d.col0 || col == d.col1 || row == d.row0 || row == d.row1;
}

// Height at (c, r) of the plane through three (col, row, z) points.
double plane_height(const std::array<double, 3>& a, const std::array<double, 3>& b,
                    const std::array<double, 3>& e, double c, double r) {
  const double det = (b[0] - a[0]) * (e[1] - a[1]) - (b[1] - a[1]) * (e[0] - a[0]);
  const double l1 = ((c - a[0]) * (e[1] - a[1]) - (r - a[1]) * (e[0] - a[0])) / det;
  const double l2 = ((b[0] - a[0]) * (r - a[1]) - (b[1] - a[1]) * (c - a[0])) / det;
  return (1 - l1 - l2) * a[2] + l1 * b[2] + l2 * e[2];
}

using Tri3 = std::array<std::array<double, 3>, 3>;

// Height at (c, r) of the first triangle of `tris` (whole-grid (col, row, z)) containing it;
// the least-outside one absorbs rounding. NaN when `tris` is empty.
double surface_height(const std::vector<Tri3>& tris, double c, double r) {
  double best = std::numeric_limits<double>::quiet_NaN(), best_in = -1e300;
  for (const Tri3& t : tris) {
    const auto &a = t[0], &b = t[1], &e = t[2];
    if (c < std::min({a[0], b[0], e[0]}) || c > std::max({a[0], b[0], e[0]}) ||
        r < std::min({a[1], b[1], e[1]}) || r > std::max({a[1], b[1], e[1]}))
      continue;
    const double det = (b[0] - a[0]) * (e[1] - a[1]) - (b[1] - a[1]) * (e[0] - a[0]);
    if (det == 0) continue;
    const double l1 = ((c - a[0]) * (e[1] - a[1]) - (r - a[1]) * (e[0] - a[0])) / det;
    const double l2 = ((b[0] - a[0]) * (r - a[1]) - (b[1] - a[1]) * (c - a[0])) / det;
    const double l0 = 1 - l1 - l2, in = std::min({l0, l1, l2});
    if (in > best_in) {
      best_in = in;
      best = l0 * a[2] + l1 * b[2] + l2 * e[2];
      if (in >= 0) break;
    }
  }
  return best;
}

}  // namespace

// A resident block: its data and its refinement, kept while resident.
struct TerrainRuntime::Block {
  std::shared_ptr<const LoadedBlock> data;
  std::unique_ptr<pm::SelectiveRefinement> sel;
  std::uint64_t last_used = 0;   // frame it was last wanted
  std::uint64_t last_drawn = 0;  // frame it was last drawn (0: never)
  pm::RenderMesh rm;             // the refinement's displayed mesh, cached while it does not change
  bool rm_valid = false;
  bool blending = false;  // swap-in blend from `old` running
  double blend_t0 = 0;
  std::vector<Tri3> old;  // whole-grid triangles drawn over the block before it arrived
  std::unordered_map<std::uint32_t, double> old_z;  // old surface at local samples
};

// One selected node's mesh this frame (whole-grid samples).
struct TerrainRuntime::Patch {
  std::int64_t node = 0;
  StitchPatch sp;  // domain, vertices (col,row), triangles
  std::vector<double> rest_z, display_z;
  std::vector<double> tri_error;             // logical error per triangle, metres
  double bound_px = 0;                       // own bound of the unstitched triangles at rest
  const pm::Heightfield* heights = nullptr;  // PM blocks: the block's samples (block-local)
  pm::ErrorMetric metric = pm::ErrorMetric::Continuous;
  double zlo = 0, zhi = 0;  // height range of the terrain's samples in the domain
};

// A drawn triangle that is evaluated on its own (stitched, or with a moving corner).
struct TerrainRuntime::Eval {
  std::uint32_t tri;
  double error;                // e_T (a stitched piece: its source's error plus the inserted corners' delta)
  double source_error;         // the error of the triangle it was cut from (itself when not stitched)
  std::array<double, 3> base;  // the source's true plane at the three corners
  std::size_t patch;
};

// Buffers of assemble(), kept from frame to frame so that a frame allocates nothing new.
struct TerrainRuntime::Scratch {
  std::vector<std::size_t> original_vertices;
  std::vector<StitchPatch> sps;
  std::unordered_map<std::uint64_t, std::uint32_t> border;
  std::vector<double> rest, display, allowed;
  std::vector<std::vector<std::uint32_t>> gidx;
  std::vector<Eval> eval;
  std::vector<std::uint8_t> moving;
  std::vector<std::uint32_t> piece;
};

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
  tree_bytes_ = tree_blob->size() * 3;  // decoded: doubles for the points, about 3x the blob
  // Block summaries with their stand-ins, when the build stored them (it does not for blocks
  // with voids: they have no rectangular stand-in). Without them no block is drawn as its
  // stand-in, and a missing PmBlock root leaves nothing to draw until it arrives.
  if (db.read_blob(kBlockSummariesBlob)) {
    sums_ = read_block_summaries(db, grid_);
    for (std::size_t i = 0; i < sums_.size(); ++i)  // a summary without a surface: its two triangles
      if (sums_[i].triangles.empty()) {
        const SampleRect d = grid_.domain(grid_.key(i));
        set_two_triangle_standin(sums_[i], d.width(), d.height());
      }
  } else {
    sums_.assign(grid_.block_count(), BlockSummary{});
  }
  for (const BlockSummary& s : sums_) summary_bytes_ += 160 + s.points.size() * 16 + s.triangles.size() * 20;
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
  prep_options_ = refinement_options(opt_, tau_);
  loader_ = std::make_unique<BlockLoader>(blocks ? std::move(blocks) : database_source(db_path), grid_,
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
                                          });
}

TerrainRuntime::~TerrainRuntime() { loader_.reset(); }

void TerrainRuntime::set_options(const RuntimeOptions& options) {
  check_options(options);
  const bool refine_changed = options.tolerance_px != opt_.tolerance_px ||
                              options.morph_seconds != opt_.morph_seconds ||
                              options.target_triangles != opt_.target_triangles;
  // The flight history is kept unless the predictor itself changes (a new tau must not make
  // the next frames predict from nothing).
  if (!(options.predictor == opt_.predictor)) predictor_ = FlightPredictor(options.predictor);
  opt_ = options;
  if (refine_changed) tau_ = opt_.tolerance_px;
}

void TerrainRuntime::fit_clip_planes(pm::Camera& cam) const {
  const pm::Box& box = terrain_box();
  const double dx = std::max({box.lo.x - cam.x, 0.0, cam.x - box.hi.x}),
               dy = std::max({box.lo.y - cam.y, 0.0, cam.y - box.hi.y}),
               dz = std::max({box.lo.z - cam.z, 0.0, cam.z - box.hi.z});
  const double dmin = std::sqrt(dx * dx + dy * dy + dz * dz);
  const double fx = std::max(std::abs(cam.x - box.lo.x), std::abs(cam.x - box.hi.x)),
               fy = std::max(std::abs(cam.y - box.lo.y), std::abs(cam.y - box.hi.y)),
               fz = std::max(std::abs(cam.z - box.lo.z), std::abs(cam.z - box.hi.z));
  const double dmax = std::sqrt(fx * fx + fy * fy + fz * fz);
  cam.near_m = std::clamp(0.5 * dmin, 0.05, 1000.0);
  cam.far_m = std::max(cam.near_m * 2.0, 1.01 * dmax + 1.0);
}

bool TerrainRuntime::loading() const { return loader_->pending() > 0; }

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

void TerrainRuntime::wait_for_loader(double timeout_s) const {
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  const std::size_t before = loader_->pending();
  while (loader_->pending() > 0 && loader_->pending() >= before && std::chrono::steady_clock::now() < until)
    std::this_thread::sleep_for(std::chrono::microseconds(500));
}

std::size_t TerrainRuntime::estimate_bytes(BlockKey k) const {
  return std::size_t(double(block_vertices_[grid_.index(k)]) * bytes_per_vertex_);
}

std::size_t TerrainRuntime::fixed_bytes() const {
  return tree_bytes_ + summary_bytes_ + mesh_.memory_bytes() +
         4 * (height_index_.start.capacity() + height_index_.tris.capacity());
}

// Selection (header, step 2). Returns false when the subtree needs a block that is not resident.
bool TerrainRuntime::visit(const pm::View& view, double tau, std::int64_t id, Selection& sel,
                           double parent_px) {
  const TreeNode& n = tree_.node(id);
  ++stats_.nodes_visited;
  if (view.outside(n.bbox)) {
    ++stats_.nodes_culled;
    return true;
  }
  const double limit = kSelectShare * tau;
  if (n.strategy == Strategy::PmBlock) {
    // The stand-in, when it meets tau / 2: the whole box first, then triangle by triangle.
    const BlockSummary& sum = sums_[grid_.index(*n.block)];
    if (!sum.triangles.empty() && (view.vertical_error_px(n.bbox, sum.standin_error) <= limit ||
                                   standin_bound_px(grid_, *n.block, sum, view) <= limit)) {
      sel.standins.push_back(id);
      return true;
    }
    sel.needed.push_back({id, parent_px});
    if (!blocks_.count(*n.block)) return false;
    sel.pms.push_back(id);
    return true;
  }
  const double b = view.vertical_error_px(n.bbox, n.error);
  if (n.leaf() || b <= limit) {
    sel.coarse.push_back(id);
    return true;
  }
  const std::size_t c0 = sel.coarse.size(), p0 = sel.pms.size(), s0 = sel.standins.size();
  bool complete = true;
  for (std::int64_t c : n.children) complete = visit(view, tau, c, sel, b) && complete;
  if (!complete) {  // a needed block is missing: this node, resident, is drawn for its subtree
    sel.coarse.resize(c0);
    sel.pms.resize(p0);
    sel.standins.resize(s0);
    sel.coarse.push_back(id);
    ++stats_.fallback_nodes;
  }
  return true;
}

void TerrainRuntime::make_room(std::size_t bytes, const std::set<BlockKey>& keep) {
  std::size_t resident = fixed_bytes();
  for (const auto& [k, b] : blocks_) resident += b->data->memory_bytes;
  while (resident + bytes > opt_.budget_bytes) {
    auto victim = blocks_.end();
    for (auto it = blocks_.begin(); it != blocks_.end(); ++it) {
      if (keep.count(it->first)) continue;
      if (victim == blocks_.end() || it->second->last_used < victim->second->last_used) victim = it;
    }
    if (victim == blocks_.end()) return;
    resident -= victim->second->data->memory_bytes;
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
    const std::uint64_t nv = r.block->pm.full_vertex_count();
    if (nv > 0)
      bytes_per_vertex_ = 0.8 * bytes_per_vertex_ + 0.2 * double(r.block->memory_bytes) / double(nv);
    make_room(r.block->memory_bytes, keep);
    std::size_t resident = fixed_bytes();
    for (const auto& [kk, b] : blocks_) resident += b->data->memory_bytes;
    if (resident + r.block->memory_bytes > opt_.budget_bytes) {
      ++stats_.dropped_total;
      continue;
    }
    auto b = std::make_unique<Block>();
    b->data = std::move(r.block);
    b->sel = r.selection
                 ? std::move(r.selection)
                 : std::make_unique<pm::SelectiveRefinement>(*b->data->dag, refinement_options(opt_, tau_));
    b->last_used = frame_;
    blocks_[k] = std::move(b);
    keep.insert(k);
  }
}

void TerrainRuntime::queue_loads(const pm::View& view,
                                 const std::vector<std::pair<std::int64_t, double>>& needed) {
  // Requests in priority order (lower first): needed blocks by screen error, then the active
  // region around the eye, then the regions around the predicted path. The queue stops where
  // the estimated memory would pass the budget.
  std::vector<BlockLoader::Request> req;
  std::set<BlockKey> seen;
  std::size_t planned = fixed_bytes();
  for (const auto& [k, b] : blocks_)
    if (b->last_used == frame_) planned += b->data->memory_bytes, seen.insert(k);
  auto want = [&](BlockKey k, double priority) {
    if (!seen.insert(k).second) return true;
    const auto it = blocks_.find(k);
    const std::size_t bytes = it != blocks_.end() ? it->second->data->memory_bytes : estimate_bytes(k);
    if (planned + bytes > opt_.budget_bytes) return false;
    planned += bytes;
    if (it != blocks_.end())
      it->second->last_used = frame_;  // keep what the policy wants
    else
      req.push_back({k, priority});
    return true;
  };
  std::vector<std::pair<double, BlockKey>> order;
  for (const auto& [id, px] : needed) order.push_back({-px, *tree_.node(id).block});
  std::sort(order.begin(), order.end());
  bool room = true;
  for (std::size_t i = 0; i < order.size() && room; ++i)
    room = want(order[i].second, double(i) / double(order.size() + 1));
  const pm::Vec3 eye = view.eye();
  const double scale = 1.0 / (grid_.block_extent_m() * double(2 * opt_.region.n_max + 3));
  auto dist = [&](BlockKey k) {
    const pm::Box b = block_box(grid_, k, sums_[grid_.index(k)]);
    const double dx = std::max({b.lo.x - eye.x, 0.0, eye.x - b.hi.x}),
                 dy = std::max({b.lo.y - eye.y, 0.0, eye.y - b.hi.y});
    return std::min(0.99, std::hypot(dx, dy) * scale);
  };
  // The inner blocks of the active region around `centre`, nearest the eye first, at
  // priorities base + spread * distance (distance scaled into [0, 0.99]).
  auto want_region = [&](const pm::Vec3& centre, double base, double spread) {
    const ActiveRegion r = active_region(grid_, sums_, centre, opt_.region);
    std::vector<std::pair<double, BlockKey>> around;
    for (BlockKey k : r.inner) around.push_back({dist(k), k});
    std::sort(around.begin(), around.end());
    for (std::size_t i = 0; i < around.size() && room; ++i)
      room = want(around[i].second, base + spread * around[i].first);
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
      std::vector<std::pair<double, BlockKey>> ahead;
      needed_at(pm::View(c), tau_, 0, std::numeric_limits<double>::infinity(), ahead);
      std::sort(ahead.begin(), ahead.end());
      for (std::size_t i = 0; i < ahead.size() && room; ++i) room = want(ahead[i].second, 2.0 + pt.dt);
      if (room)
        want_region(pt.position, 2.0 + pt.dt + 0.5 * opt_.prefetch_step_s, 0.25 * opt_.prefetch_step_s);
    }
  }
  loader_->set_queue(std::move(req));
}

// The PM blocks a view would need (the selection's rules, with the stand-in tried by its whole
// box only: a cheap, conservative test for prefetching), largest screen error first.
void TerrainRuntime::needed_at(const pm::View& view, double tau, std::int64_t id, double parent_px,
                               std::vector<std::pair<double, BlockKey>>& out) const {
  const TreeNode& n = tree_.node(id);
  if (view.outside(n.bbox)) return;
  const double limit = kSelectShare * tau;
  if (n.strategy == Strategy::PmBlock) {
    const BlockSummary& sum = sums_[grid_.index(*n.block)];
    if (!sum.triangles.empty() && view.vertical_error_px(n.bbox, sum.standin_error) <= limit) return;
    out.push_back({-parent_px, *n.block});
    return;
  }
  const double b = view.vertical_error_px(n.bbox, n.error);
  if (n.leaf() || b <= limit) return;
  for (std::int64_t c : n.children) needed_at(view, tau, c, b, out);
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
  stats_ = RuntimeFrameStats{};
  RuntimeFrameStats& s = stats_;
  s.frame = frame_;
  s.time_s = time_s;
  s.evicted_total = prev.evicted_total;
  s.dropped_total = prev.dropped_total;
  s.prefetch_hits_total = prev.prefetch_hits_total;
  s.prefetch_misses_total = prev.prefetch_misses_total;
  s.peak_resident_bytes = prev.peak_resident_bytes;
  s.nodes_resident = tree_.size();

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
  const std::vector<std::pair<std::int64_t, double>>& needed = sel.needed;
  // A PmBlock root that is missing is drawn as its stand-in (no ancestor exists).
  const bool root_standin = !root_ok && !sums_[grid_.index(*tree_.root().block)].triangles.empty();
  s.needed_in_view = needed.size();
  std::set<BlockKey> needed_now;
  for (const auto& [id, px] : needed) {
    const BlockKey k = *tree_.node(id).block;
    needed_now.insert(k);
    if (blocks_.count(k)) {
      blocks_[k]->last_used = frame_;
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
  for (const auto& [id, px] : needed) {
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
          const BlockSummary& sum = sums_[grid_.index(*a.block)];
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
    p.metric = b.data->pm.metric();
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
    const BlockSummary& sum = sums_[grid_.index(*n.block)];
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
  {
    std::set<BlockKey> keep;
    for (const auto& [k, b] : blocks_)
      if (b->last_drawn == frame_) keep.insert(k);
    make_room(0, keep);
    make_room(0, {});
  }
  s.evicted_total += s.blocks_evicted;
  s.blocks_resident = blocks_.size();
  s.blocks_loading = loader_->pending();
  s.bytes_read_total = loader_->bytes_read();
  s.bytes_read = s.bytes_read_total - prev.bytes_read_total;
  s.resident_bytes = fixed_bytes();
  for (const auto& [k, b] : blocks_) s.resident_bytes += b->data->memory_bytes;
  s.peak_resident_bytes = std::max(s.peak_resident_bytes, s.resident_bytes);
  {
    std::lock_guard lock(prep_mutex_);
    prep_view_ = view, prep_time_ = time_s, prep_options_ = refinement_options(opt_, tau);
  }
  s.update_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  s.update_cpu_ms = thread_cpu_ms() - cpu0;
  return stats_;
}

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
          base[std::size_t(c)] = plane_height(q[0], q[1], q[2], g.x, g.y);
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
  const pm::Vec3 fwd = view.forward();
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

double TerrainRuntime::max_height_at(double x, double y) const {
  auto [c, r] = grid_.to_grid(x, y);
  c = std::clamp(c, 0.0, double(grid_.grid_width() - 1));
  r = std::clamp(r, 0.0, double(grid_.grid_height() - 1));
  const TreeNode* n = &tree_.root();
  for (bool deeper = true; deeper;) {
    deeper = false;
    for (std::int64_t k : n->children) {
      const SampleRect& d = tree_.node(k).domain;
      if (c >= d.col0 && c <= d.col1 && r >= d.row0 && r <= d.row1) {
        n = &tree_.node(k);
        deeper = true;
        break;
      }
    }
  }
  return n->bbox.hi.z;
}

double TerrainRuntime::drawn_height(double x, double y) const {
  // A bucket grid over the drawn triangles' sample-space boxes, built on the first call after
  // an update: a query then tests the triangles of one bucket (ray marches call it often).
  HeightIndex& ix = height_index_;
  const std::uint64_t W = std::uint64_t(grid_.grid_width());
  auto corners = [&](std::size_t f, std::array<double, 3> q[3]) {
    const auto& t = mesh_.triangles[f];
    for (int k = 0; k < 3; ++k) {
      const std::uint64_t sm = mesh_.samples[t[std::size_t(k)]];
      q[k] = {double(sm % W), double(sm / W), mesh_.positions[t[std::size_t(k)]].z};
    }
  };
  if (ix.frame != frame_) {
    ix.frame = frame_;
    const int side = std::clamp(int(std::sqrt(double(mesh_.triangles.size()) / 4.0)), 1, 256);
    ix.nx = ix.ny = side;
    ix.cell_w = double(std::max(grid_.grid_width() - 1, 1)) / side;
    ix.cell_h = double(std::max(grid_.grid_height() - 1, 1)) / side;
    ix.start.assign(std::size_t(side) * side + 1, 0);
    std::vector<std::array<int, 4>> span(mesh_.triangles.size());
    for (std::size_t f = 0; f < mesh_.triangles.size(); ++f) {
      std::array<double, 3> q[3];
      corners(f, q);
      auto cell = [&](double v, double w, int n) { return std::clamp(int(std::floor(v / w)), 0, n - 1); };
      span[f] = {cell(std::min({q[0][0], q[1][0], q[2][0]}), ix.cell_w, side),
                 cell(std::max({q[0][0], q[1][0], q[2][0]}), ix.cell_w, side),
                 cell(std::min({q[0][1], q[1][1], q[2][1]}), ix.cell_h, side),
                 cell(std::max({q[0][1], q[1][1], q[2][1]}), ix.cell_h, side)};
      for (int j = span[f][2]; j <= span[f][3]; ++j)
        for (int i = span[f][0]; i <= span[f][1]; ++i) ++ix.start[std::size_t(j) * side + i + 1];
    }
    for (std::size_t k = 1; k < ix.start.size(); ++k) ix.start[k] += ix.start[k - 1];
    ix.tris.resize(ix.start.back());
    std::vector<std::uint32_t> fill(ix.start.begin(), ix.start.end() - 1);
    for (std::size_t f = 0; f < mesh_.triangles.size(); ++f)
      for (int j = span[f][2]; j <= span[f][3]; ++j)
        for (int i = span[f][0]; i <= span[f][1]; ++i)
          ix.tris[fill[std::size_t(j) * side + i]++] = std::uint32_t(f);
  }
  const auto [c, r] = grid_.to_grid(x, y);
  if (!(c >= 0 && r >= 0 && c <= grid_.grid_width() - 1 && r <= grid_.grid_height() - 1))
    return std::numeric_limits<double>::quiet_NaN();
  const int i = std::clamp(int(std::floor(c / ix.cell_w)), 0, ix.nx - 1);
  const int j = std::clamp(int(std::floor(r / ix.cell_h)), 0, ix.ny - 1);
  const std::size_t bucket = std::size_t(j) * ix.nx + i;
  for (std::uint32_t k = ix.start[bucket]; k < ix.start[bucket + 1]; ++k) {
    std::array<double, 3> q[3];
    corners(ix.tris[k], q);
    if (c < std::min({q[0][0], q[1][0], q[2][0]}) || c > std::max({q[0][0], q[1][0], q[2][0]}) ||
        r < std::min({q[0][1], q[1][1], q[2][1]}) || r > std::max({q[0][1], q[1][1], q[2][1]}))
      continue;
    const auto &a = q[0], &b = q[1], &e = q[2];
    const double det = (b[0] - a[0]) * (e[1] - a[1]) - (b[1] - a[1]) * (e[0] - a[0]);
    if (det == 0) continue;
    const double l1 = ((c - a[0]) * (e[1] - a[1]) - (r - a[1]) * (e[0] - a[0])) / det;
    const double l2 = ((b[0] - a[0]) * (r - a[1]) - (b[1] - a[1]) * (c - a[0])) / det;
    if (l1 >= -1e-12 && l2 >= -1e-12 && 1 - l1 - l2 >= -1e-12)
      return (1 - l1 - l2) * a[2] + l1 * b[2] + l2 * e[2];
  }
  return std::numeric_limits<double>::quiet_NaN();
}

}  // namespace terralod::blocks
