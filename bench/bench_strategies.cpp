// Benchmark (not a test) of the approximation-tree node strategies on N44W072 (the paper's
// comparison, seeds/approximation-tree.txt section 3.2: TIN best error, grid least memory,
// non-regular grid between): bytes per node, error at an equal point budget s, and, along a
// scripted flight, nodes selected, triangles drawn and selection time at alpha = 1, 2, 4 px;
// plus the build time of the whole block database.
//
// Usage: terralod-bench-strategies [--dem FILE] [--leaf-error M] [--frames N] [--keep-db]
//   --dem         elevation file (default TERRALOD_DATA_DIR/N44W072.hgt; exits 0 if absent)
//   --leaf-error  pure grid/TIN/non-regular trees stop splitting at this error (default 2 m)
//   --frames      frames of the scripted flight (default 40)
// Memory: the terrain, four trees, the block PMs with their collapse DAGs (~60 bytes/sample).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <numeric>
#include <string>
#include <vector>

#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/collapse_dag.hpp"
#include "terralod/pm/linf_error.hpp"
#include "terralod/pm/pm_io.hpp"
#include "terralod/pm/selective_refinement.hpp"
#include "timing.hpp"

namespace {

namespace tb = terralod::blocks;
namespace pm = terralod::pm;
using namespace terralod::bench;

/// The upper of the two middle values for an even count (this table's convention since its
/// first run; timing.hpp's median() takes the lower one).
double upper_median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

/// Exact error of a PM reduced to `points` vertices (or its base mesh if that has more).
double pm_error_at(const pm::ProgressiveMesh& p, std::size_t points) {
  const std::size_t keep = std::max(points, p.base_vertex_count());
  const pm::TriangleMesh m = p.extract_after(p.full_vertex_count() - keep);
  const pm::LInfError err(p.heightfield(), p.metric());
  const int W = p.heightfield().width();
  auto g = [&](std::uint32_t v) { return pm::GridPoint{int(m.vertices[v] % W), int(m.vertices[v] / W)}; };
  double worst = 0.0;
  for (const auto& t : m.triangles) worst = std::max(worst, err.triangle(g(t[0]), g(t[1]), g(t[2])));
  return worst;
}

pm::Camera flight_camera(const pm::Heightfield& hf, int frame, int frames) {
  // South-west to north-east across the tile at 2500 m, looking ahead and 25 degrees down.
  const double t = frames > 1 ? double(frame) / double(frames - 1) : 0.0;
  const auto [x0, y0] = hf.transform.to_world(0.1 * (hf.width() - 1), 0.9 * (hf.height() - 1));
  const auto [x1, y1] = hf.transform.to_world(0.9 * (hf.width() - 1), 0.1 * (hf.height() - 1));
  return pm::Camera{.x = x0 + t * (x1 - x0),
                    .y = y0 + t * (y1 - y0),
                    .z = 2500.0,
                    .yaw_deg = 45.0,
                    .pitch_deg = -25.0,
                    .fovy_deg = 60.0,
                    .width_px = 1280,
                    .height_px = 720,
                    .near_m = 1.0,
                    .far_m = 200000.0,
                    .ground = {}};
}

struct Row {
  std::string name;
  std::size_t nodes = 0;
  double bytes_per_node = 0, build_ms = 0;
  int depth = 0;
  double budget_error_mean = 0, budget_error_max = 0;
  struct Sel {
    double selected = 0, triangles = 0, select_ms = 0, refine_ms = 0, bound_px = 0;
  };
  std::map<double, Sel> sel;
};

}  // namespace

