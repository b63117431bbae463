// Block database: one SQLite file holding a built terrain — its metadata, the progressive mesh
// of every block, named blobs (the approximation tree, ...), texture tiles and small build state —
// with every blob checksummed, crash-consistent writes and concurrent readers.
//
// Usage:
//   #include <terralod/blocks/block_database.hpp>
//   namespace tb = terralod::blocks;
//   tb::DatabaseInfo info;
//   info.grid_width = 1201; info.grid_height = 1201; info.block_size = 257;
//   info.transform = hf.transform; info.crs_wkt = hf.crs_wkt; info.source = "N44W072.hgt";
//   auto db = tb::BlockDatabase::create("terrain.db", info);       // throws if the file exists
//   db.put_block({/*col=*/0, /*row=*/0}, terralod::pm::encode_pm(block_pm));
//   {
//     tb::BlockDatabase::Transaction t(db);                         // several puts, one commit
//     db.put_blob("tree", tree_bytes);
//     db.set_meta("build_complete", "1");
//     t.commit();                                                   // rolled back if not reached
//   }
//   auto reader = tb::BlockDatabase::open("terrain.db");            // any thread, own connection
//   for (tb::BlockKey k : reader.blocks()) auto pm = terralod::pm::decode_pm(reader.read_block(k));
//   try { reader.read_block({9, 9}); }
//   catch (const tb::DatabaseError& e) { /* "terrain.db: block (9,9): not in the database" */ }
//
// Contract:
//   path       UTF-8 file name of the SQLite file. SQLite also keeps "<path>-wal" and
//              "<path>-shm" beside it while connections are open (WAL mode); the folder must be
//              writable for ReadWrite and, unless both files already exist, for ReadOnly too.
//   BlockKey   (col,row) index of a block in the block grid (not samples); any int is storable.
//              blocks() is sorted by operator<=> (col, then row).
//   blobs      any size from 0 to 1,000,000,000 bytes (SQLite's limit; larger -> DatabaseError).
//              Spans are only read during the call; returned vectors are owned by the caller.
//   names      named blobs ("tree", "hybrid", ...), texture layers and meta keys are any UTF-8
//              strings (case-sensitive). put_* and set_meta replace an existing entry.
//   texture    a tile is addressed by (layer, node, level); node is the approximation-tree node
//              id, level the pyramid level (both any value; the database does not interpret them).
//   threads    one BlockDatabase object is one SQLite connection: use it from one thread at a
//              time. Other threads open their own (cheap: open() reads the schema and the info
//              row). WAL lets any number of readers read while one writer writes; a reader sees
//              the database as of the start of each call (each read is its own read
//              transaction; blocks() then read_block() may miss a block added in between).
//   errors     bad data (missing/garbage/truncated/foreign/newer file, missing or corrupted
//              item, an SQLite I/O error) throws DatabaseError, what() = "<path>: <problem>",
//              naming the item when there is one: "terrain.db: block (3,1): checksum mismatch".
//              API misuse (writing through a ReadOnly object, nested Transactions, using a
//              moved-from object) is an assertion.
//   memory     a read allocates the blob's size once; check_integrity() streams one blob at a
//              time; each connection keeps SQLite's page cache (default 2 MB) and about 20
//              prepared statements.
//
// Crash consistency: each put/set is one SQLite transaction (or part of the enclosing
// Transaction). The file is in WAL mode with synchronous=NORMAL: a transaction is complete once
// its commit frame is in the WAL; a process killed at any moment (SIGKILL included) leaves the
// file in the state of its last committed transaction (the OS keeps written pages; SQLite's
// WAL frame checksums drop a torn tail). A power loss may lose the last few commits but never
// corrupts the file. create() writes the schema and metadata in one transaction: an interrupted
// create() leaves no file, a file that open() rejects with "not a terralod database
// (interrupted create?)" (is_interrupted_create() is true of it: delete it and create again;
// create() discards the journal files left beside it), or a complete empty database.
//
// On-disk format (format version 1). SQLite 3 database, PRAGMA application_id = 0x544C4F44
// ("TLOD"), PRAGMA user_version = format version, journal_mode = WAL. Tables:
//   info           exactly one row (id = 1), written once by create():
//     id                INTEGER PRIMARY KEY CHECK (id = 1)
//     format_version    INTEGER  (1; open() rejects larger values as "newer")
//     kind              TEXT     DatabaseInfo::kind ("blocks" | "hybrid")
//     grid_width        INTEGER  samples per row of the whole terrain (>= 0)
//     grid_height       INTEGER  sample rows of the whole terrain (>= 0)
//     transform         BLOB     48 bytes: GridTransform x0, xc, xr, y0, yc, yr as IEEE-754
//                                binary64 little-endian (bit-exact, -0.0 and all)
//     crs_wkt           TEXT     coordinate reference system as WKT, '' if unknown
//     block_size        INTEGER  samples per block side (2^k+1), 0 if not blocked
//     build_parameters  TEXT     JSON of the build options
//     source            TEXT     input file name
//     info_crc32        INTEGER  CRC-32 of the canonical encoding of the fields above (see
//                                block_database_encoding.cpp, info_crc); checked by open()
//   blocks         one row per block PM (pm::encode_pm bytes):
//     col INTEGER, row INTEGER  block index, PRIMARY KEY (col, row)
//     size INTEGER              byte length of data
//     crc32 INTEGER             CRC-32 (zlib, polynomial 0xEDB88320) of data, as unsigned 32-bit
//     data BLOB
//   blobs          named blobs: name TEXT PRIMARY KEY, size INTEGER, crc32 INTEGER, data BLOB
//   texture_tiles  layer TEXT, node INTEGER, level INTEGER, size INTEGER, crc32 INTEGER,
//                  data BLOB, PRIMARY KEY (layer, node, level)
//   meta           small key/value state: key TEXT PRIMARY KEY, value TEXT NOT NULL
//   object_layers, object_features, object_blocks: present once an object layer was added;
//                  documented in terralod/blocks/object_layers.hpp.
// Every read of a blob checks that length(data) == size and crc32(data) == crc32.
#pragma once

