// Tests for terralod export --format quantized-mesh (blocks/terrain_export.hpp): every tile is
// read back by the independent reader of tests/support and checked against the DEM's samples,
// with the geoid taken from PROJ directly (not through the exporter's code).
#include <gdal_priv.h>
#include <gdalwarper.h>
#include <gtest/gtest.h>
#include <ogr_spatialref.h>
#include <proj.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <numbers>
#include <regex>
#include <set>
#include <sstream>

#include "geographic_tiff.hpp"
#include "quantized_mesh_reader.hpp"
#include "run_command.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/database_extract.hpp"
#include "terralod/blocks/database_terrain.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/geo_grid.hpp"
#include "terralod/blocks/terrain_export.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/geodesy.hpp"

namespace {

namespace tb = terralod::blocks;
namespace pm = terralod::pm;
namespace tt = terralod::test;
namespace fs = std::filesystem;
constexpr int kQ = 32767;

/// A w x h crop of N44W072.hgt from sample (c0, r0), georeferenced as read_dem does it.
pm::Heightfield crop(int c0, int r0, int w, int h) {
  const pm::Heightfield all = tb::read_dem(std::string(TERRALOD_DATA_DIR) + "/N44W072.hgt");
  pm::Heightfield hf(w, h);
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) hf.at(c, r) = all.at(c0 + c, r0 + r);
  const pm::GridTransform& t = all.transform;
  hf.transform = pm::GridTransform{t.x0 + c0 * t.xc, t.xc, 0, t.y0 + r0 * t.yr, 0, t.yr};
  const pm::GridTransform& g = *all.crs_transform;
  hf.crs_transform = pm::GridTransform{g.x0 + c0 * g.xc, g.xc, 0, g.y0 + r0 * g.yr, 0, g.yr};
  hf.crs_wkt = all.crs_wkt;
  hf.vertical_datum = all.vertical_datum;
  hf.source = "N44W072 crop";
  return hf;
}

/// EGM96 undulations straight from PROJ: ellipsoidal height of orthometric height 0.
std::vector<double> egm96(const std::vector<std::array<double, 2>>& lonlat) {
  PJ_CONTEXT* ctx = proj_context_create();
  PJ* raw = proj_create_crs_to_crs(ctx, "EPSG:4326+5773", "EPSG:4979", nullptr);
  PJ* op = proj_normalize_for_visualization(ctx, raw);
  std::vector<double> n;
  for (const auto& p : lonlat) n.push_back(proj_trans(op, PJ_FWD, proj_coord(p[0], p[1], 0, 0)).xyz.z);
  proj_destroy(op), proj_destroy(raw), proj_context_destroy(ctx);
  return n;
}

struct Tileset {
  std::vector<std::vector<tb::TileRange>> available;
  std::vector<double> bound, max_error;
  std::map<std::array<int, 3>, tt::DecodedTile> tiles;
};

std::vector<double> numbers_after(const std::string& text, const std::string& key) {
  const auto at = text.find("\"" + key + "\": [");
  EXPECT_NE(at, std::string::npos) << key;
  std::vector<double> out;
  if (at == std::string::npos) return out;
  std::istringstream s(text.substr(at + key.size() + 5, text.find(']', at) - at - key.size() - 5));
  std::string item;
  while (std::getline(s, item, ',')) out.push_back(std::stod(item));
  return out;
}

Tileset read_tileset(const fs::path& dir) {
  Tileset t;
  const std::string layer = tt::slurp(dir / "layer.json");
  EXPECT_NE(layer.find("\"format\": \"quantized-mesh-1.0\""), std::string::npos);
  EXPECT_NE(layer.find("\"scheme\": \"tms\""), std::string::npos);
  EXPECT_NE(layer.find("\"projection\": \"EPSG:4326\""), std::string::npos);
  const std::string avail = layer.substr(layer.find("\"available\""));
  std::istringstream lines(avail.substr(avail.find('\n') + 1));
  const std::regex range(R"(\{"startX": (\d+), "startY": (\d+), "endX": (\d+), "endY": (\d+)\})");
  for (std::string line; std::getline(lines, line) && line.find('[') != std::string::npos;) {
    t.available.emplace_back();
    for (std::sregex_iterator it(line.begin(), line.end(), range), end; it != end; ++it)
      t.available.back().push_back(
          {std::stoi((*it)[1]), std::stoi((*it)[2]), std::stoi((*it)[3]), std::stoi((*it)[4])});
  }
  t.bound = numbers_after(layer, "bound");
  t.max_error = numbers_after(layer, "max_error");
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (e.path().extension() != ".terrain") continue;
    const fs::path rel = fs::relative(e.path(), dir);
    auto it = rel.begin();
    const int z = std::stoi(it->string()), x = std::stoi((++it)->string()),
              y = std::stoi((++it)->stem().string());
    const std::string bytes = tt::slurp(e.path());
    t.tiles[{z, x, y}] = tt::decode_quantized_mesh_tile(
        std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()));
  }
  return t;
}

bool available(const Tileset& t, int z, int x, int y) {
  if (z >= int(t.available.size())) return false;
  for (const tb::TileRange& r : t.available[std::size_t(z)])
    if (x >= r.start_x && x <= r.end_x && y >= r.start_y && y <= r.end_y) return true;
  return false;
}

double decoded_height(const tt::DecodedTile& d, std::size_t i) {
  return double(d.min_height) + double(d.h[i]) / kQ * (double(d.max_height) - double(d.min_height));
}

/// The tile's height at (u, v) (real, in the tile's quantized frame) as a client interpolates it;
/// NaN when no triangle holds the point.
double interpolate(const tt::DecodedTile& d, double u, double v) {
  for (const auto& tri : d.triangles) {
    const double ax = d.u[tri[0]], ay = d.v[tri[0]], bx = d.u[tri[1]], by = d.v[tri[1]], cx = d.u[tri[2]],
                 cy = d.v[tri[2]];
    const double det = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay);
    const double l1 = ((u - ax) * (cy - ay) - (cx - ax) * (v - ay)) / det;
    const double l2 = ((bx - ax) * (v - ay) - (u - ax) * (by - ay)) / det;
    const double l0 = 1 - l1 - l2;
    if (l0 >= -1e-9 && l1 >= -1e-9 && l2 >= -1e-9)
      return l0 * decoded_height(d, tri[0]) + l1 * decoded_height(d, tri[1]) + l2 * decoded_height(d, tri[2]);
  }
  return std::nan("");
}

/// The antimeridian: on every level, the east edge of tile x = 2^(z+1) - 1 is the west edge of
/// tile x = 0 (the same vertices, decoded heights and normals). Returns the pairs checked.
std::size_t antimeridian_pairs(const Tileset& t) {
  std::size_t pairs = 0;
  for (const auto& [id, a] : t.tiles) {
    if (id[1] != (2 << id[0]) - 1) continue;
    const auto it = t.tiles.find({id[0], 0, id[2]});
    EXPECT_NE(it, t.tiles.end()) << "no tile " << id[0] << "/0/" << id[2];
    if (it == t.tiles.end()) continue;
    const auto &ea = a.edges[2], &eb = it->second.edges[0];
    EXPECT_EQ(ea.size(), eb.size()) << id[0] << "/" << id[1] << "/" << id[2];
    for (std::size_t k = 0; k < std::min(ea.size(), eb.size()); ++k) {
      EXPECT_EQ(a.v[ea[k]], it->second.v[eb[k]]);
      EXPECT_EQ(decoded_height(a, ea[k]), decoded_height(it->second, eb[k]))
          << id[0] << "/" << id[1] << "/" << id[2] << " v " << a.v[ea[k]];
      EXPECT_EQ(a.normals[ea[k]], it->second.normals[eb[k]]) << id[0] << "/" << id[1] << "/" << id[2];
    }
    ++pairs;
  }
  return pairs;
}

