// The block database as a BlockSource of the loader (one read-only connection per loader
// thread), and the block summaries (with their stand-ins) read from, or computed over, a database.
#include "terralod/blocks/active_region.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/block_loader.hpp"
#include "terralod/pm/pm_io.hpp"

namespace terralod::blocks {

namespace {
class DatabaseSource final : public BlockSource {
 public:
  explicit DatabaseSource(const std::string& path)
      : db_(BlockDatabase::open(path, BlockDatabase::Mode::ReadOnly)) {
    // Each blob is read once: pages kept beyond the b-tree's inner ones would only take room
    // from the blocks in the runtime's budget (memory_bytes counts the limit).
    db_.set_cache_limit(std::size_t(256) << 10);
  }
  std::vector<std::uint8_t> read(BlockKey k) override { return db_.read_block(k); }
  std::string name() const override { return db_.path(); }
  std::size_t memory_bytes() const override { return db_.memory_bytes(); }

 private:
  BlockDatabase db_;
};
}  // namespace

BlockSourceFactory database_source(const std::string& path) {
  return [path]() -> std::unique_ptr<BlockSource> { return std::make_unique<DatabaseSource>(path); };
}

std::vector<BlockSummary> read_block_summaries(const BlockDatabase& db, const BlockGrid& grid,
                                               const std::function<void(double)>& progress,
                                               const StandinOptions& standin) {
  if (const auto blob = db.read_blob(kBlockSummariesBlob))
    return decode_block_summaries(grid, *blob, db.path());
  StandinOptions o = standin;
  std::vector<BlockSummary> out(grid.block_count());
  for (std::size_t i = 0; i < out.size(); ++i) {
    const BlockKey k = grid.key(i);
    const std::vector<std::uint8_t> blob = db.read_block(k);
    const pm::ProgressiveMesh pm = pm::decode_pm(
        blob, db.path() + ": block (" + std::to_string(k.col) + "," + std::to_string(k.row) + ")");
    const SampleRect d = grid.domain(k);
    if (pm.heightfield().width() != d.width() || pm.heightfield().height() != d.height())
      throw DatabaseError(db.path(), "block (" + std::to_string(k.col) + "," + std::to_string(k.row) +
                                         "): size does not match the block grid");
    // Each block's errors are measured with the metric its PM was built with (stored in the
    // PM itself, not searched for in the build parameters' JSON).
    o.metric = pm.metric();
    try {
      out[i] = summarize_block(pm, k, o);
    } catch (const std::invalid_argument& e) {
      throw DatabaseError(db.path(), e.what());
    }
    if (progress) progress(double(i + 1) / double(out.size()));
  }
  return out;
}

}  // namespace terralod::blocks
