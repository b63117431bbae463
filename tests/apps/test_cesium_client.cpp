// A real CesiumJS client on the quantized-mesh tileset of `terralod export`: a crop of the SRTM
// tile N44W072 (Mount Washington) is built into a database by `terralod build`, exported with
// `terralod export --format quantized-mesh`, and loaded in headless Chromium by CesiumJS through
// Cesium.CesiumTerrainProvider (tools/cesium/check_terrain.mjs, versions pinned in
// tools/cesium/package-lock.json). The globe's tiles must load without an error, the screenshot
// must show relief, and Cesium.sampleTerrainMostDetailed at 100 DEM samples must give the DEM
// height plus the EGM96 geoid undulation, computed independently by PROJ's cs2cs, within the
// tileset's own deepest-level error bound (layer.json: "terralod" -> "max_error", last entry).
//
// Fails, never skips, when Node.js, Chromium, tools/cesium/node_modules or cs2cs are missing
// (scripts/install-deps.sh installs them); skips only without N44W072.hgt in TERRALOD_DATA_DIR.
// The screenshot is kept at TERRALOD_CESIUM_SCREENSHOT (build/tests/apps/cesium_screenshot.png).
//
// The same database exported with `--format 3dtiles --meshopt` (3D Tiles 1.1, glb contents
// compressed with EXT_meshopt_compression, ellipsoidal heights) is loaded through Cesium.Cesium3DTileset
// (check_terrain.mjs --3dtiles), with heights from Scene.sampleHeightMostDetailed, checked against the same
// DEM + EGM96 within the largest geometricError of the tileset's deepest tiles; its screenshot is
// cesium_3dtiles_screenshot.png next to the other.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "run_command.hpp"

