// The --texture-db / --layer / --lens options of `terralod view` and `terralod-fly`.
#include "layer_options.hpp"

#include <cassert>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "cli_common.hpp"
#include "terralod/blocks/block_database.hpp"

namespace terralod::cli {

namespace rd = terralod::render;
namespace tb = terralod::blocks;

namespace {

std::vector<std::string> split(const std::string& text, char sep) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (true) {
    const std::size_t at = text.find(sep, start);
    out.push_back(text.substr(start, at == std::string::npos ? std::string::npos : at - start));
    if (at == std::string::npos) return out;
    start = at + 1;
  }
}

bool parse_number(const std::string& s, double& out) {
  if (s.empty()) return false;
  char* end = nullptr;
  errno = 0;
  out = std::strtod(s.c_str(), &end);
  return *end == '\0' && errno != ERANGE && std::isfinite(out);
}

}  // namespace

LayerSpec parse_layer_spec(const std::string& text) {
  const std::vector<std::string> f = split(text, ':');
  const auto bad = [&](const std::string& why) {
    return UsageError("--layer '" + text + "': " + why +
                      " (NAME[:blend|add|subtract|multiply[:WEIGHT[:lens]]])");
  };
  if (f.size() > 4) throw bad("too many fields");
  LayerSpec s;
  s.name = f[0];
  if (s.name.empty()) throw bad("empty layer name");
  if (f.size() > 1) {
    const std::string& op = f[1];
    if (op == "blend")
      s.op = rd::LayerOp::Blend;
    else if (op == "add")
      s.op = rd::LayerOp::Add;
    else if (op == "subtract")
      s.op = rd::LayerOp::Subtract;
    else if (op == "multiply")
      s.op = rd::LayerOp::Multiply;
    else
      throw bad("unknown operation '" + op + "'");
  }
  if (f.size() > 2) {
    double w = 0;
    if (!parse_number(f[2], w) || w < 0.0 || w > 1.0) throw bad("the weight must be a number in [0, 1]");
    s.weight = float(w);
  }
  if (f.size() > 3) {
    if (f[3] != "lens") throw bad("the fourth field can only be 'lens'");
    s.lens = true;
  }
  return s;
}

LensSpec parse_lens(const std::string& option, const std::string& text) {
  const std::vector<std::string> f = split(text, ',');
  LensSpec l;
  if (f.size() != 3 || !parse_number(f[0], l.x) || !parse_number(f[1], l.y) ||
      !parse_number(f[2], l.radius) || !(l.radius > 0))
    throw UsageError("option '" + option + "' needs X,Y,RADIUS (world metres, RADIUS > 0), not '" + text +
                     "'");
  return l;
}

LayerSetup LayerSetup::open(const std::string& db_path, const std::vector<std::string>& specs,
                            std::optional<LensSpec> lens, const LayerSetupOptions& options,
                            const std::vector<rd::PatchDomain>* drawn_tree) {
  if (options.max_texture_size < 1) throw std::invalid_argument("LayerSetup: max_texture_size must be >= 1");
  LayerSetup s;
  s.db_path_ = db_path;
  s.budget_bytes_ = options.budget_bytes;
  s.lens_texture_size_ = options.lens_texture_size;
  const tb::BlockDatabase db = tb::BlockDatabase::open(db_path);
  for (const std::string& text : specs) {
    const LayerSpec spec = parse_layer_spec(text);
    int index = -1;
    for (std::size_t i = 0; i < s.records_.size(); ++i)
      if (s.records_[i].name == spec.name) index = int(i);
    if (index < 0) {
      index = int(s.records_.size());
      s.records_.push_back(rd::read_layer_record(db, spec.name));
      const rd::LayerRecord& rec = s.records_.back();
      int level = int(rec.levels.size()) - 1;  // the coarsest when nothing fits
      for (std::size_t k = 0; k < rec.levels.size(); ++k)
        if (rec.levels[k].width <= options.max_texture_size &&
            rec.levels[k].height <= options.max_texture_size) {
          level = int(k);
          break;
        }
      if (level < 0)
        throw tb::DatabaseError(db_path, "texture layer '" + spec.name + "' has no pyramid levels");
      s.levels_.push_back(level);
    }
    rd::LayerStyle st;
    st.name = spec.name;
    st.op = spec.op;
    st.weight = spec.weight;
    st.topographic = s.records_[std::size_t(index)].kind == "shading";
    if (spec.lens) st.mask = rd::MaskSource::Lens;
    s.styles_.push_back(st);
    s.specs_.push_back(spec);
    s.layer_of_.push_back(index);
  }
  if (lens) {
    s.lens_.enabled = true;
    s.lens_radius_ = lens->radius;
    s.move_lens(lens->x, lens->y);
  }
  if (drawn_tree) {
    s.open_patches(db, *drawn_tree, options);
    return s;
  }
  // Each load opens its own read-only connection (the cache's worker thread).
  auto records = std::make_shared<const std::vector<rd::LayerRecord>>(s.records_);
  rd::TextureCacheOptions co;
  co.budget_bytes = options.budget_bytes;
  s.cache_ = std::make_unique<rd::TextureCache>(
      [db_path, records](const rd::TextureKey& k) {
        const tb::BlockDatabase conn = tb::BlockDatabase::open(db_path);
        return rd::read_layer_level(conn, records->at(std::size_t(k.layer)), int(k.node));
      },
      co);
  for (std::size_t i = 0; i < s.records_.size(); ++i) s.cache_->request({int(i), s.levels_[i]});
  return s;
}

