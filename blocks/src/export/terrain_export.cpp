// terralod export: quantized-mesh and 3D Tiles tilesets (see terrain_export.hpp).
#include "terralod/blocks/terrain_export.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <numbers>
#include <sstream>

#include "glb_tile.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/database_extract.hpp"
#include "terralod/blocks/geo_grid.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/atomic_file.hpp"
#include "terralod/pm/json.hpp"
#include "terralod/pm/parallel.hpp"
#include "tile_mesher.hpp"

namespace terralod::blocks {
namespace {

namespace fs = std::filesystem;
constexpr int kQ = 32767;
constexpr const char* kJournal = ".terralod-export";
constexpr int kExportVersion = 1;  // bump when the tiles written for the same inputs change

std::string num(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

/// The terrain's rectangle as parts within [-180, 180] degrees of longitude: itself, or, for a
/// terrain across the antimeridian (whose GeoGrid runs past 180 or -180 to stay continuous), the
/// parts on either side of it.
std::vector<GeoRect> wrapped_parts(const GeoRect& b) {
  if (b.east - b.west >= 360.0) return {{-180.0, b.south, 180.0, b.north}};
  if (b.east > 180.0) return {{b.west, b.south, 180.0, b.north}, {-180.0, b.south, b.east - 360.0, b.north}};
  if (b.west < -180.0) return {{b.west + 360.0, b.south, 180.0, b.north}, {-180.0, b.south, b.east, b.north}};
  return {b};
}

/// Tiles of level z that overlap a part of the terrain (wrapped_parts) with a positive area, one
/// range a part (level 0: both tiles, as CesiumJS always asks for them).
std::vector<TileRange> tiles_over(int z, const std::vector<GeoRect>& parts) {
  if (z == 0) return {{0, 0, 1, 0}};
  const double w = 180.0 / std::ldexp(1.0, z);
  const int nx = 2 << z, ny = 1 << z;
  auto first = [&](double v, double origin, int n) {
    return std::clamp(int(std::floor((v - origin) / w)), 0, n - 1);
  };
  auto last = [&](double v, double origin, int n) {
    return std::clamp(int(std::ceil((v - origin) / w)) - 1, 0, n - 1);
  };
  std::vector<TileRange> ranges;
  for (const GeoRect& b : parts)
    if (b.east > b.west)
      ranges.push_back({first(b.west, -180.0, nx), first(b.south, -90.0, ny), last(b.east, -180.0, nx),
                        last(b.north, -90.0, ny)});
  return ranges;
}

bool overlaps(const TileId& id, const std::vector<GeoRect>& parts) {
  const GeoRect r = tile_rect(id);
  for (const GeoRect& b : parts)
    if (r.west < b.east && b.west < r.east && r.south < b.north && b.south < r.north) return true;
  return false;
}

/// Where a tile's rectangle lies in the GeoGrid's longitudes: the tile's own, or, for a terrain
/// across the antimeridian, the same place 360 degrees east or west (tile edges never cross
/// +-180, so one of the three holds all of the tile's terrain). Vertices placed there have the
/// same ECEF positions and the same positions within the tile.
GeoRect rect_in_grid(const GeoRect& r, const GeoGrid& g) {
  const double centre = g.lon(0.5 * (g.width - 1)), mid = 0.5 * (r.west + r.east);
  const double shift = 360.0 * std::round((centre - mid) / 360.0);
  return {r.west + shift, r.south, r.east + shift, r.north};
}

/// The tiles of each level. Quantized-mesh: those over the terrain (clients upsample the rest
/// from the parent). 3D Tiles: every child of a tile over the terrain, since REPLACE refinement
/// draws the children instead of the parent and a missing child would leave a hole.
std::vector<std::vector<TileId>> level_tiles(ExportFormat format, int max_level,
                                             const std::vector<GeoRect>& terrain) {
  std::vector<std::vector<TileId>> tiles(std::size_t(max_level) + 1);
  tiles[0] = {{0, 0, 0}, {0, 1, 0}};
  for (int z = 1; z <= max_level; ++z) {
    if (format == ExportFormat::QuantizedMesh) {
      for (const TileRange& r : tiles_over(z, terrain))
        for (int y = r.start_y; y <= r.end_y; ++y)
          for (int x = r.start_x; x <= r.end_x; ++x) tiles[std::size_t(z)].push_back({z, x, y});
    } else {
      for (const TileId& p : tiles[std::size_t(z) - 1])
        if (overlaps(p, terrain))
          for (int k = 0; k < 4; ++k)
            tiles[std::size_t(z)].push_back({z, 2 * p.x + (k & 1), 2 * p.y + (k >> 1)});
    }
  }
  return tiles;
}

/// Levels whose tiles' metadata extension lists the availability of their subtree
/// (layer.json's metadataAvailability, as Cesium World Terrain does): CesiumJS records the
/// metadata of every tile that has it, and needs metadataAvailability to have somewhere to.
constexpr int kMetadataLevels = 10;

/// `"available": [...], ` for a tile at a multiple of kMetadataLevels: for each of the next
/// kMetadataLevels levels (to max_level), the tiles of its subtree over the terrain; "" otherwise.
std::string subtree_availability(const TileId& id, int max_level, const std::vector<GeoRect>& terrain) {
  if (id.z % kMetadataLevels != 0 || id.z >= max_level) return "";
  std::string a = "\"available\":[";
  for (int k = 1; k <= kMetadataLevels && id.z + k <= max_level; ++k) {
    const int n = 1 << k;
    a += k > 1 ? ",[" : "[";
    bool first = true;
    for (const TileRange& all : tiles_over(id.z + k, terrain)) {
      const TileRange mine = {std::max(all.start_x, id.x * n), std::max(all.start_y, id.y * n),
                              std::min(all.end_x, id.x * n + n - 1), std::min(all.end_y, id.y * n + n - 1)};
      if (mine.start_x > mine.end_x || mine.start_y > mine.end_y) continue;
      if (!first) a += ",";
      a += "{\"startX\":" + std::to_string(mine.start_x);
      a += ",\"startY\":" + std::to_string(mine.start_y);
      a += ",\"endX\":" + std::to_string(mine.end_x);
      a += ",\"endY\":" + std::to_string(mine.end_y) + "}";
      first = false;
    }
    a += "]";
  }
  return a + "],";
}

/// The largest distance from the rectangle's centre (ECEF, height 0) to a point of the rectangle
/// at a height in [lo, hi], over its corners, edge midpoints and centre (the extremes of a patch
/// of the ellipsoid lie on its boundary).
double farthest_from_centre(const GeoRect& r, double lo, double hi) {
  const double cx = 0.5 * (r.west + r.east), cy = 0.5 * (r.south + r.north);
  const pm::Ecef c = pm::ecef_from_geodetic({cx, cy, 0.0});
  double far = 0;
  for (double lon : {r.west, cx, r.east})
    for (double lat : {r.south, cy, r.north})
      for (double h : {lo, hi}) {
        const pm::Ecef p = pm::ecef_from_geodetic({lon, lat, h});
        far = std::max(far, std::hypot(p[0] - c[0], p[1] - c[1], p[2] - c[2]));
      }
  return far;
}

/// A power of two >= x (x > 0).
double pow2_at_least(double x) { return std::ldexp(1.0, int(std::ceil(std::log2(x)))); }

/// Lowest and highest value a tile's vertices can take: lattice points within one step of the
/// tile (holes and the ring as background), and the background when the tile reaches past them.
std::pair<double, double> tile_height_range(const detail::GeoField& f, const GeoRect& r) {
  const GeoGrid& g = f.grid();
  constexpr int pad = detail::GeoField::kPad;
  const int c0 = std::max(-pad, int(std::floor((r.west - g.west) / g.dlon)) - 1);
  const int c1 = std::min(g.width - 1 + pad, int(std::ceil((r.east - g.west) / g.dlon)) + 1);
  const int r0 = std::max(-pad, int(std::floor((g.north - r.north) / g.dlat)) - 1);
  const int r1 = std::min(g.height - 1 + pad, int(std::ceil((g.north - r.south) / g.dlat)) + 1);
  double lo = f.background(), hi = f.background();  // corners and background points
  for (int row = r0; row <= r1; ++row)
    for (int c = c0; c <= c1; ++c) {
      const double v = f.lattice(c, row);
      if (v == v) lo = std::min(lo, v), hi = std::max(hi, v);
    }
  return {lo, hi};
}

/// The ellipsoid's unit normal (ECEF) at (lon, lat), the same for every copy of a point: at a
/// pole exactly up (every longitude is that point; an oct-encoded normal otherwise flips between
/// the two sides of the encoding's fold with the sign of a 1e-17 component).
pm::Ecef ellipsoid_normal(double lon, double lat) {
  if (std::abs(lat) == 90.0) return {0.0, 0.0, lat > 0.0 ? 1.0 : -1.0};
  return pm::geodetic_surface_normal(detail::one_meridian(lon), lat);
}

/// The unit normal (ECEF) of the field at (lon, lat), from central differences `step` degrees
/// apart: a function of the position only, so tiles that share a vertex give it one normal. At a
/// pole, where east has no direction, the ellipsoid's normal.
pm::Ecef field_normal(const detail::GeoField& f, double lon, double lat, double step) {
  if (std::abs(lat) == 90.0) return ellipsoid_normal(lon, lat);
  constexpr double kDeg = std::numbers::pi / 180.0;
  // The same normal on either side of the antimeridian: east and north are one meridian's (and
  // on a grid around the Earth, GeoField reads the same columns).
  const double meridian = detail::one_meridian(lon);
  const double metres = pm::kWgs84A * kDeg;
  const double dx = 2 * step * metres * std::max(std::cos(lat * kDeg), 1e-6), dy = 2 * step * metres;
  const double gx = (f.at(lon + step, lat) - f.at(lon - step, lat)) / dx;
  const double gy = (f.at(lon, lat + step) - f.at(lon, lat - step)) / dy;
  const double sl = std::sin(meridian * kDeg), cl = std::cos(meridian * kDeg), sp = std::sin(lat * kDeg),
               cp = std::cos(lat * kDeg);
  const pm::Ecef east{-sl, cl, 0}, north{-sp * cl, -sp * sl, cp}, up{cp * cl, cp * sl, sp};
  pm::Ecef n;
  for (int k = 0; k < 3; ++k)
    n[std::size_t(k)] = -gx * east[std::size_t(k)] - gy * north[std::size_t(k)] + up[std::size_t(k)];
  const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  for (double& v : n) v /= len;
  return n;
}

double decoded_height(const QuantizedMeshTile& t, std::size_t v) {
  return double(t.min_height) + double(t.h[v]) / kQ * (double(t.max_height) - double(t.min_height));
}

struct TileRecord {
  double max_error = 0;                   ///< at the samples, the tile as a quantized-mesh client decodes it
  double geometric_error = 0;             ///< 3D Tiles: max_error + the glTF quantization + the chord sag
  double min_height = 0, max_height = 0;  ///< of what is drawn (3D Tiles: sag included)
  std::size_t vertices = 0, triangles = 0, bytes = 0;
};

/// The journal: the parameters line, then "z x y max_error geometric_error min_height max_height
/// vertices triangles bytes" per tile.
class Journal {
 public:
  Journal(const std::string& dir, const std::string& parameters)
      : path_((fs::path(dir) / kJournal).string()) {
    std::ifstream in(path_);
    std::string line;
    if (in && std::getline(in, line) && line == parameters) {
      while (std::getline(in, line)) {
        std::istringstream s(line);
        TileId id;
        TileRecord r;
        if (s >> id.z >> id.x >> id.y >> r.max_error >> r.geometric_error >> r.min_height >> r.max_height >>
            r.vertices >> r.triangles >> r.bytes)
          done_[{id.z, id.x, id.y}] = r;
      }
      resumed_ = true;
    }
    in.close();
    if (!resumed_) pm::write_file_atomically(path_, parameters + "\n");
    out_.open(path_, std::ios::app);
    if (!out_) throw ExportError(path_ + ": cannot append to the export journal");
  }
  bool resumed() const { return resumed_; }
  const TileRecord* find(const TileId& id) const {
    auto it = done_.find({id.z, id.x, id.y});
    return it == done_.end() ? nullptr : &it->second;
  }
  void add(const TileId& id, const TileRecord& r) {
    std::lock_guard<std::mutex> lock(m_);
    out_ << id.z << ' ' << id.x << ' ' << id.y << ' ' << num(r.max_error) << ' ' << num(r.geometric_error)
         << ' ' << num(r.min_height) << ' ' << num(r.max_height) << ' ' << r.vertices << ' ' << r.triangles
         << ' ' << r.bytes << '\n';
    out_.flush();
    if (!out_) throw ExportError(path_ + ": cannot append to the export journal");
  }

 private:
  std::string path_;
  std::map<std::array<int, 3>, TileRecord> done_;
  bool resumed_ = false;
  std::ofstream out_;
  std::mutex m_;
};

/// Makes `dir` ready: created when missing; refused when it holds files but no journal; the
/// tiles of an export with other parameters removed.
void prepare_folder(const std::string& dir, const std::string& parameters) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir))
    throw ExportError(dir + ": cannot create the output folder: " + ec.message());
  const fs::path journal = fs::path(dir) / kJournal;
  const bool ours = fs::exists(journal);
  if (!ours && !fs::is_empty(dir))
    throw ExportError(dir +
                      ": the output folder is not empty and holds no terralod export; choose an empty or "
                      "new folder");
  // Nothing is listed until the export ends.
  fs::remove(fs::path(dir) / "layer.json", ec);
  fs::remove(fs::path(dir) / "tileset.json", ec);
  if (!ours) return;
  std::ifstream in(journal);
  std::string first;
  std::getline(in, first);
  if (first == parameters) return;
  for (const auto& e : fs::directory_iterator(dir)) {  // another export's tiles: start over
    const std::string name = e.path().filename().string();
    if (e.is_directory() && !name.empty() && std::all_of(name.begin(), name.end(), ::isdigit))
      fs::remove_all(e.path());
  }
  fs::remove(journal);
}

