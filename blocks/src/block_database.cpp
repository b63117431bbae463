// Block database on SQLite: reading and writing its items (blocks, named blobs, texture tiles,
// meta) and write transactions. The file itself (schema, create, open) is
// block_database_schema.cpp, the connection (statements, verified reads, checked bindings)
// block_database_connection.cpp, the byte encodings and checksums block_database_encoding.cpp,
// check_integrity() block_database_integrity.cpp; the on-disk format is documented in
// terralod/blocks/block_database.hpp.
//
// Memory: reads allocate the blob once.
#include "terralod/blocks/block_database.hpp"

#include <sqlite3.h>

#include <algorithm>
#include <cassert>
#include <climits>
#include <memory>
#include <utility>

#include "block_database_connection.hpp"
#include "block_database_encoding.hpp"
#include "terralod/pm/byte_io.hpp"

namespace terralod::blocks {

namespace {

using detail::blob_item;
using detail::block_name;
using detail::tile_name;
using detail::Use;
using enum detail::Stmt;

}  // namespace

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

void BlockDatabase::remove_blob(const std::string& name) {
  assert(impl_);
  Impl& d = *impl_;
  d.require_writable();
  const std::string item = blob_item(name);
  Use st(d.stmt(kRemoveBlob, item));
  d.bind_text(st, 1, name, item);
  d.step_write(st, item);
}

void BlockDatabase::put_blob_in_pieces(const std::string& name, std::uint64_t size, std::uint32_t crc32,
                                       const std::function<void(const BlobPieceWriter&)>& fill) {
  assert(impl_);
  Impl& d = *impl_;
  d.require_writable();
  const std::string item = blob_item(name);
  if (size > std::uint64_t(sqlite3_limit(d.db, SQLITE_LIMIT_LENGTH, -1)))
    d.fail(item + ": " + std::to_string(size) + " bytes is more than SQLite stores in one blob");
  {
    Use st(d.stmt(kPutZeroBlob, item));
    d.bind_text(st, 1, name, item);
    d.check(sqlite3_bind_int64(st, 2, std::int64_t(size)), item);
    d.check(sqlite3_bind_int64(st, 3, std::int64_t(crc32)), item);
    d.step_write(st, item);
  }
  sqlite3_blob* b = nullptr;
  d.check(sqlite3_blob_open(d.db, "main", "blobs", "data", sqlite3_last_insert_rowid(d.db), 1, &b),
          item + ": cannot be opened for writing");
  const std::unique_ptr<sqlite3_blob, int (*)(sqlite3_blob*)> close(b, sqlite3_blob_close);
  // Pieces are gathered into writes of 1 MiB: each sqlite3_blob_write finds its offset along
  // the blob's chain of overflow pages, so a write per small piece costs quadratic time.
  constexpr std::size_t kWrite = 1 << 20;
  std::vector<std::uint8_t> buf;
  buf.reserve(std::size_t(std::min<std::uint64_t>(size, kWrite)));
  std::uint64_t at = 0, written = 0;
  std::uint32_t crc = 0;
  auto flush = [&] {
    d.check(sqlite3_blob_write(b, buf.data(), int(buf.size()), int(written)), item + ": cannot be written");
    written += buf.size();
    buf.clear();
  };
  fill([&](std::span<const std::uint8_t> piece) {
    if (piece.size() > size - at)
      d.fail(item + ": more than the " + std::to_string(size) + " bytes announced");
    crc = pm::crc32_of(piece, crc);
    at += piece.size();
    while (!piece.empty()) {
      const std::size_t n = std::min(piece.size(), kWrite - buf.size());
      buf.insert(buf.end(), piece.begin(), piece.begin() + std::ptrdiff_t(n));
      piece = piece.subspan(n);
      if (buf.size() == kWrite) flush();
    }
  });
  if (!buf.empty()) flush();
  if (at != size)
    d.fail(item + ": " + std::to_string(at) + " bytes given, " + std::to_string(size) + " announced");
  if (crc != crc32) d.fail(item + ": the pieces given do not have the CRC-32 announced");
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
  put_blob("georeference", detail::encode_georeference(g));
}

std::optional<Georeference> BlockDatabase::georeference() const {
  const std::optional<std::vector<std::uint8_t>> b = read_blob("georeference");
  if (!b) return std::nullopt;
  return detail::decode_georeference(*b, path());
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