void LayerSetup::open_patches(const tb::BlockDatabase& db, const std::vector<rd::PatchDomain>& drawn_tree,
                              const LayerSetupOptions& options) {
  // The patch tiles are keyed by the node ids of the texture database's own tree: it must be
  // the drawn one.
  const std::vector<rd::PatchDomain> own = rd::tree_domains(db);
  if (own.empty())
    throw tb::DatabaseError(db_path_, "has no approximation tree, so its texture layers have no patches");
  bool same = own.size() == drawn_tree.size();
  for (std::size_t i = 0; same && i < own.size(); ++i)
    same = own[i].domain == drawn_tree[i].domain && own[i].parent == drawn_tree[i].parent;
  if (!same)
    throw tb::DatabaseError(db_path_, "its approximation tree (" + std::to_string(own.size()) +
                                          " nodes) is not the drawn terrain's (" +
                                          std::to_string(drawn_tree.size()) +
                                          " nodes): its texture patches cannot be placed");
  std::vector<std::shared_ptr<const rd::TextureTree>> trees;
  std::vector<rd::TextureLoader> loaders;
  for (const rd::LayerRecord& rec : records_) {
    if (rec.patches == 0)
      throw tb::DatabaseError(db_path_, "texture layer '" + rec.name +
                                            "' has no patch tiles (it was stored without the tree): store it "
                                            "again with 'terralod texture'");
    auto tree = std::make_shared<const rd::TextureTree>(drawn_tree, rec.levels, rec.georef, rec.constraints);
    loaders.push_back(rd::database_tile_loader(db_path_, rec.name, tree));
    trees.push_back(std::move(tree));
  }
  rd::PatchTextureOptions po;
  po.gamma_px = options.gamma_px;
  po.budget_bytes = options.budget_bytes;
  patches_ = std::make_unique<rd::PatchTextures>(
      std::move(trees),
      [loaders = std::move(loaders)](const rd::TextureKey& k) { return loaders.at(std::size_t(k.layer))(k); },
      po);
}

const rd::PatchTextureFrame& LayerSetup::patch_frame(const pm::View& view,
                                                     std::span<const std::int64_t> triangle_node, bool wait) {
  assert(patches_);
  std::vector<bool> enabled(records_.size(), false);
  for (std::size_t i = 0; i < styles_.size(); ++i)
    if (styles_[i].enabled) enabled[std::size_t(layer_of_[i])] = true;
  const rd::PatchTextureFrame* f = &patches_->frame(view, triangle_node, enabled);
  for (int k = 0; wait && f->stats.from_parent > 0 && k < 64; ++k) {
    wait_loaded(/*timeout_ms=*/600000);
    f = &patches_->frame(view, triangle_node, enabled);
  }
  return *f;
}

