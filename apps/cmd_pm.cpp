// terralod pm: builds the progressive mesh of a DEM and writes it to a .pm file.
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <string>

#include "commands.hpp"
#include "dem_options.hpp"
#include "terrain_input.hpp"
#include "terralod/pm/openmesh_build.hpp"
#include "terralod/pm/pm_io.hpp"

namespace terralod::cli {

CommandSpec pm_spec() {
  CommandSpec s;
  s.name = "pm";
  s.summary = "Build the progressive mesh of a DEM and write it to a .pm file.";
  s.description =
      std::string(
          "Collapses edges in order of increasing L-infinity error until nothing can collapse; the file\n"
          "holds the grid and the whole collapse sequence, so any error level can be extracted later.\n"
          "A progress bar goes to stderr, one line per stage to stdout.\n\n"
          "--decimater openmesh builds the same kind of PM through OpenMesh's own decimater framework\n"
          "(DecimaterT with the L-infinity module), for comparisons and for users of that framework.\n"
          "It is slow: OpenMesh re-measures every candidate collapse of every vertex whose ring\n"
          "changed, in full; the fast builder keeps bounds and caches. It runs on one thread\n"
          "(--threads does not apply). The build line names the decimater that ran.\n\n") +
      kDemFormats;
  s.options = concat(
      concat(concat({{"--input", "DEM", "elevation model to read", true},
                     {"--out", "FILE.pm", "progressive mesh file to write", true}},
                    build_option_specs()),
             {{"--decimater", "NAME", "fast (the PM builder, default) or openmesh (a slow reference)"}}),
      dem_option_specs());
  return s;
}

int cmd_pm(const Args& a) {
  const std::string input = a.get("--input"), out = a.get("--out");
  if (!is_pm_file(out)) throw UsageError("option '--out' must name a .pm file, not '" + out + "'");
  const blocks::DemOptions dem = dem_options_from(a);
  const pm::BuildOptions build = build_options_from(a);
  const std::string decimater = a.get_choice("--decimater", {"fast", "openmesh"}, "fast");
  check_output_folder(out);

  const pm::Heightfield hf = read_stage(input, dem);
  double build_ms = 0.0;
  const pm::ProgressiveMesh mesh = build_with_progress(
      hf, build, build_ms, decimater == "openmesh" ? &pm::build_with_decimater : &pm::ProgressiveMesh::build);
  print_line(build_line(mesh, build_ms) + ", decimater " + decimater);
  const auto t = std::chrono::steady_clock::now();
  pm::write_pm(mesh, out);
  const double ms = ms_since(t);
  const std::uintmax_t bytes = std::filesystem::file_size(out);
  print_line(strf("write %s: %s, %.2f bytes/vertex, %s", out.c_str(), format_bytes(bytes).c_str(),
                  double(bytes) / double(std::max<std::size_t>(1, mesh.full_vertex_count())),
                  format_duration(ms).c_str()));
  return 0;
}

}  // namespace terralod::cli
