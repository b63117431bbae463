// Extruded-shape benchmark (not a test): 10,000 buildings over N44W072 in a block database,
// extruded every frame on the drawn terrain (blocks::ShapeExtruder) along a scripted flight at
// 1280 x 720: thread CPU time of extrude() per frame (median, p99) with the buildings placed in
// view, and once for every building at the end (the worst frame: all of them in view).
//
// Usage: terralod-bench-shapes [--buildings N] [--frames F]
//   Builds (or reuses) a database of N44W072 (blocks of 129 samples) in the temporary folder
//   and adds a layer of N (default 10000) buildings, unless it has one of that size: rectangles
//   10-40 m a side turned at random, every tenth with a square courtyard, heights 5-60 m, at
//   uniformly random places in a 12 km square around the flight (fixed seed 1), written as
//   GeoJSON in longitude/latitude.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "object_bench.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/object_layers.hpp"
#include "terralod/blocks/object_placement.hpp"
#include "terralod/blocks/object_shapes.hpp"
#include "terralod/blocks/terrain_runtime.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/timing.hpp"

namespace tb = terralod::blocks;
namespace pm = terralod::pm;
namespace fs = std::filesystem;

namespace {

// Where the flight starts, in samples: 10 % of the tile from its south-west corner.
std::pair<double, double> start_of(int width, int height) { return {0.1 * (width - 1), 0.9 * (height - 1)}; }

// The database of N44W072 with a layer "buildings<N>" of n buildings in the 12 km square
// north-east of the flight's start.
std::string prepare(long n) {
  const pm::Heightfield hf = tb::read_dem(terralod::bench::n44w072_path());
  const std::string path = terralod::bench::n44w072_database(hf);
  const std::string layer = "buildings" + std::to_string(n);
  auto db = tb::BlockDatabase::open(path, tb::BlockDatabase::Mode::ReadWrite);
  for (const tb::ObjectLayerInfo& l : tb::object_layers(db))
    if (l.name == layer) return path;
  const std::string json = (fs::temp_directory_path() / "terralod-bench-shapes.geojson").string();
  {
    std::mt19937_64 rng(1);
    // Metres per sample east and north (the world frame's spacing).
    const double east = hf.transform.spacing_x(), north = hf.transform.spacing_y();
    const auto [c0, r0] = start_of(hf.width(), hf.height());
    std::uniform_real_distribution<double> uc(c0, c0 + 12000 / east), ur(r0 - 12000 / north, r0), us(10, 40),
        ua(0, std::numbers::pi), uh(5, 60);
    const auto ring = [&](double c, double r, double a, double w, double d, bool reverse) {
      std::string s = "[";
      for (int k = 0; k <= 4; ++k) {
        const int j = reverse ? (4 - k) % 4 : k % 4;
        const double u = (j == 1 || j == 2 ? 0.5 : -0.5) * w, v = (j >= 2 ? 0.5 : -0.5) * d;  // metres
        const auto [lon, lat] = hf.crs_transform->to_world(c + (u * std::cos(a) - v * std::sin(a)) / east,
                                                           r - (u * std::sin(a) + v * std::cos(a)) / north);
        char p[64];
        std::snprintf(p, sizeof p, "%s[%.9f, %.9f]", k ? ", " : "", lon, lat);
        s += p;
      }
      return s + "]";
    };
    std::ofstream f(json);
    f << "{\"type\": \"FeatureCollection\", \"features\": [\n";
    for (long k = 0; k < n; ++k) {
      const double c = uc(rng), r = ur(rng), a = ua(rng), w = us(rng), d = us(rng), h = uh(rng);
      std::string rings = ring(c, r, a, w, d, false);
      if (k % 10 == 0) rings += ", " + ring(c, r, a, 0.4 * w, 0.4 * d, true);
      f << (k ? "," : "") << "{\"type\": \"Feature\", \"properties\": {\"height\": " << std::round(h)
        << "}, \"geometry\": {\"type\": \"Polygon\", \"coordinates\": [" << rings << "]}}\n";
    }
    f << "]}\n";
  }
  tb::ObjectLayerOptions lo;
  lo.name = layer;
  lo.input = json;
  lo.height_field = "height";
  const tb::ObjectLayerReport r = tb::add_object_layer(db, lo);
  std::printf("layer %s: %lld points, read %.2f s, stored %.2f s\n", layer.c_str(), (long long)r.points,
              r.read_ms / 1e3, r.write_ms / 1e3);
  fs::remove(json);
  return path;
}

}  // namespace

