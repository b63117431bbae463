// DEM reader: turns an elevation file (SRTM .hgt, any GDAL raster, a PNG/TIFF heightmap, an Esri
// ASCII grid) into a metric pm::Heightfield, with voids filled or kept as holes.
//
// Usage:
//   #include <terralod/blocks/dem_reader.hpp>
//   namespace tb = terralod::blocks;
//   terralod::pm::Heightfield hf = tb::read_dem("N44W072.hgt");       // 1201 x 1201, metres
//   auto [x, y] = hf.transform.to_world(/*col=*/0, /*row=*/1200);      // (0, 0): south-west sample
//
//   tb::DemOptions png;
//   png.vertical_scale = 0.1;        // one raw unit = 10 cm
//   png.heightmap_spacing = 2.0;     // 2 m between samples
//   auto island = tb::read_dem("island.png", png);
//
//   try { tb::read_dem("broken.tif"); }
//   catch (const tb::DemError& e) { /* e.what(): "broken.tif: <what is wrong>" */ }
//
// Contract:
//   path    UTF-8 file name. Any GDAL path works for GDAL rasters (including /vsi... paths).
//           The format comes from options.format; Format::Auto picks by extension
//           (case-insensitive): .hgt -> Hgt, .asc -> AsciiGrid; anything else -> Gdal, or
//           Heightmap when GDAL finds neither a geotransform nor a CRS (a PNG's may be in a
//           world file or a .aux.xml beside it) and the file is an image OpenImageIO reads
//           (PNG, TIFF, PGM, ...), or when GDAL cannot open it and OpenImageIO can (OpenEXR).
//   options see DemOptions below.
//   result  A Heightfield of width x height >= 2 x 2 samples. Row 0 is the file's first
//           (northern) row, column 0 its western column. Heights in metres (heightmaps: raw
//           value * vertical_scale + vertical_offset), all finite. hf.source = path,
//           hf.crs_wkt = the source CRS as WKT (empty when the file has none), hf.frame = one
//           line saying how the world frame was made, hf.voids = how many samples were void
//           and how many were filled.
//   errors  Every failure (missing or unreadable file, wrong size, more than one band or
//           channel, a grid smaller than 2 x 2, no valid sample at all, a malformed ASCII
//           grid) throws DemError; its what() is "<path>: <problem>". Nothing else is thrown
//           for bad data, except std::bad_alloc when memory runs out.
//
// Formats:
//   Hgt        SRTM tile, read without GDAL: big-endian int16, row-major, row 0 = north edge,
//              n x n samples with n*n*2 == file size, -32768 = void. The file name gives the
//              south-west corner (N44W072.hgt: latitude 44, longitude -72); spacing 1/(n-1)
//              degrees. CRS: WGS 84 geographic.
//   Gdal       Any single-band raster GDAL opens, or one with an alpha band besides (0 =
//              void; gdalwarp -dstalpha). Band 1 is read as double; band scale/offset
//              are applied; a band in feet is converted to metres. The band's nodata value,
//              its mask band (when it has a real one), NaN, +-inf and heights beyond 10,000 km
//              (fills a file does not declare, such as -3.4e38) are voids. The geotransform
//              is taken in GDAL's corner convention and converted to sample centres.
//   Heightmap  Grey image, or grey and alpha (0 = void), read with OpenImageIO: 8/16/32-bit
//              integers are read as raw integers (never normalised), floats as is (NaN/inf and
//              beyond 10,000 km = void). open_dem_source decodes it once into an unnamed
//              temporary file (TMPDIR, 4 bytes a sample, 8 for 32-bit images) and reads its
//              windows from there.
//   AsciiGrid  Esri ASCII grid: header keys ncols, nrows, xllcorner|xllcenter,
//              yllcorner|yllcenter, cellsize (or dx and dy), optional NODATA_value, any
//              order, case-insensitive; then nrows x ncols numbers, north row first. A
//              sidecar <name>.prj, when present, gives the CRS.
//
// World frame (every Heightfield is metric; x east, y north, metres; always affine):
//   - Geographic CRS (.hgt, EPSG:4326 GeoTIFFs, .asc with a geographic .prj): a local
//     equirectangular frame
//         x = R * cos(phi_c) * (lon - lon0) * pi / 180,    y = R * (lat - lat0) * pi / 180,
//     R = 6371008.8 m (mean Earth radius), (lon0, lat0) = the smallest longitude and latitude
//     over the four corner sample centres (for a north-up raster: the centre of the
//     south-west sample, which lands at (0, 0)), phi_c = latitude of the centre of the grid.
//     For N44W072.hgt: dy = R*pi/180/1200 = 92.66 m, dx = dy * cos(44.5 deg) = 66.09 m.
//     Distortion: distances are exact along the parallel phi_c and north-south; east-west
//     they are off by cos(phi)/cos(phi_c) - 1 (about 0.9 % at the north and south edges of a
//     1-degree tile at 45 deg), and against the ellipsoid the sphere adds its own error (1.1 % in
//     all for N44W072.hgt, as frame_scale_error measures). hf.frame records lon0, lat0 and phi_c
//     so the map can be inverted.
//     This is DemOptions::crs = "native", the library's default; "auto" (the CLI's default) and
//     a named CRS warp the DEM to a projected CRS instead (below).
//   - Projected CRS: the CRS coordinates, with its linear unit converted to metres
//     (UTM-sized values stay as they are; they are doubles).
//   - Geotransform but no CRS: the geotransform's units are taken as metres.
//   - No georeferencing (plain images, rasters without geotransform): north-up, spacing
//     options.heightmap_spacing, the south-west sample at (0, 0), so x0 = 0 and
//     y0 = (height - 1) * spacing.
//   - DemOptions::crs = "auto", geographic CRS: the DEM is read (and its voids filled) as above,
//     then warped (warped_source in dem_frame.hpp: bilinear at positions measured within 1e-3
//     samples of the exact transformation, the same code open_dem_source reads windows with) to the azimuthal
//     equidistant projection on the source's ellipsoid, centred on the DEM, onto a north-up grid of cells of
//     the source's east-west and north-south ground spacings at its centre (not square: about the
//     source's sample count) covering the source's footprint; cells outside the footprint, and
//     voids kept as holes, are holes (mask 0, never valid samples; their heights, for the surfaces
//     drawn through them, are those at the nearest point of the footprint, or of the valid
//     neighbours of a kept void). World = k0 * projected metres with k0 = 2 / (1 + c_max / sin
//     c_max), c_max = the angular distance of the farthest DEM corner from the centre: the radial scale (1)
//     and the tangential one (c / sin c) are then balanced, so distances are true to within about c_max^2 /
//     12: 0.081 % for 8 x 8 degrees on the equator, 0.1 % up to about 9 x 9 degrees. Beyond that (its
//     balanced scale error measured over 0.1 %), auto takes whichever of the azimuthal frame, one
//     centred on the data, a transverse Mercator on its central meridian, a Lambert conformal conic
//     with its standard parallel at its central latitude, a Mercator and an oblique Mercator along
//     its best-fitting great circle has the narrowest scale range over the part of the footprint
//     that may hold data (DemSource::may_have_data over a 64 x 64 division, counting empty cells
//     that the void fill fills, DemSource::filled_void_cells), balanced by
//     k0 = 2 / (min + max): strips about 7 degrees wide stay within 0.1 % however long, in any
//     direction; an extent wide both ways (a continent) is beyond every flat frame, and the
//     frame's text says so. When even the truest is beyond +-50 % (kFlatFrameLimit in
//     dem_auto_frame.hpp: a global DEM), the DEM keeps its native grid and frame, and the frame's
//     text says why. A CRS of the user's choice may do better. Projected inputs, and
//     inputs without a CRS, stay native. hf.crs_wkt is the target CRS and hf.crs_transform maps
//     samples to it.
//   - DemOptions::crs = any CRS GDAL's SetFromUserInput accepts ("EPSG:32619", a PROJ string,
//     WKT), which must be projected: the same warp to it, world = its coordinates in metres.
//   Every frame with a CRS has its worst scale error measured (frame_scale_error) and stated at
//   the end of hf.frame: "...; scale error within +-0.081 %". hf.vertical_datum is the source's
//   in every frame.
//
// Voids (fill_voids = true, the default): filled by harmonic (Laplace) inpainting: each void
//   sample becomes the mean of its 4-neighbours inside the grid, valid samples held fixed
//   (solved by multigrid-preconditioned conjugate gradients to a residual of 1e-10 of the
//   region's height scale). Every filled value lies within [min, max] of the valid samples
//   4-adjacent to its 4-connected void region, exactly (the discrete maximum principle, enforced
//   by a final clip and bound-preserving Gauss-Seidel sweeps): no spikes, no NaN. Each region is
//   solved alone on its bounding box plus one ring (blocks/void_fill.hpp), so its filled heights
//   depend only on the samples of that box, not on the rest of the file or on the window a
//   reader holds. A region whose bounding box has more than 4096 x 4096 samples
//   (VoidFillOptions::max_region_cells) is not filled: it stays a hole, so the Heightfield then
//   has a mask, 0 on that region's samples (which hold 0), and hf.voids.filled < hf.voids.voids.
//   Cost: about 115 bytes and 0.8 us per void sample for large voids. Measured (Release):
//   N44W072.hgt reads in 3 ms, N22W160.hgt (4279 voids in 182 regions) reads and fills in 8 ms
//   (measured with the former joint solve; the per-region fill measured no slower in the same
//   run); the first call in a process adds about 25 ms of GDAL driver registration. With
//   fill_voids = false the Heightfield gets a mask (1 valid, 0 void) and void samples hold 0.
//   Voids are: SRTM -32768, the band's nodata value, samples outside a GDAL mask band or under
//   a 0 of an alpha band, NaN and +-inf, ASCII grid NODATA_value, and in every format heights
//   more than 1e7 m from the datum (no terrain: a fill value the file does not declare, most
//   often -3.4e38).
#pragma once

