// The SQLite connection behind one BlockDatabase: opening and configuring it, its cached
// statements, checked column reads, verified blob reads and checked bindings (see
// block_database_connection.hpp).
//
// Crash consistency (SIGKILL of the writer at any moment): journal_mode=WAL (set by create()
// and open(), block_database_schema.cpp) with synchronous=NORMAL (configure() below). In WAL
// mode a transaction is committed when its frames, the last one
// marked as a commit frame, are written to the -wal file; write() hands them to the OS page
// cache, which outlives the process, so a killed process loses at most the transaction it was
// in the middle of, and a torn tail is dropped on recovery by the WAL's salted frame checksums.
// NORMAL (fsync only at checkpoints) therefore gives full consistency against process death;
// FULL (fsync of every commit) would only add durability of the last commits across a power
// loss, which a resumable build does not need, at the price of one fsync per block. A power
// loss under NORMAL can lose recent commits but still never corrupts the file (the WAL is
// fsynced before every checkpoint writes back into the database).
//
// Hostile files (fuzzing, issue 9): connections run with SQLITE_DBCONFIG_DEFENSIVE,
// trusted_schema=OFF and cell_size_check=ON, without mmap, and every read goes through the
// size + CRC-32 check (verify()).
//
// Memory: per connection SQLite's page cache (default ~2 MB) plus kStatementCount prepared
// statements; reads allocate the blob once.
#include "block_database_connection.hpp"

#include <climits>
#include <cstdint>

#include "block_database_encoding.hpp"
#include "terralod/pm/byte_io.hpp"

