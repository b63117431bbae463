// Block database on SQLite: schema, checksummed blob storage, crash-consistent writes and
// per-connection prepared statements. The on-disk format (tables and columns) is documented in
// terralod/blocks/block_database.hpp; the canonical encoding behind info_crc32 is encode_info()
// below.
//
// Crash consistency (SIGKILL of the writer at any moment): journal_mode=WAL with
// synchronous=NORMAL. In WAL mode a transaction is committed when its frames, the last one
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
// trusted_schema=OFF and cell_size_check=ON, without mmap; open() only accepts a file whose
// five tables are real tables (not views that could run arbitrary queries) with the expected
// columns, and every read goes through the size + CRC-32 check.
//
// Memory: per connection SQLite's page cache (default ~2 MB) plus kStatementCount prepared
// statements; reads allocate the blob once; check_integrity streams one row at a time.
#include "terralod/blocks/block_database.hpp"

#include <fcntl.h>
#include <sqlite3.h>
#include <unistd.h>
#include <zlib.h>

#include <array>
#include <bit>
#include <cassert>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <system_error>
#include <utility>

namespace terralod::blocks {

namespace {

namespace fs = std::filesystem;
using Impl = detail::BlockDatabaseImpl;

constexpr std::int64_t kApplicationId = 0x544C4F44;  // "TLOD"
constexpr int kBusyTimeoutMs = 10000;
constexpr std::size_t kTransformBytes = 48;

std::uint32_t crc32_of(const void* data, std::size_t size) {
  if (size == 0) return 0;  // the CRC-32 of nothing
  return std::uint32_t(crc32_z(0L, static_cast<const Bytef*>(data), z_size_t(size)));
}

std::string block_name(BlockKey k) {
  return "block (" + std::to_string(k.col) + "," + std::to_string(k.row) + ")";
}
std::string blob_item(const std::string& name) { return "blob '" + name + "'"; }
std::string tile_name(const std::string& layer, std::int64_t node, int level) {
  return "texture tile (layer '" + layer + "', node " + std::to_string(node) + ", level " +
         std::to_string(level) + ")";
}

// Canonical encoding of DatabaseInfo for info_crc32 (all integers little-endian):
//   u32 format_version, then for kind: u64 byte length + UTF-8 bytes, i32 grid_width,
//   i32 grid_height, 48 bytes transform (as the transform column), crs_wkt, i32 block_size,
//   build_parameters, source (strings as for kind).
struct Writer {
  std::vector<std::uint8_t> b;
  void u64(std::uint64_t v) {
    for (int i = 0; i < 8; ++i) b.push_back(std::uint8_t(v >> (8 * i)));
  }
  void u32(std::uint32_t v) {
    for (int i = 0; i < 4; ++i) b.push_back(std::uint8_t(v >> (8 * i)));
  }
  void str(const std::string& s) {
    u64(s.size());
    b.insert(b.end(), s.begin(), s.end());
  }
};

std::vector<std::uint8_t> encode_transform(const pm::GridTransform& t) {
  Writer w;
  for (double v : {t.x0, t.xc, t.xr, t.y0, t.yc, t.yr}) w.u64(std::bit_cast<std::uint64_t>(v));
  return w.b;
}

pm::GridTransform decode_transform(const std::uint8_t* p) {
  double v[6];
  for (int k = 0; k < 6; ++k) {
    std::uint64_t bits = 0;
    for (int i = 0; i < 8; ++i) bits |= std::uint64_t(p[8 * k + i]) << (8 * i);
    v[k] = std::bit_cast<double>(bits);
  }
  return pm::GridTransform{v[0], v[1], v[2], v[3], v[4], v[5]};
}

bool transform_is_finite(const pm::GridTransform& t) {
  for (double v : {t.x0, t.xc, t.xr, t.y0, t.yc, t.yr})
    if (!std::isfinite(v)) return false;
  return true;
}

std::uint32_t info_crc(int format_version, const DatabaseInfo& info) {
  Writer w;
  w.u32(std::uint32_t(format_version));
  w.str(info.kind);
  w.u32(std::uint32_t(info.grid_width));
  w.u32(std::uint32_t(info.grid_height));
  const auto t = encode_transform(info.transform);
  w.b.insert(w.b.end(), t.begin(), t.end());
  w.str(info.crs_wkt);
  w.u32(std::uint32_t(info.block_size));
  w.str(info.build_parameters);
  w.str(info.source);
  return crc32_of(w.b.data(), w.b.size());
}

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
  kPutTile,
  kReadTile,
  kListLayers,
  kListTiles,
  kSetMeta,
  kGetMeta,
  kListMeta,
  kStatementCount
};

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
    "INSERT OR REPLACE INTO texture_tiles(layer, node, level, size, crc32, data) VALUES (?1, ?2, ?3, ?4, ?5, "
    "?6)",
    "SELECT size, crc32, data FROM texture_tiles WHERE layer = ?1 AND node = ?2 AND level = ?3",
    "SELECT DISTINCT layer FROM texture_tiles ORDER BY layer",
    "SELECT node, level FROM texture_tiles WHERE layer = ?1 ORDER BY node, level",
    "INSERT OR REPLACE INTO meta(key, value) VALUES (?1, ?2)",
    "SELECT value FROM meta WHERE key = ?1",
    "SELECT key FROM meta ORDER BY key",
};