namespace {

namespace fs = std::filesystem;
using terralod::test::quote;
using terralod::test::run_command;
using terralod::test::slurp;

const fs::path& tmp_dir() { return terralod::test::process_temp_dir("cesium"); }

// --- the DEM: a crop of N44W072.hgt ---------------------------------------------------------------
//
// N44W072.hgt: 1201 x 1201 big-endian int16 samples, row 0 at latitude 45, column 0 at longitude
// -72, 3 arc-seconds apart (1/1200 degree). The crop: 257 x 257 samples, top-left (column 712,
// row 748), about 17 km x 24 km around Mount Washington (1917 m, sample column 840 row 876), so
// longitudes -71.4067 .. -71.1933 and latitudes 44.1633 .. 44.3767; no voids. Heights are metres
// above the EGM96 geoid (SRTM's vertical datum).
constexpr int kTile = 1201, kCol0 = 712, kRow0 = 748, kSize = 257;
constexpr double kStep = 1.0 / 1200.0;

double lon_of(int col) { return -72.0 + (kCol0 + col) * kStep; }  // crop column -> degrees
double lat_of(int row) { return 45.0 - (kRow0 + row) * kStep; }   // crop row -> degrees

struct Dem {
  std::vector<double> h;  // kSize x kSize, row 0 north; empty when the .hgt is absent
  double at(int col, int row) const { return h[std::size_t(row) * kSize + col]; }
};

const Dem& dem() {
  static const Dem d = [] {
    Dem r;
    const std::string bytes = slurp(fs::path(TERRALOD_DATA_DIR) / "N44W072.hgt");
    if (bytes.size() != std::size_t(kTile) * kTile * 2) return r;
    r.h.resize(std::size_t(kSize) * kSize);
    for (int row = 0; row < kSize; ++row)
      for (int col = 0; col < kSize; ++col) {
        const std::size_t i = 2 * (std::size_t(kRow0 + row) * kTile + kCol0 + col);
        r.h[std::size_t(row) * kSize + col] =
            double(std::int16_t(std::uint16_t(std::uint8_t(bytes[i]) << 8 | std::uint8_t(bytes[i + 1]))));
      }
    return r;
  }();
  return d;
}

// WGS 84 geographic, for the ASCII grid's .prj.
constexpr const char* kWgs84Wkt =
    "GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS 84\",6378137,298.257223563,"
    "AUTHORITY[\"EPSG\",\"7030\"]],AUTHORITY[\"EPSG\",\"6326\"]],PRIMEM[\"Greenwich\",0,"
    "AUTHORITY[\"EPSG\",\"8901\"]],UNIT[\"degree\",0.0174532925199433,AUTHORITY[\"EPSG\",\"9122\"]],"
    "AXIS[\"Latitude\",NORTH],AXIS[\"Longitude\",EAST],AUTHORITY[\"EPSG\",\"4326\"]]";

std::string fixed(double v, int digits = 12) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

/// The crop as an Esri ASCII grid with a geographic .prj (sample-centre georeferencing).
void write_crop(const fs::path& asc) {
  std::ofstream f(asc);
  f << "ncols " << kSize << "\nnrows " << kSize << "\nxllcenter " << fixed(lon_of(0), 15) << "\nyllcenter "
    << fixed(lat_of(kSize - 1), 15) << "\ncellsize " << fixed(kStep, 15) << "\nNODATA_value -32768\n";
  for (int row = 0; row < kSize; ++row) {
    for (int col = 0; col < kSize; ++col) f << (col ? " " : "") << dem().at(col, row);
    f << "\n";
  }
  std::ofstream(fs::path(asc).replace_extension(".prj")) << kWgs84Wkt << "\n";
}

// --- small JSON readers for the two files we read (layer.json, the checker's result) --------------

/// The position just after `"key":` (a member's name, not a string value that happens to read the
/// same), searching from `from`; npos when there is none.
std::size_t after_key(const std::string& json, const std::string& key, std::size_t from = 0) {
  const std::string quoted = "\"" + key + "\"";
  for (std::size_t p = json.find(quoted, from); p != std::string::npos; p = json.find(quoted, p + 1)) {
    const std::size_t colon = json.find_first_not_of(" \t\r\n", p + quoted.size());
    if (colon != std::string::npos && json[colon] == ':') return colon + 1;
  }
  return std::string::npos;
}

/// The numbers of the array that is the value of member `key` (the first after `from`; null
/// entries as NaN), or nothing when the member or a well-formed array of numbers is absent.
std::optional<std::vector<double>> number_array(const std::string& json, const std::string& key,
                                                std::size_t from = 0) {
  std::size_t p = after_key(json, key, from);
  if (p == std::string::npos) return std::nullopt;
  p = json.find_first_not_of(" \t\r\n", p);
  if (p == std::string::npos || json[p] != '[') return std::nullopt;
  std::vector<double> v;
  ++p;
  for (;;) {
    p = json.find_first_not_of(" \t\r\n,", p);
    if (p == std::string::npos) return std::nullopt;
    if (json[p] == ']') return v;
    if (json.compare(p, 4, "null") == 0) {
      v.push_back(std::nan(""));
      p += 4;
      continue;
    }
    char* end = nullptr;
    const double x = std::strtod(json.c_str() + p, &end);
    if (end == json.c_str() + p) return std::nullopt;
    v.push_back(x);
    p = std::size_t(end - json.c_str());
  }
}

/// True when member `key` is `true`.
bool is_true(const std::string& json, const std::string& key) {
  const std::size_t p = json.find_first_not_of(" \t\r\n", after_key(json, key));
  return p != std::string::npos && json.compare(p, 4, "true") == 0;
}

/// tileset.json's deepest content level (z of the "z/x/y.glb" URIs) and the largest geometricError
/// of the tiles at that level, or nothing. A tile's own geometricError is the last one before its
/// content's URI (its children follow the content).
std::optional<std::pair<int, double>> deepest_geometric_error(const std::string& tileset) {
  std::vector<std::pair<int, double>> tiles;  // level, geometricError
  for (std::size_t p = after_key(tileset, "uri"); p != std::string::npos; p = after_key(tileset, "uri", p)) {
    const std::size_t q = tileset.find('"', p);
    if (q == std::string::npos) return std::nullopt;
    char* end = nullptr;
    const long level = std::strtol(tileset.c_str() + q + 1, &end, 10);
    if (end == tileset.c_str() + q + 1 || *end != '/') return std::nullopt;
    const std::size_t g = tileset.rfind("\"geometricError\"", q);
    if (g == std::string::npos) return std::nullopt;
    const std::size_t v = after_key(tileset, "geometricError", g);
    const double e = std::strtod(tileset.c_str() + v, &end);
    if (end == tileset.c_str() + v) return std::nullopt;
    tiles.push_back({int(level), e});
  }
  if (tiles.empty()) return std::nullopt;
  std::pair<int, double> r{-1, 0.0};
  for (const auto& [level, e] : tiles)
    if (level > r.first)
      r = {level, e};
    else if (level == r.first)
      r.second = std::max(r.second, e);
  return r;
}

/// layer.json's `"terralod": {"max_error": [...]}` (metres per level), or nothing.
std::optional<std::vector<double>> layer_max_error(const std::string& layer) {
  const std::size_t member = after_key(layer, "terralod");
  if (member == std::string::npos) return std::nullopt;
  return number_array(layer, "max_error", member);
}

// --- the tools ---------------------------------------------------------------------------------------

/// Fails the test when a tool the check needs is missing (a failure, never a skip).
void require_tools() {
  const std::string hint =
      ": run scripts/install-deps.sh (apt chromium, proj-bin, nodejs; npm ci --prefix tools/cesium)";
  const fs::path tools = fs::path(TERRALOD_CESIUM_CHECK).parent_path();
  ASSERT_TRUE(fs::exists(TERRALOD_NODE)) << "Node.js (" << TERRALOD_NODE << ") is missing" << hint;
  ASSERT_TRUE(fs::exists(TERRALOD_CESIUM_CHECK)) << TERRALOD_CESIUM_CHECK << " is missing";
  ASSERT_TRUE(fs::exists(tools / "node_modules/cesium/Build/Cesium/Cesium.js"))
      << "CesiumJS (" << tools / "node_modules/cesium"
      << ") is missing" << hint;
  ASSERT_TRUE(fs::exists(tools / "node_modules/puppeteer-core/package.json"))
      << "puppeteer-core (" << tools / "node_modules/puppeteer-core"
      << ") is missing" << hint;
  ASSERT_TRUE(fs::exists(TERRALOD_CHROMIUM)) << "Chromium (" << TERRALOD_CHROMIUM << ") is missing" << hint;
  ASSERT_TRUE(fs::exists(TERRALOD_CS2CS)) << "PROJ's cs2cs (" << TERRALOD_CS2CS << ") is missing" << hint;
}

terralod::test::CommandResult terralod(const std::string& args) {
  return terralod::test::run_tool(TERRALOD_CLI, args);
}

struct Point {
  int col = 0, row = 0;  // crop sample
  double lon = 0, lat = 0, dem = 0;
  double expected = 0;  // ellipsoidal: DEM + EGM96 undulation (cs2cs)
};

/// 100 distinct DEM samples of the crop (not on its border), drawn with a fixed, printed seed
/// (mt19937's raw output, so the same on every platform).
std::vector<Point> sample_points() {
  constexpr std::uint32_t kSeed = 20240621;
  std::printf("points: seed %u\n", kSeed);
  std::mt19937 rng(kSeed);
  std::set<std::pair<int, int>> seen;
  std::vector<Point> pts;
  while (pts.size() < 100) {
    const int col = 1 + int(rng() % (kSize - 2)), row = 1 + int(rng() % (kSize - 2));
    if (!seen.insert({col, row}).second) continue;
    Point p;
    p.col = col;
    p.row = row;
    p.lon = lon_of(col);
    p.lat = lat_of(row);
    p.dem = dem().at(col, row);
    pts.push_back(p);
  }
  return pts;
}

/// Fills Point::expected with PROJ: cs2cs from WGS 84 + EGM96 height (EPSG:4326+5773, input
/// "lat lon H") to WGS 84 3D (EPSG:4979, output "lat lon h"), h = H + N. --no-ballpark: without
/// the EGM96 grid (proj-data's egm96_15.gtx) cs2cs fails instead of leaving the height as it is.
void add_geoid(std::vector<Point>& pts) {
  const fs::path in = tmp_dir() / "cs2cs_in.txt";
  {
    std::ofstream f(in);
    for (const Point& p : pts) f << fixed(p.lat) << " " << fixed(p.lon) << " " << fixed(p.dem, 3) << "\n";
  }
  const auto r = run_command(quote(TERRALOD_CS2CS) + " --no-ballpark -f %.6f EPSG:4326+5773 EPSG:4979 < " +
                             quote(in.string()));
  ASSERT_EQ(r.status, 0) << r.err << r.out;
  std::istringstream out(r.out);
  for (Point& p : pts) {
    std::string line;
    ASSERT_TRUE(std::getline(out, line)) << "cs2cs gave fewer lines than points:\n" << r.out << r.err;
    double lat = 0, lon = 0, h = 0;
    ASSERT_EQ(std::sscanf(line.c_str(), "%lf %lf %lf", &lat, &lon, &h), 3) << "cs2cs: '" << line << "'\n"
                                                                           << r.err;
    ASSERT_NEAR(lat, p.lat, 1e-6) << line;
    ASSERT_NEAR(lon, p.lon, 1e-6) << line;
    // EGM96 lies 27.3 .. 27.7 m below the ellipsoid here: anything else means no geoid was applied.
    ASSERT_TRUE(h - p.dem > -29.0 && h - p.dem < -26.0)
        << "cs2cs gave an EGM96 undulation of " << h - p.dem << " m at " << line << "\n"
        << r.err;
    p.expected = h;
  }
}

/// Runs check_terrain.mjs; returns its result JSON ("" when it wrote none).
struct Check {
  terralod::test::CommandResult run;
  std::string json;
};
/// `view`: --view and --pitch of check_terrain.mjs; empty: the crop, seen obliquely.
Check check_terrain(const fs::path& tiles, const fs::path& points, const fs::path& out, const fs::path& png,
                    bool tiles3d = false, std::string view = {}) {
  if (view.empty())
    view = fixed(lon_of(0), 6) + "," + fixed(lat_of(kSize - 1), 6) + "," + fixed(lon_of(kSize - 1), 6) + "," +
           fixed(lat_of(0), 6);
  std::string cmd = quote(TERRALOD_NODE) + " " + quote(TERRALOD_CESIUM_CHECK) + " --tiles " +
                    quote(tiles.string()) + " --out " + quote(out.string()) + " --view " + view +
                    " --timeout 240 --chromium " + quote(TERRALOD_CHROMIUM);
  if (!points.empty()) cmd += " --points " + quote(points.string());
  if (!png.empty()) cmd += " --screenshot " + quote(png.string());
  if (tiles3d) cmd += " --3dtiles";
  fs::remove(out);
  Check c;
  c.run = run_command(cmd);
  c.json = slurp(out);
  return c;
}

/// The database of the crop, built once per process (an empty path after a failure).
const fs::path& database() {
  static const fs::path d = [] {
    const fs::path asc = tmp_dir() / "n44w072_crop.asc", db = tmp_dir() / "crop.db";
    write_crop(asc);
    // --crs native: the database keeps the DEM's own lon/lat samples, so the client's heights are
    // compared with the samples themselves (an "auto" frame would resample them twice: to the
    // azimuthal equidistant grid, then back to lon/lat for the export).
    const auto b = terralod("build --threads 1 --crs native --input " + quote(asc.string()) + " --out " +
                            quote(db.string()));
    if (b.status != 0) {
      ADD_FAILURE() << "terralod build failed:\n" << b.out << b.err;
      return fs::path();
    }
    return db;
  }();
  return d;
}

/// The database exported as `format` (plus `options`) into tmp_dir()/`name` (an empty path after a
/// failure).
fs::path export_database(const std::string& format, const std::string& name,
                         const std::string& options = "") {
  if (database().empty()) return {};
  const fs::path dir = tmp_dir() / name;
  // SRTM heights are EGM96: asked for explicitly, since the crop is an ASCII grid, not a .hgt.
  const auto e = terralod("export --threads 1 --db " + quote(database().string()) + " --format " + format +
                          " --vertical-datum egm96 " + options + " --out " + quote(dir.string()));
  if (e.status != 0) {
    ADD_FAILURE() << "terralod export --format " << format << " failed:\n" << e.out << e.err;
    return {};
  }
  std::printf("%s", e.err.c_str());
  // The export says what it did to the heights (ExportReport::heights_converted).
  EXPECT_NE(e.out.find("heights above the WGS 84 ellipsoid, converted from EGM96"), std::string::npos)
      << e.out;
  return dir;
}

/// The database's quantized-mesh tileset, made once per process (empty paths after a failure).
struct Tileset {
  fs::path dir;
  std::string layer;  // layer.json
};
const Tileset& tileset() {
  static const Tileset t = [] {
    Tileset r;
    r.dir = export_database("quantized-mesh", "tiles");
    if (!r.dir.empty()) r.layer = slurp(r.dir / "layer.json");
    return r;
  }();
  return t;
}

/// The points as check_terrain.mjs's --points JSON.
void write_points(const std::vector<Point>& pts, const fs::path& file) {
  std::ofstream f(file);
  f << "[\n";
  for (std::size_t i = 0; i < pts.size(); ++i)
    f << "  {\"lon\": " << fixed(pts[i].lon) << ", \"lat\": " << fixed(pts[i].lat) << "}"
      << (i + 1 < pts.size() ? ",\n" : "\n");
  f << "]\n";
}

/// Every point of the checker's result has a height (sampled at level `deepest`, by the result's
/// "levels") within `bound` of the DEM + EGM96; prints mean and max |difference|.
void expect_heights_within(const std::string& json, const std::vector<Point>& pts, int deepest, double bound,
                           const char* what) {
  const auto heights = number_array(json, "heights");
  const auto levels = number_array(json, "levels");
  ASSERT_TRUE(heights && levels) << json;
  ASSERT_EQ(heights->size(), pts.size()) << json;
  ASSERT_EQ(levels->size(), pts.size()) << json;
  double worst = 0, sum = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const Point& p = pts[i];
    const double h = (*heights)[i], d = std::abs(h - p.expected);
    EXPECT_EQ((*levels)[i], deepest) << "point " << i << " (" << fixed(p.lon, 6) << ", " << fixed(p.lat, 6)
                                     << ")";
    ASSERT_TRUE(std::isfinite(h)) << "no height at point " << i;
    EXPECT_LE(d, bound) << "point " << i << " (" << fixed(p.lon, 6) << ", " << fixed(p.lat, 6)
                        << ", crop sample " << p.col << "," << p.row << "): Cesium " << fixed(h, 3)
                        << " m, DEM " << p.dem << " m + geoid " << fixed(p.expected - p.dem, 3)
                        << " m = " << fixed(p.expected, 3) << " m";
    worst = std::max(worst, d);
    sum += d;
  }
  std::printf("%s: mean |diff| %.4f m, max %.4f m, bound %.4f m\n", what, sum / double(pts.size()), worst,
              bound);
}

