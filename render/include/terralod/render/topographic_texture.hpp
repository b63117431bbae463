// Topographic (shading) textures computed on the CPU from the full-resolution heightfield.
//
// A topographic texture stores the shade of the full-resolution terrain, one texel per DEM sample
// at level 0, so a coarse geometric LOD drawn with it keeps every topographic detail (Döllner,
// Baumann & Hinrichs, "Texturing techniques for terrain visualization" / "Dynamic 3D maps and
// their texture-based design", section 4: shading textures, self-shadowing, cartographic and
// relative-height shading). The result never depends on the geometric LOD being drawn.
//
// Usage:
//   terralod::pm::Heightfield hf = terralod::blocks::read_dem("N44W072.hgt");
//   terralod::render::ShadingOptions o;                  // Lambert, azimuth 315, altitude 45
//   o.shadows = true;
//   terralod::render::FloatRaster s = terralod::render::shade_terrain(hf, o);   // 1201 x 1201
//   terralod::render::RgbaImage tex = terralod::render::grey_to_rgba(s);        // rgba_image.hpp
//   // A coarser level: every 4th sample of the north-west quarter.
//   terralod::render::TexelRegion r{/*col0=*/0, /*row0=*/0, /*cols=*/600, /*rows=*/600, /*step=*/4};
//   terralod::render::FloatRaster q = terralod::render::shade_terrain(hf, o, r);   // 150 x 150
//   // The same on the GPU (OSMesa): gpu_shading.hpp, shade_terrain_gpu(hf, o, r).
//   // A terrain larger than memory, window by window, the same values: terrain_windows.hpp,
//   // shade_terrain(terrain_windows(database_terrain), o, r).
//
// Frames and formulas (x east, y north, z up, metres; the heightfield's GridTransform maps
// (col,row) to (x,y), see pm/heightfield.hpp):
//   Texel (i, j) of the output is the sample (col, row) = (col0 + i*step, row0 + j*step); output
//   row 0 is heightfield row `row0` (the northern edge for north-up data), i.e. top row first.
//   Heights are z = vertical_exaggeration * sample.
//
//   Normal, Horn (1981) 3x3 weighted differences in grid units, with the window
//         a b c        a = z(col-1,row-1)  b = z(col,row-1)  c = z(col+1,row-1)
//         d e f        d = z(col-1,row)                      f = z(col+1,row)
//         g h i        g = z(col-1,row+1)  h = z(col,row+1)  i = z(col+1,row+1)
//     dz/dcol = ((c + 2f + i) - (a + 2d + g)) / 8,   dz/drow = ((g + 2h + i) - (a + 2b + c)) / 8.
//     Samples outside the grid, and holes, are replaced by the nearest edge sample (clamped
//     index) and by the centre sample e respectively ("replicating the edge": on a plane the
//     border texels therefore see half the slope across the border).
//     World gradient: [gx, gy] = J^-T [dz/dcol, dz/drow] with J = [[xc, xr], [yc, yr]]
//     (for north-up data gx = dz/dcol / dx, gy = -dz/drow / dy).
//     n = (-gx, -gy, 1) / sqrt(1 + gx^2 + gy^2).
//   Light toward azimuth A (degrees clockwise from north) and altitude h (degrees above the
//     horizon): l(A, h) = (sin A cos h, cos A cos h, sin h).
//   Diffuse D = max(0, n.l) (0 when the texel is in shadow).
//   Methods (every value is clamped to [0, 1] only where said):
//     Lambert:  I = ambient + (1 - ambient) * D. With ambient = 0 and shadows off this is the
//               conventional GIS hillshade: gdaldem hillshade writes 1 + 254 * I (tested).
//     Phong:    I = min(1, ka + kd * D + ks * S),  S = max(0, r.v)^shininess when n.l > 0 and the
//               texel is lit, else 0;  r = 2 (n.l) n - l, viewer straight above v = (0, 0, 1).
//     Multidirectional (GDAL `gdaldem hillshade -multidirectional`, after Mark (1992), USGS
//               OF 92-422, "multidirectional oblique-weighted" shading): for the azimuths A_k
//               (default 225, 270, 315, 360) and the common altitude h,
//                 I = ambient + (1 - ambient) * sum_k w_k D_k / sum_k w_k,
//                 D_k = max(0, n.l(A_k, h)) (0 if shadowed from A_k),
//                 w_k = (g . d_k)^2 / |g|^2,  d_k = (sin A_k, cos A_k),  g = (gx, gy);
//               on flat ground (g = 0) all w_k = 1. For the default azimuths these are GDAL's
//               weights (x^2, y^2, (x -+ y)^2 / 2) and, with ambient 0, I equals GDAL's value.
//     RelativeHeight (the "relative height of a terrain part" shading of the paper, fig. 5):
//                 I = (z - zmin) / (zmax - zmin), 0.5 where zmax == zmin,
//               zmin/zmax over the valid samples within Chebyshev distance relative_radius
//               (in samples, clipped to the grid) of the texel's sample; relative_radius = 0
//               means over the whole heightfield. No light: `shadows` must be false.
//   Self-shadowing (shadows = true): a ray leaves the texel's sample at its height z0 toward the
//     light; at horizontal distance t (metres) it is at z0 + t tan h. It is tested against the
//     full-resolution surface at every crossing of a grid line (column line col = k or row line
//     row = k) until it leaves the grid or rises above the highest sample: there the surface
//     height is the linear interpolation of the two samples on that grid line (exactly the
//     bilinear surface there). The texel is shadowed when the surface is above the ray by more
//     than shadow_bias metres at any crossing. A vertical step of height H between two samples
//     therefore casts a shadow of length H / tan h measured from the top edge, to within one
//     texel. Holes never occlude. Shadows use the full-resolution grid whatever `step` is.
//     Acceleration that does not change the answer: where the ray enters a block of 16 x 16
//     cells above the block's highest sample (its boundary lines included), the crossings in
//     that block are skipped (the ray only rises); on N44W072 at altitude 10 this halves the
//     instruction count (callgrind).
//   Holes: a texel whose sample is a hole is NaN (grey_to_rgba makes it transparent).
//
// Cost: O(texels) for Horn; shadows O(texels * L) with L the number of cells a ray crosses
// before it climbs above the highest sample (about (zmax - z0) / (spacing * tan h)), fewer
// with the block skipping, plus O(samples) once for the block maxima (8 bytes per block); relative
// height O(texels * radius) (separable min/max). Memory: the output (4 bytes per texel) plus,
// for RelativeHeight with a radius R > 0, the row-wise min and max of the texel columns over
// the region's rows widened by R (8 bytes each).
// Parallel: rows are handed out one at a time to `threads` threads (pm::parallel_for); the result does not
// depend on the number of threads.
#pragma once

