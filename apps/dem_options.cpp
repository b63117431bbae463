// The DEM and build option groups of the terralod commands (see dem_options.hpp).
#include "dem_options.hpp"

#include <string>

namespace terralod::cli {

const char* const kDemFormats =
    "DEM formats: SRTM .hgt, Esri ASCII grid .asc, PNG/TIFF heightmaps, any single-band raster\n"
    "GDAL reads. Geographic DEMs are mapped to a local metric frame (x east, y north, metres).";

std::vector<OptionSpec> dem_option_specs() {
  return {
      {"--keep-voids", "", "keep DEM voids as holes instead of filling them"},
      {"--vertical-scale", "S", "heightmaps: metres per raw unit (default 1)"},
      {"--spacing", "M", "heightmaps and rasters without georeferencing: metres between samples (default 1)"},
  };
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
  if (o.vertical_scale == 0.0) throw UsageError("option '--vertical-scale' must not be 0");
  if (o.heightmap_spacing <= 0.0) throw UsageError("option '--spacing' must be > 0");
  return o;
}

pm::BuildOptions build_options_from(const Args& a) {
  pm::BuildOptions o;
  o.metric = metric_from(a);
  o.threads = int(a.get_int("--threads", 0, 0, 1024));
  return o;
}

}  // namespace terralod::cli