class QuantizedMeshExport : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const fs::path dir = tt::process_temp_dir("terralod-export");
    db_ = (dir / "crop.db").string();
    hf_ = new pm::Heightfield(crop(600, 600, 161, 161));
    tb::DatabaseBuildOptions o;
    o.block_size = 65;
    tb::build_database(*hf_, db_, o);
    out_ = dir / "qm";
    report_ = new tb::ExportReport(tb::export_terrain(db_, out_.string()));
  }
  static void TearDownTestSuite() {
    delete hf_;
    delete report_;
  }
  static inline std::string db_;
  static inline fs::path out_;
  static inline pm::Heightfield* hf_ = nullptr;
  static inline tb::ExportReport* report_ = nullptr;
};

TEST_F(QuantizedMeshExport, LayerJsonListsExactlyTheTilesWrittenAndTheirParents) {
  const Tileset t = read_tileset(out_);
  ASSERT_EQ(t.available.size(), report_->levels.size());
  ASSERT_EQ(report_->levels.size(), 13u);  // 1/1200 degree: level 12's tiles span 52.7 samples
  ASSERT_EQ(t.bound.size(), t.available.size());
  ASSERT_EQ(t.max_error.size(), t.available.size());
  EXPECT_TRUE(available(t, 0, 0, 0) && available(t, 0, 1, 0));
  std::size_t listed = 0;
  for (std::size_t z = 0; z < t.available.size(); ++z)
    for (const tb::TileRange& r : t.available[z])
      for (int y = r.start_y; y <= r.end_y; ++y)
        for (int x = r.start_x; x <= r.end_x; ++x) {
          ++listed;
          EXPECT_TRUE(t.tiles.count({int(z), x, y}))
              << z << "/" << x << "/" << y << " is listed, not written";
          if (z > 0) {
            EXPECT_TRUE(available(t, int(z) - 1, x / 2, y / 2)) << z << "/" << x << "/" << y;
          }
        }
  EXPECT_EQ(listed, t.tiles.size());
  for (const auto& [id, d] : t.tiles) EXPECT_TRUE(available(t, id[0], id[1], id[2]));
  // Deeper levels have several tiles: the crop crosses tile edges there.
  EXPECT_GE(t.available.back().front().end_x - t.available.back().front().start_x, 2);
  // Bounds shrink from level to level, and each level meets its own.
  for (std::size_t z = 0; z < t.bound.size(); ++z) {
    EXPECT_LE(t.max_error[z], t.bound[z]) << "level " << z;
    if (z > 0) {
      EXPECT_LT(t.bound[z], t.bound[z - 1]);
    }
  }
  EXPECT_DOUBLE_EQ(t.bound.back(), 1.0);
}

TEST_F(QuantizedMeshExport, EveryTileCoversItsRectangleOnceWithExactEdgeLists) {
  const Tileset t = read_tileset(out_);
  for (const auto& [id, d] : t.tiles) {
    SCOPED_TRACE(std::to_string(id[0]) + "/" + std::to_string(id[1]) + "/" + std::to_string(id[2]));
    double area = 0;
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> half;
    for (const auto& tri : d.triangles) {
      const std::int64_t a = std::int64_t(d.u[tri[1]] - d.u[tri[0]]) * (d.v[tri[2]] - d.v[tri[0]]) -
                             std::int64_t(d.u[tri[2]] - d.u[tri[0]]) * (d.v[tri[1]] - d.v[tri[0]]);
      ASSERT_GT(a, 0) << "a triangle is not counter-clockwise in (u, v)";
      area += 0.5 * double(a);
      for (int k = 0; k < 3; ++k) ++half[{tri[std::size_t(k)], tri[std::size_t((k + 1) % 3)]}];
    }
    EXPECT_DOUBLE_EQ(area, double(kQ) * kQ);
    for (const auto& [e, n] : half) {
      EXPECT_EQ(n, 1);
      if (half.count({e.second, e.first})) continue;  // interior: its twin runs the other way
      const bool border = (d.u[e.first] == d.u[e.second] && (d.u[e.first] == 0 || d.u[e.first] == kQ)) ||
                          (d.v[e.first] == d.v[e.second] && (d.v[e.first] == 0 || d.v[e.first] == kQ));
      EXPECT_TRUE(border) << "an edge without a twin inside the tile";
    }
    for (int side = 0; side < 4; ++side) {
      std::vector<std::uint32_t> want;
      for (std::uint32_t i = 0; i < d.u.size(); ++i) {
        const int c = side % 2 == 0 ? d.u[i] : d.v[i];
        if (c == (side < 2 ? 0 : kQ)) want.push_back(i);
      }
      const std::vector<int>& along = side % 2 == 0 ? d.v : d.u;
      std::sort(want.begin(), want.end(),
                [&](std::uint32_t a, std::uint32_t b) { return along[a] < along[b]; });
      EXPECT_EQ(d.edges[std::size_t(side)], want) << "edge list " << side;
    }
    EXPECT_EQ(d.normals.size(), d.u.size());
    EXPECT_NE(d.metadata.find("\"max_error\""), std::string::npos);
  }
}

TEST_F(QuantizedMeshExport, EveryTileIsWithinItsBoundAtEverySampleWithTheGeoid) {
  const Tileset t = read_tileset(out_);
  const pm::GridTransform& g = *hf_->crs_transform;
  std::vector<std::array<double, 2>> lonlat;
  for (int r = 0; r < hf_->height(); ++r)
    for (int c = 0; c < hf_->width(); ++c) lonlat.push_back({g.x0 + c * g.xc, g.y0 + r * g.yr});
  const std::vector<double> n = egm96(lonlat);
  EXPECT_NEAR(n[0], -27.6, 1.5);  // EGM96 near (-71.5, 44.5): the geoid is about 28 m below WGS 84
  std::size_t checked = 0;
  for (const auto& [id, d] : t.tiles) {
    const tb::GeoRect rect = tb::tile_rect({id[0], id[1], id[2]});
    const double bound = t.bound[std::size_t(id[0])];
    double worst = 0;
    for (std::size_t i = 0; i < lonlat.size(); ++i) {
      const auto [lon, lat] = lonlat[i];
      if (lon < rect.west || lon > rect.east || lat < rect.south || lat > rect.north) continue;
      const double u = (lon - rect.west) / (rect.east - rect.west) * kQ,
                   v = (lat - rect.south) / (rect.north - rect.south) * kQ;
      const double h = interpolate(d, u, v);
      ASSERT_TRUE(std::isfinite(h)) << "no triangle over a sample";
      worst = std::max(worst, std::abs(h - (hf_->samples()[i] + n[i])));
      ++checked;
    }
    EXPECT_LE(worst, bound + 1e-6) << id[0] << "/" << id[1] << "/" << id[2];
  }
  EXPECT_GE(checked, std::size_t(hf_->size()) * 13);  // every sample, on every level
}