std::vector<OptionSpec> layer_option_specs() {
  return {
      {"--texture-db", "FILE.db", "block database holding the texture layers of --layer (default --db)"},
      {"--layer", "NAME[:OP[:W[:lens]]]",
       "draw a texture layer (repeatable, in order): OP blend|add|subtract|multiply, W in [0,1]", false,
       /*repeatable=*/true},
      {"--lens", "X,Y,RADIUS", "highlight lens (world metres) masking the layers marked ':lens'"},
      {"--gamma", "PIXELS2",
       "--db with --layer: texel area on screen a patch's texture may reach (> 0, default 1)"},
      {"--texture-memory", "MB",
       "texture memory budget of the --layer textures, megabytes (default 537: 512 MiB)"},
  };
}

LayerSetupOptions layer_setup_options(const Args& a) {
  LayerSetupOptions lo;
  lo.gamma_px = a.get_double("--gamma", 1.0);
  if (!(lo.gamma_px > 0))
    throw UsageError("option '--gamma' must be > 0 pixels^2, not '" + a.get("--gamma") + "'");
  const double mb = a.get_double("--texture-memory", 536.870912);
  if (!(mb * 1e6 >= 1))
    throw UsageError("option '--texture-memory' must be > 0 megabytes, not '" + a.get("--texture-memory") +
                     "'");
  lo.budget_bytes = std::size_t(mb * 1e6);
  return lo;
}

std::vector<rd::LayeredItem> LayerSetup::items(rd::LayeredRenderer& renderer, rd::MeshId mesh,
                                               const rd::PatchTextureFrame& frame) {
  assert(patches_);
  std::vector<rd::LayeredItem> out;
  out.reserve(frame.groups.size());
  for (const rd::PatchTextureGroup& g : frame.groups) {
    rd::LayeredItem item{mesh, std::vector<rd::LayerBinding>(styles_.size()), g.first_triangle,
                         g.triangle_count};
    for (std::size_t i = 0; i < styles_.size(); ++i) {
      const std::size_t layer = std::size_t(layer_of_[i]);
      item.layers[i].georef = records_[layer].georef;
      if (!styles_[i].enabled || !g.pixels[layer]) continue;
      item.layers[i].texture = renderer.texture_for(g.used[layer], *g.pixels[layer]);
      item.layers[i].georef = patches_->tree(int(layer)).patch(g.used[layer].node).georef;
    }
    out.push_back(std::move(item));
  }
  return out;
}

void LayerSetup::move_lens(double x, double y) {
  lens_.rect = {x - lens_radius_, y - lens_radius_, x + lens_radius_, y + lens_radius_};
}

void LayerSetup::set_lens_radius(double radius) {
  if (!(radius > 0)) throw std::invalid_argument("LayerSetup: the lens radius must be > 0");
  const double x = 0.5 * (lens_.rect.minx + lens_.rect.maxx), y = 0.5 * (lens_.rect.miny + lens_.rect.maxy);
  lens_radius_ = radius;
  move_lens(x, y);
}

void LayerSetup::attach(rd::LayeredRenderer& renderer) const {
  renderer.options().texture_budget_bytes = budget_bytes_;
  renderer.set_lens_texture(rd::make_lens_texture(lens_texture_size_));
}

std::vector<rd::LayerBinding> LayerSetup::bindings(rd::LayeredRenderer& renderer) {
  assert(cache_ && "bindings() is whole-layer mode; per-patch mode draws items()");
  cache_->begin_frame();
  std::vector<rd::LayerBinding> b(styles_.size());
  for (std::size_t i = 0; i < styles_.size(); ++i) {
    const int layer = layer_of_[i];
    b[i].georef = records_[std::size_t(layer)].georef;
    if (!styles_[i].enabled) continue;
    const rd::TextureKey key{layer, levels_[std::size_t(layer)]};
    if (const auto px = cache_->request(key)) b[i].texture = renderer.texture_for(key, *px);
  }
  return b;
}

void LayerSetup::wait_loaded(int timeout_ms) {
  if (patches_) {
    patches_->cache().wait_idle(timeout_ms);
    if (patches_->cache().stats().failures > 0) throw std::runtime_error(patches_->cache().last_error());
    return;
  }
  for (std::size_t i = 0; i < styles_.size(); ++i)
    if (styles_[i].enabled) cache_->request({layer_of_[i], levels_[std::size_t(layer_of_[i])]});
  cache_->wait_idle(timeout_ms);
  if (cache_->stats().failures > 0) throw std::runtime_error(cache_->last_error());
}

}  // namespace terralod::cli
