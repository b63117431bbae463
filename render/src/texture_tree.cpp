// Texture trees: sub-image choice per node, pruning, the visual texture error gamma and
// texture reuse by ancestors (approximation-tree.txt sections 3.3, 4.1, 4.2).
// Memory: O(nodes); no pixels are touched here.
#include "terralod/render/texture_tree.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>

namespace terralod::render {
namespace {

int next_pow2(int v) {
  int p = 1;
  while (p < v) p *= 2;
  return p;
}

// Whole texels of an axis [0, n) covering [a, b] (texel units), clipped to the image.
// A relative slack of 1e-9 texels keeps a bound that lands on a texel edge from taking one
// more texel through rounding.
std::pair<int, int> texel_span(double a, double b, int n) {
  const int lo = int(std::floor(a + 1e-9));
  const int hi = int(std::ceil(b - 1e-9));
  return {std::clamp(lo, 0, n), std::clamp(std::max(hi, lo + 1), 0, n)};
}

// Start of a window of `size` texels that contains [lo, hi) and stays inside [0, n) if it can.
int place(int lo, int size, int n) {
  if (lo + size <= n) return lo;
  return std::max(0, n - size);
}

}  // namespace

PixelRect choose_subimage(const std::vector<LevelSize>& levels, const GeoRect& g, const GeoRect& d,
                          const TextureConstraints& c) {
  assert(!levels.empty() && c.max_texture_size >= 1 && g.width() > 0 && g.height() > 0);
  const int last = int(levels.size()) - 1;
  for (int k = 0; k <= last; ++k) {
    const LevelSize ls = levels[std::size_t(k)];
    const double tx = g.width() / ls.width, ty = g.height() / ls.height;
    const auto [x0, x1] = texel_span((d.minx - g.minx) / tx, (d.maxx - g.minx) / tx, ls.width);
    const auto [y0, y1] = texel_span((g.maxy - d.maxy) / ty, (g.maxy - d.miny) / ty, ls.height);
    int w = std::max(1, x1 - x0), h = std::max(1, y1 - y0);
    if (c.power_of_two) w = next_pow2(w), h = next_pow2(h);
    if ((w > c.max_texture_size || h > c.max_texture_size) && k < last) continue;
    PixelRect r;
    r.level = k;
    r.width = w;
    r.height = h;
    r.x0 = c.power_of_two ? place(x0, w, ls.width) : x0;
    r.y0 = c.power_of_two ? place(y0, h, ls.height) : y0;
    return r;
  }
  return {};  // unreachable: the last level always returns
}

GeoRect pixel_rect_georef(const std::vector<LevelSize>& levels, const GeoRect& g, const PixelRect& r) {
  const LevelSize ls = levels.at(std::size_t(r.level));
  const double tx = g.width() / ls.width, ty = g.height() / ls.height;
  return GeoRect{g.minx + r.x0 * tx, g.maxy - (r.y0 + r.height) * ty, g.minx + (r.x0 + r.width) * tx,
                 g.maxy - r.y0 * ty};
}

double visual_texture_error_px(const pm::View& view, const pm::Box& b, double w, double h) {
  assert(w > 0 && h > 0);
  const pm::Vec3& e = view.eye();
  const pm::Vec3 p{std::clamp(e.x, b.lo.x, b.hi.x), std::clamp(e.y, b.lo.y, b.hi.y),
                   std::clamp(e.z, b.lo.z, b.hi.z)};
  const double dx[4] = {-0.5, 0.5, 0.5, -0.5}, dy[4] = {-0.5, -0.5, 0.5, 0.5};
  double px[4], py[4];
  for (int i = 0; i < 4; ++i)
    if (!view.project(pm::Vec3{p.x + dx[i] * w, p.y + dy[i] * h, p.z}, px[i], py[i]))
      return std::numeric_limits<double>::infinity();
  double area2 = 0;  // shoelace
  for (int i = 0; i < 4; ++i) area2 += px[i] * py[(i + 1) % 4] - px[(i + 1) % 4] * py[i];
  return std::abs(area2) / 2;
}

TextureTree::TextureTree(std::vector<PatchDomain> nodes, std::vector<LevelSize> levels, const GeoRect& g,
                         const TextureConstraints& c)
    : nodes_(std::move(nodes)), levels_(std::move(levels)), georef_(g), constraints_(c) {
  assert(!levels_.empty() && g.width() > 0 && g.height() > 0);
  const std::size_t n = nodes_.size();
  for (std::size_t i = 0; i < n; ++i) {
    const PatchDomain& d = nodes_[i];
    if (d.id != std::int64_t(i))
      throw std::invalid_argument("TextureTree: node at position " + std::to_string(i) + " has id " +
                                  std::to_string(d.id));
    if ((i == 0) != (d.parent < 0) || d.parent >= std::int64_t(n))
      throw std::invalid_argument("TextureTree: node " + std::to_string(i) + " has parent " +
                                  std::to_string(d.parent));
    for (std::int64_t ch : d.children)
      if (ch <= 0 || ch >= std::int64_t(n) || nodes_[std::size_t(ch)].parent != d.id)
        throw std::invalid_argument("TextureTree: node " + std::to_string(i) + " lists child " +
                                    std::to_string(ch) + " whose parent is not it");
  }
  patch_index_.assign(n, -1);
  owner_.assign(n, -1);
  if (n == 0) return;
  // Top-down: each node gets a patch unless an ancestor already uses level 0.
  std::vector<std::pair<std::int64_t, bool>> stack{{0, false}};  // (node, inside a pruned subtree)
  while (!stack.empty()) {
    const auto [id, pruned] = stack.back();
    stack.pop_back();
    const PatchDomain& d = nodes_[std::size_t(id)];
    bool finest = pruned;
    if (!pruned) {
      const GeoRect dom{d.bbox.lo.x, d.bbox.lo.y, d.bbox.hi.x, d.bbox.hi.y};
      const bool misses =
          dom.maxx <= g.minx || dom.minx >= g.maxx || dom.maxy <= g.miny || dom.miny >= g.maxy;
      if (!misses) {
        TexturePatch p;
        p.node = id;
        p.rect = choose_subimage(levels_, g, dom, c);
        p.georef = pixel_rect_georef(levels_, g, p.rect);
        const LevelSize ls = levels_[std::size_t(p.rect.level)];
        p.texel_w = g.width() / ls.width;
        p.texel_h = g.height() / ls.height;
        patch_index_[std::size_t(id)] = std::int64_t(patches_.size());
        patches_.push_back(p);
        finest = p.rect.level == 0;
      }
    }
    owner_[std::size_t(id)] =
        patch_index_[std::size_t(id)] >= 0 ? id : (d.parent >= 0 ? owner_[std::size_t(d.parent)] : -1);
    for (std::int64_t ch : d.children) stack.push_back({ch, finest});
  }
  patch_count_ = patches_.size();
}

const TexturePatch& TextureTree::patch(std::int64_t node) const {
  const std::int64_t i = patch_index_.at(std::size_t(node));
  assert(i >= 0 && "TextureTree::patch: the node has no patch of its own");
  return patches_[std::size_t(i)];
}

double TextureTree::texel_m(std::int64_t node) const {
  const std::int64_t o = owner(node);
  return o < 0 ? 0.0 : std::max(patch(o).texel_w, patch(o).texel_h);
}

std::int64_t TextureTree::parent_patch(std::int64_t node) const {
  const std::int64_t o = owner(node);
  if (o < 0) return -1;
  const std::int64_t p = nodes_[std::size_t(o)].parent;
  return p < 0 ? -1 : owner(p);
}

PatchSelection select_patches(const TextureTree& tree, const pm::View& view, const PatchSelectionOptions& o) {
  PatchSelection out;
  if (tree.node_count() == 0) return out;
  std::vector<std::int64_t> stack{0};
  while (!stack.empty()) {
    const std::int64_t id = stack.back();
    stack.pop_back();
    const PatchDomain& d = tree.domain(id);
    ++out.visited;
    if (o.cull && view.outside(d.bbox)) {
      ++out.culled;
      continue;
    }
    bool refine = false;
    if (!d.children.empty()) {
      refine = view.vertical_error_px(d.bbox, d.error) > o.alpha_px;
      const std::int64_t own = tree.owner(id);
      if (!refine && own >= 0 && tree.patch(own).rect.level > 0) {
        const TexturePatch& p = tree.patch(own);
        refine = visual_texture_error_px(view, d.bbox, p.texel_w, p.texel_h) > o.gamma_px;
      }
    }
    if (!refine) {
      out.selected.push_back(id);
      continue;
    }
    for (auto it = d.children.rbegin(); it != d.children.rend(); ++it) stack.push_back(*it);
  }
  return out;
}

std::vector<TextureGroup> choose_textures(const TextureTree& tree, const pm::View& view,
                                          std::span<const std::int64_t> selected, double gamma_px) {
  std::vector<TextureGroup> groups;
  std::map<std::int64_t, std::size_t> group_of;
  std::vector<std::int64_t> path;
  for (std::int64_t n : selected) {
    const pm::Box& box = tree.domain(n).bbox;
    // Patches on the path from the root down to owner(n), root first.
    path.clear();
    for (std::int64_t a = tree.owner(n); a >= 0;) {
      path.push_back(a);
      const std::int64_t up = tree.domain(a).parent;
      a = up >= 0 ? tree.owner(up) : -1;
    }
    std::reverse(path.begin(), path.end());
    std::int64_t use = tree.owner(n);
    for (std::int64_t a : path) {
      const TexturePatch& p = tree.patch(a);
      if (visual_texture_error_px(view, box, p.texel_w, p.texel_h) <= gamma_px) {
        use = a;
        break;
      }
    }
    auto [it, fresh] = group_of.try_emplace(use, groups.size());
    if (fresh) groups.push_back(TextureGroup{use, {}});
    groups[it->second].nodes.push_back(n);
  }
  return groups;
}

}  // namespace terralod::render