TEST_F(QuantizedMeshExport, NeighboursShareIdenticalEdgeVertices) {
  const Tileset t = read_tileset(out_);
  std::size_t pairs = 0;
  for (const auto& [id, a] : t.tiles)
    for (int dir = 0; dir < 2; ++dir) {  // east neighbour, north neighbour
      const std::array<int, 3> other = {id[0], id[1] + (dir == 0), id[2] + (dir == 1)};
      const auto it = t.tiles.find(other);
      if (it == t.tiles.end()) continue;
      const tt::DecodedTile& b = it->second;
      const auto& ea = a.edges[dir == 0 ? 2 : 3];  // a's east (north) edge
      const auto& eb = b.edges[dir == 0 ? 0 : 1];  // b's west (south) edge
      ASSERT_EQ(ea.size(), eb.size()) << "edge between " << id[0] << "/" << id[1] << "/" << id[2]
                                      << " and its " << (dir == 0 ? "east" : "north") << " neighbour";
      for (std::size_t k = 0; k < ea.size(); ++k) {
        EXPECT_EQ(dir == 0 ? a.v[ea[k]] : a.u[ea[k]], dir == 0 ? b.v[eb[k]] : b.u[eb[k]]);
        EXPECT_NEAR(decoded_height(a, ea[k]), decoded_height(b, eb[k]), 1e-9);
        EXPECT_EQ(a.normals[ea[k]], b.normals[eb[k]]);
      }
      ++pairs;
    }
  EXPECT_GE(pairs, 10u);
}

TEST_F(QuantizedMeshExport, HeaderBoundsWhatTheClientDraws) {
  const Tileset t = read_tileset(out_);
  for (const auto& [id, d] : t.tiles) {
    const tb::GeoRect r = tb::tile_rect({id[0], id[1], id[2]});
    for (std::size_t i = 0; i < d.u.size(); ++i) {
      const pm::Ecef p =
          pm::ecef_from_geodetic({r.west + (r.east - r.west) * d.u[i] / kQ,
                                  r.south + (r.north - r.south) * d.v[i] / kQ, decoded_height(d, i)});
      EXPECT_LE(std::hypot(p[0] - d.sphere[0], p[1] - d.sphere[1], p[2] - d.sphere[2]),
                d.sphere[3] * (1 + 1e-9));
      EXPECT_GE(decoded_height(d, i), d.min_height - 1e-9);
      EXPECT_LE(decoded_height(d, i), d.max_height + 1e-9);
    }
  }
}

TEST_F(QuantizedMeshExport, TheDatabaseRecordsWhereItLiesAndInfoReportsIt) {
  const tb::BlockDatabase db = tb::BlockDatabase::open(db_, tb::BlockDatabase::Mode::ReadOnly);
  const std::optional<tb::Georeference> g = db.georeference();
  ASSERT_TRUE(g.has_value());
  EXPECT_EQ(g->vertical_datum, "EGM96");  // an SRTM .hgt states it
  EXPECT_EQ(g->crs_transform, *hf_->crs_transform);
  const std::string json = tb::summarize_database(db).to_json();
  EXPECT_NE(json.find("\"vertical_datum\": \"EGM96\""), std::string::npos) << json;
  EXPECT_NE(json.find("\"crs_transform\": [-71.5, "), std::string::npos) << json;
}

// The export reads a database on a longitude/latitude grid a row of blocks at a time (blocks of
// 65 here: 3 x 3 of them), which gives the grid the whole terrain read at once gives, bit for bit.
TEST_F(QuantizedMeshExport, AGridReadByRowsOfBlocksIsTheWholeTerrainsGrid) {
  const tb::BlockDatabase handle = tb::BlockDatabase::open(db_, tb::BlockDatabase::Mode::ReadOnly);
  tb::DatabaseTerrain terrain(handle, {.cache_bytes = 0});
  const tb::GeoGrid windows = tb::make_geo_grid(terrain, "", db_);
  const tb::GeoGrid whole = tb::make_geo_grid(tb::read_database_terrain(handle), "", db_);
  EXPECT_EQ(windows.width, hf_->width());
  EXPECT_EQ(windows.height, hf_->height());
  EXPECT_EQ(windows.west, whole.west);
  EXPECT_EQ(windows.north, whole.north);
  EXPECT_TRUE(windows.heights == whole.heights);
  EXPECT_TRUE(windows.mask == whole.mask);
  EXPECT_NE(windows.horizontal.find("own samples"), std::string::npos) << windows.horizontal;
}

/// The vertices of a glb tile written by the 3D Tiles export, decoded as a client does: SHORT
/// normalized positions (stride 8) times the node's scale plus its translation, glTF axes back
/// to ECEF ((x, y, z)_ECEF = (x, -z, y)_glTF).
std::vector<pm::Ecef> glb_vertices(const fs::path& file) {
  const std::string b = tt::slurp(file);
  EXPECT_GE(b.size(), 28u) << file;
  std::uint32_t json_len = 0;
  std::memcpy(&json_len, b.data() + 12, 4);
  const std::string json = b.substr(20, json_len);
  const std::size_t bin = 20 + json_len + 8;
  auto numbers = [&](const std::string& key) {
    std::vector<double> v;
    const auto at = json.find("\"" + key + "\":[");
    EXPECT_NE(at, std::string::npos) << key;
    std::istringstream s(json.substr(at + key.size() + 4, json.find(']', at) - at - key.size() - 4));
    for (std::string item; std::getline(s, item, ',');) v.push_back(std::stod(item));
    return v;
  };
  const std::vector<double> t = numbers("translation"), sc = numbers("scale");
  const auto count_at = json.find("\"count\":");
  const std::size_t n = std::stoul(json.substr(count_at + 8));
  std::vector<pm::Ecef> out;
  for (std::size_t i = 0; i < n; ++i) {
    std::int16_t q[3];
    std::memcpy(q, b.data() + bin + 8 * i, 6);
    double g[3];
    for (int k = 0; k < 3; ++k)
      g[k] = t[std::size_t(k)] + std::max(q[k] / 32767.0, -1.0) * sc[std::size_t(k)];
    out.push_back({g[0], -g[2], g[1]});
  }
  return out;
}

// 3D Tiles: neighbouring glb tiles quantize on one lattice per level, so every vertex on a shared
// edge is at the same point in both (no crack a client could see through).
TEST_F(QuantizedMeshExport, ThreeDTilesNeighboursStoreSharedVerticesAtOnePoint) {
  const fs::path out = tt::process_temp_dir("terralod-export") / "3dtiles";
  const tb::ExportReport r = tb::export_terrain(db_, out.string(), {.format = tb::ExportFormat::Tiles3D});
  ASSERT_EQ(r.levels.size(), 13u);
  std::size_t pairs = 0, shared = 0;
  for (const auto& e : fs::directory_iterator(out / "12"))
    for (const auto& f : fs::directory_iterator(e.path())) {
      const int x = std::stoi(e.path().filename().string()), y = std::stoi(f.path().stem().string());
      const fs::path east = out / "12" / std::to_string(x + 1) / (std::to_string(y) + ".glb");
      if (!fs::exists(east)) continue;
      const double edge = tb::tile_rect({12, x, y}).east;
      const std::vector<pm::Ecef> a = glb_vertices(f.path()), b = glb_vertices(east);
      std::size_t on_edge = 0;
      for (const pm::Ecef& p : a) {
        if (std::abs(pm::geodetic_from_ecef(p).lon_deg - edge) > 1e-6) continue;
        ++on_edge;
        double nearest = 1e300;
        for (const pm::Ecef& o : b)
          nearest = std::min(nearest, std::hypot(p[0] - o[0], p[1] - o[1], p[2] - o[2]));
        EXPECT_LT(nearest, 1e-6) << f.path() << ": an edge vertex has no twin in " << east;
      }
      EXPECT_GE(on_edge, 2u) << f.path();
      shared += on_edge;
      ++pairs;
    }
  EXPECT_GE(pairs, 3u);
  EXPECT_GT(shared, pairs * 2);
}