#include <compare>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <terralod/pm/heightfield.hpp>
#include <vector>

namespace terralod::blocks {

namespace detail {
struct BlockDatabaseImpl;  // the SQLite connection and its cached statements (block_database_connection.hpp)
struct ImplAccess;         // lets the library's other stores (object_layers.cpp) use the connection
}  // namespace detail

/// Bad or unreadable database content. what() = "<path>: <problem>".
class DatabaseError : public std::runtime_error {
 public:
  DatabaseError(const std::string& path, const std::string& problem)
      : std::runtime_error(path + ": " + problem), path_(path) {}
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

/// Index of a block in the block grid.
struct BlockKey {
  int col = 0, row = 0;
  auto operator<=>(const BlockKey&) const = default;
};

/// Address of a texture tile within one layer.
struct TextureTileKey {
  std::int64_t node = 0;
  int level = 0;
  auto operator<=>(const TextureTileKey&) const = default;
};

/// Where the terrain lies on the Earth, for exporters that need longitude, latitude and the
/// heights' datum (Heightfield::crs_transform, Heightfield::vertical_datum). Stored as the named
/// blob "georeference": 48 bytes crs_transform (as the info table's transform), u64 byte length
/// and the UTF-8 bytes of vertical_datum (little-endian).
struct Georeference {
  pm::GridTransform crs_transform;  ///< (col,row) -> coordinates of DatabaseInfo::crs_wkt
  std::string vertical_datum;       ///< as the source states it; empty when unknown
  bool operator==(const Georeference&) const = default;
};

/// The metadata, written once by create().
struct DatabaseInfo {
  std::string kind = "blocks";          ///< "blocks" (block PMs + tree) or "hybrid"
  int grid_width = 0, grid_height = 0;  ///< samples of the whole terrain
  pm::GridTransform transform;          ///< (col,row) -> world metres, as in the Heightfield
  std::string crs_wkt;                  ///< empty if unknown
  int block_size = 0;                   ///< samples per block side (2^k+1); 0 if not blocked
  std::string build_parameters;         ///< JSON text of the build options (compared on resume)
  std::string source;                   ///< the input file
  bool operator==(const DatabaseInfo&) const = default;
};

class BlockDatabase {
 public:
  enum class Mode { ReadOnly, ReadWrite };
  /// Format version written by create() and the newest one open() accepts.
  static constexpr int kFormatVersion = 1;

  /// Creates a new database at `path` holding `info`, opened ReadWrite. Throws DatabaseError if
  /// `path` already exists or cannot be written, or if info.transform is not finite; on
  /// failure nothing is left at `path`. Sizes in `info` must be >= 0 (asserted).
  static BlockDatabase create(const std::string& path, const DatabaseInfo& info);
  /// Opens an existing database; checks that it is a terralod database of a supported format
  /// version with the expected schema and reads its info. Throws DatabaseError otherwise.
  static BlockDatabase open(const std::string& path, Mode mode = Mode::ReadOnly);
  /// True when `path` is what a create() killed before its commit leaves: a file open() rejects
  /// with "not a terralod database (interrupted create?)". It holds nothing; a caller that was
  /// creating the database may delete it (with its -wal, -shm and -journal files) and create
  /// again. Reads only; false for anything else, a complete database or a foreign file included.
  static bool is_interrupted_create(const std::string& path);

  BlockDatabase(BlockDatabase&&) noexcept;
  BlockDatabase& operator=(BlockDatabase&&) noexcept;
  BlockDatabase(const BlockDatabase&) = delete;
  BlockDatabase& operator=(const BlockDatabase&) = delete;
  ~BlockDatabase();

