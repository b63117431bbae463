// The SQLite connection behind one BlockDatabase (private to the block database's files): its
// prepared statements, checked column reads, blob reads verified by size and CRC-32, blob and
// text bindings, the statement scope guards, and the names that errors give each item.
//
// Contract: every method that fails throws DatabaseError naming the database's path; the
// statements of kSql are prepared on first use and kept until the connection closes (Use
// resets one after each use); OneOff prepares and finalizes a statement of its own.
#pragma once

#include <sqlite3.h>

#include <array>
#include <cassert>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "terralod/blocks/block_database.hpp"

namespace terralod::blocks::detail {

/// How errors name the items: "block (3,1)", "blob 'tree'", "texture tile (layer 'x', node 5, level 2)".
std::string block_name(BlockKey k);
std::string blob_item(const std::string& name);
std::string tile_name(const std::string& layer, std::int64_t node, int level);

// Every statement a connection uses, prepared on first use and kept until the connection closes.
enum Stmt : int {
  kBegin,
  kCommit,
  kRollback,
  kPutBlock,
  kHasBlock,
  kReadBlock,
  kListBlocks,
  kPutBlob,
  kReadBlob,
  kListBlobs,
  kRemoveBlob,
  kPutZeroBlob,
  kPutTile,
  kReadTile,
  kListLayers,
  kListTiles,
  kSetMeta,
  kGetMeta,
  kListMeta,
  kStatementCount
};

struct BlockDatabaseImpl {
  using Mode = BlockDatabase::Mode;
  std::string path;
  Mode mode = Mode::ReadOnly;
  DatabaseInfo info;
  int format_version = 0;
  sqlite3* db = nullptr;
  std::array<sqlite3_stmt*, kStatementCount> stmts{};
  bool in_transaction = false;

  BlockDatabaseImpl() = default;
  BlockDatabaseImpl(const BlockDatabaseImpl&) = delete;
  BlockDatabaseImpl& operator=(const BlockDatabaseImpl&) = delete;
  ~BlockDatabaseImpl();

  [[noreturn]] void fail(const std::string& problem) const { throw DatabaseError(path, problem); }
  /// Throws "<path>: <what>: <SQLite's message>" unless rc is one of the ok codes.
  void check(int rc, const std::string& what) const;
  void exec(const char* sql, const std::string& what) const;
  /// The cached statement `s`, reset and with its bindings cleared by the Use guard.
  sqlite3_stmt* stmt(Stmt s, const std::string& what);
  /// Text of column `i` (must be TEXT); `what` names the item for the error.
  std::string text(sqlite3_stmt* st, int i, const std::string& what) const;
  std::int64_t integer(sqlite3_stmt* st, int i, const std::string& what) const;
  /// Checks columns (size, crc32, data) starting at `first` of the current row; returns the
  /// problem ("" if none). With `out`, copies the verified bytes there.
  std::string verify(sqlite3_stmt* st, int first, std::vector<std::uint8_t>* out) const;
  /// Reads one verified blob by a statement whose columns are (size, crc32, data); nullopt if
  /// there is no row.
  std::optional<std::vector<std::uint8_t>> read_one(sqlite3_stmt* st, const std::string& item);
  void require_writable() const {
    assert(mode == Mode::ReadWrite && "BlockDatabase: writing through a ReadOnly database");
  }
  /// Binds the blob (size, crc, data) at parameters first, first+1, first+2.
  void bind_blob(sqlite3_stmt* st, int first, std::span<const std::uint8_t> blob, const std::string& item);
  void step_write(sqlite3_stmt* st, const std::string& item);
  /// Binds s without copying it (SQLITE_STATIC): s must outlive the statement's step.
  void bind_text(sqlite3_stmt* st, int i, const std::string& s, const std::string& item);
  /// A temporary (a std::string made from a const char*, say) would be gone before the step:
  /// the caller names the string instead.
  void bind_text(sqlite3_stmt* st, int i, std::string&& s, const std::string& item) = delete;
  /// Per-connection settings, before anything is read.
  void configure();
};

/// The connection behind a BlockDatabase, for the library's stores that keep tables of their own.
struct ImplAccess {
  static BlockDatabaseImpl& of(const BlockDatabase& db) {
    assert(db.impl_ && "BlockDatabase: use of a moved-from object");
    return *db.impl_;
  }
};

/// A new connection to `path` in `mode`, configured (the file must exist: create() makes it
/// itself, so SQLITE_OPEN_CREATE is never used).
std::unique_ptr<BlockDatabaseImpl> connect(const std::string& path, BlockDatabase::Mode mode);

/// Resets a cached statement and clears its bindings when the scope ends.
class Use {
 public:
  explicit Use(sqlite3_stmt* s) : s_(s) {}
  ~Use() {
    sqlite3_reset(s_);
    sqlite3_clear_bindings(s_);
  }
  Use(const Use&) = delete;
  Use& operator=(const Use&) = delete;
  operator sqlite3_stmt*() const { return s_; }

 private:
  sqlite3_stmt* s_;
};

/// A one-off statement (schema checks, integrity scans), finalized at scope end.
class OneOff {
 public:
  OneOff(BlockDatabaseImpl& db, const char* sql, const std::string& what) {
    db.check(sqlite3_prepare_v2(db.db, sql, -1, &s_, nullptr), what);
  }
  ~OneOff() { sqlite3_finalize(s_); }
  OneOff(const OneOff&) = delete;
  OneOff& operator=(const OneOff&) = delete;
  operator sqlite3_stmt*() const { return s_; }

 private:
  sqlite3_stmt* s_ = nullptr;
};

}  // namespace terralod::blocks::detail
