// The --texture-db / --layer / --lens options of `terralod view` and `terralod-fly`.
#include "layer_options.hpp"

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
    return UsageError("--layer '" + text + "': " + why + " (NAME[:blend|add|subtract|multiply[:WEIGHT[:lens]]])");
  };
  if (f.size() > 4) throw bad("too many fields");
  LayerSpec s;
  s.name = f[0];
  if (s.name.empty()) throw bad("empty layer name");
  if (f.size() > 1) {
    const std::string& op = f[1];
    if (op == "blend") s.op = rd::LayerOp::Blend;
    else if (op == "add") s.op = rd::LayerOp::Add;
    else if (op == "subtract") s.op = rd::LayerOp::Subtract;
    else if (op == "multiply") s.op = rd::LayerOp::Multiply;
    else throw bad("unknown operation '" + op + "'");
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
  if (f.size() != 3 || !parse_number(f[0], l.x) || !parse_number(f[1], l.y) || !parse_number(f[2], l.radius) ||
      !(l.radius > 0))
    throw UsageError("option '" + option + "' needs X,Y,RADIUS (world metres, RADIUS > 0), not '" + text + "'");
  return l;
}

LayerSetup LayerSetup::open(const std::string& db_path, const std::vector<std::string>& specs,
                            std::optional<LensSpec> lens, const LayerSetupOptions& options) {
  if (options.max_texture_size < 1) throw std::invalid_argument("LayerSetup: max_texture_size must be >= 1");
  LayerSetup s;
  s.db_path_ = db_path;
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
        if (rec.levels[k].width <= options.max_texture_size && rec.levels[k].height <= options.max_texture_size) {
          level = int(k);
          break;
        }
      if (level < 0) throw tb::DatabaseError(db_path, "texture layer '" + spec.name + "' has no pyramid levels");
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
  renderer.set_lens_texture(rd::make_lens_texture(lens_texture_size_));
}

std::vector<rd::LayerBinding> LayerSetup::bindings(rd::LayeredRenderer& renderer) {
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
  for (std::size_t i = 0; i < styles_.size(); ++i)
    if (styles_[i].enabled) cache_->request({layer_of_[i], levels_[std::size_t(layer_of_[i])]});
  cache_->wait_idle(timeout_ms);
  if (cache_->stats().failures > 0) throw std::runtime_error(cache_->last_error());
}

}  // namespace terralod::cli