TEST_F(QuantizedMeshExport, AnInterruptedExportResumesToTheSameFiles) {
  const fs::path out = tt::process_temp_dir("terralod-export") / "interrupted";
  struct Stop {};
  tb::ExportOptions o;
  o.threads = 1;
  o.progress = [](const tb::ExportProgress& p) {
    if (p.tiles_done == 12) throw Stop{};
  };
  EXPECT_THROW(tb::export_terrain(db_, out.string(), o), Stop);
  EXPECT_FALSE(fs::exists(out / "layer.json")) << "an unfinished export lists tiles as available";
  const tb::ExportReport r = tb::export_terrain(db_, out.string());
  EXPECT_EQ(r.tiles_reused, 12u);
  EXPECT_EQ(r.tiles_written + r.tiles_reused, report_->tiles_written);
  std::size_t files = 0;
  for (const auto& e : fs::recursive_directory_iterator(out_)) {
    if (!e.is_regular_file() || e.path().filename() == ".terralod-export") continue;
    const fs::path other = out / fs::relative(e.path(), out_);
    EXPECT_EQ(tt::slurp(e.path()), tt::slurp(other)) << other;
    ++files;
  }
  EXPECT_EQ(files, report_->tiles_written + 1);
  for (const auto& e : fs::recursive_directory_iterator(out))
    EXPECT_NE(e.path().extension(), ".tmp") << "a temporary was left: " << e.path();
}

TEST_F(QuantizedMeshExport, RefusesWhatItCannotDoNamingTheCulprit) {
  const fs::path dir = tt::process_temp_dir("terralod-export");
  // A terrain without a CRS.
  pm::Heightfield plain = crop(0, 0, 33, 33);
  plain.crs_wkt.clear();
  plain.crs_transform.reset();
  const std::string nocrs = (dir / "nocrs.db").string();
  tb::DatabaseBuildOptions o;
  o.block_size = 33;
  tb::build_database(plain, nocrs, o);
  try {
    tb::export_terrain(nocrs, (dir / "nocrs").string());
    ADD_FAILURE() << "exported a terrain without a CRS";
  } catch (const tb::ExportError& e) {
    EXPECT_NE(std::string(e.what()).find(nocrs), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("coordinate reference system"), std::string::npos) << e.what();
  }
  // An output folder that cannot be made (its parent is a file).
  const fs::path file = dir / "a-file";
  std::ofstream(file) << "x";
  try {
    tb::export_terrain(db_, (file / "out").string());
    ADD_FAILURE() << "wrote under a file";
  } catch (const tb::ExportError& e) {
    EXPECT_NE(std::string(e.what()).find((file / "out").string()), std::string::npos) << e.what();
  }
  // A folder with someone else's files.
  const fs::path theirs = dir / "theirs";
  fs::create_directories(theirs);
  std::ofstream(theirs / "notes.txt") << "mine";
  EXPECT_THROW(tb::export_terrain(db_, theirs.string()), tb::ExportError);
  EXPECT_EQ(tt::slurp(theirs / "notes.txt"), "mine");
  // An unknown vertical datum.
  EXPECT_THROW(tb::export_terrain(db_, (dir / "datum").string(), {.vertical_datum = "EPSG:999999"}),
               tb::ExportError);
}

/// hf (geographic WGS 84) warped to UTM zone 19N through GDAL and written as a GeoTIFF with that
/// CRS: a projected DEM, whose cells outside hf's footprint are 0, or nodata with nodata_outside.
void write_utm_geotiff(const pm::Heightfield& hf, const std::string& path, bool nodata_outside = false) {
  GDALAllRegister();
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  GDALDataset* src = mem->Create("", hf.width(), hf.height(), 1, GDT_Float64, nullptr);
  if (nodata_outside) src->GetRasterBand(1)->SetNoDataValue(-32768);  // the warp keeps it for outside
  const pm::GridTransform& t = *hf.crs_transform;
  double gt[6] = {t.x0 - 0.5 * t.xc, t.xc, 0, t.y0 - 0.5 * t.yr, 0, t.yr};
  src->SetGeoTransform(gt);
  OGRSpatialReference wgs84, utm;
  wgs84.SetWellKnownGeogCS("WGS84");
  utm.importFromEPSG(32619);
  char* wkt = nullptr;
  wgs84.exportToWkt(&wkt);
  src->SetProjection(wkt);
  CPLFree(wkt);
  std::vector<double> z(hf.samples());
  ASSERT_EQ(src->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, hf.width(), hf.height(), z.data(), hf.width(),
                                            hf.height(), GDT_Float64, 0, 0),
            CE_None);
  utm.exportToWkt(&wkt);
  GDALDatasetH warped = GDALAutoCreateWarpedVRT(src, nullptr, wkt, GRA_Bilinear, 0.0, nullptr);
  CPLFree(wkt);
  ASSERT_NE(warped, nullptr);
  GDALDatasetH out =
      GDALCreateCopy(GDALGetDriverByName("GTiff"), path.c_str(), warped, FALSE, nullptr, nullptr, nullptr);
  ASSERT_NE(out, nullptr);
  GDALClose(out);
  GDALClose(warped);
  GDALClose(src);
}

// A DEM in a projected CRS is warped back to longitude/latitude and lands where it belongs: the
// exported surface matches the geographic original to within the resampling of two warps, which
// a misplacement by one sample (90 m in these mountains) would exceed many times.
TEST_F(QuantizedMeshExport, AProjectedDemIsWarpedToWhereItBelongs) {
  const fs::path dir = tt::process_temp_dir("terralod-export");
  const std::string tif = (dir / "utm.tif").string(), db = (dir / "utm.db").string();
  ASSERT_NO_FATAL_FAILURE(write_utm_geotiff(*hf_, tif));
  const pm::Heightfield utm = tb::read_dem(tif, {.fill_voids = false});
  ASSERT_TRUE(utm.crs_transform.has_value());
  tb::DatabaseBuildOptions o;
  o.block_size = 65;
  tb::build_database(utm, db, o);
  {
    // The exporter reads the database window by window (blocks of 65: many rows of blocks),
    // which gives the grid the whole terrain in memory gives, bit for bit.
    const tb::BlockDatabase handle = tb::BlockDatabase::open(db, tb::BlockDatabase::Mode::ReadOnly);
    tb::DatabaseTerrain terrain(handle, {.cache_bytes = 0});
    const tb::GeoGrid windows = tb::make_geo_grid(terrain, "", db);
    const tb::GeoGrid whole = tb::make_geo_grid(tb::read_database_terrain(handle), "", db);
    EXPECT_EQ(windows.width, whole.width);
    EXPECT_EQ(windows.height, whole.height);
    EXPECT_EQ(windows.west, whole.west);
    EXPECT_EQ(windows.north, whole.north);
    EXPECT_TRUE(windows.heights == whole.heights);
    EXPECT_TRUE(windows.mask == whole.mask);
    EXPECT_EQ(windows.horizontal, whole.horizontal);
  }
  const fs::path out = dir / "utm-tiles";
  const tb::ExportReport r = tb::export_terrain(db, out.string(), {.max_level = 12});
  EXPECT_NE(r.horizontal.find("warped"), std::string::npos) << r.horizontal;
  const Tileset t = read_tileset(out);
  const pm::GridTransform& g = *hf_->crs_transform;
  std::vector<std::array<double, 2>> lonlat;
  std::vector<double> want;
  for (int r0 = 20; r0 < hf_->height() - 20; r0 += 12)
    for (int c0 = 20; c0 < hf_->width() - 20; c0 += 12) {
      lonlat.push_back({g.x0 + c0 * g.xc, g.y0 + r0 * g.yr});
      want.push_back(hf_->at(c0, r0));
    }
  const std::vector<double> n = egm96(lonlat);
  std::vector<double> diff;
  for (std::size_t i = 0; i < lonlat.size(); ++i) {
    const auto [lon, lat] = lonlat[i];
    for (const auto& [id, d] : t.tiles) {
      if (id[0] != 12) continue;
      const tb::GeoRect rect = tb::tile_rect({id[0], id[1], id[2]});
      if (lon < rect.west || lon > rect.east || lat < rect.south || lat > rect.north) continue;
      const double h = interpolate(d, (lon - rect.west) / (rect.east - rect.west) * kQ,
                                   (lat - rect.south) / (rect.north - rect.south) * kQ);
      diff.push_back(std::abs(h - (want[i] + n[i])));
      break;
    }
  }
  ASSERT_GE(diff.size(), 100u);
  std::sort(diff.begin(), diff.end());
  EXPECT_LT(diff[diff.size() / 2], 5.0) << "median";
  EXPECT_LT(diff[diff.size() * 9 / 10], 25.0) << "90th percentile";
}