// The schema of format version 1 (see the header for the meaning of each column).
constexpr const char* kSchema = R"sql(
CREATE TABLE info (
  id INTEGER PRIMARY KEY CHECK (id = 1),
  format_version INTEGER NOT NULL,
  kind TEXT NOT NULL,
  grid_width INTEGER NOT NULL,
  grid_height INTEGER NOT NULL,
  transform BLOB NOT NULL,
  crs_wkt TEXT NOT NULL,
  block_size INTEGER NOT NULL,
  build_parameters TEXT NOT NULL,
  source TEXT NOT NULL,
  info_crc32 INTEGER NOT NULL
);
CREATE TABLE blocks (
  col INTEGER NOT NULL, row INTEGER NOT NULL,
  size INTEGER NOT NULL, crc32 INTEGER NOT NULL, data BLOB NOT NULL,
  PRIMARY KEY (col, row)
);
CREATE TABLE blobs (
  name TEXT NOT NULL PRIMARY KEY,
  size INTEGER NOT NULL, crc32 INTEGER NOT NULL, data BLOB NOT NULL
);
CREATE TABLE texture_tiles (
  layer TEXT NOT NULL, node INTEGER NOT NULL, level INTEGER NOT NULL,
  size INTEGER NOT NULL, crc32 INTEGER NOT NULL, data BLOB NOT NULL,
  PRIMARY KEY (layer, node, level)
);
CREATE TABLE meta (
  key TEXT NOT NULL PRIMARY KEY,
  value TEXT NOT NULL
);
)sql";

// Each table with the columns open() requires (a query that must prepare).
constexpr std::array<std::pair<const char*, const char*>, 5> kTables = {{
    {"info",
     "SELECT id, format_version, kind, grid_width, grid_height, transform, crs_wkt, block_size, "
     "build_parameters, source, info_crc32 FROM info"},
    {"blocks", "SELECT col, row, size, crc32, data FROM blocks"},
    {"blobs", "SELECT name, size, crc32, data FROM blobs"},
    {"texture_tiles", "SELECT layer, node, level, size, crc32, data FROM texture_tiles"},
    {"meta", "SELECT key, value FROM meta"},
}};

}  // namespace

struct detail::BlockDatabaseImpl {
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
  ~BlockDatabaseImpl() {
    for (sqlite3_stmt* s : stmts) sqlite3_finalize(s);
    sqlite3_close_v2(db);  // the last connection to close checkpoints and removes the WAL
  }

  [[noreturn]] void fail(const std::string& problem) const { throw DatabaseError(path, problem); }
  /// Throws "<path>: <what>: <SQLite's message>" unless rc is one of the ok codes.
  void check(int rc, const std::string& what) const {
    if (rc == SQLITE_OK || rc == SQLITE_DONE || rc == SQLITE_ROW) return;
    const char* msg = db ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
    fail(what + " (" + (msg ? msg : sqlite3_errstr(rc)) + ")");
  }

  void exec(const char* sql, const std::string& what) const {
    char* err = nullptr;
    const int rc = sqlite3_exec(db, sql, nullptr, nullptr, &err);
    if (rc != SQLITE_OK) {
      const std::string msg = err ? err : sqlite3_errstr(rc);
      sqlite3_free(err);
      fail(what + " (" + msg + ")");
    }
  }

  /// The cached statement `s`, reset and with its bindings cleared by the Use guard.
  sqlite3_stmt* stmt(Stmt s, const std::string& what) {
    if (!stmts[s])
      check(sqlite3_prepare_v3(db, kSql[s], -1, SQLITE_PREPARE_PERSISTENT, &stmts[s], nullptr), what);
    return stmts[s];
  }

  /// Text of column `i` (must be TEXT); `what` names the item for the error.
  std::string text(sqlite3_stmt* st, int i, const std::string& what) const {
    if (sqlite3_column_type(st, i) != SQLITE_TEXT) fail(what + ": corrupt record (not text)");
    const auto* p = sqlite3_column_text(st, i);
    return std::string(reinterpret_cast<const char*>(p), std::size_t(sqlite3_column_bytes(st, i)));
  }