/// `terralod build` of a DEM file, then `export` of it as heights above the ellipsoid: the
/// tileset in `dir` and its levels' measured errors (layer.json).
void build_and_export(const fs::path& dem, const fs::path& db, const fs::path& dir,
                      std::vector<double>& max_error) {
  const auto b =
      terralod("build --threads 1 --input " + quote(dem.string()) + " --out " + quote(db.string()));
  ASSERT_EQ(b.status, 0) << b.out << b.err;
  const auto e = terralod("export --threads 1 --vertical-datum ellipsoid --db " + quote(db.string()) +
                          " --out " + quote(dir.string()));
  ASSERT_EQ(e.status, 0) << e.out << e.err;
  const auto levels = layer_max_error(slurp(dir / "layer.json"));
  ASSERT_TRUE(levels && !levels->empty());
  max_error = *levels;
}

/// The points `in` (two numbers each, in cs2cs's order for CRS `from`) in CRS `to`, through cs2cs
/// with output `format`; `name` names the file of points.
void cs2cs(const std::string& name, const std::string& from, const std::string& to, const char* format,
           const std::vector<std::array<double, 2>>& in, std::vector<std::array<double, 2>>& out) {
  const fs::path file = tmp_dir() / (name + ".txt");
  {
    std::ofstream f(file);
    for (const auto& [a, b] : in) f << fixed(a, 9) << " " << fixed(b, 9) << "\n";
  }
  const auto r = run_command(quote(TERRALOD_CS2CS) + " -f " + format + " " + from + " " + to + " < " +
                             quote(file.string()));
  ASSERT_EQ(r.status, 0) << r.err;
  std::istringstream lines(r.out);
  out.assign(in.size(), {0.0, 0.0});
  for (auto& [a, b] : out) {
    std::string line;
    ASSERT_TRUE(std::getline(lines, line) && std::sscanf(line.c_str(), "%lf %lf", &a, &b) == 2) << r.out;
  }
}

