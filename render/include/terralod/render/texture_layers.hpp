// Texture layers: how any number of switchable layers combine (blend by weight, add, subtract,
// multiply, masking by an alpha layer or a moving highlight lens, animated key-frame
// sequences), with the exact CPU reference the GPU renderer (layered_renderer.hpp) follows.
//
// Usage:
//   using namespace terralod::render;
//   std::vector<LayerStyle> styles(2);
//   styles[0].name = "shade";  styles[0].op = LayerOp::Blend;  styles[0].topographic = true;
//   styles[1].name = "landuse"; styles[1].op = LayerOp::Multiply; styles[1].weight = 0.6f;
//   styles[1].mask = MaskSource::Lens;                  // only inside the lens
//   std::vector<LayerSource> src = {{{shade_img}, georef}, {{landuse_img}, georef}};
//   Lens lens{/*enabled=*/true, GeoRect{x - 500, y - 500, x + 500, y + 500}};
//   RgbaImage out = combine_layers(styles, src, &lens_img, lens, georef, 256, 256);
//
// Combination, per point, colours in [0,1] (dynamic-3d-maps-texture-layers.txt section 6):
//   c = base (LayerStackOptions::base_color); then for each enabled layer L that is not
//   mask_only, in order, with texel (rgb, a) and s = weight * a * m (m = mask value, 1 if none):
//     Blend     c = c + (rgb - c) * s          (weighted interpolation, alpha : 1 - alpha)
//     Add       c = c + s * rgb
//     Subtract  c = c - s * rgb
//     Multiply  c = c * (1 + (rgb - 1) * s)    (modulate)
//   and c is clamped to [0,1] after every layer (as a framebuffer does between passes).
//   Finally, when lighting is on and no enabled layer is topographic, c *= light (the
//   renderer's per-vertex Lambert term); a topographic layer means decal mode: no lighting.
//   The output byte is round(255 c).
//   Mask value m: MaskSource::Layer -> the alpha of layer mask_layer (which may be disabled or
//   mask_only; its own mask is not applied); MaskSource::Lens -> the lens texture's alpha at
//   the point when the lens is enabled and the point is inside its rectangle, else 0;
//   invert_mask uses 1 - m.
//   Sequences: a layer with several frames is a key-frame sequence; at time t in
//   [0, frames-1] its texel is (1-f) K_i + f K_(i+1), i = floor(t), f = t - i, per channel in
//   [0,1] (bytes / 255).
//   Sampling: nearest texel of each layer's image at the point (the CPU reference; the GPU
//   filters as RendererOptions say). Images map to their georef as texture_tree.hpp says.
//
// Contract: styles.size() == sources.size(); weight in [0,1]; mask_layer a valid index other
// than the layer itself when mask == Layer; time in [0, frames-1]; each source has >= 1 frame,
// all frames of one source the same size. Violations are asserts.
// Memory: the output image (4 bytes per pixel); no copies of the sources.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "terralod/render/rgba_image.hpp"
#include "terralod/render/texture_tree.hpp"

namespace terralod::render {

enum class LayerOp : std::uint8_t { Blend, Add, Subtract, Multiply };
enum class MaskSource : std::uint8_t { None, Layer, Lens };

/// How one layer takes part in the combination; change freely between frames.
struct LayerStyle {
  std::string name;
  bool enabled = true;
  LayerOp op = LayerOp::Blend;
  float weight = 1.0f;  ///< [0,1]
  MaskSource mask = MaskSource::None;
  int mask_layer = -1;  ///< for MaskSource::Layer
  bool invert_mask = false;
  bool mask_only = false;    ///< contributes no colour; only serves as a mask
  bool topographic = false;  ///< a shading texture: when enabled, no per-vertex lighting
  float time = 0.0f;         ///< sequences: position in [0, frames-1]
};

/// The highlight lens: a small alpha texture (its A channel is the mask; for a luminance lens
/// put the luminance into A, as make_lens_texture does) placed over a world rectangle.
/// Moving it changes only `rect` (a uniform on the GPU; no layer is re-merged or re-uploaded).
struct Lens {
  bool enabled = false;
  GeoRect rect;  ///< world rectangle the lens texture covers
};

struct LayerStackOptions {
  std::array<float, 3> base_color{0.5f, 0.5f, 0.5f};  ///< colour under all layers, [0,1]
  bool lighting = true;  ///< per-vertex lighting when no topographic layer is enabled
};

/// One layer's pixels for the CPU reference: key frames (>= 1) over one georef.
struct LayerSource {
  std::vector<RgbaImage> frames;
  GeoRect georef;
};

/// Key-frame interpolation of a sequence at time t (see above): i and f.
struct SequencePosition {
  int i = 0, j = 0;  ///< the two key frames (j = i at the last frame or with one frame)
  float f = 0.0f;    ///< weight of frame j
};
SequencePosition sequence_position(int frames, float time);

/// True when the styles turn lighting off (an enabled topographic layer).
bool decal_mode(std::span<const LayerStyle> styles);

/// The combination at one point: texels (r,g,b,a in [0,1], one per layer, sequences already
/// interpolated), the lens alpha there (0 outside or disabled) and the lighting factor
/// (ignored in decal mode or with lighting off). Returns c in [0,1]^3 before rounding.
std::array<float, 3> combine_texels(std::span<const LayerStyle> styles,
                                    std::span<const std::array<float, 4>> texels, float lens_alpha,
                                    float light, const LayerStackOptions& options = {});

/// The exact CPU reference over a width x height output grid covering `out_georef` (pixel
/// centres sampled), light = 1 everywhere. Output alpha is 255.
RgbaImage combine_layers(std::span<const LayerStyle> styles, std::span<const LayerSource> sources,
                         const RgbaImage* lens_image, const Lens& lens, const GeoRect& out_georef, int width,
                         int height, const LayerStackOptions& options = {});

/// A round highlight-lens texture: alpha 255 inside the inscribed circle, falling linearly to
/// 0 over the outer `soft` fraction of the radius; white RGB. size >= 1, soft in [0,1].
RgbaImage make_lens_texture(int size, float soft = 0.25f);

}  // namespace terralod::render