  std::int64_t integer(sqlite3_stmt* st, int i, const std::string& what) const {
    if (sqlite3_column_type(st, i) != SQLITE_INTEGER) fail(what + ": corrupt record (not an integer)");
    return sqlite3_column_int64(st, i);
  }

  /// Checks columns (size, crc32, data) starting at `first` of the current row; returns the
  /// problem ("" if none). With `out`, copies the verified bytes there.
  std::string verify(sqlite3_stmt* st, int first, std::vector<std::uint8_t>* out) const {
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
    if (crc < 0 || crc > std::int64_t(UINT32_MAX) || crc32_of(data, std::size_t(n)) != std::uint32_t(crc))
      return "checksum mismatch";
    if (out) {
      const auto* p = static_cast<const std::uint8_t*>(data);
      out->assign(p, p + n);
    }
    return "";
  }

  /// Reads one verified blob by a statement whose columns are (size, crc32, data); nullopt if
  /// there is no row.
  std::optional<std::vector<std::uint8_t>> read_one(sqlite3_stmt* st, const std::string& item) {
    const int rc = sqlite3_step(st);
    if (rc == SQLITE_DONE) return std::nullopt;
    if (rc != SQLITE_ROW) check(rc, item + ": cannot be read");
    std::vector<std::uint8_t> bytes;
    const std::string problem = verify(st, 0, &bytes);
    if (!problem.empty()) fail(item + ": " + problem);
    return bytes;
  }

  void require_writable() const {
    assert(mode == Mode::ReadWrite && "BlockDatabase: writing through a ReadOnly database");
  }

  /// Binds the blob (size, crc, data) at parameters first, first+1, first+2.
  void bind_blob(sqlite3_stmt* st, int first, std::span<const std::uint8_t> blob, const std::string& item) {
    if (blob.size() > std::size_t(sqlite3_limit(db, SQLITE_LIMIT_LENGTH, -1)))
      fail(item + ": " + std::to_string(blob.size()) + " bytes is more than SQLite stores in one blob");
    check(sqlite3_bind_int64(st, first, std::int64_t(blob.size())), item);
    check(sqlite3_bind_int64(st, first + 1, std::int64_t(crc32_of(blob.data(), blob.size()))), item);
    // A zero-length blob must be bound as a blob, not NULL (data is NOT NULL).
    static const std::uint8_t empty = 0;
    check(sqlite3_bind_blob64(st, first + 2, blob.empty() ? &empty : blob.data(), blob.size(), SQLITE_STATIC),
          item);
  }

  void step_write(sqlite3_stmt* st, const std::string& item) {
    const int rc = sqlite3_step(st);
    if (rc != SQLITE_DONE) check(rc == SQLITE_ROW ? SQLITE_ERROR : rc, item + ": cannot be written");
  }

  void bind_text(sqlite3_stmt* st, int i, const std::string& s, const std::string& item) {
    check(sqlite3_bind_text64(st, i, s.data(), s.size(), SQLITE_STATIC, SQLITE_UTF8), item);
  }

  /// Per-connection settings, before anything is read.
  void configure() {
    sqlite3_extended_result_codes(db, 1);
    sqlite3_busy_timeout(db, kBusyTimeoutMs);
    sqlite3_db_config(db, SQLITE_DBCONFIG_DEFENSIVE, 1, nullptr);
    sqlite3_db_config(db, SQLITE_DBCONFIG_TRUSTED_SCHEMA, 0, nullptr);
    exec("PRAGMA cell_size_check = ON; PRAGMA mmap_size = 0", "cannot configure the connection");
    if (mode == Mode::ReadWrite) exec("PRAGMA synchronous = NORMAL", "cannot configure the connection");
  }
};

namespace {

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
  OneOff(Impl& db, const char* sql, const std::string& what) {
    db.check(sqlite3_prepare_v2(db.db, sql, -1, &s_, nullptr), what);
  }
  ~OneOff() { sqlite3_finalize(s_); }
  OneOff(const OneOff&) = delete;
  OneOff& operator=(const OneOff&) = delete;
  operator sqlite3_stmt*() const { return s_; }

 private:
  sqlite3_stmt* s_ = nullptr;
};

// create() makes the file itself (O_EXCL), so SQLITE_OPEN_CREATE is never used.
std::unique_ptr<Impl> connect(const std::string& path, BlockDatabase::Mode mode) {
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  impl->mode = mode;
  int flags = SQLITE_OPEN_NOMUTEX | SQLITE_OPEN_EXRESCODE;
  flags |= mode == BlockDatabase::Mode::ReadOnly ? SQLITE_OPEN_READONLY : SQLITE_OPEN_READWRITE;
  const int rc = sqlite3_open_v2(path.c_str(), &impl->db, flags, nullptr);
  if (rc != SQLITE_OK) impl->check(rc, "cannot open the database");
  impl->configure();
  return impl;
}

