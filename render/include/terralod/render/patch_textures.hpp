// PatchTextures: the texture of every drawn patch, per layer, from the layers' texture trees
// by the visual texture error gamma; the parent's texture while a patch loads; the resident
// texture memory within a budget. It turns a drawn mesh whose triangles know their
// approximation-tree node (blocks::DrawnMesh::triangle_node) into triangle ranges, each drawn
// with one set of textures (LayeredItem::first_triangle / triangle_count).
//
// Usage:
//   std::vector<std::shared_ptr<const TextureTree>> trees = {shade_tree, ortho_tree};  // per layer
//   PatchTextures pt(trees, loader, {/*gamma_px=*/1.0, /*budget_bytes=*/256u << 20});
//   // per frame, after the runtime's update:
//   const PatchTextureFrame& f = pt.frame(view, mesh.triangle_node, {true, true});
//   // draw mesh triangles in the order f.triangle_order (upload them so), then per group g:
//   //   LayeredItem{mesh_id, bindings from g.used / g.pixels, g.first_triangle, g.triangle_count}
//
// Rule (approximation-tree.txt 4.2, dynamic-3d-maps-texture-layers.txt 3.1):
//   - For each node N drawn this frame and each enabled layer, the wanted patch is the one
//     choose_textures() (texture_tree.hpp) picks: the patch of N's ancestor-or-self closest to
//     the root whose texel, placed at the point of N's box nearest the eye, covers at most
//     gamma pixels^2; owner(N) (the finest it has) when none does.
//   - Budget: every layer's patches are at most max_patch_bytes(layer). While the wanted
//     patches (distinct, all layers) times their layer's max_patch_bytes exceed budget_bytes,
//     gamma is doubled for this frame (PatchTextureStats::gamma_px says the value used; at
//     most 2^24 times). A texel seen from inside its node's box or edge-on has an unbounded
//     gamma, so if the patches still do not fit, the deepest wanted patches are replaced by
//     their parent patches until they fit; at the root's patches it stops. The patches bound in a frame are
//     never more than those wanted (each wanted patch is bound as itself or one ancestor), so the cache,
//     which evicts least-recently-used patches not bound this frame, holds at most budget_bytes whenever the
//     root patches fit (TextureCache's contract).
//   - Loading: a wanted patch that is not resident is requested (a worker thread reads it)
//     and the nearest resident ancestor patch is bound meanwhile (TextureCache::resolve);
//     none resident: the layer is unbound (transparent) on that group.
//   - Grouping: nodes binding the same patches in every layer share a group; the triangles are
//     ordered by group (first appearance of the group), keeping their order inside a group.
//     Triangles of a node that is not in the trees (negative or too large) go to a group with
//     no textures.
//   - Not thread-safe (one frame thread). Cost per frame: O(triangles + drawn nodes x
//     (depth + layers)); nothing is read on the frame thread.
//   - Memory: the cache's pixels (<= budget as above) + 4 bytes per triangle + 8 per tree node.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "terralod/pm/view.hpp"
#include "terralod/render/draw_mesh.hpp"
#include "terralod/render/rgba_image.hpp"
#include "terralod/render/texture_cache.hpp"
#include "terralod/render/texture_tree.hpp"

namespace terralod::render {

struct PatchTextureOptions {
  double gamma_px = 1.0;                              ///< texel area on screen, pixels^2, > 0
  std::size_t budget_bytes = std::size_t(256) << 20;  ///< resident texture pixels
  int threads = 1;                                    ///< loader threads, >= 1
};

struct PatchTextureGroup {
  std::size_t first_triangle = 0, triangle_count = 0;    ///< range of PatchTextureFrame::triangle_order
  std::vector<TextureKey> used;                          ///< per layer; node -1: unbound
  std::vector<std::shared_ptr<const RgbaImage>> pixels;  ///< per layer; null when unbound
};

struct PatchTextureStats {
  std::size_t nodes = 0;           ///< distinct drawn nodes
  std::size_t wanted = 0;          ///< distinct patches wanted (all layers)
  std::size_t from_parent = 0;     ///< wanted patches not resident, bound as an ancestor's or unbound
  double gamma_px = 0;             ///< gamma used this frame (raised when the budget required)
  std::size_t resident_bytes = 0;  ///< the cache's pixels after the frame's requests
};

struct PatchTextureFrame {
  std::vector<std::uint32_t> triangle_order;  ///< the drawn mesh's triangles, grouped
  std::vector<PatchTextureGroup> groups;
  PatchTextureStats stats;
};

/// `mesh` with its triangles in `order` (a permutation, e.g. PatchTextureFrame::triangle_order)
/// written to `out` (vertex data copied; out's buffers reused).
void order_triangles(const DrawMesh& mesh, std::span<const std::uint32_t> order, DrawMesh& out);

class PatchTextures {
 public:
  /// One tree per layer (TextureKey::layer is the index), built over the same node ids as the
  /// drawn mesh's triangle_node. `loader` reads the patch of key.node of layer key.layer (any
  /// worker thread). std::invalid_argument for no tree, a null tree, gamma <= 0, threads < 1.
  PatchTextures(std::vector<std::shared_ptr<const TextureTree>> trees, TextureLoader loader,
                const PatchTextureOptions& options = {});

  /// The frame's groups. `enabled` has one flag per layer (a disabled layer binds nothing and
  /// loads nothing). Never waits for a load.
  const PatchTextureFrame& frame(const pm::View& view, std::span<const std::int64_t> triangle_node,
                                 const std::vector<bool>& enabled);

  std::size_t layer_count() const { return trees_.size(); }
  const TextureTree& tree(int layer) const { return *trees_.at(std::size_t(layer)); }
  /// The largest patch of the layer, bytes (4 per pixel).
  std::size_t max_patch_bytes(int layer) const { return max_patch_bytes_.at(std::size_t(layer)); }
  const PatchTextureOptions& options() const { return options_; }
  void set_gamma(double gamma_px);
  TextureCache& cache() { return *cache_; }
  const TextureCache& cache() const { return *cache_; }

 private:
  std::vector<std::shared_ptr<const TextureTree>> trees_;
  std::vector<std::size_t> max_patch_bytes_;
  PatchTextureOptions options_;
  std::unique_ptr<TextureCache> cache_;
  PatchTextureFrame frame_;
  // Scratch, kept between frames.
  std::vector<std::int32_t> node_slot_;  // per tree node: index into nodes_, -1
  std::vector<std::int64_t> nodes_;      // distinct drawn nodes in first-appearance order
  std::vector<int> depth_;               // per tree node, the root 0
};

}  // namespace terralod::render
