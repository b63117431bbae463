// ObjectRenderer: draws 3D map objects (issue 19) into a TerrainRenderer frame, depth-tested
// against the terrain: icons (1-3 textured quads, the paper's trees), labels (FreeType text
// billboards with a dark halo) and object meshes (extruded shapes, draped lines).
//
// Usage:
//   terralod::render::TerrainRenderer terrain(*ctx);
//   terralod::render::ObjectRenderer objects(*ctx);               // loads the label font
//   auto marker = objects.add_icon_style(terralod::render::default_marker_image(), /*quads=*/1);
//   auto tree = objects.load_icon_style("tree.png", /*quads=*/2);  // OpenImageIO, RGBA
//   terrain.draw(camera, items);                                   // the terrain first
//   objects.draw_mesh(terrain, buildings, {0.8f, 0.75f, 0.7f, 1.0f});
//   objects.draw_mesh(terrain, roads, {0.2f, 0.2f, 0.2f, 1.0f}, {.on_terrain = true});
//   objects.draw_icons(terrain, {{anchor, marker, /*size_m=*/20.0}});
//   // labels: declutter first with the rectangles the renderer will draw
//   auto p = terralod::render::project_point(camera, anchor);     // nullopt behind the camera
//   terralod::render::PixelBox r = objects.label_rect({p->x, p->y}, "Mont Blanc", 14);
//   ... LabelDeclutterer::update(candidates with r) ...
//   objects.draw_labels(terrain, shown_labels);
//   terralod::render::Image img = terrain.read_color();          // terrain + objects
//
// Contract:
//   - Drawing calls bind the last frame of a FrameSource (terrain_renderer.hpp: a
//     TerrainRenderer, or a LayeredRenderer with texture layers; its framebuffer, depth buffer,
//     camera, depth convention and light) and draw into it; call them after its draw() and
//     before read_color()/present(). Both renderers must use the same
//     context; the ObjectRenderer must be destroyed before it. Not thread-safe.
//   - Coordinates: anchors and mesh positions are world metres in doubles; each call subtracts
//     the camera position (the per-frame origin) in doubles before anything becomes a float,
//     so UTM-sized coordinates never meet float arithmetic.
//   - Icons: the image's bottom centre stands on the anchor; height size_m metres, width
//     size_m * image width / height. quads = 1: a billboard turning about the vertical axis to
//     face the camera; 2 or 3: vertical quads crossing at the vertical axis through the anchor,
//     180/quads degrees apart, fixed in the world (the first along world x). Texels with alpha
//     below options.icon_alpha_cutoff are discarded (alpha test: depth stays exact, no sorting).
//   - Labels: glyphs from FreeType (options.font, DejaVu Sans by default, Debian package
//     fonts-dejavu-core) at `size_px` pixels per em, each with a halo of options.halo_px pixels
//     (the glyph coverage's maximum over a disc of that radius, drawn first in halo_color).
//     The label's rectangle is the union of its glyphs' boxes (ink + halo); label_rect() is
//     exactly the pixels draw_labels() may touch: the rectangle centred horizontally on the
//     projected anchor, its baseline options.label_offset_px above it, rounded to whole pixels
//     (texels map 1:1 to pixels, nearest sampling). A label is depth-tested at its anchor,
//     moved towards the camera by options.label_depth_share of the distance (so the ground
//     it stands on does not hide it) and does not write depth. Text without ink draws nothing.
//   - Meshes: blocks::ObjectMesh (object_mesh.hpp) in one colour, lit like the terrain (the
//     TerrainRenderer's light_direction and ambient, Lambert), with its normals or, without
//     any, flat per triangle. MeshStyle::on_terrain adds a polygon offset towards the camera so
//     that draped ribbons whose vertices lie exactly on the drawn terrain do not z-fight.
//   - Errors: an unreadable icon image or font throws std::runtime_error naming the file;
//     quads outside 1..3, an empty image, an unknown IconStyleId or a non-positive size is an
//     std::invalid_argument; GL failures throw RenderError.
//
// Cost: each draw_* call makes one buffer upload (all its instances / vertices) and one draw
// call per icon style (icons), two (labels: halo, then text) or one (a mesh), whatever the
// number of objects. Labels lay out on the CPU (cached glyphs: a map lookup per character);
// new glyphs are rasterised once and the atlas re-uploaded when it changed.
// Memory: on the GPU, 4 bytes per icon texel (+1/3 for mipmaps), 2 per atlas texel (512 wide),
// 16 bytes per icon instance, 36 per label glyph, 24 per mesh vertex + 12 per triangle, reused
// from call to call (buffers grow, never shrink).
#pragma once

#include <cstdint>
#include <glm/glm.hpp>
#include <initializer_list>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "terralod/blocks/object_mesh.hpp"
#include "terralod/render/camera.hpp"
#include "terralod/render/gl_context.hpp"
#include "terralod/render/rgba_image.hpp"
#include "terralod/render/terrain_renderer.hpp"