/// Reads and verifies the info row into `info` and `format_version`.
void read_info(Impl& d, DatabaseInfo& info, int& format_version) {
  const std::string what = "info";
  OneOff st(d, kTables[0].second, "cannot read the info table");
  // kTables[0] has no WHERE: take the row with id = 1 and reject any other row.
  bool found = false;
  for (int rc; (rc = sqlite3_step(st)) != SQLITE_DONE;) {
    if (rc != SQLITE_ROW) d.check(rc, "cannot read the info table");
    if (found || d.integer(st, 0, what) != 1) d.fail("corrupt info table (more than one row)");
    found = true;
    const std::int64_t version = d.integer(st, 1, what);
    if (version > BlockDatabase::kFormatVersion)
      d.fail("format version " + std::to_string(version) + " is newer than this terralod reads (" +
             std::to_string(BlockDatabase::kFormatVersion) + "); use a newer terralod");
    if (version < 1) d.fail("corrupt info table (format version " + std::to_string(version) + ")");
    format_version = int(version);
    info.kind = d.text(st, 2, what);
    const auto dim = [&](int col, const char* name) {
      const std::int64_t v = d.integer(st, col, what);
      if (v < 0 || v > INT_MAX)
        d.fail(std::string("corrupt info table (") + name + " " + std::to_string(v) + ")");
      return int(v);
    };
    info.grid_width = dim(3, "grid_width");
    info.grid_height = dim(4, "grid_height");
    if (sqlite3_column_type(st, 5) != SQLITE_BLOB || sqlite3_column_bytes(st, 5) != int(kTransformBytes))
      d.fail("corrupt info table (the transform is not 48 bytes)");
    info.transform = decode_transform(static_cast<const std::uint8_t*>(sqlite3_column_blob(st, 5)));
    if (!transform_is_finite(info.transform)) d.fail("corrupt info table (the transform is not finite)");
    info.crs_wkt = d.text(st, 6, what);
    info.block_size = dim(7, "block_size");
    info.build_parameters = d.text(st, 8, what);
    info.source = d.text(st, 9, what);
    const std::int64_t crc = d.integer(st, 10, what);
    if (crc != std::int64_t(info_crc(format_version, info))) d.fail("info: checksum mismatch");
  }
  if (!found) d.fail("corrupt info table (no row)");
}

/// Identifies the file as a terralod database of a readable version with the expected schema.
void check_identity(Impl& d) {
  std::int64_t app_id = 0, objects = 0;
  {
    OneOff st(d, "PRAGMA application_id", "not a terralod database");
    const int rc = sqlite3_step(st);
    if (rc != SQLITE_ROW) {
      const int ext = sqlite3_extended_errcode(d.db);
      if ((ext & 0xff) == SQLITE_NOTADB) d.fail("not a SQLite database (not a terralod database)");
      // A terralod database is in WAL mode from its first commit on and never has a hot rollback
      // journal, except when create() was killed while switching the new file to WAL mode (a
      // ReadOnly connection cannot roll it back; a ReadWrite one would, leaving an empty file).
      if (ext == SQLITE_READONLY_ROLLBACK) d.fail("not a terralod database (interrupted create?)");
      d.check(rc, "cannot read the database header");
    }
    app_id = sqlite3_column_int64(st, 0);
  }
  {
    OneOff st(d, "SELECT count(*) FROM sqlite_schema", "cannot read the schema");
    const int rc = sqlite3_step(st);
    if (rc != SQLITE_ROW) d.check(rc, "cannot read the schema");
    objects = sqlite3_column_int64(st, 0);
  }
  if (app_id == 0 && objects == 0) d.fail("not a terralod database (interrupted create?)");
  if (app_id != kApplicationId) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "application_id 0x%08llx", static_cast<unsigned long long>(app_id));
    d.fail(std::string("not a terralod database (") + (app_id == 0 ? "an SQLite file of another kind" : buf) +
           ")");
  }
  // Tables must be real tables: a view could run any query on every read.
  for (const auto& [name, sql] : kTables) {
    OneOff st(d, "SELECT type FROM sqlite_schema WHERE name = ?1", "cannot read the schema");
    sqlite3_bind_text(st, 1, name, -1, SQLITE_STATIC);
    const int rc = sqlite3_step(st);
    if (rc != SQLITE_ROW && rc != SQLITE_DONE) d.check(rc, "cannot read the schema");
    if (rc == SQLITE_DONE) d.fail(std::string("schema mismatch: no table '") + name + "'");
    const auto* type = reinterpret_cast<const char*>(sqlite3_column_text(st, 0));
    if (!type || std::strcmp(type, "table") != 0)
      d.fail(std::string("schema mismatch: '") + name + "' is not a table");
  }
  for (const auto& [name, sql] : kTables) {
    sqlite3_stmt* s = nullptr;
    if (sqlite3_prepare_v2(d.db, sql, -1, &s, nullptr) != SQLITE_OK) {
      const std::string msg = sqlite3_errmsg(d.db);
      sqlite3_finalize(s);
      d.fail(std::string("schema mismatch in table '") + name + "' (" + msg + ")");
    }
    sqlite3_finalize(s);
  }
  read_info(d, d.info, d.format_version);
}

