// Symbol textures: the map objects that their layer's design rules draw as "symbol" (issue 19,
// point 3), drawn as 2D map symbols into the levels of a texture layer's image pyramid, each
// level showing the objects that are symbols at the distance where the renderer shows that level
// (dynamic-3d-maps-texture-layers.txt sections 4 and 5: texture-based design, symbols).
//
// Usage:
//   namespace tr = terralod::render;
//   const tb::ObjectPlacer placer(db, {"huts"});       // anchors, extents (object_placement.hpp)
//   std::vector<tr::SymbolObject> objs;
//   for (const tb::MapObject& o : placer.objects())
//     objs.push_back({o.anchor, o.extent_m, &placer.rules(o.layer)});
//   tr::SymbolStyle style;  style.diameter_texels = 7;  // red discs, dark outline
//   for (int k = 0; k < levels; ++k) {                 // one level at a time
//     const double texel_m = double(1 << k) * sample_m;
//     tr::RgbaImage lv = tr::render_symbol_level(objs, georef, sizes[k], texel_m, style);
//   }
//
// Which level shows which objects (the level's view distance):
//   The renderer picks a texture whose texel, seen from the camera, projects to about gamma_px
//   pixels (texture_tree.hpp: visual_texture_error_px, the projected area of one texel). A
//   texel of t metres seen face-on at distance d covers (t f / d)^2 pixels (f: the focal length
//   in pixels), so level k (texel size t_k) is what a view shows at
//     d_k = t_k * kSymbolReferenceFocalPx / sqrt(kSymbolReferenceGammaPx)
//   for the reference view: 1280 x 720 pixels, 60 degrees vertical field of view
//   (f = 360 / tan(30 deg) = 623.5 px) and gamma 1 pixel. An object is drawn into level k when
//   its rules choose Symbol at d_k (ObjectRules::choose(d_k, extent_m * f / d_k): distance rules
//   read d_k, screen-size rules the object's extent on screen at d_k).
//
// Contract:
//   symbol     a disc of diameter_texels texels (>= 1) centred on the object's anchor: the
//              outer ring (1 texel wide, or the whole disc when diameter_texels <= 2) is the
//              dark outline (the colour x 0.25, same alpha), the inside the colour. Constant size
//              in texels at every level, so symbols shrink on screen as coarser levels are
//              shown, like a map's symbols. Anti-aliased by coverage: a texel whose centre is at
//              distance r from the symbol's centre is covered clamp(R + 0.5 - r, 0, 1) by the
//              disc of radius R (the outline the same with R = diameter/2, the fill with R - 1).
//              Drawn over what is there with the "over" operator (straight alpha): overlapping
//              symbols stack in the order given.
//   position   the anchor (world x east, y north, metres) in texel coordinates of the level:
//              u = (x - minx) / (maxx - minx) * width, v = (maxy - y) / (maxy - miny) * height
//              (texel (i, j) covers [i, i+1) x [j, j+1); every level covers the whole georef,
//              image_pyramid.hpp). Symbols reaching past the image are clipped.
//   errors     bad arguments (diameter < 1, texel_m <= 0, an empty level, a null rules
//              pointer) are asserted: the caller checks options first.
//   cost       O(objects + symbols x diameter^2) per level; memory: the level (4 bytes a texel),
//              or the rows asked for (render_symbol_rows) and 16 bytes a symbol.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "terralod/blocks/object_layers.hpp"
#include "terralod/blocks/object_rules.hpp"
#include "terralod/render/image_pyramid.hpp"
#include "terralod/render/rgba_image.hpp"
#include "terralod/render/texture_tree.hpp"

namespace terralod::render {

/// Focal length of the reference view, pixels: 1280 x 720, 60 degrees vertical field of view
/// (360 / tan(30 deg) = 623.54, rounded).
inline constexpr double kSymbolReferenceFocalPx = 623.5;
/// Visual texture error of the reference view, pixels^2 (SelectionOptions::gamma_px).
inline constexpr double kSymbolReferenceGammaPx = 1.0;

/// d_k: the camera distance (metres) at which the reference view shows texels of texel_m
/// metres (> 0): texel_m * kSymbolReferenceFocalPx / sqrt(kSymbolReferenceGammaPx).
double symbol_level_distance_m(double texel_m);

/// One map object as the symbol texture needs it.
struct SymbolObject {
  blocks::WorldPoint anchor;                   ///< world frame, metres (MapObject::anchor)
  double extent_m = 0.0;                       ///< for screen-size rules (MapObject::extent_m)
  const blocks::ObjectRules* rules = nullptr;  ///< its layer's rules, not owned, not null
};

struct SymbolStyle {
  std::array<std::uint8_t, 4> color{200, 30, 30, 255};  ///< fill, RGBA (straight alpha)
  int diameter_texels = 7;                              ///< >= 1
};

/// Draws one symbol centred at texel coordinates (u, v) of a level (see the contract) into
/// `image`, which holds that level's rows row0 .. row0 + image.height - 1.
void draw_symbol(RgbaImage& image, double u, double v, const SymbolStyle& style, int row0 = 0);

/// A symbol's centre in texel coordinates of its level.
struct SymbolPosition {
  double u = 0, v = 0;
};

/// The symbols of one level (`size` texels covering `georef`, texels of texel_m metres): the
/// positions of the objects whose rules choose Symbol at symbol_level_distance_m(texel_m), in
/// the order given (the order they stack in).
std::vector<SymbolPosition> symbol_positions(std::span<const SymbolObject> objects, const GeoRect& georef,
                                             LevelSize size, double texel_m);

/// Rows row0 .. row0 + rows - 1 of a level `width` texels wide with the symbols at `positions`:
/// those rows of the whole level, texel for texel (a level computed band by band).
RgbaImage render_symbol_rows(std::span<const SymbolPosition> positions, int width, int row0, int rows,
                             const SymbolStyle& style);

/// One level of a symbol texture: a transparent `size` image (>= 1 x 1) covering `georef` with
/// the symbols of the objects whose rules choose Symbol at symbol_level_distance_m(texel_m).
/// `drawn`, when given, receives how many objects were drawn (clipped or not).
RgbaImage render_symbol_level(std::span<const SymbolObject> objects, const GeoRect& georef, LevelSize size,
                              double texel_m, const SymbolStyle& style, std::size_t* drawn = nullptr);

}  // namespace terralod::render
