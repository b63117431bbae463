// The block database's file: its schema (format version 1), identifying a file as a terralod
// database on open(), reading the info row, and create() and open() themselves. The on-disk
// format (tables and columns) is documented in terralod/blocks/block_database.hpp.
//
// Hostile files (fuzzing, issue 9): open() only accepts a file whose five tables are real
// tables (not views that could run arbitrary queries) with the expected columns (the
// connection's own defences are in block_database_connection.cpp).
#include "block_database_schema.hpp"

#include <fcntl.h>
#include <sqlite3.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cassert>
#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <system_error>
#include <utility>

#include "block_database_connection.hpp"
#include "block_database_encoding.hpp"
#include "terralod/blocks/block_database.hpp"

namespace terralod::blocks {

namespace {

namespace fs = std::filesystem;
using detail::BlockDatabaseImpl;
using detail::connect;
using detail::encode_transform;
using detail::info_crc;
using detail::OneOff;
using detail::read_info;
using detail::transform_is_finite;

constexpr std::int64_t kApplicationId = 0x544C4F44;  // "TLOD"

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

// The object-layer tables (terralod/blocks/object_layers.hpp documents them), created together by
// the first object layer; older databases and older terralods simply have none.
constexpr const char* kObjectSchema = R"sql(
CREATE TABLE IF NOT EXISTS object_layers (
  name TEXT NOT NULL PRIMARY KEY,
  kind TEXT NOT NULL, geometry TEXT NOT NULL, source TEXT NOT NULL, crs_wkt TEXT NOT NULL,
  feature_count INTEGER NOT NULL, skipped INTEGER NOT NULL,
  label_field TEXT NOT NULL, height_field TEXT NOT NULL, rules TEXT
);
CREATE TABLE IF NOT EXISTS object_features (
  layer TEXT NOT NULL, id INTEGER NOT NULL, source_fid INTEGER NOT NULL, part INTEGER NOT NULL,
  min_x REAL NOT NULL, min_y REAL NOT NULL, max_x REAL NOT NULL, max_y REAL NOT NULL,
  size INTEGER NOT NULL, crc32 INTEGER NOT NULL, data BLOB NOT NULL,
  PRIMARY KEY (layer, id)
);
CREATE TABLE IF NOT EXISTS object_blocks (
  layer TEXT NOT NULL, col INTEGER NOT NULL, row INTEGER NOT NULL, feature INTEGER NOT NULL,
  PRIMARY KEY (layer, col, row, feature)
) WITHOUT ROWID;
)sql";

constexpr std::array<std::pair<const char*, const char*>, 3> kObjectTables = {{
    {"object_layers",
     "SELECT name, kind, geometry, source, crs_wkt, feature_count, skipped, label_field, height_field, rules "
     "FROM object_layers"},
    {"object_features",
     "SELECT layer, id, source_fid, part, min_x, min_y, max_x, max_y, size, crc32, data FROM "
     "object_features"},
    {"object_blocks", "SELECT layer, col, row, feature FROM object_blocks"},
}};

// Whether `name` exists in the schema; a view or index of that name is a schema mismatch (a
// view could run any query on every read).
bool table_present(BlockDatabaseImpl& d, const char* name) {
  OneOff st(d, "SELECT type FROM sqlite_schema WHERE name = ?1", "cannot read the schema");
  sqlite3_bind_text(st, 1, name, -1, SQLITE_STATIC);
  const int rc = sqlite3_step(st);
  if (rc != SQLITE_ROW && rc != SQLITE_DONE) d.check(rc, "cannot read the schema");
  if (rc == SQLITE_DONE) return false;
  const auto* type = reinterpret_cast<const char*>(sqlite3_column_text(st, 0));
  if (!type || std::strcmp(type, "table") != 0)
    d.fail(std::string("schema mismatch: '") + name + "' is not a table");
  return true;
}

// The columns the code reads exist: `sql` (a SELECT of them) prepares.
void check_columns(BlockDatabaseImpl& d, const char* name, const char* sql) {
  sqlite3_stmt* s = nullptr;
  if (sqlite3_prepare_v2(d.db, sql, -1, &s, nullptr) != SQLITE_OK) {
    const std::string msg = sqlite3_errmsg(d.db);
    sqlite3_finalize(s);
    d.fail(std::string("schema mismatch in table '") + name + "' (" + msg + ")");
  }
  sqlite3_finalize(s);
}

}  // namespace

bool detail::object_tables_exist(BlockDatabaseImpl& d) {
  int present = 0;
  for (const auto& [name, sql] : kObjectTables) present += table_present(d, name);
  if (present == 0) return false;
  if (present != int(kObjectTables.size()))
    d.fail("schema mismatch: some of the object-layer tables are missing");
  for (const auto& [name, sql] : kObjectTables) check_columns(d, name, sql);
  return true;
}

void detail::create_object_tables(BlockDatabaseImpl& d) {
  assert(d.in_transaction);
  if (!object_tables_exist(d)) d.exec(kObjectSchema, "cannot create the object-layer tables");
}

