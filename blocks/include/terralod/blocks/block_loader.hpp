// Background block loader: threads (one by default) that read block blobs from a source (the
// block database, one connection per thread), decode each block's progressive mesh and build its
// collapse DAG, so that the frame loop only ever picks up finished blocks and never waits on I/O.
//
// Usage:
//   terralod::blocks::BlockLoader loader(terralod::blocks::database_source("terrain.db"), grid);
//   loader.set_queue({{/*key=*/{3, 4}, /*priority=*/0.0}, {{4, 4}, 1.5}});   // lower first
//   for (;;) {                                                              // each frame
//     for (terralod::blocks::LoadResult& r : loader.take_results()) { /* r.block or r.error */ }
//   }
//
// Contract:
//   - The factory is called once on each loader thread, to open the thread's own source (one
//     SQLite connection per thread, as block_database.hpp requires); it must be safe to call
//     from several threads at once. A factory or read that
//     throws becomes a LoadResult with `error` set (the exception's message, which names the
//     file and the block); the loader goes on with the next request.
//   - set_queue() replaces every queued (not yet started) request; keys are blocks of the grid
//     (assert); duplicates, the blocks being read and finished blocks not yet taken are dropped
//     (so no block is read twice for one request); reads in progress are never interrupted.
//     Each free thread takes the best queued request; results come in completion order.
//   - Every public member is thread-safe and returns without waiting for a read: the lock
//     guards only the queue and the result list, never the source, the decoder or the DAG.
//   - The destructor stops the threads after their reads in progress (if a source stalls
//     forever, the destructor waits for it).
//   - A block is checked against the grid: its PM's heightfield must have the block's
//     domain's size (DatabaseError-style message "<source>: block (c,r): ..." otherwise).
// Memory: one decoded block per finished result until taken (LoadedBlock::memory_bytes each).
#pragma once

#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "terralod/blocks/active_region.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/pm/collapse_dag.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "terralod/pm/selective_refinement.hpp"

namespace terralod::blocks {

/// Where block blobs come from (used by one thread at a time).
class BlockSource {
 public:
  virtual ~BlockSource() = default;
  /// The pm::encode_pm bytes of block k; throws (naming the source and block) when unavailable.
  virtual std::vector<std::uint8_t> read(BlockKey k) = 0;
  /// Name for error messages (the database path).
  virtual std::string name() const = 0;
  /// The most heap the source holds between reads (a database connection's cache limit and
  /// structures), fixed once it is open; 0 by default.
  virtual std::size_t memory_bytes() const { return 0; }
};
using BlockSourceFactory = std::function<std::unique_ptr<BlockSource>()>;

/// A factory that opens `path` read-only with BlockDatabase::open on the calling thread.
BlockSourceFactory database_source(const std::string& path);

/// A block in memory: the DAG of its PM, which selective refinement runs on.
struct LoadedBlock {
  BlockKey key;
  /// The PM's error metric. The decoded PM itself is not kept: the DAG holds a copy of all
  /// the refinement needs (heightfield, collapses), and the PM's own would be 24 bytes a vertex
  /// more for every resident block.
  pm::ErrorMetric metric = pm::ErrorMetric::Continuous;
  /// Heightfield (dag->heightfield()) in the block's own grid and transform.
  std::unique_ptr<pm::CollapseDag> dag;
  std::size_t blob_bytes = 0;  ///< bytes read from the source
  /// Bytes reserved while resident: the DAG (CollapseDag::memory_bytes) and one
  /// SelectiveRefinement over it at full resolution (SelectiveRefinement::full_memory_bytes),
  /// for the refinement options decode_block was given. Decoding peaks below it for a whole
  /// block (N44W072 in blocks of 257: 26.7 MB against 30.3 MB with the runtime's vertical
  /// geomorphs), not for a partial copy, whose decode peaks below its whole block's.
  std::size_t memory_bytes = 0;
  double read_ms = 0, decode_ms = 0;
};

/// Decodes a block blob (pm::decode_pm) and builds its DAG, skipping the collapses within
/// floor_m (CollapseDag::skip_for_floor; 0 keeps every collapse); checks its
/// size against the grid. Throws pm::PmFormatError / DatabaseError naming `source_name` and the
/// block. memory_bytes reserves a refinement with `refinement`'s options; the default reserves
/// Full geomorphs' lists, the most any options hold.
std::shared_ptr<const LoadedBlock> decode_block(
    const BlockGrid& grid, BlockKey k, std::span<const std::uint8_t> blob, const std::string& source_name,
    double floor_m = 0, const pm::RefinementOptions& refinement = {.morph_seconds = 1.0});

struct LoadResult {
  BlockKey key;
  std::shared_ptr<const LoadedBlock> block;  ///< null on error
  std::string error;                         ///< empty on success
  /// The refinement the PrepareFn made for the block on the loader thread (null without one).
  std::unique_ptr<pm::SelectiveRefinement> selection;
};

/// Optional work done on the loader thread once a block is decoded, so that the frame thread
/// does not: e.g. build the block's SelectiveRefinement and run its first, largest update.
/// Called without the loader's lock; it must be thread-safe against the caller's frame thread
/// and the other loader threads.
/// An exception becomes the result's error.
using PrepareFn = std::function<std::unique_ptr<pm::SelectiveRefinement>(const LoadedBlock&)>;

class BlockLoader {
 public:
  struct Request {
    BlockKey key;
    double priority = 0;  ///< lower is read first; ties in queue order
    double floor_m = 0;   ///< decode_block's floor: the coarsest leaves the caller can use
    /// What the caller plans for the block once loaded; held_bytes() counts it while the block
    /// is read and decoded.
    std::size_t bytes = 0;
  };

  /// `threads` (>= 1, std::invalid_argument otherwise) reading threads, each with its own source.
  BlockLoader(BlockSourceFactory factory, const BlockGrid& grid, PrepareFn prepare = {}, int threads = 1);
  ~BlockLoader();
  BlockLoader(const BlockLoader&) = delete;
  BlockLoader& operator=(const BlockLoader&) = delete;

  /// Replaces the queued requests (see the contract).
  void set_queue(std::vector<Request> requests);
  /// Finished blocks and errors since the last call, in completion order. Never waits on I/O.
  std::vector<LoadResult> take_results();
  /// True when k is queued or being read.
  bool busy(BlockKey k) const;
  /// True when k is being read or finished and not yet taken: held_bytes() counts it.
  bool holds(BlockKey k) const;
  /// Requests queued plus those being read.
  std::size_t pending() const;
  /// Finished blocks and errors that take_results() has not returned yet.
  std::size_t finished() const;
  /// Total blob bytes read so far.
  std::uint64_t bytes_read() const;
  /// Heap bytes the loader holds now: Request::bytes of each block being read, the
  /// LoadedBlock::memory_bytes of each finished block not yet taken, and its sources' bounds
  /// (BlockSource::memory_bytes; the constructor waits until every thread has opened its source).
  std::size_t held_bytes() const;

 private:
  void run();
  BlockSourceFactory factory_;
  BlockGrid grid_;
  PrepareFn prepare_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<Request> queue_;       // sorted by priority, best first
  std::vector<BlockKey> in_flight_;  // being read, one per busy thread
  std::vector<LoadResult> results_;
  std::uint64_t bytes_read_ = 0;
  std::size_t in_flight_bytes_ = 0, source_bytes_ = 0;  // Request::bytes being read; sources' bounds
  int opened_ = 0;  // threads that opened (or failed to open) their source
  bool stop_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace terralod::blocks