void remove_quietly(const std::string& p) {
  std::error_code ec;
  fs::remove(p, ec);
}

}  // namespace

// ---------------------------------------------------------------------------------------------

BlockDatabase::BlockDatabase(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
BlockDatabase::BlockDatabase(BlockDatabase&&) noexcept = default;
BlockDatabase& BlockDatabase::operator=(BlockDatabase&&) noexcept = default;
BlockDatabase::~BlockDatabase() = default;

BlockDatabase BlockDatabase::create(const std::string& path, const DatabaseInfo& info) {
  assert(info.grid_width >= 0 && info.grid_height >= 0 && info.block_size >= 0);
  if (!transform_is_finite(info.transform))
    throw DatabaseError(path, "cannot create: the grid transform is not finite");
  // Claim the name atomically: an existing file (or link) is never touched.
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) {
    const int err = errno;
    if (err == EEXIST) throw DatabaseError(path, "already exists (create() makes a new database only)");
    throw DatabaseError(path, std::string("cannot create (") + std::strerror(err) + ")");
  }
  ::close(fd);
  // We own the name now; journal files left by a database that was deleted (or by a killed
  // create()) are stale and would otherwise be replayed into the new file.
  remove_quietly(path + "-wal");
  remove_quietly(path + "-shm");
  remove_quietly(path + "-journal");
  try {
    auto impl = connect(path, Mode::ReadWrite);
    Impl& d = *impl;
    {
      OneOff st(d, "PRAGMA journal_mode = WAL", "cannot switch to WAL mode");
      if (sqlite3_step(st) != SQLITE_ROW) d.check(sqlite3_errcode(d.db), "cannot switch to WAL mode");
      const auto* m = reinterpret_cast<const char*>(sqlite3_column_text(st, 0));
      if (!m || std::strcmp(m, "wal") != 0)
        d.fail("cannot switch to WAL mode (the file system may not support it)");
    }
    // Schema, identity and info in one transaction: a kill before COMMIT leaves an empty file.
    d.exec("BEGIN IMMEDIATE", "cannot create the schema");
    d.exec(kSchema, "cannot create the schema");
    d.exec(("PRAGMA application_id = " + std::to_string(kApplicationId) +
            "; PRAGMA user_version = " + std::to_string(kFormatVersion))
               .c_str(),
           "cannot create the schema");
    {
      OneOff st(d,
                "INSERT INTO info(id, format_version, kind, grid_width, grid_height, transform, crs_wkt, "
                "block_size, build_parameters, source, info_crc32) VALUES (1, ?1, ?2, ?3, ?4, ?5, ?6, ?7, "
                "?8, ?9, ?10)",
                "cannot write the info");
      const std::vector<std::uint8_t> t = encode_transform(info.transform);
      sqlite3_bind_int(st, 1, kFormatVersion);
      d.bind_text(st, 2, info.kind, "info");
      sqlite3_bind_int(st, 3, info.grid_width);
      sqlite3_bind_int(st, 4, info.grid_height);
      sqlite3_bind_blob(st, 5, t.data(), int(t.size()), SQLITE_STATIC);
      d.bind_text(st, 6, info.crs_wkt, "info");
      sqlite3_bind_int(st, 7, info.block_size);
      d.bind_text(st, 8, info.build_parameters, "info");
      d.bind_text(st, 9, info.source, "info");
      sqlite3_bind_int64(st, 10, std::int64_t(info_crc(kFormatVersion, info)));
      d.step_write(st, "info");
    }
    d.exec("COMMIT", "cannot create the schema");
    d.info = info;
    d.format_version = kFormatVersion;
    return BlockDatabase(std::move(impl));
  } catch (...) {
    remove_quietly(path);
    remove_quietly(path + "-wal");
    remove_quietly(path + "-shm");
    throw;
  }
}

