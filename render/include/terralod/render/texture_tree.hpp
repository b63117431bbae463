// TextureTree: the texture patches of one texture layer, mirroring the approximation tree,
// with the visual texture error gamma and the choice of the texture each selected patch uses.
//
// Usage:
//   // Node domains with parent/children (ids dense, root 0), e.g. from the approximation tree:
//   std::vector<terralod::render::PatchDomain> doms = terralod::render::patch_domains(tree.nodes());
//   terralod::render::GeoRect georef{minx, miny, maxx, maxy};        // the image's world extent
//   terralod::render::TextureConstraints tc;  tc.max_texture_size = 512;
//   terralod::render::TextureTree tt(doms, pyramid.level_sizes(), georef, tc);
//   const terralod::render::TexturePatch& p = tt.patch(tt.owner(node));  // level + pixel rect
//   double g = terralod::render::visual_texture_error_px(view, doms[node].bbox, p.texel_w, p.texel_h);
//   auto sel = terralod::render::select_patches(tt, view, {/*alpha_px=*/2, /*gamma_px=*/2});
//   auto groups = terralod::render::choose_textures(tt, view, sel.selected, /*gamma_px=*/2);
//
// Algorithms (approximation-tree.txt sections 3.3, 4.1, 4.2; dynamic-3d-maps section 3.1):
//   - Sub-image of a node N (choose_subimage): the first pyramid level, finest first, whose
//     sub-image covering exactly N's world domain (whole texels, clipped to the image) fits
//     max_texture_size on both sides (after rounding each side up to a power of two when
//     power_of_two is set); the patch is that sub-image, grown to the power-of-two size and
//     shifted to stay inside the image where it can (Q_N contains Q').
//   - Pruning: a node whose patch uses level 0 has no patches below it; its descendants are
//     textured by it (owner()).
//   - gamma(N) (visual_texture_error_px): the area in pixels of the image of a w x h
//     rectangle parallel to the xy-plane, centred at the point p of N's bounding box nearest
//     the eye (w x h = one texel of N's patch), computed exactly from its four projected
//     corners. +infinity when a corner is not in front of the eye.
//   - Texture reuse (choose_textures): a selected node N is drawn with the patch of the
//     ancestor-or-self A closest to the root whose texel, placed at N's nearest point, has
//     gamma <= the threshold; if none does, with owner(N) (the finest texture it has).
//     Nodes are then grouped by the texture they use.
//   Memory: one TexturePatch (~80 bytes) + the PatchDomain copy per node.
//
// World frame: x east, y north, metres. A texture's georef covers its whole image (texel
// areas, not centres): pixel (0, 0)'s top-left corner is at (minx, maxy), rows go south.
// For one texel per DEM sample, pad the sample extent by half a cell on each side.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "terralod/blocks/sample_rect.hpp"
#include "terralod/pm/view.hpp"
#include "terralod/render/image_pyramid.hpp"

namespace terralod::render {

/// World rectangle, metres; minx < maxx, miny < maxy.
struct GeoRect {
  double minx = 0, miny = 0, maxx = 0, maxy = 0;
  double width() const { return maxx - minx; }
  double height() const { return maxy - miny; }
  bool operator==(const GeoRect&) const = default;
};

/// Constraints of the rendering system on one texture.
struct TextureConstraints {
  int max_texture_size = 2048;  ///< pixels per side, >= 1
  bool power_of_two = false;    ///< sides rounded up to powers of two (<= max_texture_size)
};

/// The domain of one approximation-tree node, as the texture tree needs it.
struct PatchDomain {
  std::int64_t id = 0, parent = -1;    ///< dense ids 0..n-1, root 0 with parent -1
  std::vector<std::int64_t> children;  ///< each child's parent is this node
  blocks::SampleRect domain;           ///< samples of the whole terrain grid
  pm::Box bbox;                        ///< world 3D box; its xy extent is the node's world domain
  double error = 0;                    ///< epsilon(N), metres (for alpha in select_patches)
};

/// PatchDomains from any node list with members id, parent, children, domain, bbox, error
/// (blocks::TreeNode has them), in id order.
template <class Node>
std::vector<PatchDomain> patch_domains(const std::vector<Node>& nodes) {
  std::vector<PatchDomain> out;
  out.reserve(nodes.size());
  for (const Node& n : nodes)
    out.push_back(PatchDomain{n.id, n.parent, n.children, n.domain, n.bbox, double(n.error)});
  return out;
}

/// The texture of one node: a sub-image of one pyramid level.
struct TexturePatch {
  std::int64_t node = -1;           ///< the node it belongs to
  PixelRect rect;                   ///< level + pixels (may reach outside the image when power_of_two)
  GeoRect georef;                   ///< world rectangle covered by rect
  double texel_w = 0, texel_h = 0;  ///< texel size at that level, metres
};

/// Pixel rectangle of `levels[k]` (k chosen as above) for a world domain. `levels` as
/// pyramid_levels() returns; image_georef the world extent of level 0.
PixelRect choose_subimage(const std::vector<LevelSize>& levels, const GeoRect& image_georef,
                          const GeoRect& domain, const TextureConstraints& constraints);

/// World rectangle covered by a pixel rectangle of a pyramid.
GeoRect pixel_rect_georef(const std::vector<LevelSize>& levels, const GeoRect& image_georef,
                          const PixelRect& r);

/// gamma: projected area in pixels of a texel_w x texel_h texel (metres, > 0) at the point of
/// `bbox` nearest the eye; +infinity when the texel is not wholly in front of the eye.
double visual_texture_error_px(const pm::View& view, const pm::Box& bbox, double texel_w, double texel_h);

class TextureTree {
 public:
  /// Builds the patches top-down from the root. Throws std::invalid_argument when the node
  /// list is not a tree with dense ids (names the node).
  TextureTree(std::vector<PatchDomain> nodes, std::vector<LevelSize> levels, const GeoRect& image_georef,
              const TextureConstraints& constraints = {});