/// Writes a GeoTIFF of w x h Float64 heights (row by row from the north) in CRS `epsg`, its
/// north-west corner at (x0, y0) and samples `step` apart.
void write_geotiff(const std::string& path, int epsg, double x0, double y0, double step, int w, int h,
                   const std::vector<double>& z) {
  OGRSpatialReference crs;
  crs.importFromEPSG(epsg);
  GDALAllRegister();
  GDALDataset* ds =
      GetGDALDriverManager()->GetDriverByName("GTiff")->Create(path.c_str(), w, h, 1, GDT_Float64, nullptr);
  ASSERT_NE(ds, nullptr) << path;
  double gt[6] = {x0, step, 0, y0, 0, -step};
  ds->SetGeoTransform(gt);
  ds->SetSpatialRef(&crs);
  std::vector<double> samples(z);
  EXPECT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, w, h, samples.data(), w, h, GDT_Float64, 0, 0),
            CE_None);
  GDALClose(ds);
}

/// The largest |drawn - DEM| of a projected DEM's samples (a GeoTIFF, heights above EGM96), drawn
/// by the deepest level of its quantized-mesh export in `out`, by ring: [0] the outermost
/// samples, [1] the next ring, [2] every 7th sample inside.
std::array<double, 3> largest_errors_by_ring(const std::string& tif, const fs::path& out) {
  std::array<double, 3> worst{0, 0, 0};
  GDALAllRegister();
  GDALDataset* ds = GDALDataset::Open(tif.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY);
  EXPECT_NE(ds, nullptr) << tif;
  if (ds == nullptr) return worst;
  const int w = ds->GetRasterXSize(), h = ds->GetRasterYSize();
  double gt[6];
  EXPECT_EQ(ds->GetGeoTransform(gt), CE_None);
  std::vector<double> z(std::size_t(w) * std::size_t(h));
  EXPECT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, w, h, z.data(), w, h, GDT_Float64, 0, 0), CE_None);
  OGRSpatialReference crs(*ds->GetSpatialRef()), wgs84;
  GDALClose(ds);
  crs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  wgs84.SetWellKnownGeogCS("WGS84");
  wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  const std::unique_ptr<OGRCoordinateTransformation> to_geog(OGRCreateCoordinateTransformation(&crs, &wgs84));
  EXPECT_TRUE(to_geog);
  if (!to_geog) return worst;
  std::vector<std::array<double, 2>> lonlat;
  std::vector<double> want;
  std::vector<int> ring;
  for (int row = 0; row < h; ++row)
    for (int c = 0; c < w; ++c) {
      const int from_edge = std::min({row, c, h - 1 - row, w - 1 - c});
      if (from_edge >= 2 && (row + c) % 7 != 0) continue;
      double x = gt[0] + (c + 0.5) * gt[1] + (row + 0.5) * gt[2],
             y = gt[3] + (c + 0.5) * gt[4] + (row + 0.5) * gt[5];
      EXPECT_TRUE(to_geog->Transform(1, &x, &y));
      lonlat.push_back({x, y});
      want.push_back(z[std::size_t(row) * std::size_t(w) + std::size_t(c)]);
      ring.push_back(std::min(from_edge, 2));
    }
  const std::vector<double> n = egm96(lonlat);
  const Tileset t = read_tileset(out);
  const int level = int(t.bound.size()) - 1, nx = 2 << level, ny = 1 << level;
  for (std::size_t i = 0; i < lonlat.size(); ++i) {
    const auto [lon, lat] = lonlat[i];
    const int x = std::clamp(int(std::floor((lon + 180.0) / 180.0 * (1 << level))), 0, nx - 1),
              y = std::clamp(int(std::floor((lat + 90.0) / 180.0 * (1 << level))), 0, ny - 1);
    const auto it = t.tiles.find({level, x, y});
    EXPECT_NE(it, t.tiles.end()) << "no tile " << level << "/" << x << "/" << y;
    if (it == t.tiles.end()) continue;
    const tb::GeoRect rect = tb::tile_rect({level, x, y});
    const double drawn = interpolate(it->second, (lon - rect.west) / (rect.east - rect.west) * kQ,
                                     (lat - rect.south) / (rect.north - rect.south) * kQ);
    EXPECT_TRUE(std::isfinite(drawn)) << lon << ", " << lat << ": no triangle";
    if (std::isfinite(drawn))
      worst[std::size_t(ring[i])] = std::max(worst[std::size_t(ring[i])], std::abs(drawn - (want[i] + n[i])));
  }
  return worst;
}

// A projected DEM (UTM, 90 m samples, every cell valid) at 44 and 70 degrees north is exported
// on a longitude/latitude grid nowhere coarser than its samples, and every sample of its two
// outermost rings is drawn as well as those inside: within the deepest level's bound plus the two
// bilinear resamplings of a smooth surface. Before, GDAL's grid of cells square in degrees had
// rows 106 m apart at 44 degrees and 187 m at 70 (its kernel, widened to match, smoothed the
// terrain), and the grid ended at the footprint's cell edge, so the outermost samples stood in
// the cliff down to the background: 330 and 403 m off.
class TerrainExportProjected : public ::testing::TestWithParam<int> {};

TEST_P(TerrainExportProjected, KeepsItsResolutionAndItsOutermostSamples) {
  const int latitude = GetParam();
  const fs::path dir = tt::process_temp_dir("terralod-export");
  const std::string name = "utm" + std::to_string(latitude);
  const std::string tif = (dir / (name + ".tif")).string(), db = (dir / (name + ".db")).string();
  constexpr int kW = 100, kH = 120;
  constexpr double kStep = 90.0;
  const double x0 = 440000.0, y0 = latitude == 70 ? 7775600.0 : 4880000.0;  // north-west corner
  // Smooth (wavelengths of 6 km and more), sloping, with no symmetry.
  auto height = [&](double x, double y) {
    return 600.0 + 250.0 * std::sin((x - x0) / 1200.0 + 0.3) * std::cos((y - y0) / 900.0 - 0.2) +
           0.05 * (x - x0);
  };
  std::vector<double> z;
  for (int r = 0; r < kH; ++r)
    for (int c = 0; c < kW; ++c) z.push_back(height(x0 + (c + 0.5) * kStep, y0 - (r + 0.5) * kStep));
  ASSERT_NO_FATAL_FAILURE(write_geotiff(tif, latitude == 70 ? 32633 : 32619, x0, y0, kStep, kW, kH, z));
  tb::DatabaseBuildOptions o;
  o.block_size = 65;
  tb::build_database(tb::read_dem(tif), db, o);

  // The grid: rows and columns (on the parallel nearest the equator) at most 90 m apart on the
  // ground (UTM's scale here is within 0.9996 .. 0.9997: a source step is 90.04 m at most).
  const tb::GeoGrid g = tb::make_geo_grid(tb::read_database_terrain(tb::BlockDatabase::open(db)), "", db);
  constexpr double a = 6378137.0, e2 = 6.69437999014e-3, k = std::numbers::pi / 180.0;
  const auto metres_a_degree = [&](double lat) {  // of a meridian and of a parallel
    const double s = std::sin(lat * k), w = 1.0 - e2 * s * s;
    return std::array<double, 2>{a * (1.0 - e2) / (w * std::sqrt(w)) * k,
                                 a / std::sqrt(w) * std::cos(lat * k) * k};
  };
  const double row_metres = g.dlat * metres_a_degree(g.lat(0))[0];  // the north row: the longest degree
  const double column_metres = g.dlon * metres_a_degree(g.lat(g.height - 1))[1];
  EXPECT_LE(row_metres, 90.05) << g.width << " x " << g.height;
  EXPECT_LE(column_metres, 90.05) << g.width << " x " << g.height;
  EXPECT_GT(row_metres, 80.0) << "not finer than needed either";

  const fs::path out = dir / (name + "-tiles");
  const tb::ExportReport r = tb::export_terrain(db, out.string(), {});
  for (const tb::ExportLevel& L : r.levels) EXPECT_LE(L.max_error, L.bound) << "level " << L.z;
  const std::array<double, 3> worst = largest_errors_by_ring(tif, out);
  const double bound = r.levels.back().bound;
  std::printf(
      "UTM at %d N: grid %d x %d (rows %.1f m, columns %.1f m apart); largest error, outermost "
      "ring %.2f m, the next %.2f m, inside %.2f m (bound %.2f m)\n",
      latitude, g.width, g.height, row_metres, column_metres, worst[0], worst[1], worst[2], bound);
  for (int ring = 0; ring < 3; ++ring) EXPECT_LE(worst[std::size_t(ring)], bound + 2.0) << "ring " << ring;
}