#include <string>
#include <vector>

#include "terralod/pm/heightfield.hpp"
#include "terralod/render/rgba_image.hpp"

namespace terralod::render {

enum class ShadingMethod { Lambert, Phong, Multidirectional, RelativeHeight };

/// "lambert", "phong", "multidirectional", "relative" (the `terralod texture shade --method`
/// names); throws std::invalid_argument naming the unknown word.
ShadingMethod parse_shading_method(const std::string& name);
const char* shading_method_name(ShadingMethod m);

/// Which samples become texels: a sub-rectangle of the heightfield and a texel step.
struct TexelRegion {
  int col0 = 0, row0 = 0;  ///< first sample, 0 <= col0 < width, 0 <= row0 < height
  int cols = -1;           ///< samples covered along a row; -1 = to the last column
  int rows = -1;           ///< samples covered along a column; -1 = to the last row
  int step = 1;            ///< texel spacing in samples, >= 1 (2^k for pyramid level k)

  /// Samples covered once -1 is resolved against a raster of full_width x full_height.
  int cols_in(int full_width) const { return cols < 0 ? full_width - col0 : cols; }
  int rows_in(int full_height) const { return rows < 0 ? full_height - row0 : rows; }
  /// Output size: ceil(cols / step) x ceil(rows / step).
  int out_width(int full_width) const { return (cols_in(full_width) + step - 1) / step; }
  int out_height(int full_height) const { return (rows_in(full_height) + step - 1) / step; }
  /// Throws std::invalid_argument unless the region lies inside full_width x full_height
  /// (non-empty) and step >= 1; `what` names the caller in the message.
  void check(int full_width, int full_height, const char* what) const;
};

struct ShadingOptions {
  ShadingMethod method = ShadingMethod::Lambert;
  double azimuth_deg = 315.0;          ///< light azimuth, degrees clockwise from north (any value)
  double altitude_deg = 45.0;          ///< light altitude above the horizon, degrees, in (0, 90]
  bool shadows = false;                ///< self-shadowing against the full-resolution terrain
  double shadow_bias = 1e-3;           ///< metres the surface must exceed the ray by to occlude, >= 0
  double vertical_exaggeration = 1.0;  ///< heights are multiplied by this, > 0 (gdaldem -z)
  double ambient = 0.0;                ///< Lambert / multidirectional ambient term, [0, 1]
  // Phong constants (I = ka + kd D + ks S, clamped to 1).
  double phong_ka = 0.15, phong_kd = 0.7, phong_ks = 0.15, phong_shininess = 16.0;
  /// Multidirectional azimuths, degrees; at least one.
  std::vector<double> multidirectional_azimuths = {225.0, 270.0, 315.0, 360.0};
  int relative_radius = 16;  ///< RelativeHeight window half-size in samples; 0 = global range
  int threads = 0;           ///< worker threads, 0 = std::thread::hardware_concurrency()
};

/// Shading values in [0, 1] (NaN at holes), out_width x out_height, top row first.
/// Misuse (region outside the grid, step < 1, altitude outside (0, 90], empty heightfield,
/// shadows with RelativeHeight, ...) throws std::invalid_argument naming the parameter.
FloatRaster shade_terrain(const pm::Heightfield& hf, const ShadingOptions& options = {},
                          const TexelRegion& region = {});

/// The same as a grey RGBA texture: grey_to_rgba(shade_terrain(hf, options, region)).
RgbaImage shading_texture(const pm::Heightfield& hf, const ShadingOptions& options = {},
                          const TexelRegion& region = {});

/// Unit vector toward a light at azimuth A and altitude h (degrees): (sin A cos h, cos A cos h, sin h).
struct Vec3d {
  double x = 0, y = 0, z = 0;
};
Vec3d light_direction(double azimuth_deg, double altitude_deg);

/// Horn unit normal at sample (col, row), world frame, with edge replication (see above).
Vec3d horn_normal(const pm::Heightfield& hf, int col, int row, double vertical_exaggeration = 1.0);

}  // namespace terralod::render
