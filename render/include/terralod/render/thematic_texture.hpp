// Thematic textures: scalar rasters (land-use classes, slope, aspect, elevation) mapped to RGBA
// by colour mappers and level-of-detail dependent design rules.
//
// After Döllner & Baumann, "Dynamic 3D maps and their texture-based design", section 5.1: a
// thematic texture maps thematic data to an image by a design rule; a rule may depend on the
// level of detail (figure 6: exact forest boundaries near the camera, a generalised look far
// away).
//
// Usage:
//   using namespace terralod::render;
//   FloatRaster slope = terrain_attribute(hf, TerrainAttribute::SlopeDegrees);      // 1 texel/sample
//   ColorRamp ramp({{0.0f, {255, 255, 255, 255}}, {45.0f, {200, 0, 0, 255}}});       // white -> red
//   RgbaImage tex = apply_mapper(slope, ramp);
//
//   ClassTable landuse({{1, {34, 139, 34, 255}}, {2, {65, 105, 225, 255}}});         // forest, water
//   ColorRamp far({{0.0f, {200, 230, 200, 255}}, {2.0f, {150, 180, 220, 255}}});
//   LodDesignRule rule(/*generalise=*/Reduction::Majority);
//   rule.add(/*max_texel_size_m=*/50.0, std::make_shared<ClassTable>(landuse));      // near: exact
//   rule.add(/*max_texel_size_m=*/1e30, std::make_shared<ColorRamp>(far));           // far
//   RgbaImage level3 = rule.render(classes, TexelRegion{0, 0, -1, -1, /*step=*/8},
//                                  /*sample_size_m=*/90.0);                          // far look
//   // Every level of a pyramid, each drawn by the rule (write with ImagePyramid::write_levels):
//   std::vector<RgbaImage> lv = render_pyramid_levels(rule, classes, 90.0, /*max_texture_size=*/1024);
//   // A terrain larger than memory, window by window (terrain_windows.hpp): terrain_attribute(
//   // TerrainWindows, ...) and write_rule_pyramid, the same values and the same file.
//
// Contract:
//   - Rasters are top row first (rgba_image.hpp); NaN means no data and maps to the mapper's
//     `nodata` colour (transparent by default).
//   - ClassTable: class id = the value rounded to the nearest integer; ids missing from the
//     table get `unknown` (default transparent). A value that is not within 1e-3 of an integer
//     is bad data for a class raster: std::invalid_argument names the value.
//   - ColorRamp: stops strictly increasing in value (else std::invalid_argument), at least one.
//     Linear mode: each channel is interpolated linearly between the two stops around v and
//     rounded to nearest; below the first / above the last stop the end colour is used.
//     Step mode (elevation bands): v in [stop_k, stop_{k+1}) gets colour k; below the first
//     stop `nodata`; at or above the last stop the last colour.
//   - terrain_attribute: Elevation (metres), SlopeDegrees = atan(|g|) in degrees [0, 90),
//     AspectDegrees = direction the slope faces (downhill), degrees clockwise from north in
//     [0, 360), NaN where the ground is flat (|g| == 0); g is the Horn gradient of
//     topographic_texture.hpp (same edge replication). Holes are NaN.
//   - Design rules: render(values, region, sample_size_m) gets the FULL-resolution raster, the
//     texels wanted (region of that raster with a step) and the size of one full-resolution
//     sample in metres; texel size = step * sample_size_m. LodDesignRule picks the first entry
//     (in the order added) whose max_texel_size_m >= texel size (the last one if none), and
//     reduces step x step blocks by `generalise`: Nearest takes the block's first sample
//     (top-left), Majority the most frequent class id in the block (smallest id on ties; NaN
//     only if the whole block is NaN), Mean the mean of its valid values.
//   - render_pyramid_levels(rule, values, sample_size_m, max_texture_size): level k has exactly
//     the size pyramid_levels(values.width, values.height, max_texture_size)[k] = w_k x h_k
//     (floor halving, image_pyramid.hpp) and is rule.render(values, region_k, sample_size_m),
//     region_k = {0, 0, min(W, w_k 2^k), min(H, h_k 2^k), step = 2^k}: texel (i, j) stands for
//     the samples [i 2^k, (i+1) 2^k) x [j 2^k, (j+1) 2^k), so its texel size is
//     2^k * sample_size_m. Where W (H) is not a multiple of 2^k the last W mod 2^k columns
//     (rows) are left out of level k (less than one of its texels; a box-filtered pyramid
//     spreads them over the level instead); where W < 2^k (w_k is the 1 of max(1, .)) its one
//     column covers all W.
//     std::invalid_argument if the rule returns an image of another size.
//   - Memory: output 4 bytes per texel; rules allocate one reduced float raster (4 bytes per texel).
//     render_pyramid_levels holds every level: about 4/3 x 4 bytes per full-resolution sample.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <utility>
#include <vector>

