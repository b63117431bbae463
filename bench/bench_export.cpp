// Benchmark (not a test) of terralod export --format quantized-mesh against what the common
// generators write (cesium-terrain-builder: a regular 65 x 65 heightmap per tile of the same
// tiling): per level, tiles, vertices, triangles, gzipped bytes and the measured L-infinity error
// at the DEM's samples (ellipsoidal heights, EGM96), for both; and the export's wall time
// (median of --runs) and tiles per second.
//
// Usage: terralod-bench-export [--dem FILE] [--runs N] [--threads T] [--max-level Z]
//   --dem        elevation file with a CRS (default TERRALOD_DATA_DIR/N44W072.hgt; exits 0 if absent)
//   --runs       exports timed (default 3; the median is reported)
//   --threads    export threads (default: every core)
//   --max-level  deepest level (default: the exporter's automatic choice)
// Memory: the terrain (about 20 bytes per sample) plus one tile per thread.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "terralod/blocks/database_extract.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/geo_grid.hpp"
#include "terralod/blocks/quantized_mesh.hpp"
#include "terralod/blocks/terrain_export.hpp"
#include "terralod/blocks/tree_builder.hpp"

namespace {

namespace tb = terralod::blocks;
namespace fs = std::filesystem;

/// Bilinear height of the grid at (lon, lat), clamped to the grid's edges (as if the DEM went on:
/// the baseline then has no cliff at the border and its error is its resampling error alone).
double bilinear(const tb::GeoGrid& g, double lon, double lat) {
  const double c = std::clamp((lon - g.west) / g.dlon, 0.0, g.width - 1.0);
  const double r = std::clamp((g.north - lat) / g.dlat, 0.0, g.height - 1.0);
  const int c0 = std::min(int(c), g.width - 2), r0 = std::min(int(r), g.height - 2);
  const double fx = c - c0, fy = r - r0;
  const double top = g.z(c0, r0) + fx * (g.z(c0 + 1, r0) - g.z(c0, r0));
  const double bot = g.z(c0, r0 + 1) + fx * (g.z(c0 + 1, r0 + 1) - g.z(c0, r0 + 1));
  return top + fy * (bot - top);
}

struct Baseline {
  std::size_t tiles = 0, vertices = 0, triangles = 0, bytes = 0;
  double max_error = 0;
};

/// A 65 x 65 heightmap tile (heightmap-1.0: u16 (h + 1000) * 5, child and water masks, gzip) of
/// `rect`, and its error at the grid's samples in the tile, the cells split along one diagonal.
void heightmap_tile(const tb::GeoGrid& g, const tb::GeoRect& rect, Baseline& b) {
  constexpr int n = 65;
  std::vector<double> h(n * n);
  std::vector<std::uint8_t> bytes;
  for (int j = 0; j < n; ++j)  // north row first
    for (int i = 0; i < n; ++i) {
      const double lon = rect.west + (rect.east - rect.west) * i / (n - 1);
      const double lat = rect.north - (rect.north - rect.south) * j / (n - 1);
      const double v = std::round((bilinear(g, lon, lat) + 1000.0) * 5.0);
      const auto q = std::uint16_t(std::clamp(v, 0.0, 65535.0));
      h[std::size_t(j * n + i)] = q / 5.0 - 1000.0;  // what a client decodes
      bytes.push_back(std::uint8_t(q & 0xff)), bytes.push_back(std::uint8_t(q >> 8));
    }
  bytes.push_back(15), bytes.push_back(0);
  b.bytes += tb::gzip(bytes).size();
  ++b.tiles;
  b.vertices += n * n;
  b.triangles += 2 * (n - 1) * (n - 1);
  const int c0 = std::max(0, int(std::ceil((rect.west - g.west) / g.dlon)));
  const int c1 = std::min(g.width - 1, int(std::floor((rect.east - g.west) / g.dlon)));
  const int r0 = std::max(0, int(std::ceil((g.north - rect.north) / g.dlat)));
  const int r1 = std::min(g.height - 1, int(std::floor((g.north - rect.south) / g.dlat)));
  for (int r = r0; r <= r1; ++r)
    for (int c = c0; c <= c1; ++c) {
      if (!g.valid(c, r)) continue;
      const double x = (g.lon(c) - rect.west) / (rect.east - rect.west) * (n - 1);
      const double y = (rect.north - g.lat(r)) / (rect.north - rect.south) * (n - 1);
      const int i = std::min(int(x), n - 2), j = std::min(int(y), n - 2);
      const double fx = x - i, fy = y - j;
      const double a = h[std::size_t(j * n + i)], bb = h[std::size_t(j * n + i + 1)],
                   cc = h[std::size_t((j + 1) * n + i)], d = h[std::size_t((j + 1) * n + i + 1)];
      const double v = fx >= fy ? a + fx * (bb - a) + fy * (d - bb) : a + fy * (cc - a) + fx * (d - cc);
      b.max_error = std::max(b.max_error, std::abs(v - g.z(c, r)));
    }
}

}  // namespace