INSTANTIATE_TEST_SUITE_P(Latitudes, TerrainExportProjected, ::testing::Values(44, 70));

// SRTM samples (257 x 257 of N44W072) on a UTM grid at 80 degrees north, where a cell of the
// longitude/latitude grid is about six rows wide in the tiles' quanta: every sample is drawn
// within the resampling of rough terrain. Measuring the lattice points only, triangles from
// vertices at the background's height a few rows beyond the terrain (a tile's forced sag point
// there) to terrain vertices passed between two columns, over no measured point, and pulled the
// outermost samples down by up to 119 m.
TEST(TerrainExportProjectedSrtm, SamplesAt80DegreesNorthStandOnTheTerrainAtItsEdge) {
  const fs::path dir = tt::process_temp_dir("terralod-export");
  const std::string tif = (dir / "utm80.tif").string(), db = (dir / "utm80.db").string();
  constexpr int kN = 257;
  const std::string hgt = std::string(TERRALOD_DATA_DIR) + "/N44W072.hgt";
  if (!fs::exists(hgt)) GTEST_SKIP() << hgt << " is absent";
  {
    const pm::Heightfield all = tb::read_dem(hgt);
    std::vector<double> z;
    for (int r = 0; r < kN; ++r)
      for (int c = 0; c < kN; ++c) z.push_back(all.at(100 + c, 100 + r));
    ASSERT_NO_FATAL_FAILURE(write_geotiff(tif, 32633, 450000.0, 9000000.0, 90.0, kN, kN, z));
  }
  tb::DatabaseBuildOptions o;
  o.block_size = 129;
  tb::build_database(tb::read_dem(tif), db, o);
  const fs::path out = dir / "utm80-tiles";
  const tb::ExportReport r = tb::export_terrain(db, out.string(), {});
  for (const tb::ExportLevel& L : r.levels) EXPECT_LE(L.max_error, L.bound) << "level " << L.z;
  const std::array<double, 3> worst = largest_errors_by_ring(tif, out);
  std::printf("SRTM at 80 N: largest error, outermost ring %.2f m, the next %.2f m, inside %.2f m\n",
              worst[0], worst[1], worst[2]);
  // Two bilinear resamplings of 90 m SRTM samples: up to about 15 m at peaks (measured 6.8 m).
  for (int ring = 0; ring < 3; ++ring) EXPECT_LE(worst[std::size_t(ring)], 25.0) << "ring " << ring;
}

// High terrain inside a 0 m border (a DEM clipped with 0 where it had no data: N44W072 + 5,000 m,
// its north edge at 45 degrees, a tile edge of levels 0 to 6) keeps every level's bound. At the
// coarse levels the lattice has fewer than 16 quanta a sample, a cliff-top sample rounded onto a
// vertex already lies across a sliver from a 0 m vertex to a tile-edge vertex, and each such stuck
// point dropped its whole triangle, so its other samples were never inserted: level 4 measured
// 5,359 m against its bound of 4,817 (a 1,440^2 version: levels 4 and 5, 5,533 and 5,456 m against
// 4,817 and 2,408). A stuck point now leaves its triangle's next worst point to be inserted, and
// one that breaks the level's bound takes another corner of its quantum cell as on fine lattices.
// At the deepest level (1 m) the foot of the cliff, an edge vertex, was rounded along the edge
// towards the cliff and drawn 4.3 m high at its sample; it now has a twin on the other side.
TEST_F(QuantizedMeshExport, HighTerrainInsideAZeroBorderKeepsEveryLevelsBound) {
  const fs::path dir = tt::process_temp_dir("terralod-export");
  const pm::Heightfield inner = crop(600, 0, 161, 161);
  constexpr int kBorder = 20;
  pm::Heightfield hf(161 + 2 * kBorder, 161 + 2 * kBorder);  // 0 m everywhere
  for (int r = 0; r < 161; ++r)
    for (int c = 0; c < 161; ++c) hf.at(c + kBorder, r + kBorder) = inner.at(c, r) + 5000.0;
  const pm::GridTransform& t = inner.transform;
  hf.transform = pm::GridTransform{t.x0 - kBorder * t.xc, t.xc, 0, t.y0 - kBorder * t.yr, 0, t.yr};
  const pm::GridTransform& g = *inner.crs_transform;
  hf.crs_transform = pm::GridTransform{g.x0 - kBorder * g.xc, g.xc, 0, g.y0 - kBorder * g.yr, 0, g.yr};
  hf.crs_wkt = inner.crs_wkt;
  hf.vertical_datum = inner.vertical_datum;
  const std::string db = (dir / "zero-border.db").string();
  tb::DatabaseBuildOptions o;
  o.block_size = 65;
  tb::build_database(hf, db, o);
  const tb::ExportReport r = tb::export_terrain(db, (dir / "zero-border-tiles").string());
  ASSERT_GE(r.levels.size(), 8u);
  for (const tb::ExportLevel& L : r.levels) {
    std::printf("level %d: %.1f m, bound %.1f m\n", L.z, L.max_error, L.bound);
    EXPECT_LE(L.max_error, L.bound) << "level " << L.z;
  }
}

// A deepest level far coarser than the samples (--max-level 0: two tiles of 180 degrees held to
// 1 m) keeps its forced grid against the Earth's curvature to 256 x 256 a tile: uncapped, it
// forced 7.8 million points a tile (a 41 x 41 DEM had not been exported after 15 minutes).
// The samples still decide the measured error.
TEST_F(QuantizedMeshExport, ADeepestLevelFarCoarserThanTheSamplesKeepsItsForcedGridSmall) {
  const fs::path out = tt::process_temp_dir("terralod-export") / "level0";
  const tb::ExportReport r = tb::export_terrain(db_, out.string(), {.max_level = 0});
  ASSERT_EQ(r.levels.size(), 1u);
  EXPECT_EQ(r.levels[0].bound, 1.0);
  EXPECT_EQ(r.levels[0].tiles, 2u);
  EXPECT_LE(r.levels[0].vertices, 2 * (257u * 257u) + hf_->size())
      << "forced points of two tiles, and the samples";
  EXPECT_GT(r.levels[0].vertices, 2 * (200u * 200u)) << "the forced grid is there";
}

