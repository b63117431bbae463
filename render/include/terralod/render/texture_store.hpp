// Texture layers persisted in the block database: the image pyramid as grid tiles, the texture
// tree's patches as one tile per node, and the layer's description as JSON metadata.
//
// Usage:
//   namespace tr = terralod::render;
//   auto db = terralod::blocks::BlockDatabase::open("terrain.db",
//   terralod::blocks::BlockDatabase::Mode::ReadWrite); tr::ImagePyramid pyr("ortho.tx"); // see
//   image_pyramid.hpp tr::LayerRecord rec;  rec.name = "ortho";  rec.kind = "image"; rec.georef =
//   tr::grid_georef(db.info().transform, db.info().grid_width, db.info().grid_height);
//   std::vector<tr::PatchDomain> doms = tr::patch_domains(tree.nodes());   // may be empty
//   tr::store_texture_layer(db, rec, pyr, doms);                      // one transaction
//   tr::LayerRecord back = tr::read_layer_record(db, "ortho");
//   tr::RgbaImage level0 = tr::read_layer_level(db, back, 0);         // exact level-0 pixels
//   auto tree = std::make_shared<tr::TextureTree>(doms, back.levels, back.georef, back.constraints);
//   tr::TextureCache cache(tr::database_tile_loader("terrain.db", back.name, tree));
//
// Storage (BlockDatabase texture tiles, layer = the layer's name):
//   - Grid tiles of pyramid level k: node = -(1 + ty * tiles_x(k) + tx), level = k, for tile
//     (tx, ty) of tile_size x tile_size pixels (edge tiles smaller), tiles_x(k) =
//     ceil(width_k / tile_size). Every level 0..levels-1 is stored completely.
//   - Patch tiles: node = the approximation-tree node id (>= 0), level = its patch's level; the
//     pixels of TexturePatch::rect (outside the image: transparent black).
//   - Tile bytes (format version 1), little-endian:
//       0  4  magic "TLTX"
//       4  4  u32 version (1)
//       8  4  u32 width   (>= 1)
//      12  4  u32 height  (>= 1)
//      16  …  zlib stream (RFC 1950) of width * height * 4 bytes RGBA8, top row first
//     The database adds its own size + CRC-32 per tile.
//   - Metadata key "texture_layer:<name>": JSON object {"format": 1, "name", "kind" ("image" |
//     "shading" | ...), "source", "georef": [minx, miny, maxx, maxy], "levels": [[w, h], ...],
//     "tile_size", "max_texture_size", "power_of_two", "patches", "parameters": {...}}.
//     Written last, in the same transaction as the tiles: a layer is listed only when complete.
//
// Errors: bad or missing tiles/metadata throw blocks::DatabaseError naming the database, the
// layer and the tile ("terrain.db: texture layer 'ortho' tile (node -3, level 0): ...").
// Memory: two tiles per core when storing (they are read and compressed on every core, written
// in order; plus the pyramid's cache); read_layer_level holds the level (4 bytes per pixel),
// export_layer_level one row of grid tiles.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "terralod/blocks/block_database.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/render/image_pyramid.hpp"
#include "terralod/render/rgba_image.hpp"
#include "terralod/render/texture_cache.hpp"
#include "terralod/render/texture_tree.hpp"

namespace terralod::render {

/// What the database says about one texture layer.
struct LayerRecord {
  std::string name;                ///< any non-empty UTF-8 without control characters
  std::string kind = "image";      ///< "image", "shading", ...
  std::string source;              ///< the input file or generator
  GeoRect georef;                  ///< world extent of level 0
  std::vector<LevelSize> levels;   ///< filled by store_texture_layer
  int tile_size = 512;             ///< grid tile side, pixels, >= 1
  TextureConstraints constraints;  ///< of the patch tiles
  std::size_t patches = 0;         ///< patch tiles stored (filled by store_texture_layer)
  std::string parameters = "{}";   ///< a JSON object (generator options), stored verbatim
};

/// The axis-aligned world rectangle of a grid of w x h samples, each sample the centre of one
/// texel (the sample extent padded by half a cell): one texel per DEM sample.
GeoRect grid_georef(const pm::GridTransform& transform, int width, int height);

std::vector<std::uint8_t> encode_texture_tile(const RgbaImage& image);
/// Throws std::runtime_error "<name_for_errors>: <problem>" for bad bytes.
RgbaImage decode_texture_tile(std::span<const std::uint8_t> bytes, const std::string& name_for_errors);

/// Grid tile node id of tile (tx, ty) of a level tiles_x tiles wide.
inline std::int64_t grid_tile_node(int tx, int ty, int tiles_x) {
  return -(1 + std::int64_t(ty) * tiles_x + tx);
}

/// Writes the layer (replacing one of the same name): every level's grid tiles, the patch of
/// every texture-tree node that has one (none when `domains` is empty), then the metadata, in
/// one transaction. Fills rec.levels and rec.patches. `progress` (optional) gets [0,1].
void store_texture_layer(blocks::BlockDatabase& db, LayerRecord& rec, const ImagePyramid& pyramid,
                         const std::vector<PatchDomain>& domains,
                         const std::function<void(double)>& progress = {});

/// The texture-tree domains of the database's approximation tree (its "tree" blob), in id
/// order; empty when it has none. DatabaseError for a malformed tree.
std::vector<PatchDomain> tree_domains(const blocks::BlockDatabase& db);

/// Names of the layers with metadata, sorted.
std::vector<std::string> stored_layers(const blocks::BlockDatabase& db);
/// The layer's record; DatabaseError when it is missing or its JSON is malformed.
LayerRecord read_layer_record(const blocks::BlockDatabase& db, const std::string& name);
/// The whole of level `level` (0 <= level < rec.levels.size()) from the grid tiles.
RgbaImage read_layer_level(const blocks::BlockDatabase& db, const LayerRecord& rec, int level);
/// One node's patch tile.
RgbaImage read_layer_patch(const blocks::BlockDatabase& db, const std::string& layer, std::int64_t node,
                           int level);

/// Writes an RGBA image as 8-bit PNG or TIFF (chosen by the extension .png / .tif / .tiff) to
/// path + ".tmp", then renames it onto path; std::runtime_error naming the file on failure.
void write_layer_image(const RgbaImage& image, const std::string& path);
/// Level `level` of the layer written as write_layer_image writes an image, one row of grid
/// tiles at a time (never the level whole: 4 bytes a pixel of one tile row); errors as
/// read_layer_level's and write_layer_image's. `progress` gets the fraction of rows written.
void export_layer_level(const blocks::BlockDatabase& db, const LayerRecord& rec, int level,
                        const std::string& path, const std::function<void(double)>& progress = {});

/// A TextureCache loader reading patch tiles of `layer` from the database at `db_path` (each
/// load opens its own read-only connection, so any worker thread may run it). The key's node
/// must have a patch in `tree` (its level comes from there).
TextureLoader database_tile_loader(std::string db_path, std::string layer,
                                   std::shared_ptr<const TextureTree> tree);

}  // namespace terralod::render