  std::size_t node_count() const { return nodes_.size(); }
  std::size_t patch_count() const { return patch_count_; }
  const PatchDomain& domain(std::int64_t node) const { return nodes_.at(std::size_t(node)); }
  const std::vector<PatchDomain>& domains() const { return nodes_; }
  const std::vector<LevelSize>& levels() const { return levels_; }
  const GeoRect& image_georef() const { return georef_; }
  const TextureConstraints& constraints() const { return constraints_; }

  /// True when the node has a patch of its own (false inside a pruned subtree, or where the
  /// domain misses the image).
  bool has_patch(std::int64_t node) const { return patch_index_.at(std::size_t(node)) >= 0; }
  /// The node's own patch; has_patch(node) must hold.
  const TexturePatch& patch(std::int64_t node) const;
  /// The node, or its nearest ancestor with a patch; -1 when none has one.
  std::int64_t owner(std::int64_t node) const { return owner_.at(std::size_t(node)); }
  /// Edge of one texel of the texture that textures `node` at best (its owner's patch),
  /// metres: max(texel_w, texel_h); 0 when no patch covers it. This is the value for
  /// blocks::TreeNode::texel_m, through which the approximation tree's select_nodes applies
  /// SelectionOptions::gamma_px.
  double texel_m(std::int64_t node) const;
  /// The nearest proper ancestor of owner(node) with a patch (the parent texture to use while
  /// the owner's loads); -1 for the root patch.
  std::int64_t parent_patch(std::int64_t node) const;

 private:
  std::vector<PatchDomain> nodes_;
  std::vector<LevelSize> levels_;
  GeoRect georef_;
  TextureConstraints constraints_;
  std::vector<TexturePatch> patches_;
  std::vector<std::int64_t> patch_index_;  // per node, -1 = none
  std::vector<std::int64_t> owner_;
  std::size_t patch_count_ = 0;
};

/// Selection over the patch domains: visit from the root, skip nodes outside the frustum,
/// select a node when alpha (pm::View::vertical_error_px of its error) <= alpha_px and gamma
/// (with its owner's texel) <= gamma_px, or when it is a leaf; gamma alone does not descend
/// below a node whose texture is already the finest (level 0). The reference the renderer and
/// benchmark use; the approximation tree's select_nodes implements the same rule.
struct PatchSelectionOptions {
  double alpha_px = std::numeric_limits<double>::infinity();  ///< geometric threshold, pixels
  double gamma_px = 1.0;                                      ///< texture threshold, pixels^2
  bool cull = true;
};
struct PatchSelection {
  std::vector<std::int64_t> selected;  ///< in depth-first order
  std::size_t visited = 0, culled = 0;
};
PatchSelection select_patches(const TextureTree& tree, const pm::View& view,
                              const PatchSelectionOptions& options = {});

/// Geometry nodes drawn with one texture patch.
struct TextureGroup {
  std::int64_t texture_node = -1;   ///< the node whose patch is used; -1: no texture
  std::vector<std::int64_t> nodes;  ///< selected nodes, in input order
};
/// The texture each selected node uses (see above), grouped by texture (groups ordered by the
/// first node using them).
std::vector<TextureGroup> choose_textures(const TextureTree& tree, const pm::View& view,
                                          std::span<const std::int64_t> selected, double gamma_px);

}  // namespace terralod::render