namespace terralod::blocks::detail {

namespace {

constexpr int kBusyTimeoutMs = 10000;

constexpr std::array<const char*, kStatementCount> kSql = {
    "BEGIN IMMEDIATE",
    "COMMIT",
    "ROLLBACK",
    "INSERT OR REPLACE INTO blocks(col, row, size, crc32, data) VALUES (?1, ?2, ?3, ?4, ?5)",
    "SELECT 1 FROM blocks WHERE col = ?1 AND row = ?2",
    "SELECT size, crc32, data FROM blocks WHERE col = ?1 AND row = ?2",
    "SELECT col, row FROM blocks ORDER BY col, row",
    "INSERT OR REPLACE INTO blobs(name, size, crc32, data) VALUES (?1, ?2, ?3, ?4)",
    "SELECT size, crc32, data FROM blobs WHERE name = ?1",
    "SELECT name FROM blobs ORDER BY name",
    "DELETE FROM blobs WHERE name = ?1",
    "INSERT OR REPLACE INTO blobs(name, size, crc32, data) VALUES (?1, ?2, ?3, zeroblob(?2))",
    "INSERT OR REPLACE INTO texture_tiles(layer, node, level, size, crc32, data) VALUES (?1, ?2, ?3, ?4, ?5, "
    "?6)",
    "SELECT size, crc32, data FROM texture_tiles WHERE layer = ?1 AND node = ?2 AND level = ?3",
    "SELECT DISTINCT layer FROM texture_tiles ORDER BY layer",
    "SELECT node, level FROM texture_tiles WHERE layer = ?1 ORDER BY node, level",
    "INSERT OR REPLACE INTO meta(key, value) VALUES (?1, ?2)",
    "SELECT value FROM meta WHERE key = ?1",
    "SELECT key FROM meta ORDER BY key",
};

}  // namespace

std::string block_name(BlockKey k) {
  return "block (" + std::to_string(k.col) + "," + std::to_string(k.row) + ")";
}
std::string blob_item(const std::string& name) { return "blob '" + name + "'"; }
std::string tile_name(const std::string& layer, std::int64_t node, int level) {
  return "texture tile (layer '" + layer + "', node " + std::to_string(node) + ", level " +
         std::to_string(level) + ")";
}

BlockDatabaseImpl::~BlockDatabaseImpl() {
  for (sqlite3_stmt* s : stmts) sqlite3_finalize(s);
  sqlite3_close_v2(db);  // the last connection to close checkpoints and removes the WAL
}

void BlockDatabaseImpl::check(int rc, const std::string& what) const {
  if (rc == SQLITE_OK || rc == SQLITE_DONE || rc == SQLITE_ROW) return;
  const char* msg = db ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
  fail(what + " (" + (msg ? msg : sqlite3_errstr(rc)) + ")");
}

void BlockDatabaseImpl::exec(const char* sql, const std::string& what) const {
  char* err = nullptr;
  const int rc = sqlite3_exec(db, sql, nullptr, nullptr, &err);
  if (rc != SQLITE_OK) {
    const std::string msg = err ? err : sqlite3_errstr(rc);
    sqlite3_free(err);
    fail(what + " (" + msg + ")");
  }
}

sqlite3_stmt* BlockDatabaseImpl::stmt(Stmt s, const std::string& what) {
  if (!stmts[s])
    check(sqlite3_prepare_v3(db, kSql[s], -1, SQLITE_PREPARE_PERSISTENT, &stmts[s], nullptr), what);
  return stmts[s];
}

std::string BlockDatabaseImpl::text(sqlite3_stmt* st, int i, const std::string& what) const {
  if (sqlite3_column_type(st, i) != SQLITE_TEXT) fail(what + ": corrupt record (not text)");
  const auto* p = sqlite3_column_text(st, i);
  return std::string(reinterpret_cast<const char*>(p), std::size_t(sqlite3_column_bytes(st, i)));
}

std::int64_t BlockDatabaseImpl::integer(sqlite3_stmt* st, int i, const std::string& what) const {
  if (sqlite3_column_type(st, i) != SQLITE_INTEGER) fail(what + ": corrupt record (not an integer)");
  return sqlite3_column_int64(st, i);
}

std::string BlockDatabaseImpl::verify(sqlite3_stmt* st, int first, std::vector<std::uint8_t>* out) const {
  if (sqlite3_column_type(st, first) != SQLITE_INTEGER ||
      sqlite3_column_type(st, first + 1) != SQLITE_INTEGER)
    return "corrupt record (size or checksum is not an integer)";
  const std::int64_t size = sqlite3_column_int64(st, first);
  const std::int64_t crc = sqlite3_column_int64(st, first + 1);
  const int type = sqlite3_column_type(st, first + 2);
  if (type != SQLITE_BLOB && type != SQLITE_NULL) return "corrupt record (data is not a blob)";
  const void* data = sqlite3_column_blob(st, first + 2);
  const int n = sqlite3_column_bytes(st, first + 2);
  if (sqlite3_errcode(db) == SQLITE_NOMEM) return "out of memory reading the data";
  if (n != size) {
    if (n < size) return "truncated (" + std::to_string(n) + " of " + std::to_string(size) + " bytes)";
    return "size mismatch (" + std::to_string(n) + " bytes stored, " + std::to_string(size) + " recorded)";
  }
  if (crc < 0 || crc > std::int64_t(UINT32_MAX) ||
      pm::crc32_of({static_cast<const std::uint8_t*>(data), std::size_t(n)}) != std::uint32_t(crc))
    return "checksum mismatch";
  if (out) {
    const auto* p = static_cast<const std::uint8_t*>(data);
    out->assign(p, p + n);
  }
  return "";
}

std::optional<std::vector<std::uint8_t>> BlockDatabaseImpl::read_one(sqlite3_stmt* st,
                                                                     const std::string& item) {
  const int rc = sqlite3_step(st);
  if (rc == SQLITE_DONE) return std::nullopt;
  if (rc != SQLITE_ROW) check(rc, item + ": cannot be read");
  std::vector<std::uint8_t> bytes;
  const std::string problem = verify(st, 0, &bytes);
  if (!problem.empty()) fail(item + ": " + problem);
  return bytes;
}

void BlockDatabaseImpl::bind_blob(sqlite3_stmt* st, int first, std::span<const std::uint8_t> blob,
                                  const std::string& item) {
  if (blob.size() > std::size_t(sqlite3_limit(db, SQLITE_LIMIT_LENGTH, -1)))
    fail(item + ": " + std::to_string(blob.size()) + " bytes is more than SQLite stores in one blob");
  check(sqlite3_bind_int64(st, first, std::int64_t(blob.size())), item);
  check(sqlite3_bind_int64(st, first + 1, std::int64_t(pm::crc32_of(blob))), item);
  // A zero-length blob must be bound as a blob, not NULL (data is NOT NULL).
  static const std::uint8_t empty = 0;
  check(sqlite3_bind_blob64(st, first + 2, blob.empty() ? &empty : blob.data(), blob.size(), SQLITE_STATIC),
        item);
}

void BlockDatabaseImpl::step_write(sqlite3_stmt* st, const std::string& item) {
  const int rc = sqlite3_step(st);
  if (rc != SQLITE_DONE) check(rc == SQLITE_ROW ? SQLITE_ERROR : rc, item + ": cannot be written");
}

void BlockDatabaseImpl::bind_text(sqlite3_stmt* st, int i, const std::string& s, const std::string& item) {
  check(sqlite3_bind_text64(st, i, s.data(), s.size(), SQLITE_STATIC, SQLITE_UTF8), item);
}

void BlockDatabaseImpl::configure() {
  sqlite3_extended_result_codes(db, 1);
  sqlite3_busy_timeout(db, kBusyTimeoutMs);
  sqlite3_db_config(db, SQLITE_DBCONFIG_DEFENSIVE, 1, nullptr);
  sqlite3_db_config(db, SQLITE_DBCONFIG_TRUSTED_SCHEMA, 0, nullptr);
  exec("PRAGMA cell_size_check = ON; PRAGMA mmap_size = 0", "cannot configure the connection");
  if (mode == Mode::ReadWrite) exec("PRAGMA synchronous = NORMAL", "cannot configure the connection");
}

std::unique_ptr<BlockDatabaseImpl> connect(const std::string& path, BlockDatabase::Mode mode) {
  auto impl = std::make_unique<BlockDatabaseImpl>();
  impl->path = path;
  impl->mode = mode;
  int flags = SQLITE_OPEN_NOMUTEX | SQLITE_OPEN_EXRESCODE;
  flags |= mode == BlockDatabase::Mode::ReadOnly ? SQLITE_OPEN_READONLY : SQLITE_OPEN_READWRITE;
  const int rc = sqlite3_open_v2(path.c_str(), &impl->db, flags, nullptr);
  if (rc != SQLITE_OK) impl->check(rc, "cannot open the database");
  impl->configure();
  return impl;
}

}  // namespace terralod::blocks::detail
