// The full-resolution terrain of a block database, read window by window: the samples of any
// rectangle of the grid without holding the whole grid, for the commands that work on every
// sample of a terrain larger than memory (texture shade and thematic).
//
// Usage:
//   namespace tb = terralod::blocks;
//   auto db = tb::BlockDatabase::open("terrain.db");
//   tb::DatabaseTerrain terrain(db);                                 // reads the info only
//   terralod::pm::Heightfield w = terrain.read({0, 0, 511, 255});    // 512 x 256 samples
//   // w.transform maps w's (0, 0) to the world point of the grid's (0, 0); w.at(i, j) is the
//   // grid's sample (col0 + i, row0 + j); holes are w's mask.
//   std::optional<tb::HeightRange> r = terrain.height_range();       // one pass over the blocks
//   terralod::pm::Heightfield all = tb::read_database_terrain(db);   // the whole grid at once
//
// Contract:
//   - Every sample is the block PM's own (pm::decode_pm_heightfield of the block); a sample on
//     the border two blocks share is the same in both. read(rect) needs rect inside the grid
//     (std::invalid_argument naming the rectangle otherwise).
//   - The window's transform is the grid's moved to rect's corner, so world positions agree
//     with the whole grid's; crs_wkt, crs_transform (moved the same way), vertical_datum and
//     source as read_database_terrain gives them.
//   - height_range(): the lowest and highest valid sample of the whole grid, exactly, or
//     nullopt when every sample is a hole; computed on the first call and kept.
//   - Errors: DatabaseError naming the file for a database without blocks, a missing block or a
//     block whose grid does not match the layout; pm::PmFormatError naming the block for a
//     corrupt one.
//   - Not thread-safe: one caller at a time (blocks are decoded on `threads` threads inside).
// Memory: the returned window (8 bytes a sample, 9 with holes) plus the cache of decoded blocks,
// at most about cache_bytes (least recently used blocks go first; a window's own blocks are
// decoded in batches of two per thread). Time: a block's heights decode at about 10 to 20 ns a
// sample (pm::decode_pm_heightfield); a window that moves along a band of rows finds most of its
// blocks in the cache.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/partition.hpp"
#include "terralod/blocks/sample_rect.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/progressive_mesh.hpp"

namespace terralod::blocks {

struct HeightRange {
  double lo = 0, hi = 0;  ///< lowest and highest valid sample, metres
};

struct DatabaseTerrainOptions {
  std::size_t cache_bytes = std::size_t(128) << 20;  ///< decoded blocks kept, bytes
  int threads = 0;                                   ///< decoding threads, 0 = all cores
};

class DatabaseTerrain {
 public:
  using Options = DatabaseTerrainOptions;
  /// Reads the database's info and layout; DatabaseError for a database without blocks. The
  /// database must outlive this object.
  explicit DatabaseTerrain(const BlockDatabase& db, const Options& options = {});

  int width() const { return layout_.grid_width; }
  int height() const { return layout_.grid_height; }
  const BlockLayout& layout() const { return layout_; }
  /// The whole grid's heightfield without samples: transform, CRS, datum, source.
  const pm::Heightfield& frame() const { return frame_; }

  /// The samples of `rect` (see the contract).
  pm::Heightfield read(const SampleRect& rect);
  /// The same samples written into `out` (rect.width() x rect.height() doubles, row by row),
  /// holes as NaN: for a caller with a buffer of its own (the export's warp reads into GDAL's).
  void read(const SampleRect& rect, double* out);
  /// The exact range of the valid samples (see the contract); `progress`, when given, gets the
  /// fraction of blocks read on the first call.
  std::optional<HeightRange> height_range(const std::function<void(double)>& progress = {});

  /// The most bytes the cache of decoded blocks held so far.
  std::size_t peak_cache_bytes() const { return peak_; }

 private:
  void require_inside(const SampleRect& rect) const;  // std::invalid_argument naming rect
  // Pastes the blocks of rect into out (rect's samples); holes go to mask, or are NaN without one.
  void paste_blocks(const SampleRect& rect, double* out, std::vector<std::uint8_t>* mask);
  void fetch(const std::vector<BlockKey>& keys);                    // decodes the ones not cached
  void evict(const std::vector<BlockKey>& keep, std::size_t room);  // to budget - room
  // The blocks' heights, read one after the other and decoded on `threads` threads.
  std::vector<std::shared_ptr<const pm::Heightfield>> decode(std::span<const BlockKey> keys) const;

  const BlockDatabase* db_;
  Options opt_;
  BlockLayout layout_;
  pm::Heightfield frame_;
  struct Entry {
    std::shared_ptr<const pm::Heightfield> hf;
    std::uint64_t used = 0;
  };
  std::map<BlockKey, Entry> cache_;
  std::uint64_t clock_ = 0;
  std::size_t bytes_ = 0, peak_ = 0;
  std::optional<std::optional<HeightRange>> range_;
};

/// The full-resolution terrain of a blocked database, assembled from its block PMs (each holds
/// its samples exactly; voids become the mask; crs_wkt, crs_transform and vertical_datum from the
/// database's info and georeference). With `pms`, the decoded PMs in layout.keys()
/// order are kept there. DatabaseError naming the file for a database without blocks or a block
/// whose grid does not match the layout. Memory: the whole grid (8 bytes a sample, 9 with
/// holes) and one batch of decoded blocks (none is cached); DatabaseTerrain reads windows instead.
pm::Heightfield read_database_terrain(const BlockDatabase& db,
                                      std::vector<pm::ProgressiveMesh>* pms = nullptr);

}  // namespace terralod::blocks