/// check_terrain.mjs over the tileset in `dir` at `pts` (files named after `name`), seen as `view`:
/// every tile loads and every height is within `bound` of the expected one (expect_heights_within).
void expect_cesium_heights(const fs::path& dir, const std::vector<Point>& pts, const std::string& name,
                           const std::string& view, int deepest, double bound, const char* what) {
  const fs::path points = tmp_dir() / (name + "_points.json"), out = tmp_dir() / (name + "_result.json");
  write_points(pts, points);
  const Check c = check_terrain(dir, points, out, {}, false, view);
  std::printf("%s", c.run.err.c_str());
  ASSERT_EQ(c.run.status, 0) << "check_terrain.mjs failed:\n" << c.run.out << c.run.err << "\n" << c.json;
  EXPECT_TRUE(is_true(c.json, "tiles_loaded")) << c.json;
  expect_heights_within(c.json, pts, deepest, bound, what);
}

// --- the screenshot ---------------------------------------------------------------------------------

struct Picture {
  int width = 0, height = 0;
  std::size_t colours = 0;       // distinct RGB values
  double luma_stddev = 0;        // over all pixels, 0..255
  double lower_half_stddev = 0;  // the terrain nearest the camera
};

std::optional<Picture> analyse_png(const fs::path& png, std::string& error) {
  auto in = OIIO::ImageInput::open(png.string());
  if (!in) {
    error = OIIO::geterror();
    return std::nullopt;
  }
  Picture p;
  p.width = in->spec().width;
  p.height = in->spec().height;
  const int channels = in->spec().nchannels;
  if (channels < 3) {
    error = "fewer than 3 channels";
    return std::nullopt;
  }
  std::vector<std::uint8_t> px(std::size_t(p.width) * p.height * channels);
  if (!in->read_image(0, 0, 0, channels, OIIO::TypeDesc::UINT8, px.data())) {
    error = in->geterror();
    return std::nullopt;
  }
  std::set<std::uint32_t> colours;
  double s = 0, s2 = 0, ls = 0, ls2 = 0;
  std::size_t lower = 0;
  for (int y = 0; y < p.height; ++y)
    for (int x = 0; x < p.width; ++x) {
      const std::uint8_t* c = &px[(std::size_t(y) * p.width + x) * channels];
      colours.insert(std::uint32_t(c[0]) << 16 | std::uint32_t(c[1]) << 8 | c[2]);
      const double l = 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
      s += l;
      s2 += l * l;
      if (y >= p.height / 2) {
        ls += l;
        ls2 += l * l;
        ++lower;
      }
    }
  const double n = double(p.width) * p.height;
  p.colours = colours.size();
  p.luma_stddev = std::sqrt(std::max(0.0, s2 / n - (s / n) * (s / n)));
  p.lower_half_stddev = std::sqrt(std::max(0.0, ls2 / lower - (ls / lower) * (ls / lower)));
  return p;
}

