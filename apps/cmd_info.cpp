// terralod info: describes a .pm file, a block database or a DEM as JSON on stdout (a hybrid
// database: cmd_hybrid.cpp).
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <tuple>

#include "commands.hpp"
#include "dem_options.hpp"
#include "terrain_input.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/dem_source.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/pm_io.hpp"

namespace terralod::cli {

CommandSpec info_spec() {
  CommandSpec s;
  s.name = "info";
  s.positionals = "FILE";
  s.min_positionals = s.max_positionals = 1;
  s.summary = "Describe a .pm file, a block database (.db) or a DEM as JSON on stdout.";
  s.description =
      std::string(
          "Fields: file, kind (pm|dem), source (the DEM file, or for a folder of tiles the mosaic: its\n"
          "files and how they were joined), grid {width, height}, transform {x0, xc, xr, y0, yc, yr,\n"
          "formula} (sample (col,row) -> world (x,y) metres), spacing {x, y} metres, frame (how the world\n"
          "frame was made; it ends with its scale error when the DEM has a CRS), scale_error (that worst\n"
          "relative error of distances in the frame, null without a CRS), crs_wkt, vertical_datum (of the\n"
          "heights, as the source states it; \"\" when it does not), height {min, max} metres and voids\n"
          "{found, filled}, of the file's own samples (not of a warped frame's cells), read window by\n"
          "window as build reads them, so that a DEM larger than memory, or a folder of tiles (read as one\n"
          "mosaic), can be described; for a .pm also metric, vertices, base_vertices, vsplits, max_error,\n"
          "error_quantum (metres), bytes, bytes_per_vertex. A block database (.db, kind blocks) prints its\n"
          "build summary, with frame {description, scale_error, vertical_datum}: the world frame it was\n"
          "built in (as for its DEM under the build's --crs), or \"not recorded (...)\" for databases\n"
          "built before frames were recorded.\n\n") +
      kDemFormats;
  s.options = dem_option_specs();
  return s;
}

namespace {

struct DemStats {
  double min = std::numeric_limits<double>::infinity(), max = -std::numeric_limits<double>::infinity();
  std::uint64_t voids = 0;  ///< void samples in the file
  std::uint64_t holes = 0;  ///< of them, those left as holes (kept, or in regions too wide to fill)
};

/// Heights and voids of the DEM at `path` in its own grid (DemOptions::crs "native"): what the
/// file holds, not the cells of a warped frame outside its footprint. Read once, in bands of
/// whole rows of about 2^20 samples, voids filled as `options` says and counted as read. Progress
/// on stderr every 10 % for grids of 2^26 samples or more.
DemStats dem_stats(const std::string& path, const blocks::DemOptions& options) {
  blocks::DemOptions native = options;
  native.crs = "native";
  const std::unique_ptr<blocks::DemSource> src = blocks::open_dem_source(path, native);
  const blocks::DemGrid& g = src->grid();
  const int rows = std::max(1, (1 << 20) / g.width);
  const bool tell = g.samples() >= (std::uint64_t(1) << 26);
  int told = 0;
  DemStats s;
  for (int r0 = 0; r0 < g.height; r0 += rows) {
    const blocks::SampleRect band{0, r0, g.width - 1, std::min(g.height, r0 + rows) - 1};
    std::size_t voids = 0;
    const pm::Heightfield b = src->read_counting_voids(band, voids);
    s.voids += voids;
    for (std::size_t i = 0; i < b.size(); ++i) {
      if (!b.valid(i)) {
        ++s.holes;
        continue;
      }
      s.min = std::min(s.min, b.samples()[i]);
      s.max = std::max(s.max, b.samples()[i]);
    }
    if (const int tenths = int(std::int64_t(band.row1 + 1) * 10 / g.height); tell && tenths > told) {
      told = tenths;
      std::fprintf(stderr, "info  heights and voids read: %d %%\n", told * 10);
    }
  }
  return s;
}

}  // namespace

int cmd_info(const Args& a) {
  const std::string file = a.positionals().at(0);
  if (lower_extension(file) == ".db") {
    const blocks::BlockDatabase db = blocks::BlockDatabase::open(file);
    if (db.info().kind == "hybrid") return info_hybrid(file);  // cmd_hybrid.cpp
    std::fputs(blocks::summarize_database(db).to_json().c_str(), stdout);
    return 0;
  }
  const blocks::DemOptions dem = dem_options_from(a);
  const bool is_pm = is_pm_file(file);
  std::optional<pm::ProgressiveMesh> mesh;
  blocks::DemGrid grid;
  double hmin = 0.0, hmax = 0.0;
  std::uint64_t found = 0, filled = 0;
  if (is_pm) {
    mesh = pm::read_pm(file);
    const pm::Heightfield& hf = mesh->heightfield();
    grid = blocks::DemGrid::of(hf);
    std::tie(hmin, hmax) = height_range(hf);
    found = hf.voids.voids, filled = hf.voids.filled;
  } else {
    // Read window by window, as build reads it, so that a continent's DEM (or a folder of tiles,
    // read as one mosaic) is described without holding it: the frame when opening, then the
    // heights and voids, in the file's own grid, in bands of whole rows.
    const blocks::DemInputs inputs({file});
    const std::unique_ptr<blocks::DemSource> src = blocks::open_dem_source(inputs.path(), dem);
    src->set_source(inputs.description());
    grid = src->grid();
    const DemStats stats = dem_stats(inputs.path(), dem);
    hmin = stats.min, hmax = stats.max, found = stats.voids, filled = stats.voids - stats.holes;
  }
  const pm::GridTransform& t = grid.transform;

  JsonWriter j;
  j.begin_object();
  j.field("file", file);
  j.field("kind", is_pm ? "pm" : "dem");
  j.field("source", grid.source);
  j.begin_object("grid");
  j.field("width", grid.width);
  j.field("height", grid.height);
  j.end_object();
  j.begin_object("transform");
  j.field("x0", t.x0);
  j.field("xc", t.xc);
  j.field("xr", t.xr);
  j.field("y0", t.y0);
  j.field("yc", t.yc);
  j.field("yr", t.yr);
  j.field("formula", "x = x0 + col*xc + row*xr; y = y0 + col*yc + row*yr");
  j.end_object();
  j.begin_object("spacing");
  j.field("x", t.spacing_x());
  j.field("y", t.spacing_y());
  j.end_object();
  j.field("frame", grid.frame);
  j.field("scale_error", grid.scale_error.value_or(std::numeric_limits<double>::quiet_NaN()));
  j.field("crs_wkt", grid.crs_wkt);
  j.field("vertical_datum", grid.vertical_datum);
  j.begin_object("height");
  j.field("min", hmin);
  j.field("max", hmax);
  j.end_object();
  j.begin_object("voids");
  j.field("found", found);
  j.field("filled", filled);
  j.end_object();
  if (is_pm) {
    const std::uintmax_t bytes = std::filesystem::file_size(file);
    j.field("metric", metric_name(mesh->metric()));
    j.field("vertices", std::uint64_t(mesh->full_vertex_count()));
    j.field("base_vertices", std::uint64_t(mesh->base_vertex_count()));
    j.field("vsplits", std::uint64_t(mesh->vsplit_count()));
    j.field("max_error", mesh->max_error());
    j.field("error_quantum", mesh->error_quantum());
    j.field("bytes", std::uint64_t(bytes));
    j.field("bytes_per_vertex", double(bytes) / double(std::max<std::size_t>(1, mesh->full_vertex_count())));
  }
  j.end_object();
  std::fputs(j.str().c_str(), stdout);
  return 0;
}

}  // namespace terralod::cli
