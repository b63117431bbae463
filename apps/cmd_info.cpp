// terralod info: describes a .pm file, a block database or a DEM as JSON on stdout (a hybrid
// database: cmd_hybrid.cpp).
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>

#include "commands.hpp"
#include "dem_options.hpp"
#include "terrain_input.hpp"
#include "terralod/blocks/block_database.hpp"
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
          "Fields: file, kind (pm|dem), grid {width, height}, transform {x0, xc, xr, y0, yc, yr, formula}\n"
          "(sample (col,row) -> world (x,y) metres), spacing {x, y} metres, frame (how the world frame\n"
          "was made; it ends with its scale error when the DEM has a CRS), scale_error (that worst\n"
          "relative error of distances in the frame, null without a CRS), crs_wkt, vertical_datum (of\n"
          "the heights, as the source states it; \"\" when it does not),\n"
          "height {min, max} metres, voids {found, filled}; for a .pm also metric, vertices,\n"
          "base_vertices, vsplits, max_error, error_quantum (metres), bytes, bytes_per_vertex.\n"
          "A block database (.db, kind blocks) prints its build summary, with frame {description,\n"
          "scale_error, vertical_datum}: the world frame it was built in (as for its DEM under the\n"
          "build's --crs), or \"not recorded (...)\" for databases built before frames were recorded.\n\n") +
      kDemFormats;
  s.options = dem_option_specs();
  return s;
}

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
  pm::Heightfield dem_hf;
  if (is_pm)
    mesh = pm::read_pm(file);
  else
    dem_hf = blocks::read_dem(file, dem);
  const pm::Heightfield& hf = is_pm ? mesh->heightfield() : dem_hf;
  const pm::GridTransform& t = hf.transform;
  const auto [hmin, hmax] = height_range(hf);

  JsonWriter j;
  j.begin_object();
  j.field("file", file);
  j.field("kind", is_pm ? "pm" : "dem");
  j.begin_object("grid");
  j.field("width", hf.width());
  j.field("height", hf.height());
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
  j.field("frame", hf.frame);
  j.field("scale_error", blocks::frame_scale_error(hf).value_or(std::numeric_limits<double>::quiet_NaN()));
  j.field("crs_wkt", hf.crs_wkt);
  j.field("vertical_datum", hf.vertical_datum);
  j.begin_object("height");
  j.field("min", hmin);
  j.field("max", hmax);
  j.end_object();
  j.begin_object("voids");
  j.field("found", std::uint64_t(hf.voids.voids));
  j.field("filled", std::uint64_t(hf.voids.filled));
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