void detail::read_info(BlockDatabaseImpl& d, DatabaseInfo& info, int& format_version) {
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

namespace {

/// What a file's header says about it: its application id, and whether it is what a killed
/// create() leaves (block_database.hpp). Throws DatabaseError when the header cannot be read for
/// another reason (not SQLite, I/O error).
struct Identity {
  std::int64_t app_id = 0;
  bool interrupted_create = false;
};

/// True when the rollback journal at `journal` restores a file of 0 pages: rolling it back
/// leaves nothing. create() switches its new, empty file to WAL mode through such a journal.
/// SQLite's journal header: 8 magic bytes, then big-endian 32-bit page count, nonce, and the
/// database's size in pages before the transaction (https://www.sqlite.org/fileformat.html).
bool journal_of_an_empty_file(const std::string& journal) {
  static constexpr unsigned char kMagic[8] = {0xd9, 0xd5, 0x05, 0xf9, 0x20, 0xa1, 0x63, 0xd7};
  unsigned char h[20] = {};
  std::ifstream f(journal, std::ios::binary);
  if (!f.read(reinterpret_cast<char*>(h), sizeof h)) return false;
  return std::equal(std::begin(kMagic), std::end(kMagic), h) && h[16] == 0 && h[17] == 0 && h[18] == 0 &&
         h[19] == 0;
}

Identity read_identity(BlockDatabaseImpl& d) {
  Identity id;
  {
    OneOff st(d, "PRAGMA application_id", "not a terralod database");
    const int rc = sqlite3_step(st);
    if (rc != SQLITE_ROW) {
      const int ext = sqlite3_extended_errcode(d.db);
      if ((ext & 0xff) == SQLITE_NOTADB) d.fail("not a SQLite database (not a terralod database)");
      // A terralod database is in WAL mode from its first commit on and never has a hot rollback
      // journal, except when create() was killed while switching the new file to WAL mode (a
      // ReadOnly connection cannot roll it back; a ReadWrite one would, leaving an empty file).
      if (ext == SQLITE_READONLY_ROLLBACK) {
        id.interrupted_create = journal_of_an_empty_file(d.path + "-journal");
        if (!id.interrupted_create) d.fail("has a hot rollback journal (not a terralod database)");
        return id;
      }
      d.check(rc, "cannot read the database header");
    }
    id.app_id = sqlite3_column_int64(st, 0);
  }
  {
    OneOff st(d, "SELECT count(*) FROM sqlite_schema", "cannot read the schema");
    const int rc = sqlite3_step(st);
    if (rc != SQLITE_ROW) d.check(rc, "cannot read the schema");
    // Before create()'s one commit the file has neither an identity nor a table.
    id.interrupted_create = id.app_id == 0 && sqlite3_column_int64(st, 0) == 0;
  }
  return id;
}

/// Identifies the file as a terralod database of a readable version with the expected schema.
void check_identity(BlockDatabaseImpl& d) {
  const Identity id = read_identity(d);
  if (id.interrupted_create) d.fail("not a terralod database (interrupted create?)");
  if (id.app_id != kApplicationId) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "application_id 0x%08llx", static_cast<unsigned long long>(id.app_id));
    d.fail(std::string("not a terralod database (") +
           (id.app_id == 0 ? "an SQLite file of another kind" : buf) + ")");
  }
  // Tables must be real tables: a view could run any query on every read.
  for (const auto& [name, sql] : kTables)
    if (!table_present(d, name)) d.fail(std::string("schema mismatch: no table '") + name + "'");
  for (const auto& [name, sql] : kTables) check_columns(d, name, sql);
  read_info(d, d.info, d.format_version);
}

void remove_quietly(const std::string& p) {
  std::error_code ec;
  fs::remove(p, ec);
}

}  // namespace

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

bool BlockDatabase::is_interrupted_create(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return false;
  try {
    // ReadOnly: a ReadWrite connection would roll a hot journal back, changing the file.
    auto impl = connect(path, Mode::ReadOnly);
    return read_identity(*impl).interrupted_create;
  } catch (const DatabaseError&) {
    return false;  // not an SQLite file, or unreadable: open() says which
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

void BlockDatabase::set_cache_limit(std::size_t bytes) {
  assert(impl_);
  impl_->exec(("PRAGMA cache_size = -" + std::to_string(std::max<std::size_t>(1, bytes >> 10))).c_str(),
              "cannot set the cache size");
}

std::size_t BlockDatabase::memory_bytes() const {
  assert(impl_);
  Impl& d = *impl_;
  // cache_size: pages when positive, KiB when negative.
  OneOff cache(d, "PRAGMA cache_size", "cache_size");
  OneOff page(d, "PRAGMA page_size", "page_size");
  const std::int64_t n = sqlite3_step(cache) == SQLITE_ROW ? sqlite3_column_int64(cache, 0) : -2000;
  const std::int64_t page_bytes = sqlite3_step(page) == SQLITE_ROW ? sqlite3_column_int64(page, 0) : 4096;
  const std::int64_t cache_bytes = n < 0 ? -n * 1024 : n * page_bytes;
  return std::size_t(cache_bytes) + (std::size_t(128) << 10);
}
const DatabaseInfo& BlockDatabase::info() const { return impl_->info; }
BlockDatabase::Mode BlockDatabase::mode() const { return impl_->mode; }
int BlockDatabase::format_version() const { return impl_->format_version; }

}  // namespace terralod::blocks
