// terralod testdem: large test terrains written to disk strip by strip (blocks/dem_writer.hpp).
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <string>

#include "commands.hpp"
#include "terralod/blocks/dem_writer.hpp"

namespace terralod::cli {

CommandSpec testdem_spec() {
  CommandSpec s;
  s.name = "testdem";
  s.summary = "Write a large test terrain: a fractal DEM of any size, or a mirror mosaic of a DEM.";
  s.description =
      "--fractal WxH --out FILE.tif: a fractal terrain of W x H samples (value-noise fBm, 30 m\n"
      "spacing, --relief metres of relief, heights in 1/16 m), computed strip by strip on every core\n"
      "and written as a tiled, deflated Float32 GeoTIFF (BigTIFF when needed) with no CRS, so that\n"
      "'terralod build --input FILE.tif' reads it as metres. Memory: 256 rows per thread plus GDAL's\n"
      "own, whatever the size.\n"
      "--mirror DEM --tiles CxR --out DIR: C x R copies of DEM, mirrored left-right in odd columns\n"
      "and top-bottom in odd rows, so that every tile border is continuous (neighbours share their\n"
      "edge samples, voids included), placed side by side in the DEM's own CRS (an .hgt's 1 x 1\n"
      "degree tile becomes C x R degrees of longitude and latitude): DIR/tile_<row>_<col>.tif and\n"
      "DIR/mosaic.vrt over them. Memory: the DEM and one tile.\n"
      "Each file is written to a temporary and renamed, so a killed run leaves no half-written file\n"
      "under its final name.";
  s.options = {
      {"--fractal", "WxH", "write a fractal terrain of W x H samples (2..1048576 each)"},
      {"--mirror", "DEM", "write the mirror mosaic of this DEM (any file 'terralod build' reads)"},
      {"--tiles", "CxR", "with --mirror: tiles across and down (default 2x2, 1..256 each)"},
      {"--seed", "S", "with --fractal: terrain seed (default 1)"},
      {"--relief", "M",
       "with --fractal: metres between the lowest and highest possible height (default 1200)"},
      {"--threads", "N", "with --fractal: worker threads (default: every core)"},
      {"--out", "PATH", "--fractal: the GeoTIFF to write; --mirror: the folder to write", true},
  };
  return s;
}

int cmd_testdem(const Args& a) {
  if (a.has("--fractal") == a.has("--mirror"))
    throw UsageError("give exactly one of --fractal WxH or --mirror DEM");
  const std::string out = a.get("--out");
  const auto t = std::chrono::steady_clock::now();
  ProgressBar bar("testdem");
  auto progress = [&bar](double f) { bar.update(f); };
  if (a.has("--fractal")) {
    if (a.has("--tiles")) throw UsageError("--tiles goes with --mirror");
    const auto [w, h] = a.get_size("--fractal", {0, 0}, 2, 1 << 20);
    pm::FractalField::Options o;
    o.width = w, o.height = h;
    o.seed = std::uint64_t(a.get_int("--seed", 1, 0, std::numeric_limits<long long>::max()));
    o.relief = a.get_double("--relief", 1200.0);
    if (!(o.relief >= 0 && o.relief <= 1e5))
      throw UsageError("option '--relief' needs metres in [0, 100000]");
    const pm::FractalField field(o);
    blocks::write_fractal_dem(field, out, int(a.get_int("--threads", 0, 1, 1024)), progress);
    bar.finish();
    std::error_code ec;
    std::printf(
        "testdem %s: fractal %lld x %lld samples (%.3g), seed %llu, %d octaves, %.0f m spacing, %s, %s\n",
        out.c_str(), w, h, double(w) * double(h), static_cast<unsigned long long>(o.seed), field.octaves(),
        o.spacing, format_bytes(std::filesystem::file_size(out, ec)).c_str(),
        format_duration(ms_since(t)).c_str());
    return 0;
  }
  for (const char* opt : {"--seed", "--relief", "--threads"})
    if (a.has(opt)) throw UsageError(std::string(opt) + " goes with --fractal");
  const auto [cols, rows] = a.get_size("--tiles", {2, 2}, 1, 256);
  const blocks::MosaicReport r =
      blocks::write_mirror_mosaic(a.get("--mirror"), int(cols), int(rows), out, progress);
  bar.finish();
  std::printf("testdem %s: mirror mosaic of %s, %lld x %lld tiles, %lld x %lld samples (%.3g), %s\n",
              r.vrt.c_str(), a.get("--mirror").c_str(), cols, rows, static_cast<long long>(r.width),
              static_cast<long long>(r.height), double(r.width) * double(r.height),
              format_duration(ms_since(t)).c_str());
  return 0;
}

}  // namespace terralod::cli
