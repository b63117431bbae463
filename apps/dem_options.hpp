// The option groups of the terralod commands that read a DEM (build, pm, extract, info, view, tin,
// hybrid, fly): their --help rows, the DEM formats paragraph, and their parsing.
//
// Usage:
//   s.options = concat(concat({{"--input", "DEM", "elevation model to read", true}}, build_option_specs()),
//                      dem_option_specs());
//   const blocks::DemOptions dem = dem_options_from(a);  // --keep-voids, --crs, --vertical-scale, --spacing,
//                                                        // --band
//   const pm::BuildOptions build = build_options_from(a);  // --metric, --threads
//
// Contract: dem_options_from throws UsageError for --vertical-scale 0, --spacing <= 0 or an empty --crs;
// build_options_from for a --metric other than continuous or samples (metric_from, which
// 'terralod build' and 'terralod tin' share), or --threads outside 0..1024 (0 = all cores).
#pragma once

#include <string>
#include <vector>

#include "cli_common.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/dem_source.hpp"
#include "terralod/pm/progressive_mesh.hpp"

namespace terralod::cli {

/// The paragraph that closes the --help of every command reading a DEM.
extern const char* const kDemFormats;

/// --keep-voids, --crs CRS, --vertical-scale S, --spacing M, --band N.
std::vector<OptionSpec> dem_option_specs();
/// `options` with those of dem_option_specs() it does not name yet appended (a command may word
/// one of them its own way).
std::vector<OptionSpec> with_dem_options(std::vector<OptionSpec> options);
/// --crs CRS alone.
OptionSpec crs_option_spec();
/// --crs: "auto" when absent; UsageError when empty.
std::string crs_from(const Args& a);
/// Prints a warning on stderr when hf's world frame has a scale error over 0.1 %
/// (blocks::frame_scale_error): distances in it are then off by more than the README promises.
void warn_about_frame(const blocks::DemGrid& grid);
/// Sets dem.on_large_void to say on stderr when a void region of 2^20 samples or more is being
/// filled and when it is done (each takes about a second or more, during which a read is
/// otherwise silent). dem_options_from sets it; commands with their own DemOptions call it.
void tell_void_fills(blocks::DemOptions& dem);
/// --metric NAME, --threads N.
std::vector<OptionSpec> build_option_specs();

/// --metric: continuous (the default) or samples (UsageError listing them otherwise).
pm::ErrorMetric metric_from(const Args& a);
/// The DEM reading options given by dem_option_specs().
blocks::DemOptions dem_options_from(const Args& a);
/// The build options given by build_option_specs().
pm::BuildOptions build_options_from(const Args& a);

}  // namespace terralod::cli
