// Textures of terrains larger than memory: a texel region of the whole terrain computed window
// by window, each window the samples its texels need and a margin around them.
//
// Usage:
//   namespace tr = terralod::render;
//   terralod::blocks::DatabaseTerrain dt(db);                    // database_terrain.hpp
//   tr::TerrainWindows t = tr::terrain_windows(dt);               // reads the exact height range once
//   tr::FloatRaster band = tr::shade_terrain(t, options, {0, y, -1, 64, 1});   // 64 rows, all columns
//   // = shade_terrain(read_database_terrain(db), options, region), bit for bit
//   tr::FloatRaster slope = tr::terrain_attribute(t, tr::TerrainAttribute::SlopeDegrees, region);
//
// Contract of compute_by_windows(t, region, margins, compute):
//   - The texels of `region` (topographic_texture.hpp's TexelRegion over the whole grid) are cut
//     into tiles; for each tile, `compute` gets the window of samples from the tile's first to
//     its last sample (the end of its last step x step block, clipped to the region) widened by
//     `margins` on each side (clipped to the grid), the tile as a TexelRegion of that window
//     (whole blocks), and the window's corner in the whole grid; it returns the tile's texels.
//     The result is the tiles put together.
//   - So compute(window, ...) equals compute(whole grid, ...) wherever a texel depends only on
//     samples within the margins of its own sample: Horn normals (1), a relative-height window
//     (its radius), a shadow ray until it is above the highest sample (shading_margins).
//   - Windows hold about window_samples samples, more where the margins are large: at least
//     64 samples beside the margins each way (or one texel, under max_side).
// Memory: one window (8 bytes a sample, 9 with holes), its tile's texels and the result.
#pragma once

#include <functional>
#include <string>

#include "terralod/pm/heightfield.hpp"
#include "terralod/render/image_pyramid.hpp"
#include "terralod/render/rgba_image.hpp"
#include "terralod/render/thematic_texture.hpp"
#include "terralod/render/topographic_texture.hpp"

namespace terralod::blocks {
class DatabaseTerrain;
}

namespace terralod::render {

/// A terrain read window by window.
struct TerrainWindows {
  int width = 0, height = 0;    ///< samples of the whole grid
  pm::GridTransform transform;  ///< the whole grid's
  /// Lowest and highest valid sample, metres, exactly; lo > hi when every sample is a hole.
  double lo = 0, hi = 0;
  /// The samples [col0, col0 + cols) x [row0, row0 + rows) as a heightfield whose transform
  /// is the whole grid's moved to its corner (blocks::DatabaseTerrain::read).
  std::function<pm::Heightfield(int col0, int row0, int cols, int rows)> read;
  std::size_t window_samples = std::size_t(1) << 22;  ///< the size windows aim at, samples
  /// > 0: no window wider or taller than this many samples (a GPU's texture limit) unless its
  /// margins alone are.
  int max_side = 0;
};

/// Windows of a block database's terrain; reads its exact height range first (one pass over
/// the blocks, `progress` gets the fraction done). `terrain` must outlive the result.
TerrainWindows terrain_windows(blocks::DatabaseTerrain& terrain,
                               const std::function<void(double)>& progress = {});

/// Samples a window reaches beyond its tile's samples, per side.
struct WindowMargins {
  int left = 0, right = 0, top = 0, bottom = 0;  ///< columns before / after, rows above / below
};

/// The window's texels: `in_window` is the tile as a region of `window`, whose sample (0, 0) is
/// the whole grid's (col0, row0).
using WindowCompute = std::function<FloatRaster(const pm::Heightfield& window, const TexelRegion& in_window,
                                                int col0, int row0)>;

/// See the contract above. Throws std::invalid_argument for a region outside the grid (what
/// `region.check` throws) and whatever `t.read` or `compute` throw.
FloatRaster compute_by_windows(const TerrainWindows& t, const TexelRegion& region,
                               const WindowMargins& margins, const WindowCompute& compute);

/// shade_terrain (topographic_texture.hpp) of the whole terrain, window by window: the same
/// values bit for bit as shade_terrain(whole heightfield, options, region). Throws what that
/// throws (options and region checked before any window is read).
FloatRaster shade_terrain(const TerrainWindows& terrain, const ShadingOptions& options,
                          const TexelRegion& region = {});

/// The margins shade_terrain's windows need: 1 (Horn's 3 x 3), the relative-height radius, and
/// with shadows, toward each light, the cells a ray crosses while it climbs from the lowest
/// sample to the highest ((hi - lo) x exaggeration / tan(altitude) metres), plus one.
WindowMargins shading_margins(const TerrainWindows& terrain, const ShadingOptions& options);

/// Writes the image pyramid (ImagePyramid::convert's file) of a texture with one texel per
/// sample of the whole terrain, whose rows band(row0, rows) computes (RGBA8, `rows` x t.width),
/// band by band as the pyramid asks for them: the texture is never whole in memory. `what`
/// names it in errors; `progress` gets the fraction written.
void convert_by_bands(const TerrainWindows& t, const std::function<RgbaImage(int row0, int rows)>& band,
                      const std::string& out_path, const PyramidOptions& options,
                      const std::function<void(double)>& progress = {}, const std::string& what = "texture");

/// The levels `rule` draws of `attribute` over the whole terrain (render_pyramid_levels,
/// thematic_texture.hpp: level k's texels from 2^k x 2^k samples each), written band by band as
/// ImagePyramid::write_levels' file, window by window: the same file as write_levels of
/// render_pyramid_levels(rule, terrain_attribute(whole), ...), never the terrain nor a level
/// whole in memory. The rule must draw each texel from its own block's samples alone, as
/// LodDesignRule does. Throws std::invalid_argument for sample_size_m <= 0, and what the
/// windows, the rule and the writer throw.
void write_rule_pyramid(const TerrainWindows& t, TerrainAttribute attribute, const DesignRule& rule,
                        double sample_size_m, const std::string& out_path, const PyramidOptions& options,
                        const std::function<void(double)>& progress = {});

/// terrain_attribute (thematic_texture.hpp) of the whole terrain, window by window (margin 1):
/// the same values bit for bit.
FloatRaster terrain_attribute(const TerrainWindows& terrain, TerrainAttribute attribute,
                              const TexelRegion& region = {});

}  // namespace terralod::render