/// The screenshot shows lit relief: many colours, contrast, and contrast in the lower half (the
/// terrain in front of the camera; the sky is one flat colour).
void expect_relief(const fs::path& png) {
  std::string error;
  const auto pic = analyse_png(png, error);
  ASSERT_TRUE(pic) << png << ": " << error;
  std::printf("screenshot %s: %d x %d, %zu colours, luma stddev %.1f (lower half %.1f)\n", png.c_str(),
              pic->width, pic->height, pic->colours, pic->luma_stddev, pic->lower_half_stddev);
  EXPECT_EQ(pic->width, 1024);
  EXPECT_EQ(pic->height, 640);
  EXPECT_GE(pic->colours, 200u);
  EXPECT_GE(pic->luma_stddev, 5.0);
  EXPECT_GE(pic->lower_half_stddev, 3.0);
}

// --- the tests ---------------------------------------------------------------------------------------

TEST(CesiumClient, LoadsTheExportedTilesetAndSamplesDemPlusEgm96) {
  ASSERT_NO_FATAL_FAILURE(require_tools());
  if (dem().h.empty()) GTEST_SKIP() << "N44W072.hgt not in " << TERRALOD_DATA_DIR;
  for (double h : dem().h) ASSERT_NE(h, -32768.0) << "the crop holds a void";

  std::vector<Point> pts = sample_points();
  ASSERT_NO_FATAL_FAILURE(add_geoid(pts));

  const Tileset& ts = tileset();
  ASSERT_FALSE(ts.dir.empty());
  const auto max_error = layer_max_error(ts.layer);
  ASSERT_TRUE(max_error && !max_error->empty()) << "no \"terralod\": {\"max_error\": [...]}:\n" << ts.layer;
  const double bound = max_error->back();
  const int deepest = int(max_error->size()) - 1;
  ASSERT_TRUE(std::isfinite(bound) && bound >= 0) << ts.layer;
  std::printf("tileset: levels 0..%d, deepest-level max_error %.4f m\n", deepest, bound);

  const fs::path points = tmp_dir() / "points.json", out = tmp_dir() / "result.json";
  write_points(pts, points);
  const fs::path png = TERRALOD_CESIUM_SCREENSHOT;
  fs::remove(png);
  const Check c = check_terrain(ts.dir, points, out, png);
  std::printf("%s", c.run.err.c_str());
  ASSERT_EQ(c.run.status, 0) << "check_terrain.mjs failed:\n" << c.run.out << c.run.err << "\n" << c.json;
  EXPECT_TRUE(is_true(c.json, "ok")) << c.json;
  EXPECT_TRUE(is_true(c.json, "tiles_loaded")) << c.json;

  // Heights: every one the DEM + EGM96 within the deepest level's bound, sampled at that level.
  // The 0.01 m margin covers float32 header heights and Cesium's interpolation arithmetic.
  expect_heights_within(c.json, pts, deepest, bound + 0.01, "Cesium heights against DEM + EGM96 (cs2cs)");
  expect_relief(png);
}

