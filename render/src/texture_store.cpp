// Texture layers in the block database: grid tiles of the pyramid, patch tiles of the texture
// tree, layer metadata as JSON (format documented in texture_store.hpp).
#include "terralod/render/texture_store.hpp"

#include <OpenImageIO/imageio.h>
#include <zlib.h>

#include <algorithm>
#include <cassert>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <stdexcept>

#include "terralod/blocks/approximation_tree.hpp"
#include "terralod/pm/atomic_file.hpp"
#include "terralod/pm/byte_io.hpp"

namespace terralod::render {
namespace {

constexpr std::uint32_t kTileVersion = 1;
const std::string kMetaPrefix = "texture_layer:";

std::string json_string(const std::string& s) {
  std::string o = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\')
      o += '\\', o += c;
    else if (static_cast<unsigned char>(c) < 0x20) {
      char b[8];
      std::snprintf(b, sizeof b, "\\u%04x", unsigned(c));
      o += b;
    } else
      o += c;
  }
  return o + "\"";
}
std::string num(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

// A minimal reader for the JSON this file writes (objects, arrays, strings, numbers, bools).
struct JsonReader {
  const std::string& s;
  std::size_t i = 0;
  std::string where;
  [[noreturn]] void fail(const std::string& what) const {
    throw std::runtime_error(where + ": malformed layer metadata at byte " + std::to_string(i) + ": " + what);
  }
  void ws() {
    while (i < s.size() && std::isspace(static_cast<unsigned char>(s[i]))) ++i;
  }
  bool eat(char c) {
    ws();
    if (i < s.size() && s[i] == c) return ++i, true;
    return false;
  }
  void expect(char c) {
    if (!eat(c)) fail(std::string("expected '") + c + "'");
  }
  std::string str() {
    expect('"');
    std::string o;
    while (i < s.size() && s[i] != '"') {
      if (s[i] == '\\' && i + 1 < s.size()) {
        ++i;
        if (s[i] == 'u' && i + 4 < s.size()) {
          o += char(std::stoi(s.substr(i + 1, 4), nullptr, 16));
          i += 5;
          continue;
        }
      }
      o += s[i++];
    }
    expect('"');
    return o;
  }
  double number() {
    ws();
    const char* b = s.c_str() + i;
    char* e = nullptr;
    const double v = std::strtod(b, &e);
    if (e == b || !std::isfinite(v)) fail("expected a number");
    i += std::size_t(e - b);
    return v;
  }
  // The raw text of any value (for "parameters").
  std::string raw() {
    ws();
    const std::size_t start = i;
    int depth = 0;
    bool in_str = false;
    for (; i < s.size(); ++i) {
      const char c = s[i];
      if (in_str) {
        if (c == '\\')
          ++i;
        else if (c == '"')
          in_str = false;
        continue;
      }
      if (c == '"')
        in_str = true;
      else if (c == '{' || c == '[')
        ++depth;
      else if (c == '}' || c == ']') {
        if (depth == 0) break;
        if (--depth == 0) {
          ++i;
          break;
        }
      } else if (c == ',' && depth == 0)
        break;
    }
    return s.substr(start, i - start);
  }
};

std::string record_json(const LayerRecord& r) {
  std::string j = "{\"format\": 1, \"name\": " + json_string(r.name) + ", \"kind\": " + json_string(r.kind) +
                  ", \"source\": " + json_string(r.source) + ", \"georef\": [" + num(r.georef.minx) + ", " +
                  num(r.georef.miny) + ", " + num(r.georef.maxx) + ", " + num(r.georef.maxy) +
                  "], \"levels\": [";
  for (std::size_t k = 0; k < r.levels.size(); ++k)
    j += (k ? ", [" : "[") + std::to_string(r.levels[k].width) + ", " + std::to_string(r.levels[k].height) +
         "]";
  j += "], \"tile_size\": " + std::to_string(r.tile_size) +
       ", \"max_texture_size\": " + std::to_string(r.constraints.max_texture_size) +
       ", \"power_of_two\": " + (r.constraints.power_of_two ? "true" : "false") +
       ", \"patches\": " + std::to_string(r.patches) +
       ", \"parameters\": " + (r.parameters.empty() ? "{}" : r.parameters) + "}";
  return j;
}

LayerRecord parse_record(const std::string& text, const std::string& where) {
  JsonReader jr{text, 0, where};
  LayerRecord r;
  r.parameters = "{}";
  int format = 0;
  jr.expect('{');
  if (!jr.eat('}')) {
    do {
      const std::string key = jr.str();
      jr.expect(':');
      if (key == "format")
        format = int(jr.number());
      else if (key == "name")
        r.name = jr.str();
      else if (key == "kind")
        r.kind = jr.str();
      else if (key == "source")
        r.source = jr.str();
      else if (key == "georef") {
        jr.expect('[');
        r.georef.minx = jr.number(), jr.expect(','), r.georef.miny = jr.number(), jr.expect(',');
        r.georef.maxx = jr.number(), jr.expect(','), r.georef.maxy = jr.number();
        jr.expect(']');
      } else if (key == "levels") {
        jr.expect('[');
        if (!jr.eat(']')) {
          do {
            jr.expect('[');
            LevelSize l;
            l.width = int(jr.number());
            jr.expect(',');
            l.height = int(jr.number());
            jr.expect(']');
            r.levels.push_back(l);
          } while (jr.eat(','));
          jr.expect(']');
        }
      } else if (key == "tile_size")
        r.tile_size = int(jr.number());
      else if (key == "max_texture_size")
        r.constraints.max_texture_size = int(jr.number());
      else if (key == "power_of_two") {
        const std::string v = jr.raw();
        r.constraints.power_of_two = v == "true";
      } else if (key == "patches")
        r.patches = std::size_t(jr.number());
      else if (key == "parameters")
        r.parameters = jr.raw();
      else
        jr.raw();  // unknown keys of later versions are skipped
    } while (jr.eat(','));
    jr.expect('}');
  }
  if (format != 1) jr.fail("format " + std::to_string(format) + " (this build reads format 1)");
  if (!(r.georef.width() > 0 && r.georef.height() > 0)) jr.fail("empty georef rectangle");
  if (r.levels.empty() || r.tile_size < 1 || r.constraints.max_texture_size < 1)
    jr.fail("no levels or a bad tile size");
  for (const LevelSize& l : r.levels)
    if (l.width < 1 || l.height < 1)
      jr.fail("a level of " + std::to_string(l.width) + " x " + std::to_string(l.height));
  return r;
}

std::string tile_item(const std::string& layer, std::int64_t node, int level) {
  return "texture layer '" + layer + "' tile (node " + std::to_string(node) + ", level " +
         std::to_string(level) + ")";
}

}  // namespace

GeoRect grid_georef(const pm::GridTransform& t, int width, int height) {
  double lo_x = 1e300, lo_y = 1e300, hi_x = -1e300, hi_y = -1e300;
  for (double c : {-0.5, width - 0.5})
    for (double r : {-0.5, height - 0.5}) {
      const auto [x, y] = t.to_world(c, r);
      lo_x = std::min(lo_x, x), hi_x = std::max(hi_x, x), lo_y = std::min(lo_y, y), hi_y = std::max(hi_y, y);
    }
  return GeoRect{lo_x, lo_y, hi_x, hi_y};
}

std::vector<std::uint8_t> encode_texture_tile(const RgbaImage& img) {
  assert(img.width >= 1 && img.height >= 1 && img.rgba.size() == std::size_t(img.width) * img.height * 4);
  pm::ByteWriter header;
  header.raw("TLTX", 4);
  header.u32(kTileVersion);
  header.u32(std::uint32_t(img.width));
  header.u32(std::uint32_t(img.height));
  std::vector<std::uint8_t> out = std::move(header.bytes);
  uLongf z = compressBound(uLong(img.rgba.size()));
  const std::size_t head = out.size();
  out.resize(head + z);
  if (compress2(out.data() + head, &z, img.rgba.data(), uLong(img.rgba.size()), 6) != Z_OK)
    throw std::runtime_error("texture tile: zlib compression failed");
  out.resize(head + z);
  return out;
}

RgbaImage decode_texture_tile(std::span<const std::uint8_t> b, const std::string& name) {
  if (b.size() < 16 || std::memcmp(b.data(), "TLTX", 4) != 0)
    throw std::runtime_error(name + ": not a texture tile (bad magic)");
  const std::uint32_t version = pm::load_u32(b.data() + 4), w = pm::load_u32(b.data() + 8),
                      h = pm::load_u32(b.data() + 12);
  if (version != kTileVersion)
    throw std::runtime_error(name + ": texture tile format version " + std::to_string(version));
  if (w < 1 || h < 1 || w > 65536 || h > 65536)
    throw std::runtime_error(name + ": texture tile of " + std::to_string(w) + " x " + std::to_string(h) +
                             " pixels");
  // zlib cannot expand more than 1032:1: a larger claim is a corrupt header (and no huge
  // allocation is made for it).
  if (std::uint64_t(w) * h * 4 > std::uint64_t(b.size() - 16) * 1032 + 64)
    throw std::runtime_error(name + ": texture tile claims " + std::to_string(w) + " x " + std::to_string(h) +
                             " pixels but holds only " + std::to_string(b.size()) + " bytes");
  RgbaImage img(static_cast<int>(w), static_cast<int>(h));
  uLongf n = uLongf(img.rgba.size());
  if (uncompress(img.rgba.data(), &n, b.data() + 16, uLong(b.size() - 16)) != Z_OK || n != img.rgba.size())
    throw std::runtime_error(name + ": texture tile pixels are truncated or corrupt");
  return img;
}

void store_texture_layer(blocks::BlockDatabase& db, LayerRecord& rec, const ImagePyramid& pyr,
                         const std::vector<PatchDomain>& domains,
                         const std::function<void(double)>& progress) {
  assert(!rec.name.empty() && rec.tile_size >= 1 && rec.georef.width() > 0 && rec.georef.height() > 0);
  rec.levels = pyr.level_sizes();
  std::size_t work = 0, done = 0;
  for (const LevelSize& l : rec.levels)
    work += std::size_t((l.width + rec.tile_size - 1) / rec.tile_size) *
            ((l.height + rec.tile_size - 1) / rec.tile_size);
  std::unique_ptr<TextureTree> tree;
  if (!domains.empty()) {
    tree = std::make_unique<TextureTree>(domains, rec.levels, rec.georef, rec.constraints);
    work += tree->patch_count();
  }
  auto step = [&] {
    ++done;
    if (progress) progress(double(done) / double(std::max<std::size_t>(work, 1)));
  };
  blocks::BlockDatabase::Transaction t(db);
  for (int k = 0; k < int(rec.levels.size()); ++k) {
    const LevelSize l = rec.levels[std::size_t(k)];
    const int tiles_x = (l.width + rec.tile_size - 1) / rec.tile_size,
              tiles_y = (l.height + rec.tile_size - 1) / rec.tile_size;
    for (int ty = 0; ty < tiles_y; ++ty)
      for (int tx = 0; tx < tiles_x; ++tx) {
        PixelRect r{k, tx * rec.tile_size, ty * rec.tile_size,
                    std::min(rec.tile_size, l.width - tx * rec.tile_size),
                    std::min(rec.tile_size, l.height - ty * rec.tile_size)};
        db.put_texture_tile(rec.name, grid_tile_node(tx, ty, tiles_x), k, encode_texture_tile(pyr.read(r)));
        step();
      }
  }
  rec.patches = 0;
  if (tree)
    for (std::int64_t n = 0; n < std::int64_t(tree->node_count()); ++n)
      if (tree->has_patch(n)) {
        const TexturePatch& p = tree->patch(n);
        db.put_texture_tile(rec.name, n, p.rect.level, encode_texture_tile(pyr.read(p.rect)));
        ++rec.patches;
        step();
      }
  db.set_meta(kMetaPrefix + rec.name, record_json(rec));
  t.commit();
}

std::vector<PatchDomain> tree_domains(const blocks::BlockDatabase& db) {
  const auto blob = db.read_blob("tree");
  if (!blob) return {};
  return patch_domains(blocks::decode_tree(*blob, db.path() + ": tree").nodes());
}

std::vector<std::string> stored_layers(const blocks::BlockDatabase& db) {
  std::vector<std::string> out;
  for (const std::string& name : db.texture_layers())
    if (db.get_meta(kMetaPrefix + name)) out.push_back(name);
  std::sort(out.begin(), out.end());
  return out;
}

LayerRecord read_layer_record(const blocks::BlockDatabase& db, const std::string& name) {
  const std::optional<std::string> meta = db.get_meta(kMetaPrefix + name);
  if (!meta) {
    std::string have;
    for (const std::string& l : stored_layers(db)) have += (have.empty() ? "" : ", ") + l;
    throw blocks::DatabaseError(
        db.path(), "no texture layer '" + name + "' (layers: " + (have.empty() ? "none" : have) + ")");
  }
  try {
    return parse_record(*meta, "texture layer '" + name + "'");
  } catch (const std::runtime_error& e) {
    throw blocks::DatabaseError(db.path(), e.what());
  }
}

RgbaImage read_layer_patch(const blocks::BlockDatabase& db, const std::string& layer, std::int64_t node,
                           int level) {
  const std::string item = tile_item(layer, node, level);
  const auto bytes = db.read_texture_tile(layer, node, level);
  if (!bytes) throw blocks::DatabaseError(db.path(), item + ": missing");
  try {
    return decode_texture_tile(*bytes, item);
  } catch (const std::runtime_error& e) {
    throw blocks::DatabaseError(db.path(), e.what());
  }
}

RgbaImage read_layer_level(const blocks::BlockDatabase& db, const LayerRecord& rec, int level) {
  assert(level >= 0 && level < int(rec.levels.size()));
  const LevelSize l = rec.levels[std::size_t(level)];
  const int ts = rec.tile_size, tiles_x = (l.width + ts - 1) / ts, tiles_y = (l.height + ts - 1) / ts;
  RgbaImage out(l.width, l.height);
  for (int ty = 0; ty < tiles_y; ++ty)
    for (int tx = 0; tx < tiles_x; ++tx) {
      const std::int64_t node = grid_tile_node(tx, ty, tiles_x);
      const RgbaImage tile = read_layer_patch(db, rec.name, node, level);
      const int w = std::min(ts, l.width - tx * ts), h = std::min(ts, l.height - ty * ts);
      if (tile.width != w || tile.height != h)
        throw blocks::DatabaseError(db.path(), tile_item(rec.name, node, level) + ": " +
                                                   std::to_string(tile.width) + " x " +
                                                   std::to_string(tile.height) + " pixels, expected " +
                                                   std::to_string(w) + " x " + std::to_string(h));
      for (int y = 0; y < h; ++y)
        std::memcpy(out.pixel(tx * ts, ty * ts + y), tile.pixel(0, y), std::size_t(w) * 4);
    }
  return out;
}

void write_layer_image(const RgbaImage& img, const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  const char* format = ext == ".png" ? "png" : (ext == ".tif" || ext == ".tiff") ? "tiff" : nullptr;
  if (!format) throw std::runtime_error(path + ": the file name must end in .png, .tif or .tiff");
  const std::string tmp = path + ".tmp";
  auto out = OIIO::ImageOutput::create(format);
  OIIO::ImageSpec spec(img.width, img.height, 4, OIIO::TypeDesc::UINT8);
  spec.alpha_channel = 3;
  spec.attribute("oiio:UnassociatedAlpha", 1);  // straight alpha, as RgbaImage holds it
  if (format == std::string("tiff")) spec.attribute("compression", "zip");
  bool ok = out && out->open(tmp, spec) && out->write_image(OIIO::TypeDesc::UINT8, img.rgba.data());
  std::string why = ok ? "" : (out ? out->geterror() : OIIO::geterror());
  if (out) ok = out->close() && ok;
  if (!ok) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw std::runtime_error(path + ": cannot write the image: " + why);
  }
  pm::rename_into_place(tmp, path);
}

TextureLoader database_tile_loader(std::string db_path, std::string layer,
                                   std::shared_ptr<const TextureTree> tree) {
  return
      [db_path = std::move(db_path), layer = std::move(layer), tree = std::move(tree)](const TextureKey& k) {
        const blocks::BlockDatabase db = blocks::BlockDatabase::open(db_path);
        return read_layer_patch(db, layer, k.node, tree->patch(k.node).rect.level);
      };
}

}  // namespace terralod::render
