// Windows of a block database's full-resolution terrain (database_terrain.hpp): blocks decoded
// to their heights only, kept in a small least-recently-used cache, pasted into the window.
#include "terralod/blocks/database_terrain.hpp"

#include <algorithm>
#include <limits>
#include <stdexcept>
#include <string>

#include "terralod/pm/parallel.hpp"
#include "terralod/pm/pm_io.hpp"

namespace terralod::blocks {
namespace {

std::string block_name(BlockKey k) {
  return "block (" + std::to_string(k.col) + "," + std::to_string(k.row) + ")";
}

// The grid's transform moved to sample (col, row), as block_heightfield moves it.
pm::GridTransform moved(pm::GridTransform t, int col, int row) {
  const auto [x0, y0] = t.to_world(col, row);
  t.x0 = x0, t.y0 = y0;
  return t;
}

// The rows and columns of blocks whose samples meet `r` (the lowest index of a shared border).
void blocks_over(const BlockLayout& l, const SampleRect& r, int& c0, int& r0, int& c1, int& r1) {
  const int step = l.block_size - 1;
  const auto first = [step](int s, int n) { return s == 0 ? 0 : std::min((s - 1) / step, n - 1); };
  c0 = first(r.col0, l.blocks_x), c1 = first(r.col1, l.blocks_x);
  r0 = first(r.row0, l.blocks_y), r1 = first(r.row1, l.blocks_y);
}

// Copies the samples of block `b` (covering `br` of the grid) that lie in window `w` into `out`
// (w's samples, row by row). A hole is marked 0 in `mask` when one is given (allocated all valid
// at the first hole), else written as NaN.
void paste(const pm::Heightfield& b, const SampleRect& br, const SampleRect& w, double* out,
           std::vector<std::uint8_t>* mask) {
  const int x0 = std::max(br.col0, w.col0), x1 = std::min(br.col1, w.col1);
  const int y0 = std::max(br.row0, w.row0), y1 = std::min(br.row1, w.row1);
  for (int y = y0; y <= y1; ++y) {
    const double* src = &b.samples()[std::size_t(y - br.row0) * b.width() + std::size_t(x0 - br.col0)];
    const std::size_t row = std::size_t(y - w.row0) * std::size_t(w.width());
    std::copy(src, src + (x1 - x0 + 1), out + row + std::size_t(x0 - w.col0));
    if (!b.has_holes()) continue;
    for (int x = x0; x <= x1; ++x) {
      if (b.valid(x - br.col0, y - br.row0)) continue;
      const std::size_t i = row + std::size_t(x - w.col0);
      if (!mask) {
        out[i] = std::numeric_limits<double>::quiet_NaN();
        continue;
      }
      if (mask->empty()) mask->assign(w.samples(), 1);
      (*mask)[i] = 0;
    }
  }
}

void check_block_grid(const BlockDatabase& db, BlockKey k, const pm::Heightfield& b, const SampleRect& r) {
  if (b.width() != r.width() || b.height() != r.height())
    throw DatabaseError(db.path(), block_name(k) + ": its grid does not match the block layout");
}

// The whole grid's heightfield without samples: what every window carries besides its samples.
pm::Heightfield grid_frame(const BlockDatabase& db) {
  const DatabaseInfo& info = db.info();
  if (info.block_size <= 0)
    throw DatabaseError(db.path(), "not a blocked database (kind '" + info.kind + "'): no terrain samples");
  pm::Heightfield f;
  f.transform = info.transform;
  f.crs_wkt = info.crs_wkt;
  f.source = info.source;
  if (const std::optional<Georeference> g = db.georeference()) {
    f.crs_transform = g->crs_transform;
    f.vertical_datum = g->vertical_datum;
  }
  return f;
}

// An empty heightfield of `r` carrying frame's metadata, moved to r's corner.
pm::Heightfield window_of(const pm::Heightfield& frame, const SampleRect& r) {
  pm::Heightfield w(r.width(), r.height());
  w.transform = moved(frame.transform, r.col0, r.row0);
  if (frame.crs_transform) w.crs_transform = moved(*frame.crs_transform, r.col0, r.row0);
  w.crs_wkt = frame.crs_wkt;
  w.source = frame.source;
  w.vertical_datum = frame.vertical_datum;
  return w;
}

std::size_t heightfield_bytes(const pm::Heightfield& h) { return h.size() * 8 + h.mask().size() + 256; }

}  // namespace

DatabaseTerrain::DatabaseTerrain(const BlockDatabase& db, const Options& options)
    : db_(&db), opt_(options), frame_(grid_frame(db)) {
  const DatabaseInfo& info = db.info();
  layout_ = partition(info.grid_width, info.grid_height, info.block_size);
}

void DatabaseTerrain::evict(const std::vector<BlockKey>& keep, std::size_t room) {
  while (bytes_ + room > opt_.cache_bytes) {
    auto oldest = cache_.end();
    for (auto it = cache_.begin(); it != cache_.end(); ++it)
      if (std::find(keep.begin(), keep.end(), it->first) == keep.end() &&
          (oldest == cache_.end() || it->second.used < oldest->second.used))
        oldest = it;
    if (oldest == cache_.end()) return;  // only the batch in use is left
    bytes_ -= heightfield_bytes(*oldest->second.hf);
    cache_.erase(oldest);
  }
}

std::vector<std::shared_ptr<const pm::Heightfield>> DatabaseTerrain::decode(
    std::span<const BlockKey> keys) const {
  // SQLite reads one at a time; the decoding, most of the time, on every core.
  std::vector<std::vector<std::uint8_t>> bytes;
  for (BlockKey k : keys) bytes.push_back(db_->read_block(k));
  std::vector<std::shared_ptr<const pm::Heightfield>> out(keys.size());
  pm::parallel_for(keys.size(), opt_.threads, [&](std::size_t i) {
    auto b = std::make_shared<const pm::Heightfield>(
        pm::decode_pm_heightfield(bytes[i], db_->path() + ": " + block_name(keys[i])));
    check_block_grid(*db_, keys[i], *b, layout_.rect(keys[i]));
    out[i] = std::move(b);
  });
  return out;
}

void DatabaseTerrain::fetch(const std::vector<BlockKey>& keys) {
  std::vector<BlockKey> missing;
  std::size_t room = 0;  // what the missing blocks will take, holes aside
  for (BlockKey k : keys)
    if (!cache_.count(k)) missing.push_back(k), room += layout_.rect(k).samples() * 8 + 256;
  evict(keys, room);  // the least recently used blocks go before the new ones come
  std::vector<std::shared_ptr<const pm::Heightfield>> decoded = decode(missing);
  for (std::size_t i = 0; i < missing.size(); ++i) {
    bytes_ += heightfield_bytes(*decoded[i]);
    cache_[missing[i]] = Entry{std::move(decoded[i]), 0};
  }
  for (BlockKey k : keys) cache_[k].used = ++clock_;
  peak_ = std::max(peak_, bytes_);
  evict(keys, 0);
}

void DatabaseTerrain::require_inside(const SampleRect& rect) const {
  if (rect.col0 < 0 || rect.row0 < 0 || rect.col1 >= width() || rect.row1 >= height() ||
      rect.col0 > rect.col1 || rect.row0 > rect.row1)
    throw std::invalid_argument(db_->path() + ": samples [" + std::to_string(rect.col0) + ".." +
                                std::to_string(rect.col1) + "] x [" + std::to_string(rect.row0) + ".." +
                                std::to_string(rect.row1) + "] are not inside the " +
                                std::to_string(width()) + " x " + std::to_string(height()) + " grid");
}

void DatabaseTerrain::paste_blocks(const SampleRect& rect, double* out, std::vector<std::uint8_t>* mask) {
  int c0, r0, c1, r1;
  blocks_over(layout_, rect, c0, r0, c1, r1);
  // Batches of a few blocks per thread: decoded together, pasted, then free to be evicted.
  const std::size_t batch = std::size_t(2 * pm::thread_count(opt_.threads));
  std::vector<BlockKey> keys;
  const auto flush = [&] {
    fetch(keys);
    for (BlockKey k : keys) paste(*cache_.at(k).hf, layout_.rect(k), rect, out, mask);
    keys.clear();
  };
  for (int r = r0; r <= r1; ++r)
    for (int c = c0; c <= c1; ++c) {
      keys.push_back({c, r});
      if (keys.size() == batch) flush();
    }
  if (!keys.empty()) flush();
}

pm::Heightfield DatabaseTerrain::read(const SampleRect& rect) {
  require_inside(rect);
  pm::Heightfield out = window_of(frame_, rect);
  std::vector<std::uint8_t> mask;
  paste_blocks(rect, out.samples().data(), &mask);
  if (!mask.empty()) out.set_mask(std::move(mask));
  return out;
}

void DatabaseTerrain::read(const SampleRect& rect, double* out) {
  require_inside(rect);
  paste_blocks(rect, out, nullptr);
}

std::optional<HeightRange> DatabaseTerrain::height_range(const std::function<void(double)>& progress) {
  if (range_) return *range_;
  const std::vector<BlockKey> keys = layout_.keys();
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  const std::size_t batch = std::size_t(4 * pm::thread_count(opt_.threads));
  for (std::size_t b0 = 0; b0 < keys.size(); b0 += batch) {
    const std::size_t n = std::min(batch, keys.size() - b0);
    const auto blocks = decode(std::span(keys).subspan(b0, n));
    std::vector<HeightRange> part(n, HeightRange{lo, hi});
    pm::parallel_for(n, opt_.threads, [&](std::size_t i) {
      const pm::Heightfield& b = *blocks[i];
      for (std::size_t s = 0; s < b.size(); ++s)
        if (b.valid(s)) part[i].lo = std::min(part[i].lo, b[s]), part[i].hi = std::max(part[i].hi, b[s]);
    });
    for (const HeightRange& p : part) lo = std::min(lo, p.lo), hi = std::max(hi, p.hi);
    if (progress) progress(double(b0 + n) / double(keys.size()));
  }
  range_ = lo <= hi ? std::optional<HeightRange>(HeightRange{lo, hi}) : std::nullopt;
  return *range_;
}

pm::Heightfield read_database_terrain(const BlockDatabase& db, std::vector<pm::ProgressiveMesh>* pms) {
  if (!pms) {
    // Each block is pasted once: none is kept beyond its batch (a cache would hold up to 8 more
    // bytes a sample until the read ends, more or less of them as the threads' timing goes).
    DatabaseTerrain t(db, {.cache_bytes = 0});
    return t.read({0, 0, t.width() - 1, t.height() - 1});
  }
  const pm::Heightfield frame = grid_frame(db);
  const DatabaseInfo& info = db.info();
  const BlockLayout layout = partition(info.grid_width, info.grid_height, info.block_size);
  const SampleRect all{0, 0, info.grid_width - 1, info.grid_height - 1};
  pm::Heightfield hf = window_of(frame, all);
  std::vector<std::uint8_t> mask;
  for (BlockKey k : layout.keys()) {
    pm::ProgressiveMesh p = pm::decode_pm(db.read_block(k), db.path() + ": " + block_name(k));
    check_block_grid(db, k, p.heightfield(), layout.rect(k));
    paste(p.heightfield(), layout.rect(k), all, hf.samples().data(), &mask);
    pms->push_back(std::move(p));
  }
  if (!mask.empty()) hf.set_mask(std::move(mask));
  return hf;
}

}  // namespace terralod::blocks