int main(int argc, char** argv) {
  long n = 10000, frames = 600;
  if (const auto status = terralod::bench::parse_options(
          argc, argv, {{"--buildings", &n}, {"--frames", &frames}},
          "usage: terralod-bench-shapes [--buildings N] [--frames F]\n"
          "Extrudes N random buildings (default 10000) in a 12 km square of N44W072 on the drawn\n"
          "terrain every frame of an F-frame flight (default 600) at 1280x720 and prints the\n"
          "extrusion's thread CPU time per frame, then for all N buildings at once."))
    return *status;
  if (n < 1 || frames < 1) {
    std::fprintf(stderr, "terralod-bench-shapes: need --buildings >= 1 and --frames >= 1\n");
    return 2;
  }
  if (terralod::bench::skipped_without_n44w072()) return 0;
  try {
    const std::string path = prepare(n);
    const auto db = tb::BlockDatabase::open(path);
    tb::ObjectPlacer placer(db, {"buildings" + std::to_string(n)});
    tb::ShapeExtruder shapes(placer);
    std::printf("planned %zu footprints in %.1f ms (%zu degenerate, %zu not simple, %zu default heights)\n",
                shapes.plan_stats().polygons, shapes.plan_stats().plan_ms, shapes.plan_stats().degenerate,
                shapes.plan_stats().not_simple, shapes.plan_stats().default_heights);
    tb::RuntimeOptions opt;
    opt.morph_seconds = 0.5;
    tb::TerrainRuntime rt(path, opt);
    // From the start north-east over the town at 100 m/s, 300 m above the highest sample,
    // 20 degrees down, turning slowly.
    const auto [start_col, start_row] = start_of(rt.grid().grid_width(), rt.grid().grid_height());
    const auto [x, y] = rt.grid().transform().to_world(start_col, start_row);
    terralod::bench::ArcFlight flight{x, y, std::numbers::pi / 4, 100, 6000, 300, rt.terrain_box().hi.z};
    tb::ObjectMesh mesh;
    std::vector<double> extrude_ms, count, tris, drawn;
    for (long f = 0; f < frames; ++f) {
      pm::Camera c = flight.next();
      rt.fit_camera(c);
      const pm::View view(c);
      rt.update_until_loaded(view, double(f) / 60.0);
      const std::vector<tb::PlacedObject>& placed = placer.place(rt, view);
      const double t0 = pm::thread_cpu_ms();
      shapes.extrude(rt, placed, mesh);
      extrude_ms.push_back(pm::thread_cpu_ms() - t0);
      count.push_back(double(shapes.stats().shapes));
      tris.push_back(double(mesh.triangles.size()));
      drawn.push_back(double(shapes.stats().drawn_triangles) / std::max(1.0, double(shapes.stats().shapes)));
    }
    std::printf(
        "%ld frames at 1280x720: extrusion thread CPU median %.3f ms, p99 %.3f ms for a median of %.0f "
        "buildings in view (%.0f mesh triangles, %.1f drawn triangles examined per building)\n",
        frames, pm::median(extrude_ms), pm::quantile(extrude_ms, 0.99), pm::median(count), pm::median(tris),
        pm::median(drawn));
    // Every building at once, on the last frame's terrain (anchors' z unused by extrude).
    std::vector<tb::PlacedObject> all;
    for (const tb::MapObject& m : placer.objects()) all.push_back({&m, {m.anchor.x, m.anchor.y, 0.0}});
    shapes.extrude(rt, all, mesh);  // grows the buffers
    const double t0 = pm::thread_cpu_ms();
    shapes.extrude(rt, all, mesh);
    std::printf(
        "all %zu buildings at once: %.3f ms (%zu extruded, %zu over nothing drawn, %zu mesh triangles)\n",
        all.size(), pm::thread_cpu_ms() - t0, shapes.stats().shapes, shapes.stats().skipped_undrawn,
        mesh.triangles.size());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "terralod-bench-shapes: %s\n", e.what());
    return 1;
  }
  return 0;
}
