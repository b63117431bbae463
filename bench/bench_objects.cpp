// Map-object placement benchmark (not a test): 100,000 points over N44W072 in a block database,
// placed every frame on the drawn terrain (blocks::ObjectPlacer) along a scripted flight at
// 1280 x 720. Two layers of the same points, in the same run:
//   ruled   the issue's pipeline: design rules (icons up to 2 km, labels up to 8 km ranked by
//           the attribute "rank", nothing farther), placement, and decluttering of the labels
//           (LabelDeclutterer; rectangles of 0.6 x 14 px per character by 14 px): thread CPU time
//           per frame of place() + building the candidates + update(), against the target of
//           1 ms (issue 19);
//   all     no rules (every point an icon at every distance): place() alone, the baseline whose
//           cost grows with every object in view.
// Also: the drawn-height index the first height query of a frame builds (shared with
// everything else that asks for heights) and a pick through the image centre.
//
// Usage: terralod-bench-objects [--points N] [--frames F]
//   Builds (or reuses) a database of N44W072 (blocks of 129 samples) in the temporary folder
//   and adds the two layers of N (default 100000) uniformly random points, written as GeoJSON
//   in longitude/latitude (fixed seed 1), unless the database already has them.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "object_bench.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/label_declutter.hpp"
#include "terralod/blocks/object_layers.hpp"
#include "terralod/blocks/object_placement.hpp"
#include "terralod/blocks/terrain_runtime.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/timing.hpp"

namespace tb = terralod::blocks;
namespace pm = terralod::pm;
namespace fs = std::filesystem;

namespace {

double pct(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, std::size_t(q * double(v.size() - 1) + 0.5))];
}

const char* kRules = R"({"ranges": [{"max_distance_m": 2000, "draw": "icon"},
  {"max_distance_m": 8000, "draw": "label"}, {"draw": "none"}], "priority_field": "rank"})";

// The database of N44W072 with layers "points<N>" (no rules) and "ruled<N>" (kRules) of the same
// n random points.
std::string prepare(long n) {
  const pm::Heightfield hf = tb::read_dem(terralod::bench::n44w072_path());
  const std::string path = terralod::bench::n44w072_database(hf);
  const std::string layer = "points" + std::to_string(n), ruled = "ruled" + std::to_string(n);
  auto db = tb::BlockDatabase::open(path, tb::BlockDatabase::Mode::ReadWrite);
  std::vector<std::string> missing = {layer, ruled};
  for (const tb::ObjectLayerInfo& l : tb::object_layers(db)) std::erase(missing, l.name);
  if (missing.empty()) return path;
  const std::string json = (fs::temp_directory_path() / "terralod-bench-objects.geojson").string();
  {
    std::mt19937_64 rng(1);
    std::uniform_real_distribution<double> uc(0, hf.width() - 1), ur(0, hf.height() - 1);
    std::ofstream f(json);
    f << "{\"type\": \"FeatureCollection\", \"features\": [\n";
    char line[256];
    for (long k = 0; k < n; ++k) {
      const auto [lon, lat] = hf.crs_transform->to_world(uc(rng), ur(rng));
      std::snprintf(
          line, sizeof line,
          "%s{\"type\": \"Feature\", \"properties\": {\"name\": \"p%ld\", \"rank\": %ld}, \"geometry\": "
          "{\"type\": \"Point\", \"coordinates\": [%.9f, %.9f]}}\n",
          k ? "," : "", k, k % 100, lon, lat);
      f << line;
    }
    f << "]}\n";
  }
  for (const std::string& name : missing) {
    tb::ObjectLayerOptions lo;
    lo.name = name;
    lo.input = json;
    if (name == ruled) lo.rules_json = kRules;
    const tb::ObjectLayerReport r = tb::add_object_layer(db, lo);
    std::printf("layer %s: %lld points, read %.2f s, stored %.2f s\n", name.c_str(), (long long)r.points,
                r.read_ms / 1e3, r.write_ms / 1e3);
  }
  fs::remove(json);
  return path;
}

}  // namespace

