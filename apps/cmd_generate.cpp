// terralod generate: writes the built-in generated terrain, of any size, as a GeoTIFF DEM.
#include <chrono>
#include <filesystem>
#include <string>

#include "commands.hpp"
#include "terrain_input.hpp"
#include "terralod/blocks/dem_writer.hpp"

namespace terralod::cli {

CommandSpec generate_spec() {
  CommandSpec s;
  s.name = "generate";
  s.summary = "Write the built-in generated terrain of any size as a GeoTIFF DEM.";
  s.description =
      "Generates the fractal terrain of 'terralod demo' and 'terralod-fly' (30 m spacing, about\n"
      "1200 m of relief, heights in 1/16 m) with --size x --size samples and writes it as a\n"
      "single-band Float32 GeoTIFF (tiled, deflate) with the sample spacing in its geotransform\n"
      "and no CRS, so that 'terralod build --input FILE.tif' reads it back as metres, exactly. For\n"
      "terrains larger than the examples, e.g. the runtime benchmark's 4097 x 4097 (123 km).";
  s.options = {{"--size", "N", "samples per side (2..8193)", true},
               {"--seed", "S", "terrain seed (default 1)"},
               {"--out", "FILE.tif", "output GeoTIFF (written to a temporary, then renamed)", true}};
  return s;
}

int cmd_generate(const Args& a) {
  const pm::Heightfield hf = generate_stage(a);
  const auto t = std::chrono::steady_clock::now();
  const std::string out = a.get("--out");
  blocks::write_geotiff(hf, out);
  std::error_code ec;
  print_line(strf("write %s: %s in %s", out.c_str(),
                  format_bytes(std::filesystem::file_size(out, ec)).c_str(),
                  format_duration(ms_since(t)).c_str()));
  return 0;
}

}  // namespace terralod::cli