// The 3D Tiles export of the same database through Cesium.Cesium3DTileset: every tile loads,
// Scene.sampleHeightMostDetailed reaches the deepest tiles at every point and gives the DEM +
// EGM96 within the largest geometricError of those tiles (tileset.json). No margin: the
// exporter's geometricError already includes glTF quantization and the sag of flat triangles.
TEST(CesiumClient, Loads3DTilesAndSamplesDemPlusEgm96) {
  ASSERT_NO_FATAL_FAILURE(require_tools());
  if (dem().h.empty()) GTEST_SKIP() << "N44W072.hgt not in " << TERRALOD_DATA_DIR;
  std::vector<Point> pts = sample_points();
  ASSERT_NO_FATAL_FAILURE(add_geoid(pts));

  // Compressed with EXT_meshopt_compression: CesiumJS decodes it, and test_gltf_validator shows the
  // decoded tiles equal the uncompressed export's (same vertices, same triangles), so this one
  // browser run checks both forms.
  const fs::path dir = export_database("3dtiles", "tiles_3d", "--meshopt");
  ASSERT_FALSE(dir.empty());
  const std::string json = slurp(dir / "tileset.json");
  const auto deepest = deepest_geometric_error(json);
  ASSERT_TRUE(deepest) << "no tiles with z/x/y.glb content and geometricError in " << dir / "tileset.json";
  const auto [level, bound] = *deepest;
  ASSERT_TRUE(std::isfinite(bound) && bound > 0) << bound;
  std::printf("3D tileset: deepest level %d, largest geometricError there %.4f m\n", level, bound);

  const fs::path points = tmp_dir() / "points.json", out = tmp_dir() / "result_3dtiles.json";
  write_points(pts, points);
  const fs::path png = fs::path(TERRALOD_CESIUM_SCREENSHOT).parent_path() / "cesium_3dtiles_screenshot.png";
  fs::remove(png);
  const Check c = check_terrain(dir, points, out, png, /*tiles3d=*/true);
  std::printf("%s", c.run.err.c_str());
  ASSERT_EQ(c.run.status, 0) << "check_terrain.mjs --3dtiles failed:\n"
                             << c.run.out << c.run.err << "\n"
                             << c.json;
  EXPECT_TRUE(is_true(c.json, "ok")) << c.json;
  EXPECT_TRUE(is_true(c.json, "tiles_loaded")) << c.json;
  expect_heights_within(c.json, pts, level, bound, "Cesium 3D Tiles heights against DEM + EGM96 (cs2cs)");
  expect_relief(png);
}

