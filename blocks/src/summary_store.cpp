// The runtime's block summaries, stand-ins read on demand (see summary_store.hpp).
#include "summary_store.hpp"

#include <sqlite3.h>

#include <algorithm>
#include <utility>

#include "block_database_connection.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/pm/byte_io.hpp"
#include "terralod/pm/memory_bytes.hpp"

namespace terralod::blocks::detail {

// The database connection and the summaries blob open on it. The handle keeps SQLite's cursor,
// with its cache of the blob's overflow pages (4 bytes a page), for the store's life.
class SummaryStore::Blob {
 public:
  Blob(BlockDatabase db, sqlite3_blob* handle, std::uint64_t size)
      : db_(std::move(db)), handle_(handle), size_(size) {}
  ~Blob() { sqlite3_blob_close(handle_); }
  Blob(const Blob&) = delete;
  Blob& operator=(const Blob&) = delete;

  std::uint64_t size() const { return size_; }
  void read(std::uint64_t offset, std::span<std::uint8_t> out, const std::string& what) const {
    BlockDatabaseImpl& d = ImplAccess::of(db_);
    d.check(sqlite3_blob_read(handle_, out.data(), int(out.size()), int(offset)), what + ": cannot be read");
  }
  // The connection's page cache limit plus the cursor's overflow-page list.
  std::size_t memory_bytes() const {
    return db_.memory_bytes() + 4 * std::size_t(size_ / 512 + 1);  // pages are >= 512 bytes
  }