int main(int argc, char** argv) {
  std::string dem = std::string(TERRALOD_DATA_DIR) + "/N44W072.hgt";
  double leaf_error = 2.0;
  int frames = 40;
  bool keep_db = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--dem" && i + 1 < argc)
      dem = argv[++i];
    else if (a == "--leaf-error" && i + 1 < argc)
      leaf_error = std::atof(argv[++i]);
    else if (a == "--frames" && i + 1 < argc)
      frames = std::max(1, std::atoi(argv[++i]));
    else if (a == "--keep-db")
      keep_db = true;
    else {
      std::printf(
          "usage: terralod-bench-strategies [--dem FILE] [--leaf-error M] [--frames N] [--keep-db]\n");
      return a == "--help" || a == "-h" ? 0 : 2;
    }
  }
  if (!std::filesystem::exists(dem)) {
    std::printf("skipped: %s is absent\n", dem.c_str());
    return 0;
  }
  const pm::Heightfield hf = tb::read_dem(dem);
  std::printf("terrain %s: %d x %d samples\n", dem.c_str(), hf.width(), hf.height());

  // 1. The whole database (default options: 257-sample blocks, grid levels above PM blocks).
  const std::string db_path =
      (std::filesystem::temp_directory_path() / "terralod-bench-strategies.db").string();
  for (const std::string& f : {db_path, db_path + "-wal", db_path + "-shm"}) std::filesystem::remove(f);
  tb::DatabaseBuildOptions dbo;
  dbo.threads = 2;
  auto t = Clock::now();
  const tb::DatabaseSummary summary = tb::build_database(hf, db_path, dbo);
  const double db_ms = ms_since(t);
  std::printf("database build: %zu blocks, %zu nodes, %.2f bytes/vertex, %.1f s (2 threads)\n",
              summary.blocks, summary.nodes, summary.bytes_per_vertex, db_ms / 1000.0);

  const tb::BlockDatabase db = tb::BlockDatabase::open(db_path);
  const tb::ApproximationTree pm_tree = tb::decode_tree(*db.read_blob("tree"), db_path + ": tree");
  std::map<std::pair<int, int>, std::size_t> block_index;
  std::vector<pm::ProgressiveMesh> pms;
  for (tb::BlockKey k : db.blocks()) {
    block_index[{k.col, k.row}] = pms.size();
    pms.push_back(pm::decode_pm(db.read_block(k), "block"));
  }

  // 2. Pure trees with the same point budget s = 25 ((4+1)^2 for the grid).
  const tb::BlockLayout layout = tb::partition(hf.width(), hf.height(), 257);
  std::vector<Row> rows;
  std::vector<tb::ApproximationTree> trees;
  const std::pair<const char*, tb::StrategyChoice> kinds[] = {
      {"grid", tb::StrategyChoice::Grid},
      {"nonregular", tb::StrategyChoice::NonRegularGrid},
      {"tin", tb::StrategyChoice::Tin}};
  for (const auto& [name, choice] : kinds) {
    tb::TreeBuildOptions o;
    o.levels = {choice};
    o.pm_leaves = false;
    o.leaf_error = leaf_error;
    o.threads = 2;
    t = Clock::now();
    trees.push_back(tb::build_tree(hf, layout, o));
    Row r;
    r.name = name;
    r.build_ms = ms_since(t);
    rows.push_back(r);
    std::printf("tree %-10s built in %.1f s\n", name, rows.back().build_ms / 1000.0);
    std::fflush(stdout);
  }
  trees.push_back(pm_tree);
  {
    Row r;
    r.name = "pm_block";
    r.build_ms = db_ms;
    rows.push_back(r);
  }
  for (std::size_t i = 0; i < trees.size(); ++i) {
    const tb::ApproximationTree& tr = trees[i];
    rows[i].nodes = tr.size();
    rows[i].depth = tr.depth();
    double bytes = 0;
    for (const tb::TreeNode& n : tr.nodes()) bytes += double(tb::encoded_node_bytes(n));
    rows[i].bytes_per_node = bytes / double(tr.size());
  }
  // PM-block nodes carry their surface in the block blob: count it in their bytes.
  rows[3].bytes_per_node = double(summary.block_bytes + summary.tree_bytes) / double(pm_tree.size());

  // 3. Error at an equal point budget s = 25 over every block domain.
  {
    const auto grid = tb::make_grid_strategy(4);
    const auto nonreg = tb::make_nonregular_strategy(25, pm::ErrorMetric::Continuous);
    const auto tin = tb::make_tin_strategy(25, pm::ErrorMetric::Continuous);
    const tb::NodeStrategy* strategies[] = {grid.get(), nonreg.get(), tin.get()};
    for (int s = 0; s < 3; ++s) {
      double sum = 0, worst = 0;
      for (tb::BlockKey k : layout.keys()) {
        const double e = tb::surface_error(hf, strategies[s]->approximate(hf, layout.rect(k)),
                                           pm::ErrorMetric::Continuous);
        sum += e;
        worst = std::max(worst, e);
      }
      rows[std::size_t(s)].budget_error_mean = sum / double(layout.count());
      rows[std::size_t(s)].budget_error_max = worst;
    }
    double sum = 0, worst = 0;
    for (const auto& p : pms) {
      const double e = pm_error_at(p, 25);
      sum += e;
      worst = std::max(worst, e);
    }
    rows[3].budget_error_mean = sum / double(pms.size());
    rows[3].budget_error_max = worst;
  }

  // 4. The scripted flight.
  std::vector<std::unique_ptr<pm::CollapseDag>> dags;
  for (const auto& p : pms) dags.push_back(std::make_unique<pm::CollapseDag>(p));
  for (double alpha : {1.0, 2.0, 4.0}) {
    for (std::size_t i = 0; i < trees.size(); ++i) {
      std::vector<double> sel, tris, sms, rms, bound;
      std::vector<std::unique_ptr<pm::SelectiveRefinement>> refiners(pms.size());
      for (int f = 0; f < frames; ++f) {
        const pm::View view(flight_camera(hf, f, frames));
        tb::SelectionOptions so;
        so.alpha_px = alpha;
        const tb::SelectionResult r = tb::select_nodes(trees[i], view, so);
        double triangles = double(r.triangles), b = r.bound_px;
        const auto tr = Clock::now();
        for (std::size_t k = 0; k < r.selected.size(); ++k) {
          const tb::TreeNode& n = trees[i].node(r.selected[k]);
          if (n.strategy != tb::Strategy::PmBlock) continue;
          const std::size_t bi = block_index.at({n.block->col, n.block->row});
          pm::RefinementOptions ro;
          ro.tolerance_px = r.visual[k].tolerance_px;
          if (!refiners[bi]) refiners[bi] = std::make_unique<pm::SelectiveRefinement>(*dags[bi], ro);
          const pm::FrameStats& fs = refiners[bi]->update(view, f / 30.0);
          triangles += double(fs.triangles);
          b = std::max(b, fs.bound_px);
        }
        rms.push_back(ms_since(tr));
        sel.push_back(double(r.selected.size()));
        tris.push_back(triangles);
        sms.push_back(r.ms);
        bound.push_back(b);
      }
      Row::Sel& s = rows[i].sel[alpha];
      s.selected = upper_median(sel);
      s.triangles = upper_median(tris);
      s.select_ms = upper_median(sms);
      s.refine_ms = upper_median(rms);
      s.bound_px = *std::max_element(bound.begin(), bound.end());
    }
  }

  std::printf(
      "\nStrategies on %s (s = 25 points per node, pure trees down to %.1f m; PM block = the\n"
      "database tree: grid levels above one PM leaf per 257-sample block, refined at alpha).\n"
      "Flight: %d frames, 1280 x 720, fovy 60, 2500 m, pitch -25; medians per frame.\n\n",
      dem.c_str(), leaf_error, frames);
  std::printf("%-10s %7s %5s %10s %9s | %14s %14s\n", "strategy", "nodes", "depth", "bytes/node", "build s",
              "err@s mean m", "err@s max m");
  for (const Row& r : rows)
    std::printf("%-10s %7zu %5d %10.1f %9.2f | %14.2f %14.2f\n", r.name.c_str(), r.nodes, r.depth,
                r.bytes_per_node, r.build_ms / 1000.0, r.budget_error_mean, r.budget_error_max);
  std::printf("\n%-10s %5s %9s %11s %10s %10s %9s\n", "strategy", "alpha", "selected", "triangles",
              "select ms", "refine ms", "bound px");
  for (const Row& r : rows)
    for (const auto& [alpha, s] : r.sel)
      std::printf("%-10s %5.0f %9.0f %11.0f %10.3f %10.3f %9.2f\n", r.name.c_str(), alpha, s.selected,
                  s.triangles, s.select_ms, s.refine_ms, s.bound_px);
  std::printf(
      "\n(bound px: the largest guaranteed screen error of a frame; pure trees exceed alpha where a\n"
      "leaf of error %.1f m is still too coarse, PM blocks refine to alpha.)\n",
      leaf_error);
  if (!keep_db)
    for (const std::string& f : {db_path, db_path + "-wal", db_path + "-shm"}) std::filesystem::remove(f);
  return 0;
}