namespace terralod::render {

struct ObjectRendererOptions {
  std::string font = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";  ///< labels' TrueType font
  int halo_px = 2;                               ///< label outline radius, pixels, 0..8
  glm::vec4 text_color{1.0f, 1.0f, 1.0f, 1.0f};  ///< straight alpha
  glm::vec4 halo_color{0.05f, 0.05f, 0.06f, 0.85f};
  int label_offset_px = 8;          ///< baseline this many pixels above the projected anchor
  double label_depth_share = 0.02;  ///< label depth test at the anchor moved this share towards the camera
  float icon_alpha_cutoff = 0.5f;   ///< icon texels below this alpha are not drawn, (0, 1]
  bool finish = false;              ///< glFinish after each draw_* (for timing)
};

/// Handle of an icon style (image + quad count); 0 is never valid.
struct IconStyleId {
  std::uint32_t value = 0;
  bool operator==(const IconStyleId&) const = default;
};

struct IconInstance {
  glm::dvec3 anchor{0.0};  ///< world metres: the icon's bottom centre
  IconStyleId style;
  double size_m = 20.0;  ///< height, metres, > 0 (the rules' icon_size_m)
};

struct LabelInstance {
  glm::dvec3 anchor{0.0};  ///< world metres: the point the label stands above
  std::string text;        ///< UTF-8 (invalid bytes show as U+FFFD)
  int size_px = 14;        ///< pixels per em, >= 1 (the rules' label_size_px, rounded)
};

/// Half-open pixel rectangle [x0, x1) x [y0, y1), image coordinates (top-left origin), the
/// convention of blocks::LabelDeclutterer's candidates.
struct PixelBox {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  int width() const { return x1 - x0; }
  int height() const { return y1 - y0; }
  bool empty() const { return x1 <= x0 || y1 <= y0; }
  bool operator==(const PixelBox&) const = default;
};

struct MeshStyle {
  bool on_terrain = false;     ///< polygon offset towards the camera (draped ribbons)
  float offset_factor = 1.0f;  ///< glPolygonOffset slope factor used when on_terrain
  float offset_units = 4.0f;   ///< glPolygonOffset units used when on_terrain
};

/// What one draw_* call did.
struct ObjectDrawStats {
  std::size_t objects = 0;  ///< icons, labels or triangles drawn
  std::size_t draw_calls = 0;
  std::size_t bytes_uploaded = 0;  ///< instance / vertex data (+ the label atlas when it changed)
};

/// A world point projected with `camera`: image x, y in pixels (top-left origin, pixel
/// centres at +0.5) and the distance along the view axis; nullopt when it is not in front of
/// the near plane. Doubles throughout.
struct ScreenPoint {
  double x = 0.0, y = 0.0, eye_depth = 0.0;
};
std::optional<ScreenPoint> project_point(const Camera& camera, const glm::dvec3& world);

/// The built-in icon image: a red map pin with a white dot and a dark rim, `size` x `size`
/// pixels (>= 8), alpha 0 or 255, its tip at the bottom centre. Generated, no file.
RgbaImage default_marker_image(int size = 64);

class ObjectRenderer {
 public:
  /// Compiles the shaders and opens options.font (std::runtime_error naming it on failure).
  explicit ObjectRenderer(GlContext& context, const ObjectRendererOptions& options = {});
  ~ObjectRenderer();
  ObjectRenderer(const ObjectRenderer&) = delete;
  ObjectRenderer& operator=(const ObjectRenderer&) = delete;

  const ObjectRendererOptions& options() const { return options_; }

  /// Uploads an icon image (RGBA, straight alpha, top row first) drawn with `quads` quads (1..3).
  IconStyleId add_icon_style(const RgbaImage& image, int quads);
  /// Reads an image file through OpenImageIO (grey, RGB, with or without alpha; only a channel
  /// the file marks as alpha is alpha, else the icon is opaque) and adds it.
  IconStyleId load_icon_style(const std::string& path, int quads);

  /// Width and height in pixels of the rectangle a label of `text` at `size_px` covers.
  glm::ivec2 measure_label(std::string_view text, int size_px);
  /// The rectangle draw_labels() covers for a label whose anchor projects to `anchor_px`.
  PixelBox label_rect(const glm::dvec2& anchor_px, std::string_view text, int size_px);

  ObjectDrawStats draw_icons(FrameSource& frame, std::span<const IconInstance> icons);
  ObjectDrawStats draw_icons(FrameSource& frame, std::initializer_list<IconInstance> icons) {
    return draw_icons(frame, std::span<const IconInstance>(icons.begin(), icons.size()));
  }
  ObjectDrawStats draw_labels(FrameSource& frame, std::span<const LabelInstance> labels);
  ObjectDrawStats draw_labels(FrameSource& frame, std::initializer_list<LabelInstance> labels) {
    return draw_labels(frame, std::span<const LabelInstance>(labels.begin(), labels.size()));
  }
  ObjectDrawStats draw_mesh(FrameSource& frame, const blocks::ObjectMesh& mesh, const glm::vec4& color,
                            const MeshStyle& style = {});

 private:
  struct Impl;
  GlContext& ctx_;
  ObjectRendererOptions options_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace terralod::render