// A projected DEM of high terrain (the crop raised by 5,000 m, as a plateau such as Tibet's) keeps
// its deepest level's 1 m at every sample of the grid the exporter warps it to, measured here on
// the decoded tiles, whether the DEM's cells outside its footprint are nodata (the warp back to
// longitude/latitude leaves holes there, read as the ellipsoid) or 0 (a cliff of valid samples,
// as a warp without a nodata value writes). Either way the samples at the edge stand at the top
// of a 5,000 m cliff, and rounding their positions to the tile's lattice towards the cliff (a
// third of a quantum) tilted it by 3.5 m at a sample.
TEST_F(QuantizedMeshExport, SamplesAtTheTopOfACliffKeepTheBoundOnHighTerrain) {
  const fs::path dir = tt::process_temp_dir("terralod-export");
  pm::Heightfield high = *hf_;
  for (double& z : high.samples()) z += 5000.0;
  for (const bool nodata : {true, false}) {
    SCOPED_TRACE(nodata ? "nodata outside the footprint" : "0 outside the footprint");
    const std::string name = nodata ? "high-nodata" : "high-zero";
    const std::string tif = (dir / (name + ".tif")).string(), db = (dir / (name + ".db")).string();
    ASSERT_NO_FATAL_FAILURE(write_utm_geotiff(high, tif, nodata));
    tb::DatabaseBuildOptions o;
    o.block_size = 65;
    tb::build_database(tb::read_dem(tif, {.fill_voids = false}), db, o);
    const fs::path out = dir / (name + "-tiles");
    const tb::ExportReport r = tb::export_terrain(db, out.string(), {.max_level = 12});
    for (const tb::ExportLevel& L : r.levels) EXPECT_LE(L.max_error, L.bound) << "level " << L.z;
    const tb::GeoGrid g = tb::make_geo_grid(tb::read_database_terrain(tb::BlockDatabase::open(db)), "", db);
    const Tileset t = read_tileset(out);
    std::size_t checked = 0, cliff_tops = 0;
    for (const auto& [id, d] : t.tiles) {
      if (id[0] != 12) continue;
      const tb::GeoRect rect = tb::tile_rect({id[0], id[1], id[2]});
      double worst = 0;
      for (int row = 0; row < g.height; ++row)
        for (int c = 0; c < g.width; ++c) {
          const double lon = g.lon(c), lat = g.lat(row);
          if (!g.valid(c, row) || lon < rect.west || lon > rect.east || lat < rect.south || lat > rect.north)
            continue;
          const double h = interpolate(d, (lon - rect.west) / (rect.east - rect.west) * kQ,
                                       (lat - rect.south) / (rect.north - rect.south) * kQ);
          ASSERT_TRUE(std::isfinite(h)) << "no triangle over a sample";
          worst = std::max(worst, std::abs(h - g.z(c, row)));
          ++checked;
          // A sample above 4,000 m beside a hole or a sample below 1,000 m.
          const auto low = [&](int x) {
            return x >= 0 && x < g.width && (!g.valid(x, row) || g.z(x, row) < 1000);
          };
          cliff_tops += g.z(c, row) > 4000 && (low(c - 1) || low(c + 1));
        }
      EXPECT_LE(worst, 1.0) << id[0] << "/" << id[1] << "/" << id[2];
    }
    EXPECT_GE(checked, std::size_t(hf_->size()) / 2);
    EXPECT_GE(cliff_tops, 100u);
  }
}

// A DEM across the antimeridian (a geographic GeoTIFF from 179.8 to 180.2 degrees, as GDAL writes
// one of Fiji's islands): built (warped to its azimuthal frame) and exported, its tiles lie on both
// ends of the tiling (x = 0 and x = 2^(z+1) - 1), every sample is drawn within the last level's
// bound (plus the two bilinear resamplings of a smooth surface, millimetres), and the two tiles of
// the antimeridian share their edge vertices. Before, the warp back to longitude/latitude spanned
// the whole Earth with the terrain cut in two, and no tile was written.
TEST(TerrainExportAntimeridian, TilesOnBothSidesDrawTheTerrainSeamlessly) {
  const fs::path dir = tt::process_temp_dir("terralod-export");
  const std::string tif = (dir / "antimeridian.tif").string(), db = (dir / "antimeridian.db").string();
  constexpr int kW = 241, kH = 121;
  constexpr double kStep = 1.0 / 600.0, kWest = 179.8, kNorth = -16.9;
  auto height = [](double lon, double lat) {
    return 500.0 +
           200.0 * std::sin(2.0 * M_PI * (lon - 179.8) / 0.4) * std::cos(2.0 * M_PI * (lat + 17.0) / 0.2);
  };
  ASSERT_NO_FATAL_FAILURE(tt::write_geographic_tiff(tif, kWest, kNorth, kW, kH, kStep, height));
  tb::DatabaseBuildOptions o;
  o.block_size = 65;
  tb::build_database(tb::read_dem(tif), db, o);
  const fs::path out = dir / "antimeridian-tiles";
  const tb::ExportReport r = tb::export_terrain(db, out.string(), {.max_level = 11});
  EXPECT_GT(r.bounds.west, 179.0);
  EXPECT_LT(r.bounds.east, -179.0);
  const Tileset t = read_tileset(out);
  const int z = 11, nx = 2 << z;
  std::set<int> columns;
  for (const auto& [id, d] : t.tiles)
    if (id[0] == z) columns.insert(id[1]);
  ASSERT_FALSE(columns.empty());
  EXPECT_EQ(*columns.begin(), 0);
  EXPECT_EQ(*columns.rbegin(), nx - 1);
  for (const auto& [id, d] : t.tiles)  // layer.json lists the tiles on both sides
    EXPECT_TRUE(available(t, id[0], id[1], id[2])) << id[0] << "/" << id[1] << "/" << id[2];
  // Every 4th sample, through the tile of the last level that holds it.
  std::vector<std::array<double, 2>> lonlat;
  std::vector<double> want;
  for (int row = 0; row < kH; row += 4)
    for (int c = 0; c < kW; c += 4) {
      const double lon = kWest + c * kStep, lat = kNorth - row * kStep;
      lonlat.push_back({std::remainder(lon, 360.0), lat});
      want.push_back(height(lon, lat));
    }
  const std::vector<double> n = egm96(lonlat);
  std::size_t east_of_180 = 0;
  for (std::size_t i = 0; i < lonlat.size(); ++i) {
    const auto [lon, lat] = lonlat[i];
    const int x = std::clamp(int(std::floor((lon + 180.0) / 180.0 * (1 << z))), 0, nx - 1),
              y = std::clamp(int(std::floor((lat + 90.0) / 180.0 * (1 << z))), 0, (1 << z) - 1);
    const auto it = t.tiles.find({z, x, y});
    ASSERT_NE(it, t.tiles.end()) << "no tile " << z << "/" << x << "/" << y << " over longitude " << lon;
    const tb::GeoRect rect = tb::tile_rect({z, x, y});
    const double h = interpolate(it->second, (lon - rect.west) / (rect.east - rect.west) * kQ,
                                 (lat - rect.south) / (rect.north - rect.south) * kQ);
    ASSERT_TRUE(std::isfinite(h)) << "longitude " << lon << ": no triangle";
    EXPECT_NEAR(h, want[i] + n[i], t.bound[z] + 0.05) << "longitude " << lon << ", latitude " << lat;
    east_of_180 += lon < 0;
  }
  EXPECT_GE(east_of_180, lonlat.size() / 3);
  EXPECT_GE(antimeridian_pairs(t), std::size_t(z + 1));  // every level, normals included
}

