// Private to the terrain runtime: the block summaries of a database, with the stand-in surfaces
// read from it only for the blocks a frame looks at.
//
// A summary's stand-in (its points, triangles and per-triangle errors) is most of its memory:
// about 3.5 kB of a 64-point TIN stand-in's 3.7 kB in memory. Holding every block's, as the
// runtime did, makes what it keeps resident grow with the terrain, about 4 kB a block of 257²
// samples: 620 MB for 10¹⁰ samples, more than a flight's budget before any block is read. The
// store keeps every block's fields (heights, errors, kind: a BlockSummary with empty vectors,
// about 150 bytes) and where its record lies in the "block_summaries" blob (16 bytes); a
// stand-in is decoded from its record when a frame first asks for it and dropped some frames
// after its last use. The selection asks only for blocks whose parent it refined, so what is
// held follows the view, not the terrain.
//
// Reading a record: SQLite's incremental blob I/O on a handle kept open for the store's life (a
// record at the end of a large blob is found through the cursor's overflow-page cache, not by
// walking the blob's page chain from its start). Opening streams the blob once in pieces of
// 1 MiB, checking the database's size and CRC-32 of the whole blob and the blob's own trailer,
// and records each record's CRC-32, which every later read is checked against (DatabaseError
// naming the file and the block otherwise). A version 1 blob (two-triangle summaries, 64 bytes
// a block) is decoded whole and held, as are databases without summaries.
// The open handle holds a read transaction: the store reads the database as it was when it
// opened (its WAL snapshot), whatever another connection writes afterwards; such writes still
// commit, but the WAL is not checkpointed past the snapshot until the store closes.
//
// Usage (one thread, the runtime's update()):
//   SummaryStore store(db_path, grid);
//   if (store.has_standin(i)) { const BlockSummary& s = store.summary(i, frame); ... }
//   store.trim(frame);  // at the frame's end: stand-ins unused for kKeepFrames frames go
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include "terralod/blocks/active_region.hpp"

namespace terralod::blocks::detail {

class SummaryStore {
 public:
  /// Frames a stand-in stays after its last use (a view that turns back finds it still there).
  static constexpr std::uint64_t kKeepFrames = 120;

  /// Opens its own read-only connection to `db_path`. Without a summaries blob every block's
  /// summary is empty (no stand-in). DatabaseError when the blob is corrupt or does not match
  /// the grid.
  SummaryStore(const std::string& db_path, const BlockGrid& grid);
  ~SummaryStore();
  SummaryStore(const SummaryStore&) = delete;
  SummaryStore& operator=(const SummaryStore&) = delete;

  /// Every block's summary in BlockGrid::index order, without its stand-in surface where that
  /// is read on demand (heights, errors, kind and flags are always there).
  std::span<const BlockSummary> fields() const { return fields_; }
  /// Whether block i has a stand-in surface (a block without valid samples, or a database
  /// without summaries, has none).
  bool has_standin(std::size_t i) const;
  /// Block i's whole summary, its stand-in read now if it is not held; marks it used at `frame`.
  /// The reference stays valid until the next trim().
  const BlockSummary& summary(std::size_t i, std::uint64_t frame);
  /// Drops the stand-ins last used before frame - kKeepFrames.
  void trim(std::uint64_t frame);

  /// Heap held for every block (fields, record index), fixed from opening.
  std::size_t fixed_bytes() const;
  /// Heap held by the stand-ins read so far and not dropped.
  std::size_t held_bytes() const;
  std::size_t held_count() const { return held_.size(); }
  /// Stand-ins read from the database so far (a dropped one read again counts again).
  std::uint64_t reads() const { return reads_; }

 private:
  struct Record {
    std::uint64_t offset = 0;  // in the blob; size 0: no record to read (the fields are whole)
    std::uint32_t size = 0;
    std::uint32_t crc = 0;  // CRC-32 of the record's bytes, taken while the blob was checked
  };
  struct Held {
    BlockSummary summary;
    std::uint64_t last_used = 0;
  };
  class Blob;  // the open blob handle (summary_store.cpp)

  void index_blob(std::uint32_t blob_crc);

  std::string path_;
  BlockGrid grid_;
  std::vector<BlockSummary> fields_;
  std::vector<Record> records_;  // empty when every summary is whole in fields_
  std::unordered_map<std::size_t, Held> held_;
  std::uint64_t reads_ = 0;
  std::unique_ptr<Blob> blob_;
};

}  // namespace terralod::blocks::detail