BlockDatabase BlockDatabase::open(const std::string& path, Mode mode) {
  std::error_code ec;
  const fs::file_status s = fs::status(path, ec);
  if (!fs::exists(s)) throw DatabaseError(path, "no such file");
  if (fs::is_directory(s)) throw DatabaseError(path, "is a directory, not a database");
  auto impl = connect(path, mode);
  check_identity(*impl);
  if (mode == Mode::ReadWrite) {
    // Persistent in the file already; reasserted in case another tool changed it.
    OneOff st(*impl, "PRAGMA journal_mode = WAL", "cannot switch to WAL mode");
    if (sqlite3_step(st) != SQLITE_ROW) impl->check(sqlite3_errcode(impl->db), "cannot switch to WAL mode");
  }
  return BlockDatabase(std::move(impl));
}

const std::string& BlockDatabase::path() const { return impl_->path; }
const DatabaseInfo& BlockDatabase::info() const { return impl_->info; }
BlockDatabase::Mode BlockDatabase::mode() const { return impl_->mode; }
int BlockDatabase::format_version() const { return impl_->format_version; }

// --- blocks ----------------------------------------------------------------------------------

void BlockDatabase::put_block(BlockKey key, std::span<const std::uint8_t> blob) {
  assert(impl_);
  Impl& d = *impl_;
  d.require_writable();
  const std::string item = block_name(key);
  Use st(d.stmt(kPutBlock, item));
  d.check(sqlite3_bind_int(st, 1, key.col), item);
  d.check(sqlite3_bind_int(st, 2, key.row), item);
  d.bind_blob(st, 3, blob, item);
  d.step_write(st, item);
}

bool BlockDatabase::has_block(BlockKey key) const {
  assert(impl_);
  Impl& d = *impl_;
  const std::string item = block_name(key);
  Use st(d.stmt(kHasBlock, item));
  sqlite3_bind_int(st, 1, key.col);
  sqlite3_bind_int(st, 2, key.row);
  const int rc = sqlite3_step(st);
  if (rc != SQLITE_ROW && rc != SQLITE_DONE) d.check(rc, item + ": cannot be read");
  return rc == SQLITE_ROW;
}

std::vector<std::uint8_t> BlockDatabase::read_block(BlockKey key) const {
  assert(impl_);
  Impl& d = *impl_;
  const std::string item = block_name(key);
  Use st(d.stmt(kReadBlock, item));
  sqlite3_bind_int(st, 1, key.col);
  sqlite3_bind_int(st, 2, key.row);
  auto bytes = d.read_one(st, item);
  if (!bytes) d.fail(item + ": not in the database");
  return std::move(*bytes);
}

std::vector<BlockKey> BlockDatabase::blocks() const {
  assert(impl_);
  Impl& d = *impl_;
  Use st(d.stmt(kListBlocks, "cannot list the blocks"));
  std::vector<BlockKey> keys;
  for (int rc; (rc = sqlite3_step(st)) != SQLITE_DONE;) {
    if (rc != SQLITE_ROW) d.check(rc, "cannot list the blocks");
    const std::int64_t c = d.integer(st, 0, "blocks"), r = d.integer(st, 1, "blocks");
    if (c < INT_MIN || c > INT_MAX || r < INT_MIN || r > INT_MAX)
      d.fail("blocks: corrupt record (index out of range)");
    keys.push_back({int(c), int(r)});
  }
  return keys;
}

// --- named blobs -----------------------------------------------------------------------------

void BlockDatabase::put_blob(const std::string& name, std::span<const std::uint8_t> blob) {
  assert(impl_);
  Impl& d = *impl_;
  d.require_writable();
  const std::string item = blob_item(name);
  Use st(d.stmt(kPutBlob, item));
  d.bind_text(st, 1, name, item);
  d.bind_blob(st, 2, blob, item);
  d.step_write(st, item);
}

std::optional<std::vector<std::uint8_t>> BlockDatabase::read_blob(const std::string& name) const {
  assert(impl_);
  Impl& d = *impl_;
  const std::string item = blob_item(name);
  Use st(d.stmt(kReadBlob, item));
  d.bind_text(st, 1, name, item);
  return d.read_one(st, item);
}

void BlockDatabase::put_georeference(const Georeference& g) {
  Writer w;
  w.b = encode_transform(g.crs_transform);
  w.str(g.vertical_datum);
  put_blob("georeference", w.b);
}

