// terralod tin: a greedy-insertion TIN of a DEM's samples inside a polygon (a TIN microstructure
// for the hybrid terrain), written as a PLY/OBJ mesh.
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "commands.hpp"
#include "dem_options.hpp"
#include "terrain_input.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/greedy_tin.hpp"
#include "terralod/pm/mesh_io.hpp"
#include "terralod/pm/text.hpp"

namespace terralod::cli {
namespace {

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n"), e = s.find_last_not_of(" \t\r\n");
  return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
}

/// Reads AREA.csv: a header "x,y" then one "x,y" vertex per line (world metres); blank lines and
/// lines starting with '#' are skipped. Errors name the file and the line.
std::vector<std::array<double, 2>> read_polygon_csv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open the polygon file");
  std::vector<std::array<double, 2>> out;
  std::string text;
  bool header = false;
  for (int line_no = 1; std::getline(in, text); ++line_no) {
    const std::string l = trim(line_no == 1 ? std::string(pm::without_utf8_bom(text)) : text);
    if (l.empty() || l[0] == '#') continue;
    const auto comma = l.find(',');
    const std::string a = comma == std::string::npos ? l : trim(l.substr(0, comma));
    const std::string b = comma == std::string::npos ? std::string() : trim(l.substr(comma + 1));
    if (!header) {
      std::string h = a + "," + b;
      std::transform(h.begin(), h.end(), h.begin(), [](unsigned char c) { return char(std::tolower(c)); });
      if (h != "x,y")
        throw std::runtime_error(path + ": line " + std::to_string(line_no) +
                                 ": expected the header 'x,y', got '" + l + "'");
      header = true;
      continue;
    }
    double v[2];
    const std::string parts[2] = {a, b};
    for (int k = 0; k < 2; ++k) {
      std::size_t used = 0;
      bool ok = !parts[k].empty();
      if (ok) try {
          v[k] = std::stod(parts[k], &used);
        } catch (const std::exception&) {
          ok = false;
        }
      if (!ok || used != parts[k].size() || !std::isfinite(v[k]))
        throw std::runtime_error(path + ": line " + std::to_string(line_no) +
                                 ": expected two numbers 'x,y', got '" + l + "'");
    }
    out.push_back({v[0], v[1]});
  }
  if (!header)
    throw std::runtime_error(path + ": empty polygon file (expected the header 'x,y' and vertices)");
  if (out.size() < 3)
    throw std::runtime_error(path + ": a polygon needs at least 3 vertices, the file has " +
                             std::to_string(out.size()));
  return out;
}

}  // namespace

CommandSpec tin_spec() {
  CommandSpec s;
  s.name = "tin";
  s.summary = "Greedy-insertion TIN of a DEM's samples inside a polygon, written as a mesh.";
  s.description =
      "Triangulates the DEM samples inside or on the polygon by greedy insertion (Garland &\n"
      "Heckbert): the polygon's vertices (rounded to the nearest samples) are triangulated with the\n"
      "polygon's edges kept as the boundary, then the sample of largest vertical error is inserted\n"
      "(constrained Delaunay) until the exact L-infinity error is <= --max-error or --max-points are\n"
      "used. The printed error is measured exactly over the polygon: at the samples, and with the\n"
      "continuous metric also where triangle edges cross the grid's edges (boundary crossings can\n"
      "only shrink with samples on the boundary, so that error may stay above E; it is reported).\n"
      "AREA.csv: a header line 'x,y', then one vertex per line in world coordinates (metres, the\n"
      "DEM's frame as 'terralod info' prints it), the polygon closed implicitly, simple, either\n"
      "orientation. Output by extension: .ply, .obj, .glb or .gltf; units world (default: x east, y north,\n"
      "metres, faces counter-clockwise seen from above) or samples (x column, y row).";
  s.options = {
      {"--input", "DEM", "elevation file (SRTM .hgt, .asc, GeoTIFF, PNG heightmap, ...)", true},
      {"--polygon", "AREA.csv", "polygon in world coordinates: header 'x,y', one vertex per line", true},
      {"--max-error", "E", "largest L-infinity error allowed, metres (finite, >= 0)", true},
      {"--out", "MESH", "mesh file to write: .ply, .obj, .glb or .gltf", true},
      {"--max-points", "N", "at most N points (>= the polygon's vertex count; default: no limit)"},
      {"--units", "UNITS", "vertex coordinates: world (default) or samples"},
      {"--metric", "NAME", "error metric: continuous (true L-infinity, default) or samples"},
      {"--keep-voids", "", "keep DEM voids as holes instead of filling them (holes are never inserted)"},
  };
  s.options = with_dem_options(std::move(s.options));
  return s;
}

