// Private to terralod::blocks: the world frame of a DEM read by read_dem, as DemOptions::crs asks
// ("native", "auto" or a CRS): the warp to a projected CRS and the frame's worst scale error.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>

#include "frame_scale.hpp"
#include "terralod/blocks/dem_grid.hpp"
#include "terralod/pm/heightfield.hpp"

namespace terralod::blocks::detail {

/// `hf`, read in its native frame (dem_reader.cpp), in the frame `crs` asks for (see
/// DemOptions::crs); its hf.frame gains the frame's worst scale error when it has a CRS.
/// Throws DemError naming `path` for a CRS GDAL does not know, a geographic target CRS, a DEM
/// without a CRS to warp from, or a warp GDAL cannot do.
pm::Heightfield apply_frame(const std::string& path, pm::Heightfield hf, const std::string& crs);

/// The DEM at `path`, served by `native` in its native frame, in the frame `crs` asks for, when
/// frame_warps says that it warps; window by window when `native` is. Each target sample is the
/// bilinear interpolation of the native samples, rounded to a multiple of 1/64 m (so that blocks
/// store heights as integers), at its position in the native grid, a position
/// found by exact coordinate transformations on a lattice of every step-th sample of every
/// step-th row of the target grid, bilinear between them; the step (16, 8, 4, 2 or 1) is the
/// largest whose positions are measured within 1e-3 samples of the exact ones (16 for SRTM
/// tiles). So a sample's value depends on nothing but its place: any window, read alone or inside a
/// larger one, gives the same bits. A target sample is a hole when its position lies outside the
/// native grid's pixels (its height then that of the nearest edge point) or when a native hole
/// weighs in its interpolation (its height then that of the valid neighbours, or 0). grid().frame
/// ends with the frame's scale error measured at the valid samples of frame_scale_error's points,
/// then `height_note`. Throws DemError naming `path` as apply_frame does.
std::unique_ptr<DemSource> warped_source(const std::string& path, std::unique_ptr<DemSource> native,
                                         const std::string& crs, const std::string& height_note);

/// frame_scale_error of a grid that is read, not held: the points are found through `read`
/// (edge columns in strips of rows, then along a row only where its end is a hole).
std::optional<double> scale_error_by_reads(const DemGrid& grid,
                                           const std::function<pm::Heightfield(SampleRect)>& read);

/// Whether apply_frame warps a DEM with this CRS (crs_wkt, and a transform to it or not) to the
/// frame `crs` asks for: never for "native"; for "auto" when the CRS is geographic; always for a
/// named CRS (even the DEM's own), which apply_frame warps to or refuses.
bool frame_warps(const std::string& crs_wkt, bool has_crs_transform, const std::string& crs);

/// What apply_frame appends to a frame for scale error `e` ("" for nullopt); `automatic`: the
/// "auto" frame's warning over 0.1 %.
std::string scale_error_note(std::optional<double> e, bool automatic);

}  // namespace terralod::blocks::detail
