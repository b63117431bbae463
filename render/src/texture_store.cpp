// Texture layers in the block database: grid tiles of the pyramid, patch tiles of the texture
// tree, layer metadata as JSON (format documented in texture_store.hpp).
#include "terralod/render/texture_store.hpp"

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cassert>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <stdexcept>

#include "terralod/blocks/approximation_tree.hpp"
#include "terralod/pm/atomic_file.hpp"
#include "terralod/pm/byte_io.hpp"
#include "terralod/pm/deflate_codec.hpp"
#include "terralod/pm/json.hpp"
#include "terralod/pm/parallel.hpp"

namespace terralod::render {
namespace {

constexpr std::uint32_t kTileVersion = 1;
const std::string kMetaPrefix = "texture_layer:";

std::string num(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

std::string record_json(const LayerRecord& r) {
  std::string j = "{\"format\": 1, \"name\": " + pm::json_quote(r.name) +
                  ", \"kind\": " + pm::json_quote(r.kind) + ", \"source\": " + pm::json_quote(r.source) +
                  ", \"georef\": [" + num(r.georef.minx) + ", " + num(r.georef.miny) + ", " +
                  num(r.georef.maxx) + ", " + num(r.georef.maxy) + "], \"levels\": [";
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

// Reads a record with the strict reader (pm/json.hpp). Every record record_json ever wrote
// parses: keys in any order, unknown keys (of later versions) skipped; "parameters" keeps its
// text verbatim. Errors: "<where>: line L, column C: <what>" (JsonError) for malformed JSON or
// a value of the wrong kind, "<where>: malformed layer metadata: <what>" for bad contents.
LayerRecord parse_record(const std::string& text, const std::string& where) {
  using Kind = pm::JsonValue::Kind;
  const pm::JsonValue doc = pm::parse_json(text, where);
  const auto need = [&](const pm::JsonValue& v, Kind k, const std::string& name) -> const pm::JsonValue& {
    if (v.kind != k)
      throw pm::JsonError(text, v.begin, where,
                          name + " must be " + pm::json_kind_name(k) + ", not " + pm::json_kind_name(v.kind));
    return v;
  };
  const auto bad = [&](const std::string& what) {
    return std::runtime_error(where + ": malformed layer metadata: " + what);
  };
  // A count or size: a whole number in [0, 2^31) (2^53 for "patches").
  const auto whole = [&](const pm::JsonValue& v, const std::string& name, double max) {
    const double d = need(v, Kind::Number, "\"" + name + "\"").number;
    if (!(d >= 0 && d < max && d == std::floor(d)))
      throw pm::JsonError(text, v.begin, where,
                          "\"" + name + "\" must be a whole number in [0, " + num(max) + "), not " +
                              std::string(v.raw(text)));
    return d;
  };
  constexpr double kInt = 2147483648.0, kCount = 9007199254740992.0;
  need(doc, Kind::Object, "the layer record");
  LayerRecord r;
  r.parameters = "{}";
  double format = 0;
  for (const auto& [key, v] : doc.members) {
    if (key == "format") {
      format = need(v, Kind::Number, "\"format\"").number;
    } else if (key == "name") {
      r.name = need(v, Kind::String, "\"name\"").string;
    } else if (key == "kind") {
      r.kind = need(v, Kind::String, "\"kind\"").string;
    } else if (key == "source") {
      r.source = need(v, Kind::String, "\"source\"").string;
    } else if (key == "georef") {
      const auto& g = need(v, Kind::Array, "\"georef\"").items;
      if (g.size() != 4) throw pm::JsonError(text, v.begin, where, "\"georef\" must hold 4 numbers");
      double c[4];
      for (int k = 0; k < 4; ++k) c[k] = need(g[std::size_t(k)], Kind::Number, "\"georef\" item").number;
      r.georef = GeoRect{c[0], c[1], c[2], c[3]};
    } else if (key == "levels") {
      for (const pm::JsonValue& l : need(v, Kind::Array, "\"levels\"").items) {
        const auto& wh = need(l, Kind::Array, "a level").items;
        if (wh.size() != 2) throw pm::JsonError(text, l.begin, where, "a level must be [width, height]");
        r.levels.push_back(LevelSize{int(whole(wh[0], "width", kInt)), int(whole(wh[1], "height", kInt))});
      }
    } else if (key == "tile_size") {
      r.tile_size = int(whole(v, key, kInt));
    } else if (key == "max_texture_size") {
      r.constraints.max_texture_size = int(whole(v, key, kInt));
    } else if (key == "power_of_two") {
      r.constraints.power_of_two = need(v, Kind::Bool, "\"power_of_two\"").boolean;
    } else if (key == "patches") {
      r.patches = std::size_t(whole(v, key, kCount));
    } else if (key == "parameters") {
      r.parameters = std::string(v.raw(text));
    }  // unknown keys of later versions are skipped
  }
  if (format != 1) throw bad("format " + num(format) + " (this build reads format 1)");
  if (!(r.georef.width() > 0 && r.georef.height() > 0)) throw bad("empty georef rectangle");
  if (r.levels.empty() || r.tile_size < 1 || r.constraints.max_texture_size < 1)
    throw bad("no levels or a bad tile size");
  for (const LevelSize& l : r.levels)
    if (l.width < 1 || l.height < 1)
      throw bad("a level of " + std::to_string(l.width) + " x " + std::to_string(l.height));
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
  // libdeflate at its level 4: zlib's level 6 (used before) made the compression of the tiles
  // three quarters of 'texture shade' and 'thematic'. On 1024 x 1024 tiles of a shading, a slope
  // map and an image, 0.24, 0.19 and 0.40 of its time for 1.10, 1.07 and 1.20 of its bytes.
  // The stream is zlib's (RFC 1950) either way: tiles written by either are read by either.
  if (pm::zlib_compress(img.rgba, 4, out) == 0)
    throw std::runtime_error("texture tile: cannot allocate the deflate compressor");
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
  // Deflate cannot expand more than kMaxDeflateRatio: a larger claim is a corrupt header (and no
  // huge allocation is made for it).
  if (std::uint64_t(w) * h * 4 > std::uint64_t(b.size() - 16) * pm::kMaxDeflateRatio + 64)
    throw std::runtime_error(name + ": texture tile claims " + std::to_string(w) + " x " + std::to_string(h) +
                             " pixels but holds only " + std::to_string(b.size()) + " bytes");
  RgbaImage img(static_cast<int>(w), static_cast<int>(h));
  // Exactly the pixels, or an error: a short, long or damaged stream (checksum included).
  if (!pm::zlib_decompress(b.subspan(16), img.rgba))
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
  // Every tile to store: the grid tiles of each level, then the tree's patches.
  struct Job {
    std::int64_t node;
    PixelRect rect;
  };
  std::vector<Job> jobs;
  for (int k = 0; k < int(rec.levels.size()); ++k) {
    const LevelSize l = rec.levels[std::size_t(k)];
    const int tiles_x = (l.width + rec.tile_size - 1) / rec.tile_size,
              tiles_y = (l.height + rec.tile_size - 1) / rec.tile_size;
    for (int ty = 0; ty < tiles_y; ++ty)
      for (int tx = 0; tx < tiles_x; ++tx)
        jobs.push_back({grid_tile_node(tx, ty, tiles_x),
                        {k, tx * rec.tile_size, ty * rec.tile_size,
                         std::min(rec.tile_size, l.width - tx * rec.tile_size),
                         std::min(rec.tile_size, l.height - ty * rec.tile_size)}});
  }
  rec.patches = 0;
  if (tree)
    for (std::int64_t n = 0; n < std::int64_t(tree->node_count()); ++n)
      if (tree->has_patch(n)) {
        jobs.push_back({n, tree->patch(n).rect});
        ++rec.patches;
      }
  // Read and compressed on every core a few tiles at a time (the ImageCache is thread-safe),
  // written in order on this thread: the same rows as one after the other.
  blocks::BlockDatabase::Transaction t(db);
  const std::size_t batch = std::size_t(2 * pm::thread_count(0));
  std::vector<std::vector<std::uint8_t>> encoded(batch);
  for (std::size_t b0 = 0; b0 < jobs.size(); b0 += batch) {
    const std::size_t n = std::min(batch, jobs.size() - b0);
    pm::parallel_for(n, 0,
                     [&](std::size_t i) { encoded[i] = encode_texture_tile(pyr.read(jobs[b0 + i].rect)); });
    for (std::size_t i = 0; i < n; ++i) {
      db.put_texture_tile(rec.name, jobs[b0 + i].node, jobs[b0 + i].rect.level, encoded[i]);
      step();
    }
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

namespace {

// Rows [ty * tile_size, ...) of level `level`: the grid tiles of tile row ty side by side.
RgbaImage read_tile_row(const blocks::BlockDatabase& db, const LayerRecord& rec, int level, int ty) {
  const LevelSize l = rec.levels[std::size_t(level)];
  const int ts = rec.tile_size, tiles_x = (l.width + ts - 1) / ts;
  RgbaImage out(l.width, std::min(ts, l.height - ty * ts));
  for (int tx = 0; tx < tiles_x; ++tx) {
    const std::int64_t node = grid_tile_node(tx, ty, tiles_x);
    const RgbaImage tile = read_layer_patch(db, rec.name, node, level);
    const int w = std::min(ts, l.width - tx * ts);
    if (tile.width != w || tile.height != out.height)
      throw blocks::DatabaseError(db.path(), tile_item(rec.name, node, level) + ": " +
                                                 std::to_string(tile.width) + " x " +
                                                 std::to_string(tile.height) + " pixels, expected " +
                                                 std::to_string(w) + " x " + std::to_string(out.height));
    for (int y = 0; y < out.height; ++y)
      std::memcpy(out.pixel(tx * ts, y), tile.pixel(0, y), std::size_t(w) * 4);
  }
  return out;
}

// Writes a width x height RGBA image as 8-bit PNG or TIFF (by the extension) through path +
// ".tmp": `rows(y0, n)` points at rows y0 .. y0 + n - 1 (asked in order, n <= band), valid
// until its next call.
void write_rgba_rows(const std::string& path, int width, int height, int band,
                     const std::function<const std::uint8_t*(int y0, int n)>& rows) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  const char* format = ext == ".png" ? "png" : (ext == ".tif" || ext == ".tiff") ? "tiff" : nullptr;
  if (!format) throw std::runtime_error(path + ": the file name must end in .png, .tif or .tiff");
  const std::string tmp = path + ".tmp";
  pm::FileRemover remove_tmp(tmp);
  auto out = OIIO::ImageOutput::create(format);
  OIIO::ImageSpec spec(width, height, 4, OIIO::TypeDesc::UINT8);
  spec.alpha_channel = 3;
  spec.attribute("oiio:UnassociatedAlpha", 1);  // straight alpha, as RgbaImage holds it
  if (format == std::string("tiff")) spec.attribute("compression", "zip");
  const auto fail = [&] {
    throw std::runtime_error(path +
                             ": cannot write the image: " + (out ? out->geterror() : OIIO::geterror()));
  };
  if (!out || !out->open(tmp, spec)) fail();
  for (int y = 0; y < height; y += band) {
    const int n = std::min(band, height - y);
    if (!out->write_scanlines(y, y + n, 0, OIIO::TypeDesc::UINT8, rows(y, n))) fail();
  }
  if (!out->close()) fail();
  out.reset();
  pm::rename_into_place(tmp, path);
  remove_tmp.keep();
}

}  // namespace

RgbaImage read_layer_level(const blocks::BlockDatabase& db, const LayerRecord& rec, int level) {
  assert(level >= 0 && level < int(rec.levels.size()));
  const LevelSize l = rec.levels[std::size_t(level)];
  RgbaImage out(l.width, l.height);
  for (int ty = 0, y = 0; y < l.height; ++ty) {
    const RgbaImage band = read_tile_row(db, rec, level, ty);
    std::copy(band.rgba.begin(), band.rgba.end(), out.pixel(0, y));
    y += band.height;
  }
  return out;
}

void write_layer_image(const RgbaImage& img, const std::string& path) {
  write_rgba_rows(path, img.width, img.height, std::max(img.height, 1),
                  [&](int y0, int) { return img.rgba.data() + std::size_t(y0) * img.width * 4; });
}

void export_layer_level(const blocks::BlockDatabase& db, const LayerRecord& rec, int level,
                        const std::string& path, const std::function<void(double)>& progress) {
  assert(level >= 0 && level < int(rec.levels.size()));
  const LevelSize l = rec.levels[std::size_t(level)];
  RgbaImage band;  // the row of tiles being written
  write_rgba_rows(path, l.width, l.height, rec.tile_size, [&](int y0, int n) {
    band = read_tile_row(db, rec, level, y0 / rec.tile_size);
    assert(band.height == n);
    if (progress) progress(double(y0 + n) / double(l.height));
    return band.rgba.data();
  });
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