 private:
  BlockDatabase db_;
  sqlite3_blob* handle_;
  std::uint64_t size_;
};

namespace {

// Pieces of the blob read at once while it is indexed.
constexpr std::size_t kPiece = std::size_t(1) << 20;
// A connection that reads one record at a time needs little more than the b-tree's inner pages
// (64 kB: a stand-in read takes 5 us at the median, 88 us at most, on a 4097² terrain's flight).
constexpr std::size_t kCacheLimit = std::size_t(64) << 10;

// The summary without its stand-in surface: fields only.
BlockSummary fields_of(const BlockSummary& s) {
  BlockSummary f;
  f.z00 = s.z00, f.z10 = s.z10, f.z01 = s.z01, f.z11 = s.z11;
  f.zmin = s.zmin, f.zmax = s.zmax, f.tm_error = s.tm_error;
  f.base_is_tm = s.base_is_tm;
  f.standin = s.standin;
  f.standin_error = s.standin_error;
  f.empty = s.empty;
  return f;
}

std::size_t surface_bytes(const BlockSummary& s) {
  return pm::capacity_bytes(s.points) + pm::capacity_bytes(s.triangles) +
         pm::capacity_bytes(s.triangle_errors);
}

}  // namespace

SummaryStore::SummaryStore(const std::string& db_path, const BlockGrid& grid) : path_(db_path), grid_(grid) {
  BlockDatabase db = BlockDatabase::open(db_path);
  db.set_cache_limit(kCacheLimit);
  BlockDatabaseImpl& d = ImplAccess::of(db);
  const std::string name = kBlockSummariesBlob, item = blob_item(name);
  std::int64_t rowid = 0, size = 0, crc = 0;
  {
    OneOff st(d, "SELECT rowid, size, crc32 FROM blobs WHERE name = ?1", item);
    d.bind_text(st, 1, name, item);
    const int rc = sqlite3_step(st);
    if (rc == SQLITE_DONE) {  // no summaries: no stand-ins
      fields_.assign(grid_.block_count(), BlockSummary{});
      return;
    }
    if (rc != SQLITE_ROW) d.check(rc, item + ": cannot be read");
    rowid = d.integer(st, 0, item), size = d.integer(st, 1, item), crc = d.integer(st, 2, item);
  }
  sqlite3_blob* handle = nullptr;
  d.check(sqlite3_blob_open(d.db, "main", "blobs", "data", rowid, 0, &handle), item + ": cannot be opened");
  if (sqlite3_blob_bytes(handle) != size) {
    const int n = sqlite3_blob_bytes(handle);
    sqlite3_blob_close(handle);
    d.fail(item + ": size mismatch (" + std::to_string(n) + " bytes stored, " + std::to_string(size) +
           " recorded)");
  }
  blob_ = std::make_unique<Blob>(std::move(db), handle, std::uint64_t(size));
  index_blob(std::uint32_t(crc));
  if (records_.empty()) blob_.reset();  // version 1: decoded whole, nothing left to read
}

SummaryStore::~SummaryStore() = default;

// Streams the blob once: checks the database's CRC of it and its own trailer, and finds every
// record, decoding each (the checks decode_block_summaries makes) to keep its fields.
void SummaryStore::index_blob(std::uint32_t blob_crc) {
  const std::string item = blob_item(kBlockSummariesBlob);
  const std::uint64_t size = blob_->size();
  const auto fail = [&](const std::string& what) {
    throw DatabaseError(path_, std::string(kBlockSummariesBlob) + ": " + what);
  };
  std::uint8_t head[kBlockSummariesHeader] = {};
  if (size >= kBlockSummariesHeader) blob_->read(0, head, item);
  const std::uint32_t version = check_block_summaries_header(grid_, head, size, path_);
  if (version == 1) {  // 64 bytes a block: decoded whole, and held
    std::vector<std::uint8_t> bytes(static_cast<std::size_t>(size));
    blob_->read(0, bytes, item);
    if (pm::crc32_of(bytes) != blob_crc) fail("checksum mismatch");
    fields_ = decode_block_summaries(grid_, bytes, path_);
    return;
  }
  const std::size_t blocks = grid_.block_count();  // the header check held the blob's size to it
  fields_.resize(blocks);
  records_.resize(blocks);
  std::vector<std::uint8_t> buf;  // blob bytes from `base` on, not yet taken
  buf.reserve(2 * kPiece);
  std::uint64_t base = 0, read = 0;
  std::uint32_t whole = 0, body = 0;  // CRC-32 of every byte, and of every byte before the trailer
  std::size_t pos = kBlockSummariesHeader, i = 0;
  const std::uint64_t records_end = size - 4;
  while (read < size) {
    const std::size_t n = std::size_t(std::min<std::uint64_t>(kPiece, size - read));
    const std::size_t at = buf.size();
    buf.resize(at + n);
    blob_->read(read, std::span<std::uint8_t>(buf.data() + at, n), item);
    whole = pm::crc32_of({buf.data() + at, n}, whole);
    const std::size_t in_body =
        std::size_t(std::min<std::uint64_t>(n, records_end > read ? records_end - read : 0));
    body = pm::crc32_of({buf.data() + at, in_body}, body);
    read += n;
    // The records now whole in buf.
    while (i < blocks && base + pos + kBlockSummaryRecordHeader <= std::min(read, records_end)) {
      const std::size_t bytes =
          block_summary_record_bytes(std::span<const std::uint8_t, kBlockSummaryRecordHeader>(
              buf.data() + pos, kBlockSummaryRecordHeader));
      if (bytes == 0) fail("block record " + std::to_string(i) + ": bad kind, flags or stand-in size");
      if (base + pos + bytes > records_end)
        fail("block record " + std::to_string(i) + ": truncated stand-in");
      if (base + pos + bytes > read) break;  // the rest comes with the next piece
      const std::span<const std::uint8_t> rec(buf.data() + pos, bytes);
      const BlockSummary b = decode_block_summary_record(grid_, i, rec, path_);
      fields_[i] = fields_of(b);
      // An empty block has nothing to read: its fields are the whole summary.
      if (!b.empty) records_[i] = {base + pos, std::uint32_t(bytes), pm::crc32_of(rec)};
      pos += bytes;
      ++i;
    }
    buf.erase(buf.begin(), buf.begin() + std::ptrdiff_t(pos));
    base += pos;
    pos = 0;
  }
  if (whole != blob_crc) fail("checksum mismatch");
  if (i < blocks || base + pos != records_end)
    fail("size " + std::to_string(size) + " bytes does not end after the last block record");
  if (pm::load_u32(buf.data() + buf.size() - 4) != body) fail("checksum mismatch");
}

bool SummaryStore::has_standin(std::size_t i) const {
  return !fields_[i].triangles.empty() || (!records_.empty() && records_[i].size > 0);
}

const BlockSummary& SummaryStore::summary(std::size_t i, std::uint64_t frame) {
  if (records_.empty() || records_[i].size == 0) return fields_[i];
  if (const auto it = held_.find(i); it != held_.end()) {
    it->second.last_used = frame;
    return it->second.summary;
  }
  const Record& r = records_[i];
  const std::string what = std::string(kBlockSummariesBlob) + ": block record " + std::to_string(i);
  std::vector<std::uint8_t> bytes(r.size);
  blob_->read(r.offset, bytes, what);
  if (pm::crc32_of(bytes) != r.crc) throw DatabaseError(path_, what + ": checksum mismatch");
  ++reads_;
  Held& h = held_[i];
  h.summary = decode_block_summary_record(grid_, i, bytes, path_);
  h.last_used = frame;
  return h.summary;
}

void SummaryStore::trim(std::uint64_t frame) {
  std::erase_if(held_, [&](const auto& kv) { return kv.second.last_used + kKeepFrames < frame; });
}

std::size_t SummaryStore::fixed_bytes() const {
  std::size_t n = pm::capacity_bytes(fields_) + pm::capacity_bytes(records_);
  for (const BlockSummary& s : fields_) n += surface_bytes(s);
  return n + (blob_ ? blob_->memory_bytes() : 0);
}

std::size_t SummaryStore::held_bytes() const {
  std::size_t n = pm::detail::hash_map_bytes(held_);
  for (const auto& [i, h] : held_) n += surface_bytes(h.summary);
  return n;
}

}  // namespace terralod::blocks::detail