// A DEM around the South Pole (polar stereographic, EPSG:3031, as REMA's and BedMachine's) exports
// every longitude from the pole: CesiumJS loads the tileset and samples the DEM at points all
// around the pole (both sides of the antimeridian, 1 km from it, 0.01 degree from the pole)
// within the deepest level's bound plus the two bilinear resamplings of a smooth surface
// (centimetres). cs2cs places the points in the DEM's CRS; heights are ellipsoidal as given.
TEST(CesiumClient, SamplesATerrainAroundTheSouthPole) {
  ASSERT_NO_FATAL_FAILURE(require_tools());
  constexpr int kN = 97;
  constexpr double kCell = 1000.0, kHalf = 0.5 * (kN - 1) * kCell;
  const auto height = [](double x, double y) {
    return 1500.0 + 200.0 * std::sin(x / 20000.0 + 0.4) * std::cos(y / 15000.0 - 0.1);
  };
  const fs::path asc = tmp_dir() / "south_pole.asc", db = tmp_dir() / "south_pole.db",
                 dir = tmp_dir() / "south_pole_tiles";
  {
    std::ofstream f(asc);
    f << "ncols " << kN << "\nnrows " << kN << "\nxllcenter " << -kHalf << "\nyllcenter " << -kHalf
      << "\ncellsize " << kCell << "\n";
    for (int row = 0; row < kN; ++row) {
      for (int col = 0; col < kN; ++col)
        f << (col ? " " : "") << fixed(height(-kHalf + col * kCell, kHalf - row * kCell), 4);
      f << "\n";
    }
    std::ofstream(fs::path(asc).replace_extension(".prj"))
        << "PROJCS[\"WGS_1984_Antarctic_Polar_Stereographic\",GEOGCS[\"GCS_WGS_1984\",DATUM[\"D_WGS_1984\","
           "SPHEROID[\"WGS_1984\",6378137.0,298.257223563]],PRIMEM[\"Greenwich\",0.0],UNIT[\"Degree\","
           "0.0174532925199433]],PROJECTION[\"Stereographic_South_Pole\"],PARAMETER[\"False_Easting\",0.0],"
           "PARAMETER[\"False_Northing\",0.0],PARAMETER[\"Central_Meridian\",0.0],PARAMETER["
           "\"Standard_Parallel_1\",-71.0],UNIT[\"Meter\",1.0]]\n";
  }
  std::vector<double> max_error;
  ASSERT_NO_FATAL_FAILURE(build_and_export(asc, db, dir, max_error));
  const int deepest = int(max_error.size()) - 1;

  std::vector<Point> pts;
  std::vector<std::array<double, 2>> latlon, xy;
  for (const double lat : {-89.99, -89.9, -89.75})
    for (const double lon : {-179.99, -135.0, -90.0, -45.0, 0.0, 45.0, 90.0, 135.0, 179.99}) {
      Point p;
      p.lon = lon, p.lat = lat;
      pts.push_back(p);
      latlon.push_back({lat, lon});
    }
  ASSERT_NO_FATAL_FAILURE(cs2cs("south_pole_points", "EPSG:4326", "EPSG:3031", "%.6f", latlon, xy));
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const auto [x, y] = xy[i];
    ASSERT_LT(std::max(std::abs(x), std::abs(y)), kHalf) << x << " " << y;
    pts[i].dem = pts[i].expected = height(x, y);
  }
  expect_cesium_heights(dir, pts, "south_pole", "-180,-90,180,-89 --pitch -90", deepest,
                        max_error.back() + 0.05, "Cesium heights around the South Pole against the DEM");
}

