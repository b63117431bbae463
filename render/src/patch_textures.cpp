// Per-patch textures of the drawn mesh (patch_textures.hpp).
#include "terralod/render/patch_textures.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>

namespace terralod::render {

namespace {
// 2^24 times the asked gamma: a texel may then cover any part of the screen.
constexpr int kMaxGammaDoublings = 24;
}  // namespace

PatchTextures::PatchTextures(std::vector<std::shared_ptr<const TextureTree>> trees, TextureLoader loader,
                             const PatchTextureOptions& options)
    : trees_(std::move(trees)), options_(options) {
  if (trees_.empty()) throw std::invalid_argument("PatchTextures: no texture tree");
  for (std::size_t l = 0; l < trees_.size(); ++l) {
    if (!trees_[l]) throw std::invalid_argument("PatchTextures: layer " + std::to_string(l) + " has no tree");
    if (trees_[l]->node_count() != trees_[0]->node_count())
      throw std::invalid_argument("PatchTextures: layer " + std::to_string(l) + "'s tree has " +
                                  std::to_string(trees_[l]->node_count()) + " nodes, layer 0's " +
                                  std::to_string(trees_[0]->node_count()));
    std::size_t most = 0;
    for (std::size_t n = 0; n < trees_[l]->node_count(); ++n)
      if (trees_[l]->has_patch(std::int64_t(n))) {
        const PixelRect& r = trees_[l]->patch(std::int64_t(n)).rect;
        most = std::max(most, std::size_t(r.width) * std::size_t(r.height) * 4);
      }
    max_patch_bytes_.push_back(most);
  }
  if (!(options_.gamma_px > 0)) throw std::invalid_argument("PatchTextures: gamma must be > 0 pixels^2");
  if (options_.threads < 1) throw std::invalid_argument("PatchTextures: threads must be >= 1");
  TextureCacheOptions co;
  co.budget_bytes = options_.budget_bytes;
  co.threads = options_.threads;
  cache_ = std::make_unique<TextureCache>(std::move(loader), co);
  node_slot_.assign(trees_[0]->node_count(), -1);
  // Depth of every node (walking up: ids need not be in parent-first order).
  const TextureTree& t0 = *trees_[0];
  depth_.assign(t0.node_count(), 0);
  for (std::size_t n = 0; n < t0.node_count(); ++n)
    for (std::int64_t a = t0.domain(std::int64_t(n)).parent; a >= 0; a = t0.domain(a).parent) ++depth_[n];
}

void order_triangles(const DrawMesh& mesh, std::span<const std::uint32_t> order, DrawMesh& out) {
  assert(order.size() == mesh.triangle_count());
  out.origin = mesh.origin;
  out.xyz = mesh.xyz;
  out.z_target = mesh.z_target;
  out.normals = mesh.normals;
  out.indices.resize(mesh.indices.size());
  for (std::size_t k = 0; k < order.size(); ++k)
    for (std::size_t j = 0; j < 3; ++j) out.indices[3 * k + j] = mesh.indices[3 * std::size_t(order[k]) + j];
}

void PatchTextures::set_gamma(double gamma_px) {
  if (!(gamma_px > 0)) throw std::invalid_argument("PatchTextures: gamma must be > 0 pixels^2");
  options_.gamma_px = gamma_px;
}

const PatchTextureFrame& PatchTextures::frame(const pm::View& view,
                                              std::span<const std::int64_t> triangle_node,
                                              const std::vector<bool>& enabled) {
  if (enabled.size() != trees_.size())
    throw std::invalid_argument("PatchTextures: " + std::to_string(enabled.size()) + " enabled flags for " +
                                std::to_string(trees_.size()) + " layers");
  const std::size_t layers = trees_.size();
  PatchTextureFrame& f = frame_;
  f.stats = {};
  f.groups.clear();
  cache_->begin_frame();

  // The distinct drawn nodes, one slot each in first-appearance order; the triangles of no
  // tree node share one more slot after them.
  nodes_.clear();
  std::vector<std::int32_t> tri_slot(triangle_node.size());
  bool any_none = false;
  for (std::size_t t = 0; t < triangle_node.size(); ++t) {
    const std::int64_t n = triangle_node[t];
    if (n >= 0 && std::size_t(n) < node_slot_.size()) {
      std::int32_t& s = node_slot_[std::size_t(n)];
      if (s < 0) {
        s = std::int32_t(nodes_.size());
        nodes_.push_back(n);
      }
      tri_slot[t] = s;
    } else {
      tri_slot[t] = -1;
      any_none = true;
    }
  }
  const std::size_t tree_slots = nodes_.size();
  const std::size_t slots = tree_slots + (any_none ? 1 : 0);
  for (std::int32_t& s : tri_slot)
    if (s < 0) s = std::int32_t(tree_slots);
  f.stats.nodes = tree_slots;

  // The wanted patch of every slot and layer; gamma doubles while the budget does not hold.
  std::vector<std::int64_t> wanted(slots * layers, -1);
  // Bytes the wanted patches may take: max_patch_bytes per distinct patch; true when a
  // wanted patch has a coarser one above it.
  auto cost = [&](std::size_t& bytes, std::size_t& count) {
    bytes = count = 0;
    bool coarser = false;
    std::vector<std::int64_t> seen;
    for (std::size_t l = 0; l < layers; ++l) {
      seen.clear();
      for (std::size_t s = 0; s < slots; ++s)
        if (wanted[s * layers + l] >= 0) seen.push_back(wanted[s * layers + l]);
      std::sort(seen.begin(), seen.end());
      seen.erase(std::unique(seen.begin(), seen.end()), seen.end());
      count += seen.size();
      bytes += seen.size() * max_patch_bytes_[l];
      for (std::int64_t w : seen) coarser = coarser || trees_[l]->parent_patch(w) >= 0;
    }
    return coarser;
  };
  double gamma = options_.gamma_px;
  std::size_t bytes = 0, count = 0;
  for (int round = 0;; ++round) {
    for (std::size_t l = 0; l < layers; ++l) {
      if (!enabled[l]) continue;
      for (const TextureGroup& g : choose_textures(*trees_[l], view, nodes_, gamma))
        for (std::int64_t n : g.nodes)
          wanted[std::size_t(node_slot_[std::size_t(n)]) * layers + l] = g.texture_node;
    }
    const bool coarser = cost(bytes, count);
    if (bytes <= options_.budget_bytes || !coarser || round >= kMaxGammaDoublings) break;
    gamma *= 2;
  }
  // Texels seen from inside their node's box or edge-on have an unbounded gamma, so doubling
  // may not be enough: the deepest wanted patches then give way to their parents' until the
  // patches fit or only the roots' are left.
  for (bool coarser = cost(bytes, count); bytes > options_.budget_bytes && coarser;
       coarser = cost(bytes, count)) {
    int deepest = -1;
    for (std::size_t i = 0; i < wanted.size(); ++i)
      if (wanted[i] >= 0 && trees_[i % layers]->parent_patch(wanted[i]) >= 0)
        deepest = std::max(deepest, depth_[std::size_t(wanted[i])]);
    for (std::size_t i = 0; i < wanted.size(); ++i)
      if (wanted[i] >= 0 && depth_[std::size_t(wanted[i])] == deepest) {
        const std::int64_t up = trees_[i % layers]->parent_patch(wanted[i]);
        if (up >= 0) wanted[i] = up;
      }
  }
  f.stats.wanted = count;
  f.stats.gamma_px = gamma;
  for (std::int64_t n : nodes_) node_slot_[std::size_t(n)] = -1;  // the scratch is all -1 between frames

  // Resolve each distinct wanted patch once: itself when resident, else the nearest resident
  // ancestor (requesting the chain), else unbound.
  struct Bound {
    TextureKey used;
    std::shared_ptr<const RgbaImage> pixels;
  };
  std::map<TextureKey, Bound> bound;
  for (std::size_t s = 0; s < slots; ++s)
    for (std::size_t l = 0; l < layers; ++l) {
      const std::int64_t w = wanted[s * layers + l];
      if (w < 0) continue;
      const TextureKey key{int(l), w};
      auto [it, fresh] = bound.try_emplace(key);
      if (!fresh) continue;
      TextureKey used{int(l), -1};
      it->second.pixels = cache_->resolve(*trees_[l], key, &used);
      it->second.used = it->second.pixels ? used : TextureKey{int(l), -1};
      if (it->second.used.node != w) ++f.stats.from_parent;
    }

  // Group the slots by the patches they bind.
  std::map<std::vector<std::int64_t>, std::size_t> group_of_binding;
  std::vector<std::size_t> group_of_slot(slots);
  std::vector<std::int64_t> binding(layers);
  for (std::size_t s = 0; s < slots; ++s) {
    for (std::size_t l = 0; l < layers; ++l) {
      const std::int64_t w = wanted[s * layers + l];
      binding[l] = w < 0 ? -1 : bound.at(TextureKey{int(l), w}).used.node;
    }
    auto [it, fresh] = group_of_binding.try_emplace(binding, f.groups.size());
    if (fresh) {
      PatchTextureGroup g;
      for (std::size_t l = 0; l < layers; ++l) {
        const std::int64_t w = wanted[s * layers + l];
        g.used.push_back(TextureKey{int(l), binding[l]});
        g.pixels.push_back(w < 0 ? nullptr : bound.at(TextureKey{int(l), w}).pixels);
      }
      f.groups.push_back(std::move(g));
    }
    group_of_slot[s] = it->second;
  }

  // Triangles ordered by group (a counting sort keeps their order inside a group).
  std::vector<std::size_t> start(f.groups.size() + 1, 0);
  for (std::int32_t s : tri_slot) ++start[group_of_slot[std::size_t(s)] + 1];
  for (std::size_t g = 0; g < f.groups.size(); ++g) {
    f.groups[g].first_triangle = start[g];
    f.groups[g].triangle_count = start[g + 1];
    start[g + 1] += start[g];
  }
  f.triangle_order.resize(triangle_node.size());
  for (std::size_t t = 0; t < tri_slot.size(); ++t)
    f.triangle_order[start[group_of_slot[std::size_t(tri_slot[t])]]++] = std::uint32_t(t);
  f.stats.resident_bytes = cache_->stats().resident_bytes;
  return f;
}

}  // namespace terralod::render
