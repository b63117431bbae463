// The DEM and build option groups of the terralod commands (see dem_options.hpp).
#include "dem_options.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <optional>
#include <string>

namespace terralod::cli {

const char* const kDemFormats =
    "DEM formats: SRTM .hgt, Esri ASCII grid .asc, heightmap images without georeference (PNG,\n"
    "TIFF, PGM, OpenEXR or any image OpenImageIO reads), any raster GDAL reads (one band, or the\n"
    "one --band names; an alpha band besides marks voids).\n"
    "Geographic DEMs are warped to a metric frame (x east, y north, metres): --crs auto (the\n"
    "default) picks an azimuthal equidistant projection centred on the DEM, scaled so that distances\n"
    "are true to within 0.1 % up to about 9 x 9 degrees; beyond, the azimuthal, transverse Mercator,\n"
    "Lambert conformal conic, Mercator or oblique Mercator projection whose scale is truest over the\n"
    "DEM's data (a strip about 7 degrees wide stays within 0.1 % however long, in any direction; a\n"
    "continent cannot: the frame states its scale error; 'terralod info DEM' prints it; a DEM far\n"
    "past a hemisphere keeps its own grid); --crs native keeps the local equirectangular frame of\n"
    "earlier versions (their databases resume with it); --crs EPSG:32619 (any projected CRS GDAL\n"
    "knows) warps to that CRS. Projected DEMs stay in their own CRS unless --crs names another.\n"
    "Voids (nodata, mask, alpha 0, NaN, heights beyond 10,000 km such as an undeclared -3.4e38 fill)\n"
    "are filled from their surroundings unless --keep-voids (regions within 4096 x 4096 samples;\n"
    "wider ones stay holes); a region of 2^20 samples or more takes a second or so, told on stderr\n"
    "as 'voids filling a region of N samples (input cols C0-C1, rows R0-R1)...' and '... filled'.";

std::vector<OptionSpec> dem_option_specs() {
  return {
      {"--keep-voids", "", "keep DEM voids as holes instead of filling them"},
      crs_option_spec(),
      {"--vertical-scale", "S",
       "heightmap images only (other files are refused): metres per raw unit (default 1)"},
      {"--spacing", "M", "heightmaps and rasters without georeferencing: metres between samples (default 1)"},
      {"--band", "N",
       "rasters of several bands: the band that holds the heights, 1-based (a last alpha band marks "
       "voids; default: the only band)"},
  };
}

std::vector<OptionSpec> with_dem_options(std::vector<OptionSpec> options) {
  for (OptionSpec& o : dem_option_specs())
    if (std::none_of(options.begin(), options.end(), [&](const OptionSpec& x) { return x.name == o.name; }))
      options.push_back(std::move(o));
  return options;
}

OptionSpec crs_option_spec() {
  return {"--crs", "CRS",
          "world frame: auto (default; geographic DEMs to a balanced azimuthal equidistant projection, or to "
          "the truest of five kinds of projection over its data beyond about 9 x 9 degrees; a DEM far "
          "past a hemisphere keeps its own grid), "
          "native (the source's own frame) or a projected CRS, e.g. EPSG:32619"};
}

std::string crs_from(const Args& a) {
  const std::string crs = a.get("--crs", "auto");
  if (crs.empty()) throw UsageError("option '--crs' needs a value: auto, native or a projected CRS");
  return crs;
}

void warn_about_frame(const blocks::DemGrid& g) {
  const std::optional<double>& e = g.scale_error;
  if (!e || *e <= 0.001) return;
  std::fprintf(
      stderr,
      "warning: %s: distances in the world frame are off by up to %.3f %% (over 0.1 %%); --crs auto "
      "takes the truest of five kinds of projection, and an extent wider than about 7 degrees both ways "
      "is beyond any flat frame; a CRS named with --crs may suit its shape better. Every view "
      "(terralod fly, terralod-fly, terralod view) corrects it about the camera: what it shows is in "
      "ground metres there\n",
      g.source.c_str(), *e * 100.0);
}

std::vector<OptionSpec> build_option_specs() {
  return {
      {"--metric", "NAME",
       "error metric: continuous (true L-infinity, default) or samples (at the samples only)"},
      {"--threads", "N", "worker threads for the build, 0 = all cores (default 0)"},
  };
}

pm::ErrorMetric metric_from(const Args& a) {
  return a.get_choice("--metric", {"continuous", "samples"}, "continuous") == "samples"
             ? pm::ErrorMetric::Samples
             : pm::ErrorMetric::Continuous;
}

blocks::DemOptions dem_options_from(const Args& a) {
  blocks::DemOptions o;
  o.fill_voids = !a.has("--keep-voids");
  o.vertical_scale = a.get_double("--vertical-scale", o.vertical_scale);
  o.heightmap_spacing = a.get_double("--spacing", o.heightmap_spacing);
  o.crs = crs_from(a);
  o.band = int(a.get_int("--band", 0, 1, 1 << 20));
  tell_void_fills(o);
  if (o.vertical_scale == 0.0) throw UsageError("option '--vertical-scale' must not be 0");
  if (o.heightmap_spacing <= 0.0) throw UsageError("option '--spacing' must be > 0");
  return o;
}

void tell_void_fills(blocks::DemOptions& dem) {
  dem.on_large_void = [](const blocks::VoidSolveNotice& n) {
    // On a terminal a progress line may be open: clear it (it is redrawn at its next update).
    const char* clear = isatty(fileno(stderr)) ? "\r\033[K" : "";
    const blocks::SampleRect& e = n.extent;
    if (n.seconds < 0)
      std::fprintf(stderr, "%svoids filling a region of %zu samples (input cols %d-%d, rows %d-%d)...\n",
                   clear, n.samples, e.col0, e.col1, e.row0, e.row1);
    else
      std::fprintf(stderr, "%svoids filled the region at input cols %d-%d, rows %d-%d in %s\n", clear, e.col0,
                   e.col1, e.row0, e.row1, format_duration(n.seconds * 1000.0).c_str());
    std::fflush(stderr);
  };
}

pm::BuildOptions build_options_from(const Args& a) {
  pm::BuildOptions o;
  o.metric = metric_from(a);
  o.threads = int(a.get_int("--threads", 0, 0, 1024));
  return o;
}

}  // namespace terralod::cli