#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "terralod/blocks/dem_grid.hpp"   // frame_scale_error
#include "terralod/blocks/void_fill.hpp"  // VoidSolveNotice
#include "terralod/pm/heightfield.hpp"

namespace terralod::blocks {

/// How read_dem interprets a file. Every field has a usable default.
struct DemOptions {
  /// true: fill voids from their neighbours (hf.voids.filled == hf.voids.voids, no mask), except
  /// void regions over the size cap (see the header comment), which stay holes under a mask.
  /// false: keep voids as holes (hf.has_holes(), void samples hold 0, hf.voids.filled == 0).
  bool fill_voids = true;
  /// Metres per raw unit, heightmaps (Format::Heightmap) only: other files are refused
  /// (DemError) unless it is 1 and vertical_offset 0. Finite, non-zero.
  double vertical_scale = 1.0;
  /// Metres added after scaling, heightmaps only. Finite.
  double vertical_offset = 0.0;
  /// Metres between samples of rasters without georeferencing (plain images, GDAL rasters
  /// with no geotransform). Finite, > 0.
  double heightmap_spacing = 1.0;
  /// GDAL rasters: the band that holds the heights, 1-based (a BAG's elevation beside its
  /// uncertainty, one band of several in a GeoTIFF); a last band that is alpha marks voids. 0: the
  /// only band, or the first of two whose second is alpha. Other formats have one band: > 1 is
  /// an error there. >= 0.
  int band = 0;
  /// File format; Auto chooses by extension (see the header comment).
  enum class Format { Auto, Hgt, Gdal, Heightmap, AsciiGrid } format = Format::Auto;
  /// The world frame (see the header comment): "native" (the source's own frame, local
  /// equirectangular for geographic DEMs), "auto" (geographic DEMs warped to a balanced azimuthal
  /// equidistant projection, or beyond about 9 x 9 degrees the truest of five kinds over its data;
  /// "native" when none is within +-50 %, a DEM far past a hemisphere)
  /// or a projected CRS GDAL understands ("EPSG:32619", PROJ, WKT).
  /// Defaults to "native" so that a file is read as it is and databases built from it before
  /// this option existed resume; `terralod` commands default to "auto". Not empty.
  std::string crs = "native";
  /// open_dem_source only: bytes of filled void regions (of 1,024 samples or more) a windowed
  /// source keeps, with their values, for later reads that meet them, the least recently used
  /// leaving first (0: none kept; every read meeting a region solves it).
  std::size_t filled_void_cache_bytes = std::size_t(256) << 20;
  /// Told before and after the solve of each void region of 2^20 samples or more (about a
  /// second each; VoidFillOptions::on_solve, whose thread-safety it needs): what a read that
  /// seems to hang is doing. Extents are in the input's own grid, before any warp. Empty: silent.
  std::function<void(const VoidSolveNotice&)> on_large_void = {};
};

/// Bad data: the message is always "<path>: <problem>".
class DemError : public std::runtime_error {
 public:
  DemError(const std::string& path, const std::string& problem)
      : std::runtime_error(path + ": " + problem), path_(path), problem_(problem) {}
  /// The file that could not be read.
  const std::string& path() const noexcept { return path_; }
  /// What is wrong with it, without the path.
  const std::string& problem() const noexcept { return problem_; }