  const std::string& path() const;
  const DatabaseInfo& info() const;
  Mode mode() const;
  int format_version() const;  ///< of the file (<= kFormatVersion)
  /// The most heap the connection holds: its page cache's limit (PRAGMA cache_size, 2 MB by
  /// default) plus 128 kB for SQLite's own structures, schema and statements (about 100 kB
  /// measured on a loader's connection). Fixed while it is open, whatever it has read.
  std::size_t memory_bytes() const;
  /// Sets the page cache's limit (PRAGMA cache_size), bytes; a connection that reads each blob
  /// once (the runtime's loaders) needs little more than the b-tree's inner pages.
  void set_cache_limit(std::size_t bytes);

  // Blobs: each put is atomic (its own transaction unless inside a Transaction) and replaces
  // any previous value; every read verifies size and checksum and throws DatabaseError naming
  // the item on mismatch or truncation.
  void put_block(BlockKey key, std::span<const std::uint8_t> blob);
  bool has_block(BlockKey key) const;
  /// DatabaseError if the block is missing or corrupt.
  std::vector<std::uint8_t> read_block(BlockKey key) const;
  /// Every stored block, sorted.
  std::vector<BlockKey> blocks() const;

  /// Named blobs: "tree", "hybrid", ...
  void put_blob(const std::string& name, std::span<const std::uint8_t> blob);
  /// nullopt if absent; DatabaseError if corrupt.
  std::optional<std::vector<std::uint8_t>> read_blob(const std::string& name) const;
  /// Names of all named blobs, sorted.
  std::vector<std::string> blob_names() const;
  /// Removes the named blob; nothing happens if there is none.
  void remove_blob(const std::string& name);
  /// put_blob for a blob of `size` bytes and CRC-32 `crc32` (pm::crc32_of; a caller computes it
  /// first, e.g. by running its fill once with a writer that only sums) that fill() gives piece
  /// by piece, calling write(piece) until exactly `size` bytes are given. Memory holds 1 MiB,
  /// not the blob: the row is inserted once with zeros and its data written in place (SQLite's
  /// incremental blob I/O), never rewritten. DatabaseError if fill gives another size or CRC;
  /// call it inside a Transaction, so that a failure leaves nothing. read_blob reads the result
  /// as any blob.
  using BlobPieceWriter = std::function<void(std::span<const std::uint8_t>)>;
  void put_blob_in_pieces(const std::string& name, std::uint64_t size, std::uint32_t crc32,
                          const std::function<void(const BlobPieceWriter& write)>& fill);

  /// The "georeference" blob (see Georeference); nullopt when the database has none (built
  /// from a source without a CRS, or by a version before it was recorded); DatabaseError naming
  /// the file when it is malformed.
  void put_georeference(const Georeference& g);
  std::optional<Georeference> georeference() const;

  void put_texture_tile(const std::string& layer, std::int64_t node, int level,
                        std::span<const std::uint8_t> blob);
  /// nullopt if absent; DatabaseError if corrupt.
  std::optional<std::vector<std::uint8_t>> read_texture_tile(const std::string& layer, std::int64_t node,
                                                             int level) const;
  /// Layers that have at least one tile, sorted.
  std::vector<std::string> texture_layers() const;
  /// Tiles of one layer, sorted.
  std::vector<TextureTileKey> texture_tiles(const std::string& layer) const;

  /// Small key/value state ("build_complete", layer JSON, ...). Not checksummed: keep it small.
  void set_meta(const std::string& key, const std::string& value);
  std::optional<std::string> get_meta(const std::string& key) const;
  /// All meta keys, sorted.
  std::vector<std::string> meta_keys() const;

  struct IntegrityReport {
    bool ok = true;                     ///< no problem found
    std::vector<std::string> problems;  ///< each "<path>: <item>: <problem>"
    std::size_t items_checked = 0;      ///< blobs (blocks, named blobs, tiles, object features) verified
  };
  /// SQLite's PRAGMA integrity_check plus every blob's size and checksum. Problems are
  /// reported, not thrown (only a database that cannot be read at all throws).
  IntegrityReport check_integrity() const;

  /// RAII write transaction: BlockDatabase::Transaction t(db); ...puts...; t.commit();
  /// Destroyed without commit() -> everything since construction is rolled back.
  class Transaction;

 private:
  using Impl = detail::BlockDatabaseImpl;
  friend struct detail::ImplAccess;
  explicit BlockDatabase(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

class BlockDatabase::Transaction {
 public:
  /// Begins an IMMEDIATE transaction on `db` (which must be ReadWrite and not already in one).
  explicit Transaction(BlockDatabase& db);
  ~Transaction();  ///< rolls back if commit() was not called
  /// Commits; DatabaseError on failure (the transaction is then rolled back).
  void commit();
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;

 private:
  BlockDatabase* db_;
  bool done_ = false;
};

}  // namespace terralod::blocks