// A global DEM on cell centres (360 / step columns, as GEBCO's, ETOPO's and SRTM15+'s: no column
// on the antimeridian itself): the two tiles of the antimeridian read the same surface there,
// the one between the last column and the first, so they share their edge vertices, heights and
// normals on every level (levels 0 and 1: the deepest level's 1 m on 3-degree samples forces
// 256 x 256 vertices a tile), and the poles half a row beyond its first and last rows are one
// height each. Before, each side padded its own edge column outward, and a 1-degree
// grid's edges differed by up to 1,867 m at level 3 (a crack along the whole antimeridian).
TEST(TerrainExportAntimeridian, AGlobalGridOnCellCentresIsSeamlessAt180Degrees) {
  const fs::path dir = tt::process_temp_dir("terralod-export");
  const std::string tif = (dir / "global.tif").string(), db = (dir / "global.db").string();
  constexpr double kStep = 3.0;
  ASSERT_NO_FATAL_FAILURE(tt::write_tiff(tif, 4326, -180.0 + 0.5 * kStep, 90.0 - 0.5 * kStep, 120, 60, kStep,
                                         GDT_Float32, [](double lon, double lat) {
                                           return 1000.0 + 800.0 * std::sin(lon * M_PI / 60.0) *
                                                               std::cos(lat * M_PI / 45.0);
                                         }));
  tb::DatabaseBuildOptions o;
  o.block_size = 65;
  tb::build_database(tb::read_dem(tif), db, o);
  const fs::path out = dir / "global-tiles";
  const tb::ExportReport r = tb::export_terrain(db, out.string(), {.max_level = 1});
  for (const tb::ExportLevel& L : r.levels) EXPECT_LE(L.max_error, L.bound) << "level " << L.z;
  const Tileset t = read_tileset(out);
  EXPECT_EQ(antimeridian_pairs(t), std::size_t(1 + 2));
  // Its first and last rows lie half a row from the poles: every tile edge on a pole has one
  // height there (its row's mean), on every level, as every longitude is that one point.
  for (const int pole : {-1, 1})
    for (int level = 0; level <= 1; ++level) {
      std::set<double> heights;
      for (const auto& [id, d] : t.tiles)
        if (id[0] == level && id[2] == (pole > 0 ? (1 << level) - 1 : 0))
          for (const std::uint32_t v : d.edges[pole > 0 ? 3 : 1]) heights.insert(decoded_height(d, v));
      EXPECT_EQ(heights.size(), 1u) << (pole > 0 ? "North" : "South") << " Pole, level " << level;
    }
}

// DEMs around a pole (polar stereographic: EPSG:3031 as REMA's tiles, EPSG:3413 as ArcticDEM's)
// export: every longitude from the pole to the DEM's edge, each level within its bound, every 4th
// sample drawn within the last level's bound (plus the two bilinear resamplings of a smooth
// surface, centimetres), the tiles that meet at the pole giving it one height, and those on
// either side of the antimeridian sharing their edge vertices and normals. Before, the export
// refused them (GDAL suggests no longitude/latitude grid around a pole).
class TerrainExportPole : public ::testing::TestWithParam<int> {};

TEST_P(TerrainExportPole, ExportsEveryLongitudeWithThePoleAsOnePoint) {
  const int pole = GetParam();  // +1 north, -1 south
  const fs::path dir = tt::process_temp_dir("terralod-export");
  const std::string name = pole > 0 ? "north" : "south";
  const std::string tif = (dir / (name + ".tif")).string(), db = (dir / (name + ".db")).string();
  constexpr int kN = 65;
  constexpr double kStep = 2000.0, kHalf = 0.5 * (kN - 1) * kStep;
  // Smooth (wavelengths of 100 km and more on 2 km samples), with no symmetry about the pole.
  auto height = [](double x, double y) {
    return 800.0 + 150.0 * std::sin(x / 40000.0 + 0.3) * std::cos(y / 30000.0 - 0.2) + 0.001 * x;
  };
  {
    std::vector<double> z;
    for (int r = 0; r < kN; ++r)
      for (int c = 0; c < kN; ++c) z.push_back(height(-kHalf + c * kStep, kHalf - r * kStep));
    ASSERT_NO_FATAL_FAILURE(write_geotiff(tif, pole > 0 ? 3413 : 3031, -kHalf - 0.5 * kStep,
                                          kHalf + 0.5 * kStep, kStep, kN, kN, z));
  }
  tb::DatabaseBuildOptions o;
  o.block_size = 65;
  tb::build_database(tb::read_dem(tif), db, o);
  const fs::path out = dir / (name + "-tiles");
  const tb::ExportReport r = tb::export_terrain(db, out.string(), {});
  EXPECT_EQ(r.bounds.west, -180.0);
  EXPECT_EQ(r.bounds.east, 180.0);
  EXPECT_EQ(pole > 0 ? r.bounds.north : r.bounds.south, 90.0 * pole);
  for (const tb::ExportLevel& L : r.levels) EXPECT_LE(L.max_error, L.bound) << "level " << L.z;
  // Forced sag points along the parallels as far apart on the ground as along the meridians:
  // the deepest level (tiles of 0.7 degrees) holds 47 k vertices; 546 k when every parallel had
  // as many as a meridian, metres apart this near the pole.
  EXPECT_LT(r.levels.back().vertices, 100000u);
  const Tileset t = read_tileset(out);
  const int z = int(r.levels.size()) - 1;

  // 3D Tiles over the same meshes: bounded, finite geometric errors.
  const tb::ExportReport r3 =
      tb::export_terrain(db, (dir / (name + "-3dtiles")).string(), {.format = tb::ExportFormat::Tiles3D});
  for (const tb::ExportLevel& L : r3.levels) {
    EXPECT_LE(L.max_error, L.bound) << "3D Tiles level " << L.z;
    EXPECT_TRUE(std::isfinite(L.geometric_error)) << "3D Tiles level " << L.z;
  }
  // Every sample of the two outermost rings and every 7th inside, through the tile of the last
  // level that holds it. (Before the warp continued the terrain a sample beyond its edge and the
  // tiles measured between columns dozens of rows apart, the outermost were up to 155 m off.)
  const std::array<double, 3> worst = largest_errors_by_ring(tif, out);
  for (int ring = 0; ring < 3; ++ring)
    EXPECT_LE(worst[std::size_t(ring)], t.bound[std::size_t(z)] + 0.05) << "ring " << ring;
  // The pole: on every level, the pole edge of every tile that reaches it has one height, and
  // the ellipsoid's normal there.
  const int pole_edge = pole > 0 ? 3 : 1;  // edges: west, south, east, north
  for (int level = 0; level <= z; ++level) {
    std::vector<double> at_pole;
    for (const auto& [id, d] : t.tiles) {
      if (id[0] != level || id[2] != (pole > 0 ? (1 << level) - 1 : 0)) continue;
      for (const std::uint32_t v : d.edges[std::size_t(pole_edge)]) {
        at_pole.push_back(decoded_height(d, v));
        const std::array<double, 3> nv = tt::oct_decode(d.normals[v][0], d.normals[v][1]);
        EXPECT_NEAR(nv[2], double(pole), 1e-2) << "level " << level;
      }
    }
    ASSERT_FALSE(at_pole.empty()) << "level " << level;
    for (const double h : at_pole) EXPECT_NEAR(h, at_pole.front(), 1e-9) << "level " << level;
  }
  EXPECT_GE(antimeridian_pairs(t), std::size_t(z + 1));
}

INSTANTIATE_TEST_SUITE_P(Poles, TerrainExportPole, ::testing::Values(-1, 1),
                         [](const ::testing::TestParamInfo<int>& i) {
                           return i.param > 0 ? "North" : "South";
                         });

}  // namespace