/// The tile's mesh within `bound` as a client decodes it, and the error measured on that.
QuantizedMeshTile make_tile(const detail::GeoField& field, const GeoRect& rect, const ExportLevel& L, int sag,
                            double normal_step, double& measured) {
  const double first = std::max(0.0, L.bound * 0.9 - 0.5 * L.height_step);
  double target = first;
  QuantizedMeshTile tile;
  for (int attempt = 0;; ++attempt) {
    const detail::TileMesh mesh = detail::mesh_tile(field, rect, {target, first, sag});
    std::vector<pm::Geodetic> vertices(mesh.uv.size());
    for (std::size_t v = 0; v < vertices.size(); ++v)
      vertices[v] = {rect.west + (rect.east - rect.west) * mesh.uv[v][0] / kQ,
                     rect.south + (rect.north - rect.south) * mesh.uv[v][1] / kQ, mesh.heights[v]};
    // Normals: on the tile's edges from the terrain's gradient, a function of the position that
    // the neighbour computes alike; inside, the mesh's own area-weighted normals, so that large
    // flat triangles at the foot of a steep edge are lit as what they are.
    std::vector<pm::Ecef> ecef(vertices.size());
    for (std::size_t v = 0; v < vertices.size(); ++v) ecef[v] = pm::ecef_from_geodetic(vertices[v]);
    std::vector<pm::Ecef> normals = area_weighted_normals(ecef, mesh.triangles);
    // Beyond the samples (the apron, the cliff, the ellipsoid) edge vertices get the ellipsoid's
    // normal: a cliff's sideways normal would shade the long flat triangles at its foot.
    const GeoGrid& g = field.grid();
    for (std::size_t v = 0; v < vertices.size(); ++v) {
      const auto [u, w] = mesh.uv[v];
      if (u != 0 && w != 0 && u != kQ && w != kQ) continue;
      const double lon = vertices[v].lon_deg, lat = vertices[v].lat_deg;
      const bool over_samples = (g.wraps() || (lon >= g.lon(0) && lon <= g.lon(g.width - 1))) &&
                                lat <= g.lat(0) && lat >= g.lat(g.height - 1);
      normals[v] = over_samples ? field_normal(field, lon, lat, normal_step) : ellipsoid_normal(lon, lat);
    }
    QuantizedMeshOptions qo;
    qo.height_step = L.height_step;
    qo.normal = [&](std::size_t v) { return normals[v]; };
    tile = make_quantized_mesh(rect, vertices, mesh.triangles, qo);
    std::vector<std::array<int, 2>> uv(tile.u.size());
    std::vector<double> decoded(tile.u.size());
    for (std::size_t v = 0; v < uv.size(); ++v) {
      uv[v] = {tile.u[v], tile.v[v]};
      decoded[v] = decoded_height(tile, v);
    }
    measured = detail::tile_error(field, rect, uv, decoded, tile.triangles, /*samples_only=*/true);
    if (measured <= L.bound || attempt == 3) return tile;
    target *= 0.5;
  }
}