int cmd_tin(const Args& a) {
  using Clock = std::chrono::steady_clock;
  const std::string input = a.get("--input"), poly_path = a.get("--polygon"), out = a.get("--out");
  const double max_error = a.get_double("--max-error", 0.0);
  if (max_error < 0.0)
    throw UsageError("option '--max-error' must be >= 0, not '" + a.get("--max-error") + "'");
  check_mesh_output("--out", out);
  const pm::Units units = a.get_choice("--units", {"world", "samples"}, "world") == "samples"
                              ? pm::Units::Samples
                              : pm::Units::World;
  blocks::TinOptions opt;
  opt.max_error = max_error;
  opt.metric = metric_from(a);
  if (a.has("--max-points")) opt.max_points = std::size_t(a.get_int("--max-points", 0, 3, 1LL << 40));
  check_output_folder(out);

  const std::vector<std::array<double, 2>> world = read_polygon_csv(poly_path);
  if (opt.max_points < world.size())
    throw UsageError("option '--max-points' (" + a.get("--max-points") + ") is below the polygon's " +
                     std::to_string(world.size()) + " vertices");

  auto t = Clock::now();
  const blocks::DemOptions dem = dem_options_from(a);
  const pm::Heightfield hf = blocks::read_dem(input, dem);
  print_line(strf("read  %s: %d x %d samples, %s", input.c_str(), hf.width(), hf.height(),
                  format_duration(ms_since(t)).c_str()));

  // World -> (col,row): the inverse of the heightfield's affine GridTransform.
  const pm::GridTransform& g = hf.transform;
  const double det = g.determinant();
  if (det == 0.0 || !std::isfinite(det))
    throw std::runtime_error(input + ": the grid transform is not invertible");
  std::vector<std::array<double, 2>> grid;
  for (const auto& p : world) {
    const double dx = p[0] - g.x0, dy = p[1] - g.y0;
    grid.push_back({(g.yr * dx - g.xr * dy) / det, (-g.yc * dx + g.xc * dy) / det});
  }

  blocks::TinSurface tin;
  t = Clock::now();
  {
    ProgressBar bar("tin");
    opt.progress = [&bar](double f) { bar.update(f); };
    try {
      tin = blocks::build_greedy_tin(hf, grid, opt);
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(poly_path + ": " + e.what() + " (in " + input + "'s sample grid)");
    }
  }
  const double ms = ms_since(t);
  std::string note;
  if (tin.error > max_error && tin.points.size() >= opt.max_points)
    note = strf(" (> E: --max-points %zu reached)", opt.max_points);
  else if (tin.error > max_error)
    note = strf(
        " (> E on the polygon's boundary: its slanted edges cross grid edges, which no inner sample can "
        "fix; use --metric samples for the error at the samples)");
  print_line(
      strf("tin   %s: %zu polygon vertices, %zu points, %zu triangles, error %.6g m%s, metric %s, %.0f ms",
           poly_path.c_str(), world.size(), tin.points.size(), tin.triangles.size(), tin.error, note.c_str(),
           opt.metric == pm::ErrorMetric::Samples ? "samples" : "continuous", ms));

  pm::TriangleMesh mesh;
  mesh.vertices.reserve(tin.points.size());
  for (const auto& p : tin.points)
    mesh.vertices.push_back(std::uint32_t(std::size_t(p[1]) * hf.width() + p[0]));
  mesh.triangles = tin.triangles;
  mesh.error_bound = tin.error;
  t = Clock::now();
  pm::write_mesh(mesh, hf, out, units);
  print_line(strf("write %s: %zu vertices, %zu triangles, %s units, %s", out.c_str(), mesh.vertices.size(),
                  mesh.triangles.size(), units == pm::Units::World ? "world" : "samples",
                  format_duration(ms_since(t)).c_str()));
  return 0;
}

}  // namespace terralod::cli