std::optional<Georeference> BlockDatabase::georeference() const {
  const std::optional<std::vector<std::uint8_t>> b = read_blob("georeference");
  if (!b) return std::nullopt;
  auto bad = [&] { return DatabaseError(path(), "blob 'georeference' is malformed"); };
  if (b->size() < 56) throw bad();
  Georeference g;
  g.crs_transform = decode_transform(b->data());
  if (!transform_is_finite(g.crs_transform)) throw bad();
  std::uint64_t n = 0;
  for (int i = 0; i < 8; ++i) n |= std::uint64_t((*b)[48 + std::size_t(i)]) << (8 * i);
  if (n != b->size() - 56) throw bad();
  g.vertical_datum.assign(b->begin() + 56, b->end());
  return g;
}

std::vector<std::string> BlockDatabase::blob_names() const {
  assert(impl_);
  Impl& d = *impl_;
  Use st(d.stmt(kListBlobs, "cannot list the blobs"));
  std::vector<std::string> names;
  for (int rc; (rc = sqlite3_step(st)) != SQLITE_DONE;) {
    if (rc != SQLITE_ROW) d.check(rc, "cannot list the blobs");
    names.push_back(d.text(st, 0, "blobs"));
  }
  return names;
}

// --- texture tiles ---------------------------------------------------------------------------

void BlockDatabase::put_texture_tile(const std::string& layer, std::int64_t node, int level,
                                     std::span<const std::uint8_t> blob) {
  assert(impl_);
  Impl& d = *impl_;
  d.require_writable();
  const std::string item = tile_name(layer, node, level);
  Use st(d.stmt(kPutTile, item));
  d.bind_text(st, 1, layer, item);
  d.check(sqlite3_bind_int64(st, 2, node), item);
  d.check(sqlite3_bind_int(st, 3, level), item);
  d.bind_blob(st, 4, blob, item);
  d.step_write(st, item);
}

std::optional<std::vector<std::uint8_t>> BlockDatabase::read_texture_tile(const std::string& layer,
                                                                          std::int64_t node,
                                                                          int level) const {
  assert(impl_);
  Impl& d = *impl_;
  const std::string item = tile_name(layer, node, level);
  Use st(d.stmt(kReadTile, item));
  d.bind_text(st, 1, layer, item);
  sqlite3_bind_int64(st, 2, node);
  sqlite3_bind_int(st, 3, level);
  return d.read_one(st, item);
}

std::vector<std::string> BlockDatabase::texture_layers() const {
  assert(impl_);
  Impl& d = *impl_;
  Use st(d.stmt(kListLayers, "cannot list the texture layers"));
  std::vector<std::string> layers;
  for (int rc; (rc = sqlite3_step(st)) != SQLITE_DONE;) {
    if (rc != SQLITE_ROW) d.check(rc, "cannot list the texture layers");
    layers.push_back(d.text(st, 0, "texture_tiles"));
  }
  return layers;
}

std::vector<TextureTileKey> BlockDatabase::texture_tiles(const std::string& layer) const {
  assert(impl_);
  Impl& d = *impl_;
  const std::string what = "texture layer '" + layer + "'";
  Use st(d.stmt(kListTiles, what));
  d.bind_text(st, 1, layer, what);
  std::vector<TextureTileKey> tiles;
  for (int rc; (rc = sqlite3_step(st)) != SQLITE_DONE;) {
    if (rc != SQLITE_ROW) d.check(rc, what + ": cannot list the tiles");
    const std::int64_t level = d.integer(st, 1, what);
    if (level < INT_MIN || level > INT_MAX) d.fail(what + ": corrupt record (level out of range)");
    tiles.push_back({d.integer(st, 0, what), int(level)});
  }
  return tiles;
}

// --- meta ------------------------------------------------------------------------------------

void BlockDatabase::set_meta(const std::string& key, const std::string& value) {
  assert(impl_);
  Impl& d = *impl_;
  d.require_writable();
  const std::string item = "meta '" + key + "'";
  Use st(d.stmt(kSetMeta, item));
  d.bind_text(st, 1, key, item);
  d.bind_text(st, 2, value, item);
  d.step_write(st, item);
}

std::optional<std::string> BlockDatabase::get_meta(const std::string& key) const {
  assert(impl_);
  Impl& d = *impl_;
  const std::string item = "meta '" + key + "'";
  Use st(d.stmt(kGetMeta, item));
  d.bind_text(st, 1, key, item);
  const int rc = sqlite3_step(st);
  if (rc == SQLITE_DONE) return std::nullopt;
  if (rc != SQLITE_ROW) d.check(rc, item + ": cannot be read");
  return d.text(st, 0, item);
}

std::vector<std::string> BlockDatabase::meta_keys() const {
  assert(impl_);
  Impl& d = *impl_;
  Use st(d.stmt(kListMeta, "cannot list the meta keys"));
  std::vector<std::string> keys;
  for (int rc; (rc = sqlite3_step(st)) != SQLITE_DONE;) {
    if (rc != SQLITE_ROW) d.check(rc, "cannot list the meta keys");
    keys.push_back(d.text(st, 0, "meta"));
  }
  return keys;
}