 private:
  std::string path_;
  std::string problem_;
};

/// Reads an elevation model into a metric Heightfield (see the header comment for formats,
/// the world frame and void handling). Throws DemError on bad data; std::invalid_argument
/// when options hold an invalid value (non-finite or zero scale, spacing <= 0).
pm::Heightfield read_dem(const std::string& path, const DemOptions& options = {});

/// The inputs of `terralod build --input` as one raster for read_dem: a single file as it is;
/// several files, or a folder, as one VRT mosaic of them (GDALBuildVRT) in GDAL's in-memory file
/// system, which lives as long as this object. A folder gives its raster files (.tif .tiff .hgt
/// .hgt.zip .asc .img .dem .bil .flt .dt0 .dt1 .dt2, sorted by name; not .vrt, which a folder of
/// tiles often holds over them; its subfolders are then not searched, and the description counts
/// them), or when it holds none, those of its subfolders at any depth
/// (Copernicus DEM's folder per tile, DTED's per longitude); an archive (.zip .tar .tar.gz .tgz),
/// given or in the folder, gives those it holds, read in place through GDAL's /vsizip/ and /vsitar/
/// (ASTER GDEM's zips, Copernicus DEM's tars). The quality layers products ship beside their
/// heights (ASTER's _num, Copernicus's AUXFILES folders and _EDM _FLM _HEM _WBM files) are left
/// out. Files need not be alike (other CRSs are warped; other sample types, spacings, nodata
/// values, units and scales made alike; the description says what was done); where they overlap,
/// later names win, but two files on the same cells are refused by name (two layers of one tile, or
/// one tile twice). Voids are read (and filled) on the mosaic, not file by file, so a void that
/// crosses a file boundary is filled as if the mosaic were one file. Geographic tiles on both sides
/// of the antimeridian (S17E179 and S17W180) join east of 180 degrees: the western ones are read
/// through in-memory VRTs moved 360 degrees east, so the mosaic is 2 degrees wide, not the whole
/// Earth. DemError naming the file, folder or archive: a missing path, a folder or archive without
/// elevation files, files on the same cells, files GDAL cannot mosaic (not a raster).
class DemInputs {
 public:
  explicit DemInputs(const std::vector<std::string>& inputs);
  ~DemInputs();
  DemInputs(const DemInputs&) = delete;
  DemInputs& operator=(const DemInputs&) = delete;
  /// What read_dem reads: the one input, or the in-memory VRT.
  const std::string& path() const { return path_; }
  /// The input as the database records it (Heightfield::source): the file, or
  /// "mosaic of N files: first, second, ... (in FOLDER)".
  const std::string& description() const { return description_; }
  std::size_t files() const { return files_; }

 private:
  std::string path_, description_;
  std::size_t files_ = 0;
  bool owned_ = false;
  /// In-memory VRTs the mosaic reads some files through: warped to the others' CRS, read as
  /// their sample type, or moved by 360 degrees to join across the antimeridian.
  std::vector<std::string> made_;
};

}  // namespace terralod::blocks