int main(int argc, char** argv) {
  std::string dem = std::string(TERRALOD_DATA_DIR) + "/N44W072.hgt";
  int runs = 3, threads = 0, max_level = -1;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "%s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--help" || a == "-h") {
      std::puts(
          "usage: terralod-bench-export [--dem FILE] [--runs N] [--threads T] [--max-level Z]\n"
          "Exports FILE (built into a block database first) as quantized-mesh tiles, --runs times, and\n"
          "compares each level with a regular 65 x 65 heightmap tiling (cesium-terrain-builder's):\n"
          "tiles, vertices, triangles, gzipped bytes and the L-infinity error at the DEM's samples.");
      return 0;
    } else if (a == "--dem") {
      dem = value();
    } else if (a == "--runs") {
      runs = std::max(1, std::atoi(value().c_str()));
    } else if (a == "--threads") {
      threads = std::atoi(value().c_str());
    } else if (a == "--max-level") {
      max_level = std::atoi(value().c_str());
    } else {
      std::fprintf(stderr, "unknown option %s (see --help)\n", a.c_str());
      return 2;
    }
  }
  if (!fs::exists(dem)) {
    std::printf("%s is absent: nothing to measure\n", dem.c_str());
    return 0;
  }
  const fs::path dir = fs::temp_directory_path() / ("terralod-bench-export-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string db = (dir / "terrain.db").string();
  std::printf("build %s ...\n", dem.c_str());
  std::fflush(stdout);
  tb::build_database(tb::read_dem(dem), db, {});

  std::vector<double> seconds;
  tb::ExportReport report;
  for (int run = 0; run < runs; ++run) {
    const fs::path out = dir / "tiles";
    fs::remove_all(out);
    tb::ExportOptions o;
    o.threads = threads;
    o.max_level = max_level;
    const auto t0 = std::chrono::steady_clock::now();
    report = tb::export_terrain(db, out.string(), o);
    seconds.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    std::printf("export run %d/%d: %.2f s\n", run + 1, runs, seconds.back());
    std::fflush(stdout);
  }
  std::sort(seconds.begin(), seconds.end());
  const double median = seconds[seconds.size() / 2];
  std::size_t tiles = 0, vertices = 0, bytes = 0;
  for (const tb::ExportLevel& L : report.levels) tiles += L.tiles, vertices += L.vertices, bytes += L.bytes;

  const tb::BlockDatabase handle = tb::BlockDatabase::open(db, tb::BlockDatabase::Mode::ReadOnly);
  const tb::GeoGrid g = tb::make_geo_grid(tb::read_database_terrain(handle), "", db);
  std::printf(
      "\n%s: %d x %d samples, heights from %s; export median %.2f s over %d runs, %.0f tiles/s, "
      "%.2f bytes/vertex\n",
      dem.c_str(), g.width, g.height, report.vertical_datum.c_str(), median, runs, double(tiles) / median,
      double(bytes) / double(vertices));
  std::printf(
      "| level | bound m | tiles | terralod vertices | triangles | bytes | max error m | heightmap 65² "
      "triangles | bytes | max error m | triangles ratio |\n|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const tb::ExportLevel& L : report.levels) {
    Baseline b;
    const double w = 180.0 / std::ldexp(1.0, L.z);
    // The same tiles as the export (those over the terrain plus its ring; level 0: both).
    const double pad_lon = g.dlon, pad_lat = g.dlat;
    const int x0 = L.z == 0 ? 0 : int(std::floor((g.lon(0) - pad_lon + 180.0) / w));
    const int x1 = L.z == 0 ? 1 : int(std::ceil((g.lon(g.width - 1) + pad_lon + 180.0) / w)) - 1;
    const int y0 = L.z == 0 ? 0 : int(std::floor((g.lat(g.height - 1) - pad_lat + 90.0) / w));
    const int y1 = L.z == 0 ? 0 : int(std::ceil((g.lat(0) + pad_lat + 90.0) / w)) - 1;
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) heightmap_tile(g, tb::tile_rect({L.z, x, y}), b);
    std::printf("| %d | %.4g | %zu | %zu | %zu | %zu | %.4g | %zu | %zu | %.4g | %.3f |\n", L.z, L.bound,
                L.tiles, L.vertices, L.triangles, L.bytes, L.max_error, b.triangles, b.bytes, b.max_error,
                double(L.triangles) / double(b.triangles));
  }
  fs::remove_all(dir);
  return 0;
}