// --- integrity -------------------------------------------------------------------------------

BlockDatabase::IntegrityReport BlockDatabase::check_integrity() const {
  assert(impl_);
  Impl& d = *impl_;
  IntegrityReport report;
  const auto problem = [&](const std::string& p) { report.problems.push_back(d.path + ": " + p); };

  // SQLite's own structural check (b-trees, free list, indexes, NOT NULL), at most 100 messages.
  try {
    OneOff st(d, "PRAGMA integrity_check(100)", "integrity_check");
    for (int rc; (rc = sqlite3_step(st)) != SQLITE_DONE;) {
      if (rc != SQLITE_ROW) d.check(rc, "integrity_check failed");
      const auto* msg = reinterpret_cast<const char*>(sqlite3_column_text(st, 0));
      const std::string m = msg ? msg : "(null)";
      if (m != "ok") problem("sqlite integrity_check: " + m);
    }
  } catch (const DatabaseError& e) {
    report.problems.push_back(e.what());
  }

  // Every blob: size and checksum. Each table is one read transaction, streamed row by row.
  struct Scan {
    const char* sql;
    int first_blob_column;
    std::string (*name)(sqlite3_stmt*);
  };
  const Scan scans[] = {
      {"SELECT col, row, size, crc32, data FROM blocks ORDER BY col, row", 2,
       [](sqlite3_stmt* s) {
         return block_name({sqlite3_column_int(s, 0), sqlite3_column_int(s, 1)});
       }},
      {"SELECT name, size, crc32, data FROM blobs ORDER BY name", 1,
       [](sqlite3_stmt* s) {
         const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(s, 0));
         return blob_item(p ? p : "");
       }},
      {"SELECT layer, node, level, size, crc32, data FROM texture_tiles ORDER BY layer, node, level", 3,
       [](sqlite3_stmt* s) {
         const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(s, 0));
         return tile_name(p ? p : "", sqlite3_column_int64(s, 1), sqlite3_column_int(s, 2));
       }},
  };
  for (const Scan& scan : scans) {
    try {
      OneOff st(d, scan.sql, "cannot scan the blobs");
      for (int rc; (rc = sqlite3_step(st)) != SQLITE_DONE;) {
        if (rc != SQLITE_ROW) d.check(rc, "scan stopped");
        ++report.items_checked;
        const std::string p = d.verify(st, scan.first_blob_column, nullptr);
        if (!p.empty()) problem(scan.name(st) + ": " + p);
      }
    } catch (const DatabaseError& e) {
      report.problems.push_back(e.what());
    }
  }
  // The info row (re-read: its checksum covers every field).
  try {
    DatabaseInfo now;
    int version = 0;
    read_info(d, now, version);
    if (!(now == d.info) || version != d.format_version)
      problem("info: changed since the database was opened");
  } catch (const DatabaseError& e) {
    report.problems.push_back(e.what());
  }
  report.ok = report.problems.empty();
  return report;
}

// --- transactions ----------------------------------------------------------------------------

BlockDatabase::Transaction::Transaction(BlockDatabase& db) : db_(&db) {
  assert(db.impl_ && "Transaction on a moved-from BlockDatabase");
  Impl& d = *db.impl_;
  d.require_writable();
  assert(!d.in_transaction && "BlockDatabase::Transaction: transactions do not nest");
  Use st(d.stmt(kBegin, "cannot begin a transaction"));
  const int rc = sqlite3_step(st);
  if (rc != SQLITE_DONE) d.check(rc, "cannot begin a transaction");
  d.in_transaction = true;
}

BlockDatabase::Transaction::~Transaction() {
  if (done_ || !db_->impl_) return;
  Impl& d = *db_->impl_;
  {
    Use st(d.stmt(kRollback, "rollback"));
    (void)sqlite3_step(st);  // nothing sensible to do on failure in a destructor
  }
  d.in_transaction = false;
}

void BlockDatabase::Transaction::commit() {
  assert(!done_ && "Transaction committed twice");
  Impl& d = *db_->impl_;
  int rc;
  {
    Use st(d.stmt(kCommit, "cannot commit"));
    rc = sqlite3_step(st);
  }
  if (rc != SQLITE_DONE) {
    const std::string msg = sqlite3_errmsg(d.db);
    // Stays not-done: the destructor rolls back.
    d.fail("cannot commit the transaction (" + msg + ")");
  }
  done_ = true;
  d.in_transaction = false;
}

}  // namespace terralod::blocks