#include "terralod/pm/heightfield.hpp"
#include "terralod/render/image_pyramid.hpp"
#include "terralod/render/rgba_image.hpp"
#include "terralod/render/topographic_texture.hpp"

namespace terralod::render {

using Rgba = std::array<std::uint8_t, 4>;

/// Maps one scalar to a colour.
class ColorMapper {
 public:
  virtual ~ColorMapper() = default;
  virtual Rgba map(float value) const = 0;
  Rgba nodata = {0, 0, 0, 0};  ///< colour of NaN values
};

/// Discrete class table (land use): integral class id -> colour.
class ClassTable final : public ColorMapper {
 public:
  explicit ClassTable(std::map<int, Rgba> classes, Rgba unknown = {0, 0, 0, 0});
  Rgba map(float value) const override;

 private:
  std::map<int, Rgba> classes_;
  Rgba unknown_;
};

/// Continuous colour ramp with stops, or bands (Step mode).
class ColorRamp final : public ColorMapper {
 public:
  enum class Mode { Linear, Step };
  struct Stop {
    float value;
    Rgba color;
  };
  explicit ColorRamp(std::vector<Stop> stops, Mode mode = Mode::Linear);
  Rgba map(float value) const override;
  const std::vector<Stop>& stops() const { return stops_; }

 private:
  std::vector<Stop> stops_;
  Mode mode_;
};

/// Every value mapped through `mapper`; same size as `values`.
RgbaImage apply_mapper(const FloatRaster& values, const ColorMapper& mapper);

enum class TerrainAttribute { Elevation, SlopeDegrees, AspectDegrees };

/// A scalar raster derived from the DEM over `region` (one texel per `step` samples).
FloatRaster terrain_attribute(const pm::Heightfield& hf, TerrainAttribute attribute,
                              const TexelRegion& region = {});

/// How step x step blocks of a full-resolution raster become one texel.
enum class Reduction { Nearest, Majority, Mean };

/// Reduces `region` of `values` (step x step blocks, clipped at the region's edge).
FloatRaster reduce_raster(const FloatRaster& values, const TexelRegion& region, Reduction reduction);

/// A design rule: full-resolution thematic values -> the texture of one region at one LOD.
class DesignRule {
 public:
  virtual ~DesignRule() = default;
  /// values: full-resolution raster; region: texels wanted (region.step = 2^level for
  /// pyramid level `level`); sample_size_m: metres per full-resolution sample, > 0.
  virtual RgbaImage render(const FloatRaster& values, const TexelRegion& region,
                           double sample_size_m) const = 0;
};

/// A rule that changes its look with the texel size (cartographic generalisation).
class LodDesignRule final : public DesignRule {
 public:
  explicit LodDesignRule(Reduction generalise = Reduction::Majority) : generalise_(generalise) {}
  /// Entries are tried in the order added; max_texel_size_m > 0; mapper not null.
  void add(double max_texel_size_m, std::shared_ptr<const ColorMapper> mapper);
  /// The mapper used for texels of this size (asserts at least one entry).
  const ColorMapper& mapper_for(double texel_size_m) const;
  RgbaImage render(const FloatRaster& values, const TexelRegion& region, double sample_size_m) const override;

 private:
  Reduction generalise_;
  std::vector<std::pair<double, std::shared_ptr<const ColorMapper>>> entries_;
};

/// The levels of an image pyramid over `values` (sizes pyramid_levels(values.width,
/// values.height, max_texture_size)), level k drawn by `rule` at step 2^k (contract above).
/// sample_size_m > 0; max_texture_size >= 1; values at least 1 x 1.
std::vector<RgbaImage> render_pyramid_levels(const DesignRule& rule, const FloatRaster& values,
                                             double sample_size_m, int max_texture_size);

}  // namespace terralod::render