int main(int argc, char** argv) {
  long n = 100000, frames = 600;
  if (const auto status = terralod::bench::parse_options(
          argc, argv, {{"--points", &n}, {"--frames", &frames}},
          "usage: terralod-bench-objects [--points N] [--frames F]\n"
          "Places N random points (default 100000) over N44W072 every frame of an F-frame flight\n"
          "(default 600) at 1280x720 and prints the placement's thread CPU time per frame."))
    return *status;
  if (n < 1 || frames < 1) {
    std::fprintf(stderr, "terralod-bench-objects: need --points >= 1 and --frames >= 1\n");
    return 2;
  }
  if (terralod::bench::skipped_without_n44w072()) return 0;
  try {
    const std::string path = prepare(n);
    const auto db = tb::BlockDatabase::open(path);
    tb::ObjectPlacer placer(db, {"points" + std::to_string(n)});
    tb::ObjectPlacer ruled(db, {"ruled" + std::to_string(n)});
    tb::LabelDeclutterer declutter({.screen_width = 1280, .screen_height = 720});
    std::vector<tb::LabelCandidate> candidates;
    tb::RuntimeOptions opt;
    opt.morph_seconds = 0.5;
    tb::TerrainRuntime rt(path, opt);
    const tb::BlockGrid& grid = rt.grid();
    // The flight: 400 m/s along an arc across the tile (radius 12 km), 700 m above its highest
    // sample, looking ahead and 20 degrees down; every frame waits for its loads.
    const auto [xa, ya] = grid.transform().to_world(0, grid.grid_height() - 1);
    const auto [xb, yb] = grid.transform().to_world(grid.grid_width() - 1, 0);
    terralod::bench::ArcFlight flight{std::min(xa, xb) + 0.1 * std::abs(xb - xa),
                                      std::min(ya, yb) + 0.1 * std::abs(yb - ya),
                                      0.2,
                                      400,
                                      12000,
                                      700,
                                      rt.terrain_box().hi.z};
    std::vector<double> place_ms, index_ms, pick_ms, in_view, tested, triangles;
    std::vector<double> pipeline_ms, ruled_place_ms, ruled_tested, ruled_placed, labels_shown;
    for (long f = 0; f < frames; ++f) {
      pm::Camera c = flight.next();
      rt.fit_camera(c);
      const pm::View view(c);
      rt.update_until_loaded(view, double(f) / 60.0);
      double t0 = pm::thread_cpu_ms();
      rt.drawn_height(c.x, c.y);  // the frame's first height query builds the bucket index
      index_ms.push_back(pm::thread_cpu_ms() - t0);
      // The issue's pipeline on the ruled layer: rules + placement + decluttering, first.
      t0 = pm::thread_cpu_ms();
      candidates.clear();
      const std::vector<tb::PlacedObject>& placed = ruled.place(rt, view);
      ruled_place_ms.push_back(pm::thread_cpu_ms() - t0);
      for (const tb::PlacedObject& p : placed) {
        double px = 0, py = 0;
        if (p.draw != tb::Representation::Label || !view.project(p.anchor, px, py)) continue;
        const float w = 0.6f * 14.0f * float(p.object->name.size());
        candidates.push_back({{0, p.object->feature.id},
                              float(px - w / 2),
                              float(py - 14.0),
                              float(px + w / 2),
                              float(py),
                              p.object->priority,
                              float(p.distance)});
      }
      labels_shown.push_back(double(declutter.update(candidates).size()));
      pipeline_ms.push_back(pm::thread_cpu_ms() - t0);
      ruled_tested.push_back(double(ruled.stats().objects_tested));
      ruled_placed.push_back(double(ruled.stats().objects_placed));
      // The baseline after it, so that the sub-grids of the height index that the ruled
      // pipeline's queries build (on first use) are counted in the pipeline's time.
      t0 = pm::thread_cpu_ms();
      placer.place(rt, view);
      place_ms.push_back(pm::thread_cpu_ms() - t0);
      t0 = pm::thread_cpu_ms();
      placer.pick_pixel(rt, 640, 360);
      pick_ms.push_back(pm::thread_cpu_ms() - t0);
      in_view.push_back(double(placer.stats().objects_placed));
      tested.push_back(double(placer.stats().objects_tested));
      triangles.push_back(double(rt.stats().triangles));
    }
    std::printf(
        "%ld frames at 1280x720, %zu objects: placement thread CPU median %.3f ms, p99 %.3f ms (objects in "
        "view "
        "median %.0f, tested %.0f; %.0f triangles drawn); drawn-height index build median %.3f ms; pick at "
        "the "
        "centre median %.3f ms\n",
        frames, placer.objects().size(), pct(place_ms, 0.5), pct(place_ms, 0.99), pct(in_view, 0.5),
        pct(tested, 0.5), pct(triangles, 0.5), pct(index_ms, 0.5), pct(pick_ms, 0.5));
    std::printf(
        "memory: %.0f bytes per object (ObjectPlacer::memory_bytes, %zu objects with their attributes)\n",
        double(ruled.memory_bytes()) / double(ruled.objects().size()), ruled.objects().size());
    const double med = pct(pipeline_ms, 0.5);
    std::printf(
        "with rules: placement + rules + decluttering thread CPU median %.3f ms, p99 %.3f ms (objects tested "
        "median %.0f, placed %.0f, labels shown %.0f; place() alone %.3f ms); ratio to placement without "
        "rules %.3f; target 1 ms: "
        "%s\n",
        med, pct(pipeline_ms, 0.99), pct(ruled_tested, 0.5), pct(ruled_placed, 0.5), pct(labels_shown, 0.5),
        pct(ruled_place_ms, 0.5), med / pct(place_ms, 0.5), med <= 1.0 ? "met" : "NOT met");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "terralod-bench-objects: %s\n", e.what());
    return 1;
  }
  return 0;
}