std::string region_json(const GeoRect& r, double lo, double hi) {
  constexpr double k = std::numbers::pi / 180.0;
  return "{\"region\": [" + num(r.west * k) + ", " + num(r.south * k) + ", " + num(r.east * k) + ", " +
         num(r.north * k) + ", " + num(lo) + ", " + num(hi) + "]}";
}

/// tileset.json: a root without content over the whole Earth, the two level-0 tiles below it,
/// each tile's children below it. geometricError: the tile's own bound (TileRecord), raised where
/// needed so that it shrinks strictly from parent to child as 3D Tiles requires.
std::string tileset_json(const std::vector<std::vector<TileId>>& tiles,
                         const std::vector<std::vector<TileRecord>>& records, const std::string& datum) {
  std::map<std::array<int, 3>, std::size_t> index;
  for (std::size_t z = 0; z < tiles.size(); ++z)
    for (std::size_t i = 0; i < tiles[z].size(); ++i)
      index[{tiles[z][i].z, tiles[z][i].x, tiles[z][i].y}] = i;
  auto find = [&](int z, int x, int y) -> const TileRecord* {
    if (z >= int(tiles.size())) return nullptr;
    auto it = index.find({z, x, y});
    return it == index.end() ? nullptr : &records[std::size_t(z)][it->second];
  };
  std::function<std::pair<std::string, double>(int, int, int)> tile = [&](int z, int x, int y) {
    const TileRecord& r = *find(z, x, y);
    std::string children;
    double child_error = 0, lo = r.min_height, hi = r.max_height;
    for (int k = 0; k < 4; ++k) {
      const int cx = 2 * x + (k & 1), cy = 2 * y + (k >> 1);
      if (find(z + 1, cx, cy) == nullptr) continue;
      const auto [text, error] = tile(z + 1, cx, cy);
      children += (children.empty() ? "" : ", ") + text;
      child_error = std::max(child_error, error);
    }
    const double error =
        children.empty() ? r.geometric_error : std::max(r.geometric_error, child_error * (1 + 1e-6) + 1e-6);
    std::string j = "{\"boundingVolume\": " + region_json(tile_rect({z, x, y}), lo, hi) +
                    ", \"geometricError\": " + num(error) +
                    ", \"refine\": \"REPLACE\", \"content\": {\"uri\": \"" + std::to_string(z) + "/" +
                    std::to_string(x) + "/" + std::to_string(y) + ".glb\"}";
    if (!children.empty()) j += ", \"children\": [" + children + "]";
    return std::pair<std::string, double>{j + "}", error};
  };
  const auto [west, we] = tile(0, 0, 0);
  const auto [east, ee] = tile(0, 1, 0);
  double lo = 0, hi = 0;
  for (const TileRecord& r : records[0]) lo = std::min(lo, r.min_height), hi = std::max(hi, r.max_height);
  const double root = std::max(we, ee) * 2;
  return "{\"asset\": {\"version\": \"1.1\", \"generator\": \"terralod export\"},\n \"extras\": "
         "{\"terralod\": "
         "{\"vertical_datum\": " +
         datum + ", \"heights\": \"WGS 84 ellipsoid\"}},\n \"geometricError\": " + num(root * 2) +
         ",\n \"root\": {\"boundingVolume\": " + region_json({-180, -90, 180, 90}, lo, hi) +
         ", \"geometricError\": " + num(root) + ", \"refine\": \"REPLACE\", \"children\": [\n  " + west +
         ",\n  " + east + "]}}\n";
}

}  // namespace