// A UTM DEM (zone 19N, 90 m samples, every cell valid, heights above the ellipsoid): CesiumJS
// draws its outermost samples within the deepest level's bound plus the two bilinear
// resamplings of its smooth surface, as it draws those inside. Before, the export's grid ended
// at the footprint's cell edge, and the outermost samples stood in the cliff down to the
// ellipsoid (up to 286 m off in CesiumJS on a UTM crop of N44W072).
TEST(CesiumClient, SamplesTheOutermostSamplesOfAUtmDem) {
  ASSERT_NO_FATAL_FAILURE(require_tools());
  constexpr int kW = 100, kH = 120;
  constexpr double kCell = 90.0, kX0 = 440000.0, kY0 = 4880000.0;  // north-west corner
  const auto height = [](double x, double y) {
    return 600.0 + 250.0 * std::sin((x - kX0) / 1200.0 + 0.3) * std::cos((y - kY0) / 900.0 - 0.2) +
           0.05 * (x - kX0);
  };
  const auto x_of = [](int col) { return kX0 + (col + 0.5) * kCell; };
  const auto y_of = [](int row) { return kY0 - (row + 0.5) * kCell; };
  const fs::path asc = tmp_dir() / "utm.asc", db = tmp_dir() / "utm.db", dir = tmp_dir() / "utm_tiles";
  {
    std::ofstream f(asc);
    f << "ncols " << kW << "\nnrows " << kH << "\nxllcorner " << fixed(kX0, 1) << "\nyllcorner "
      << fixed(kY0 - kH * kCell, 1) << "\ncellsize " << kCell << "\n";
    for (int row = 0; row < kH; ++row) {
      for (int col = 0; col < kW; ++col) f << (col ? " " : "") << fixed(height(x_of(col), y_of(row)), 4);
      f << "\n";
    }
    std::ofstream(fs::path(asc).replace_extension(".prj"))
        << "PROJCS[\"WGS_1984_UTM_Zone_19N\",GEOGCS[\"GCS_WGS_1984\",DATUM[\"D_WGS_1984\",SPHEROID["
           "\"WGS_1984\",6378137.0,298.257223563]],PRIMEM[\"Greenwich\",0.0],UNIT[\"Degree\","
           "0.0174532925199433]],PROJECTION[\"Transverse_Mercator\"],PARAMETER[\"False_Easting\",500000.0],"
           "PARAMETER[\"False_Northing\",0.0],PARAMETER[\"Central_Meridian\",-69.0],PARAMETER["
           "\"Scale_Factor\",0.9996],PARAMETER[\"Latitude_Of_Origin\",0.0],UNIT[\"Meter\",1.0]]\n";
  }
  std::vector<double> max_error;
  ASSERT_NO_FATAL_FAILURE(build_and_export(asc, db, dir, max_error));
  const int deepest = int(max_error.size()) - 1;

  // Every 3rd sample of the outermost ring, corners included, and a few inside.
  std::vector<Point> pts;
  std::vector<std::array<double, 2>> xy, latlon;
  for (int row = 0; row < kH; ++row)
    for (int col = 0; col < kW; ++col) {
      const bool edge = row == 0 || col == 0 || row == kH - 1 || col == kW - 1;
      const bool corner = (row == 0 || row == kH - 1) && (col == 0 || col == kW - 1);
      if (!corner && !(edge && (row + col) % 3 == 0) && !(row % 29 == 7 && col % 23 == 5)) continue;
      Point p;
      p.col = col, p.row = row;
      p.dem = p.expected = height(x_of(col), y_of(row));
      pts.push_back(p);
      xy.push_back({x_of(col), y_of(row)});
    }
  ASSERT_NO_FATAL_FAILURE(cs2cs("utm_points", "EPSG:32619", "EPSG:4326", "%.9f", xy, latlon));
  double west = 180, east = -180, south = 90, north = -90;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    Point& p = pts[i];
    p.lat = latlon[i][0], p.lon = latlon[i][1];
    west = std::min(west, p.lon), east = std::max(east, p.lon), south = std::min(south, p.lat),
    north = std::max(north, p.lat);
  }
  const std::string view =
      fixed(west, 6) + "," + fixed(south, 6) + "," + fixed(east, 6) + "," + fixed(north, 6) + " --pitch -90";
  // The deepest level's bound and the two bilinear resamplings of this surface (2 m: measured
  // 1.1 m at the outermost samples, 2.2 m inside, in test_terrain_export's twin).
  expect_cesium_heights(dir, pts, "utm", view, deepest, max_error.back() + 2.0,
                        "Cesium heights at a UTM DEM's outermost samples against the DEM");
}

// The checker must see the tiles: the same tileset with one deepest-level tile replaced by
// garbage (still gzip, so the server sends it) must fail with a message naming the problem.
TEST(CesiumClient, ReportsABrokenTile) {
  ASSERT_NO_FATAL_FAILURE(require_tools());
  if (dem().h.empty()) GTEST_SKIP() << "N44W072.hgt not in " << TERRALOD_DATA_DIR;
  const Tileset& ts = tileset();
  ASSERT_FALSE(ts.dir.empty());
  const fs::path broken = tmp_dir() / "broken_tiles";
  fs::remove_all(broken);
  fs::copy(ts.dir, broken, fs::copy_options::recursive);
  const auto max_error = layer_max_error(ts.layer);
  ASSERT_TRUE(max_error && !max_error->empty());
  // The deepest tile under Mount Washington (crop sample 128, 128): level z has 2^z x-tiles per
  // 180 degrees, y from the south pole.
  const int z = int(max_error->size()) - 1;
  const double size = 180.0 / std::ldexp(1.0, z);
  const int x = int(std::floor((lon_of(128) + 180.0) / size)),
            y = int(std::floor((lat_of(128) + 90.0) / size));
  const fs::path tile = broken / std::to_string(z) / std::to_string(x) / (std::to_string(y) + ".terrain");
  ASSERT_TRUE(fs::exists(tile)) << tile;
  const fs::path garbage = tmp_dir() / "garbage";
  std::ofstream(garbage) << "this is not a quantized-mesh tile\n";
  const auto g = run_command("gzip -c " + quote(garbage.string()) + " > " + quote(tile.string()));
  ASSERT_EQ(g.status, 0) << g.err;
  const fs::path points = tmp_dir() / "one_point.json";
  std::ofstream(points) << "[{\"lon\": " << fixed(lon_of(128)) << ", \"lat\": " << fixed(lat_of(128))
                        << "}]\n";
  const Check c = check_terrain(broken, points, tmp_dir() / "broken_result.json", {});
  std::printf("%s", c.run.err.c_str());
  EXPECT_EQ(c.run.status, 1) << c.run.err;
  EXPECT_NE(c.run.err.find("FAILED"), std::string::npos) << c.run.err;
  EXPECT_FALSE(is_true(c.json, "ok")) << c.json;
}

}  // namespace
