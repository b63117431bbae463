// terralod demo: builds the progressive mesh of the built-in generated terrain and prints its
// levels of detail, the build and the size of the encoded .pm.
#include <algorithm>
#include <chrono>
#include <string>

#include "commands.hpp"
#include "terrain_input.hpp"
#include "terralod/pm/pm_io.hpp"

namespace terralod::cli {

CommandSpec demo_spec() {
  CommandSpec s;
  s.name = "demo";
  s.summary = "Build the progressive mesh of a generated terrain and print its levels of detail.";
  s.description =
      "Generates a fractal terrain (30 m spacing, about 1200 m of relief, heights not rounded), builds\n"
      "its progressive mesh and extracts it at E = 0, 0.5, 1, 2, 5, 10, 20 and 50 m: one line per\n"
      "level with the triangles kept and the guaranteed error bound, then the build time and the\n"
      "size of the encoded .pm.";
  s.options = {{"--size", "N", "samples per side of the terrain (default 513, 2..8193)"},
               {"--seed", "S", "terrain seed (default 1)"},
               {"--threads", "N", "worker threads for the build, 0 = all cores (default 0)"}};
  return s;
}

int cmd_demo(const Args& a) {
  using Clock = std::chrono::steady_clock;
  pm::BuildOptions bopt;
  bopt.threads = int(a.get_int("--threads", 0, 0, 1024));
  const pm::Heightfield hf = generate_stage(a);

  double build_ms = 0.0;
  const pm::ProgressiveMesh mesh = build_with_progress(hf, bopt, build_ms);

  const std::size_t full = mesh.extract_after(0).triangles.size();
  for (const double e : {0.0, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0}) {
    const auto t = Clock::now();
    const pm::TriangleMesh m = mesh.extract(e);
    const double ms = ms_since(t);
    print_line(strf("E=%g m: %zu triangles (%.1f%% of full), bound %g m, extract %s", e, m.triangles.size(),
                    100.0 * double(m.triangles.size()) / double(std::max<std::size_t>(1, full)),
                    m.error_bound, format_duration(ms).c_str()));
  }
  print_line(build_line(mesh, build_ms));
  const auto t = Clock::now();
  const std::size_t bytes = pm::encode_pm(mesh).size();
  print_line(strf("encode %s, %.2f bytes/vertex, %s", format_bytes(bytes).c_str(),
                  double(bytes) / double(std::max<std::size_t>(1, mesh.full_vertex_count())),
                  format_duration(ms_since(t)).c_str()));
  return 0;
}

}  // namespace terralod::cli