ExportReport export_terrain(const std::string& db_path, const std::string& out_dir,
                            const ExportOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  auto seconds = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  const bool qm = options.format == ExportFormat::QuantizedMesh;
  if (qm && options.meshopt)
    throw ExportError(out_dir + ": meshopt compression applies to 3D Tiles content, not to quantized-mesh");
  const BlockDatabase db = BlockDatabase::open(db_path, BlockDatabase::Mode::ReadOnly);
  try {
    require_complete_build(db);
  } catch (const std::exception& e) {
    throw ExportError(e.what());
  }
  GeoGrid grid;
  try {
    // No cache of decoded blocks: a grid on longitude/latitude is read whole, each block pasted
    // once, and a warp's chunks share only the blocks along their edges.
    DatabaseTerrain terrain(db, {.cache_bytes = 0});
    grid = make_geo_grid(terrain, options.vertical_datum, db_path);
  } catch (const GeoError& e) {
    throw ExportError(e.what());
  }
  const detail::GeoField field(grid, /*background=*/0.0);

  ExportReport report;
  report.vertical_datum = grid.vertical_datum;
  report.heights_converted = grid.heights_converted;
  report.horizontal = grid.horizontal;
  // Across the antimeridian the bounds' west is then east of their east (as in a CesiumJS
  // Rectangle).
  report.bounds = {std::remainder(grid.lon(0), 360.0), grid.lat(grid.height - 1),
                   std::remainder(grid.lon(grid.width - 1), 360.0), grid.lat(0)};
  constexpr int pad = detail::GeoField::kPad;  // the tiles over the terrain include its rings
  const std::vector<GeoRect> ringed = wrapped_parts(
      {grid.lon(-pad), grid.lat(grid.height - 1 + pad), grid.lon(grid.width - 1 + pad), grid.lat(-pad)});
  int max_level = options.max_level;
  if (max_level < 0) {
    // Sample spacing in degrees of latitude on the ground, where columns are widest (nearest the
    // equator): a grid around a pole has columns degrees apart at the pole (export/geo_grid.cpp).
    const double north = grid.lat(0), south = grid.lat(grid.height - 1);
    const double widest = south <= 0.0 && north >= 0.0 ? 0.0 : std::min(std::abs(north), std::abs(south));
    const double spacing = std::max(grid.dlat, grid.dlon * std::cos(widest * std::numbers::pi / 180.0));
    max_level = std::clamp(int(std::ceil(std::log2(180.0 / (64.0 * spacing)))), 0, 24);
  }
  if (max_level > 24)
    throw ExportError(out_dir + ": --max-level " + std::to_string(max_level) + " is above 24");

  // Tiles and per-level parameters.
  const std::vector<std::vector<TileId>> tiles = level_tiles(options.format, max_level, ringed);
  std::vector<std::vector<TileRange>> available(tiles.size());
  std::vector<double> glb_scale(tiles.size(), 0.0);  // 3D Tiles: each level's quantization lattice
  std::size_t total = 0;
  report.levels.resize(tiles.size());
  for (int z = 0; z <= max_level; ++z) {
    available[std::size_t(z)] = tiles_over(z, ringed);
    total += tiles[std::size_t(z)].size();
    ExportLevel& L = report.levels[std::size_t(z)];
    L.z = z;
    L.bound = level_max_geometric_error(z);
    if (z == max_level) L.bound = std::min(L.bound, 1.0);
    // One height step per level: the widest tile range in 32766 steps, and no finer than floats
    // hold exactly (|height| / step < 2^23).
    std::vector<std::pair<double, double>> ranges(tiles[std::size_t(z)].size());
    pm::parallel_for(ranges.size(), options.threads, [&](std::size_t i) {
      ranges[i] = tile_height_range(field, rect_in_grid(tile_rect(tiles[std::size_t(z)][i]), grid));
    });
    double span = 0, extent = 1;
    for (const auto& [lo, hi] : ranges)
      span = std::max(span, hi - lo), extent = std::max({extent, std::abs(lo), std::abs(hi)});
    L.height_step = std::max({pow2_at_least(std::max(span, 1e-3) / (kQ - 1)),
                              pow2_at_least(extent / 8388608.0), std::ldexp(1.0, -12)});
    if (!qm) {
      double far = 1.0;
      for (std::size_t i = 0; i < ranges.size(); ++i)
        far = std::max(far, farthest_from_centre(tile_rect(tiles[std::size_t(z)][i]), ranges[i].first,
                                                 ranges[i].second));
      glb_scale[std::size_t(z)] = pow2_at_least(far * 1.01 + 1.0);
    }
  }

  const DatabaseInfo& info = db.info();
  std::ostringstream params;
  params << "terralod-export " << kExportVersion
         << (qm                ? " quantized-mesh"
             : options.meshopt ? " 3dtiles-meshopt"
                               : " 3dtiles")
         << " source=" << info.source << " grid=" << info.grid_width << "x" << info.grid_height
         << " build=" << info.build_parameters << " levels=" << max_level << " datum=" << grid.vertical_datum
         << " tiles=" << total;
  std::string parameters = params.str();
  std::replace(parameters.begin(), parameters.end(), '\n', ' ');
  prepare_folder(out_dir, parameters);
  Journal journal(out_dir, parameters);

  std::size_t done = 0;
  std::mutex m;
  std::vector<std::vector<TileRecord>> records(tiles.size());
  for (int z = 0; z <= max_level; ++z) {
    ExportLevel& L = report.levels[std::size_t(z)];
    const std::vector<TileId>& level = tiles[std::size_t(z)];
    const double tile_deg = 180.0 / std::ldexp(1.0, z);
    // Flat triangles sag below the curved surface by about R theta^2 / 8 over theta radians: the
    // forced grid keeps that within a quarter of the bound (what a client draws is flat in ECEF),
    // with at most kMaxSagDivisions^2 points. The cap binds only where the deepest level's 1 m
    // falls on tiles wider than 8 degrees (--max-level 4 or less): there the drawn surface may sag
    // more (120 m on a level-0 tile), which the heights measured as a client samples them (linear
    // in longitude and latitude) do not see, and which the 3D Tiles geometricError and skirt take
    // in. Uncapped, a level-0 tile at 1 m forced 7.8 M points: 41 x 41 samples exported with
    // --max-level 0 had not finished after 15 minutes, at 2.4 GB.
    constexpr int kMaxSagDivisions = 256;
    const double tile_rad = tile_deg * std::numbers::pi / 180.0;
    const double theta = std::sqrt(8.0 * 0.25 * L.bound / pm::kWgs84A);
    const int sag = std::clamp(int(std::ceil(tile_rad / theta)), 1, kMaxSagDivisions);
    const double grid_sag = pm::kWgs84A * (tile_rad / sag) * (tile_rad / sag) / 8.0;
    const double normal_step = std::max(grid.dlon, grid.dlat);  // the terrain's own gradient
    // 3D Tiles skirts: neighbours of different levels differ at their shared edge by at most the
    // sum of their errors (each within its level's bound plus the sag, at most 1/4 of it unless
    // capped), which the coarser tile's skirt covers.
    const double skirt = 3.0 * L.bound + 2.0 * std::max(0.0, grid_sag - 0.25 * L.bound);
    std::vector<TileRecord>& rec = records[std::size_t(z)];
    rec.resize(level.size());
    std::vector<std::uint8_t> reused(level.size(), 0);
    pm::parallel_for(level.size(), options.threads, [&](std::size_t i) {
      const TileId id = level[i];
      const std::string dir = (fs::path(out_dir) / std::to_string(id.z) / std::to_string(id.x)).string();
      const std::string file = (fs::path(dir) / (std::to_string(id.y) + (qm ? ".terrain" : ".glb"))).string();
      if (const TileRecord* had = journal.find(id); had != nullptr && fs::exists(file)) {
        rec[i] = *had;
        reused[i] = 1;
      } else {
        const GeoRect rect = rect_in_grid(tile_rect(id), grid);
        TileRecord& r = rec[i];
        QuantizedMeshTile tile = make_tile(field, rect, L, sag, normal_step, r.max_error);
        r.min_height = std::numeric_limits<double>::infinity(), r.max_height = -r.min_height;
        for (std::size_t v = 0; v < tile.u.size(); ++v)
          r.min_height = std::min(r.min_height, decoded_height(tile, v)),
          r.max_height = std::max(r.max_height, decoded_height(tile, v));
        std::string bytes;
        if (qm) {
          tile.metadata = "{" + subtree_availability(id, max_level, ringed) +
                          "\"terralod\":{\"max_error\":" + num(r.max_error) + ",\"bound\":" + num(L.bound) +
                          "}}";
          const std::vector<std::uint8_t> z = gzip(encode_quantized_mesh(tile));
          bytes.assign(z.begin(), z.end());
          r.geometric_error = r.max_error;
        } else {
          const detail::GlbTile glb = detail::encode_tile_glb(
              tile, rect, [&](std::size_t v) { return oct_decode(tile.normals[v]); },
              glb_scale[std::size_t(z)], skirt, options.meshopt, file);
          // A flat triangle departs from the surface through its corners by at most the
          // sagitta of its smallest enclosing circle (radius <= longest edge / sqrt 3).
          const double sag_depth = glb.longest_edge * glb.longest_edge / (6.0 * pm::kWgs84B);
          r.geometric_error = r.max_error + glb.displacement + sag_depth;
          r.min_height -= std::max(sag_depth, skirt) + glb.displacement;
          r.max_height += glb.displacement;
          bytes = glb.bytes;
        }
        r.vertices = tile.u.size(), r.triangles = tile.triangles.size(), r.bytes = bytes.size();
        std::error_code ec;
        fs::create_directories(dir, ec);
        if (ec) throw ExportError(dir + ": cannot create the tile folder: " + ec.message());
        try {
          pm::write_file_atomically(file, bytes);
        } catch (const std::runtime_error& e) {
          throw ExportError(e.what());
        }
        journal.add(id, r);
      }
      std::lock_guard<std::mutex> lock(m);
      ++done;
      if (options.progress) options.progress({z, done, total, seconds()});
    });
    for (std::size_t i = 0; i < level.size(); ++i) {
      const TileRecord& r = rec[i];
      ++L.tiles;
      L.vertices += r.vertices, L.triangles += r.triangles, L.bytes += r.bytes;
      L.max_error = std::max(L.max_error, r.max_error);
      L.geometric_error = std::max(L.geometric_error, r.geometric_error);
      (reused[i] ? report.tiles_reused : report.tiles_written) += 1;
    }
  }

  // The index, last.
  const std::string datum = pm::json_quote(grid.vertical_datum);  // with its quotes
  try {
    if (qm) {
      std::string extra = "\"terralod\": {\"vertical_datum\": " + datum + ", \"bound\": [";
      for (std::size_t z = 0; z < report.levels.size(); ++z)
        extra += (z ? ", " : "") + num(report.levels[z].bound);
      extra += "], \"max_error\": [";
      for (std::size_t z = 0; z < report.levels.size(); ++z)
        extra += (z ? ", " : "") + num(report.levels[z].max_error);
      extra += "], \"height_step\": [";
      for (std::size_t z = 0; z < report.levels.size(); ++z)
        extra += (z ? ", " : "") + num(report.levels[z].height_step);
      extra += "]}, \"metadataAvailability\": " + std::to_string(kMetadataLevels);
      const std::string name = fs::path(info.source).stem().string();
      pm::write_file_atomically((fs::path(out_dir) / "layer.json").string(),
                                layer_json(name.empty() ? "terralod" : name, report.bounds, available,
                                           {"octvertexnormals", "metadata"}, extra));
    } else {
      pm::write_file_atomically((fs::path(out_dir) / "tileset.json").string(),
                                tileset_json(tiles, records, datum));
    }
  } catch (const std::runtime_error& e) {
    throw ExportError(e.what());
  }
  report.seconds = seconds();
  return report;
}

}  // namespace terralod::blocks
