// terralod extract: the mesh within a given L-infinity error of a .pm file, a DEM or a block
// database, written as PLY, OBJ or glTF (a hybrid database's grid level: cmd_hybrid.cpp).
#include <chrono>
#include <string>

#include "commands.hpp"
#include "dem_options.hpp"
#include "terrain_input.hpp"
#include "terralod/blocks/database_extract.hpp"

namespace terralod::cli {

CommandSpec extract_spec() {
  CommandSpec s;
  s.name = "extract";
  s.summary = "Extract the mesh within a given L-infinity error from a .pm file, a DEM or a block database.";
  s.description =
      std::string(
          "The mesh's error against the full-resolution surface is at most --max-error (the 'bound'\n"
          "printed is the guaranteed error actually reached). A DEM input is built into a progressive\n"
          "mesh in memory first (--metric, --threads and the DEM options apply to it).\n"
          "Output by extension: .ply (binary little-endian, double x y z), .obj (text), .glb (binary\n"
          "glTF 2.0) or .gltf (glTF JSON, buffer inline as base64). glTF is Y-up: (x, y, z) is stored\n"
          "as (x, z, -y), float positions relative to the mesh's centre, which is the node's translation;\n"
          "with area-weighted vertex normals.\n"
          "Units: samples = x column, y row (row 0 = the file's first row), z metres;\n"
          "       world   = x east, y north in metres from the DEM's transform (see 'terralod info'),\n"
          "                 z metres; faces counter-clockwise seen from above.\n\n") +
      kDemFormats;
  s.description +=
      "\n\nWith --db DB (a block database from 'terralod build') instead of --input, the blocks are\n"
      "extracted, their seams stitched (neighbours' border vertices inserted) and blocks whose\n"
      "stitched triangles exceed E re-extracted at E/2; the printed bound is measured exactly.";
  s.options = concat(
      concat({{"--input", "FILE", "a .pm file (from 'terralod pm') or a DEM (or use --db)"},
              {"--db", "DB", "a block database (from 'terralod build') instead of --input"},
              {"--max-error", "E",
               "largest L-infinity error allowed, metres (finite, >= 0); required except with --grid-level"},
              {"--grid-level", "L",
               "with --db of a hybrid database ('terralod hybrid'): its grid level L (0 = finest)"},
              {"--scheme", "S", "with --grid-level: triangles (default) or subcells (the paper's section 5)"},
              {"--out", "MESH", "mesh file to write: .ply, .obj, .glb or .gltf", true},
              {"--units", "UNITS", "vertex coordinates: world (default) or samples"}},
             build_option_specs()),
      dem_option_specs());
  return s;
}

int cmd_extract(const Args& a) {
  using Clock = std::chrono::steady_clock;
  const std::string input = a.get("--input"), out = a.get("--out");
  check_mesh_output("--out", out);
  if (a.has("--grid-level")) return cmd_extract_hybrid(a);  // hybrid database (cmd_hybrid.cpp)
  if (!a.has("--max-error")) throw UsageError("missing option '--max-error'");
  const double max_error = a.get_double("--max-error", 0.0);
  if (max_error < 0.0)
    throw UsageError("option '--max-error' must be >= 0, not '" + a.get("--max-error") + "'");
  const pm::Units units = a.get_choice("--units", {"world", "samples"}, "world") == "samples"
                              ? pm::Units::Samples
                              : pm::Units::World;
  if (a.has("--db") == a.has("--input")) throw UsageError("give exactly one of '--input' and '--db'");
  if (a.has("--db")) {
    check_output_folder(out);
    const auto t = Clock::now();
    const blocks::ExtractedMesh m = blocks::extract_mesh(a.get("--db"), max_error);
    print_line(strf(
        "extract %s E=%g m: %zu blocks (%zu re-extracted for seams, %zu rounds), %zu triangles, %zu "
        "vertices, "
        "%zu seam vertices inserted, measured error %g m, %s",
        a.get("--db").c_str(), max_error, m.blocks, m.blocks_refined, m.iterations, m.mesh.triangles.size(),
        m.mesh.vertices.size(), m.inserted_vertices, m.measured_error, format_duration(ms_since(t)).c_str()));
    write_mesh_stage(m.mesh, m.heightfield, out, units);
    return 0;
  }
  const blocks::DemOptions dem = dem_options_from(a);
  const pm::BuildOptions build = build_options_from(a);
  check_output_folder(out);

  const pm::ProgressiveMesh mesh = pm_input_stage(input, dem, build);

  const auto t = Clock::now();
  const pm::TriangleMesh m = mesh.extract(max_error);
  const double ms = ms_since(t);
  print_line(strf("extract E=%g m: %zu triangles, %zu vertices, bound %g m, %s", max_error,
                  m.triangles.size(), m.vertices.size(), m.error_bound, format_duration(ms).c_str()));
  write_mesh_stage(m, mesh.heightfield(), out, units);
  return 0;
}

}  // namespace terralod::cli
