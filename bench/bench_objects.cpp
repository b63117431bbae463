// Map-object placement benchmark (not a test): 100,000 points over N44W072 in a block database,
// placed every frame on the drawn terrain (blocks::ObjectPlacer) along a scripted flight at
// 1280 x 720: thread CPU time of place() per frame (median, p99), of the drawn-height index the
// first height query of a frame builds (TerrainRuntime::drawn_height, shared with everything
// else that asks for heights), and of a pick through the image centre.
//
// Usage: terralod-bench-objects [--points N] [--frames F]
//   Builds (or reuses) a database of N44W072 (blocks of 129 samples) in the temporary folder
//   and adds a layer of N (default 100000) uniformly random points, written as GeoJSON in
//   longitude/latitude (fixed seed 1), unless the database already has one of that size.
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/dem_reader.hpp"
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

// The database of N44W072 with a layer "points<N>" of n random points.
std::string prepare(long n) {
  const std::string dem = std::string(TERRALOD_DATA_DIR) + "/N44W072.hgt";
  const std::string path = (fs::temp_directory_path() / "terralod-bench-objects-129.db").string();
  const pm::Heightfield hf = tb::read_dem(dem);
  tb::DatabaseBuildOptions o;
  o.block_size = 129;
  o.threads = int(std::max(1u, std::thread::hardware_concurrency()));
  const tb::DatabaseSummary s = tb::build_database(hf, path, o);
  std::printf("%s %s: %d x %d samples in %zu blocks of %d, %.1f s\n", s.blocks_built == 0 ? "reuse" : "build",
              path.c_str(), s.grid_width, s.grid_height, s.blocks, s.block_size, s.seconds);
  const std::string layer = "points" + std::to_string(n);
  auto db = tb::BlockDatabase::open(path, tb::BlockDatabase::Mode::ReadWrite);
  for (const tb::ObjectLayerInfo& l : tb::object_layers(db))
    if (l.name == layer) return path;
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
          "%s{\"type\": \"Feature\", \"properties\": {\"name\": \"p%ld\"}, \"geometry\": {\"type\": "
          "\"Point\", \"coordinates\": [%.9f, %.9f]}}\n",
          k ? "," : "", k, lon, lat);
      f << line;
    }
    f << "]}\n";
  }
  tb::ObjectLayerOptions lo;
  lo.name = layer;
  lo.input = json;
  const tb::ObjectLayerReport r = tb::add_object_layer(db, lo);
  std::printf("layer %s: %lld points, read %.2f s, stored %.2f s\n", layer.c_str(), (long long)r.points,
              r.read_ms / 1e3, r.write_ms / 1e3);
  fs::remove(json);
  return path;
}

}  // namespace

int main(int argc, char** argv) {
  long n = 100000, frames = 600;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--points") && i + 1 < argc)
      n = std::atol(argv[++i]);
    else if (!std::strcmp(argv[i], "--frames") && i + 1 < argc)
      frames = std::atol(argv[++i]);
    else {
      std::puts(
          "usage: terralod-bench-objects [--points N] [--frames F]\n"
          "Places N random points (default 100000) over N44W072 every frame of an F-frame flight\n"
          "(default 600) at 1280x720 and prints the placement's thread CPU time per frame.");
      return std::strcmp(argv[i], "--help") && std::strcmp(argv[i], "-h") ? 2 : 0;
    }
  }
  if (n < 1 || frames < 1) {
    std::fprintf(stderr, "terralod-bench-objects: need --points >= 1 and --frames >= 1\n");
    return 2;
  }
  if (!fs::exists(std::string(TERRALOD_DATA_DIR) + "/N44W072.hgt")) {
    std::printf("skip: N44W072.hgt not in %s\n", TERRALOD_DATA_DIR);
    return 0;
  }
  try {
    const std::string path = prepare(n);
    const auto db = tb::BlockDatabase::open(path);
    tb::ObjectPlacer placer(db, {"points" + std::to_string(n)});
    tb::RuntimeOptions opt;
    opt.morph_seconds = 0.5;
    tb::TerrainRuntime rt(path, opt);
    const tb::BlockGrid& grid = rt.grid();
    const double zmax = rt.terrain_box().hi.z;
    // The flight: 400 m/s along an arc across the tile (radius 12 km), 700 m above its highest
    // sample, looking ahead and 20 degrees down; every frame waits for its loads.
    const auto [xa, ya] = grid.transform().to_world(0, grid.grid_height() - 1);
    const auto [xb, yb] = grid.transform().to_world(grid.grid_width() - 1, 0);
    double x = std::min(xa, xb) + 0.1 * std::abs(xb - xa), y = std::min(ya, yb) + 0.1 * std::abs(yb - ya);
    double heading = 0.2;
    std::vector<double> place_ms, index_ms, pick_ms, in_view, tested, triangles;
    for (long f = 0; f < frames; ++f) {
      heading += 400.0 / 12000.0 / 60.0;
      x += 400.0 / 60 * std::sin(heading), y += 400.0 / 60 * std::cos(heading);
      pm::Camera c;
      c.x = x, c.y = y, c.z = zmax + 700;
      c.yaw_deg = heading * 180 / std::numbers::pi, c.pitch_deg = -20, c.fovy_deg = 60;
      c.width_px = 1280, c.height_px = 720;
      rt.fit_clip_planes(c);
      const pm::View view(c);
      rt.update_until_loaded(view, double(f) / 60.0);
      double t0 = pm::thread_cpu_ms();
      rt.drawn_height(x, y);  // the frame's first height query builds the bucket index
      index_ms.push_back(pm::thread_cpu_ms() - t0);
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
  } catch (const std::exception& e) {
    std::fprintf(stderr, "terralod-bench-objects: %s\n", e.what());
    return 1;
  }
  return 0;
}
