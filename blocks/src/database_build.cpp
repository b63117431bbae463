// The block-database build (tree_builder.hpp: build_database, summarize_database): partition,
// per-block PMs on local threads and remote builders, crash-consistent resumable writes, then the
// approximation tree above the blocks (build_tree) and the stand-ins, written last.

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <exception>
#include <filesystem>
#include <limits>
#include <mutex>
#include <sstream>
#include <thread>

#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/byte_io.hpp"
#include "terralod/pm/json.hpp"
#include "terralod/pm/parallel.hpp"
#include "terralod/pm/pm_io.hpp"

namespace terralod::blocks {

using pm::parallel_for;

// ---------------------------------------------------------------------------------------------
// Database build

namespace {

constexpr const char* kFrameMeta = "frame";
constexpr const char* kFrameScaleErrorMeta = "frame_scale_error";

const char* metric_name(pm::ErrorMetric m) {
  return m == pm::ErrorMetric::Samples ? "samples" : "continuous";
}

std::string build_parameters_json(const DemSource& src, const DatabaseBuildOptions& o) {
  std::string levels;
  for (StrategyChoice c : o.tree.levels)
    levels += std::string(levels.empty() ? "" : ",") + strategy_choice_name(c);
  char buf[512];
  std::snprintf(
      buf, sizeof buf,
      "{\"block_size\": %d, \"metric\": \"%s\", \"strategy\": \"%s\", \"patch\": %d, \"max_points\": %zu, "
      "\"grid\": [%d, %d], \"samples_crc32\": %" PRIu32 ", \"pm_builder\": %d}",
      o.block_size, metric_name(o.metric), levels.c_str(), o.tree.patch, o.tree.max_points, src.grid().width,
      src.grid().height, src.samples_crc(), pm::ProgressiveMesh::kBuilderRevision);
  return buf;
}

std::string block_meta_key(BlockKey k) {
  return "block/" + std::to_string(k.col) + "," + std::to_string(k.row);
}

// A block's record of the block_summaries blob, stored as the block is written (in its
// transaction) and joined into the blob when the build completes, which removes them: the build
// holds no per-block summary in memory, and a resumed build does not summarize again.
std::string summary_blob_name(BlockKey k) {
  return "block_summary/" + std::to_string(k.col) + "," + std::to_string(k.row);
}

// The stand-in every block gets: opt.standin, measured in the build's metric.
StandinOptions standin_options(const DatabaseBuildOptions& opt) {
  StandinOptions s = opt.standin;
  s.metric = opt.metric;
  return s;
}

struct BlockRecord {
  double error = 0;
  std::uint64_t vertices = 0, bytes = 0;
};

std::optional<BlockRecord> read_block_record(const BlockDatabase& db, BlockKey k) {
  const auto v = db.get_meta(block_meta_key(k));
  if (!v) return std::nullopt;
  BlockRecord r;
  std::istringstream in(*v);
  in.imbue(std::locale::classic());
  if (!(in >> r.error >> r.vertices >> r.bytes))
    throw DatabaseError(db.path(), "block (" + std::to_string(k.col) + "," + std::to_string(k.row) +
                                       "): malformed build record '" + *v + "'");
  return r;
}

std::string format_record(const BlockRecord& r) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%.17g %" PRIu64 " %" PRIu64, r.error, r.vertices, r.bytes);
  return buf;
}

}  // namespace

std::string DatabaseSummary::to_json() const {
  std::string j = "{\n";
  const auto quote = [](const std::string& s) { return pm::json_quote(s); };
  auto num = [](double v) {
    if (!std::isfinite(v)) return std::string("null");
    char b[40];
    std::snprintf(b, sizeof b, "%.17g", v);
    return std::string(b);
  };
  auto field = [&](const std::string& k, const std::string& v, bool last = false) {
    j += "  " + quote(k) + ": " + v + (last ? "\n" : ",\n");
  };
  field("file", quote(path));
  field("kind", quote("blocks"));
  field("source", quote(source));
  field("complete", complete ? "true" : "false");
  field("grid",
        "{\"width\": " + std::to_string(grid_width) + ", \"height\": " + std::to_string(grid_height) + "}");
  field("block_size", std::to_string(block_size));
  field("blocks_grid", "{\"x\": " + std::to_string(blocks_x) + ", \"y\": " + std::to_string(blocks_y) + "}");
  field("blocks", std::to_string(blocks));
  if (blocks_built) field("blocks_built", std::to_string(*blocks_built));
  std::string per = "{";
  for (int s = 0; s < kStrategyCount; ++s)
    per += std::string(s ? ", " : "") + quote(strategy_name(Strategy(s))) + ": " +
           std::to_string(nodes_per_strategy[std::size_t(s)]);
  field("nodes", std::to_string(nodes));
  field("nodes_per_strategy", per + "}");
  field("tree_depth", std::to_string(tree_depth));
  field("samples", std::to_string(samples));
  field("pm_vertices", std::to_string(pm_vertices));
  field("block_bytes", std::to_string(block_bytes));
  field("tree_bytes", std::to_string(tree_bytes));
  field("summaries_bytes", std::to_string(summaries_bytes));
  field("standin", quote(standin));
  field("mean_standin_error", num(mean_standin_error));
  field("mean_tm_error", num(mean_tm_error));
  field("bytes_per_vertex", num(bytes_per_vertex));
  field("max_block_error", num(max_block_error));
  field("root_error", num(root_error));
  field("seconds", num(seconds));
  if (georeference) {
    const pm::GridTransform& t = georeference->crs_transform;
    field(
        "georeference",
        "{\"crs_transform\": [" + num(t.x0) + ", " + num(t.xc) + ", " + num(t.xr) + ", " + num(t.y0) + ", " +
            num(t.yc) + ", " + num(t.yr) + "], \"vertical_datum\": " +
            quote(georeference->vertical_datum.empty() ? "unknown (exporters assume EGM96)"
                                                       : georeference->vertical_datum) +
            ", \"frame\": " +
            quote(
                "sample (col,row) -> CRS coordinates of the source: X = crs_transform[0] + col * [1] + row * "
                "[2], Y = [3] + col * [4] + row * [5] (degrees for a geographic CRS); the runtime's world "
                "frame is the metric map of the build (the 'frame' member describes it), and its view "
                "stretches world offsets about the camera by the frame's ground scale there "
                "(TerrainRuntime::fit_camera), so that they are ground metres near the camera; "
                "'terralod export' places samples through this map and converts heights from "
                "vertical_datum to the WGS 84 ellipsoid") +
            "}");
  } else {
    field("georeference", "null");
  }
  if (frame) {
    const std::string datum = georeference ? georeference->vertical_datum : std::string();
    field("frame", "{\"description\": " + quote(*frame) + ", \"scale_error\": " +
                       (frame_scale_error ? num(*frame_scale_error) : std::string("null")) +
                       ", \"vertical_datum\": " + quote(datum) + "}");
  } else {
    field("frame", quote("not recorded (built before databases recorded their frame; 'terralod info DEM' "
                         "with the build's --crs prints it)"));
  }
  field("build_parameters", build_parameters.empty() ? "null" : build_parameters, true);
  return j + "}\n";
}

void require_complete_build(const BlockDatabase& db) {
  if (db.get_meta("build_complete").value_or("") != "1")
    throw BuildError(
        db.path() +
        ": the build is not complete (run 'terralod build' again with the same options to finish it)");
}

namespace {

// The stand-in figures of a summary, one block summary at a time.
struct StandinTally {
  std::size_t filled = 0;  // blocks with samples (an empty block has no stand-in)
  void add(DatabaseSummary& s, const BlockSummary& x) {
    if (x.empty) return;
    if (s.standin.empty()) s.standin = standin_kind_name(x.standin);
    ++filled;
    s.mean_standin_error += x.standin_error;
    s.mean_tm_error += x.tm_error;
  }
  void finish(DatabaseSummary& s) const {
    if (filled) s.mean_standin_error /= double(filled), s.mean_tm_error /= double(filled);
  }
};

// summarize_database; with_standins false leaves the stand-in figures to the caller (the build,
// which tallies them as it writes the blob, rather than reading it back whole).
DatabaseSummary summarize(const BlockDatabase& db, bool with_standins) {
  DatabaseSummary s;
  const DatabaseInfo& info = db.info();
  s.path = db.path();
  s.source = info.source;
  s.grid_width = info.grid_width;
  s.grid_height = info.grid_height;
  s.block_size = info.block_size;
  s.build_parameters = info.build_parameters;
  s.georeference = db.georeference();
  s.frame = db.get_meta(kFrameMeta);
  if (const auto e = db.get_meta(kFrameScaleErrorMeta); e && !e->empty())
    s.frame_scale_error = std::atof(e->c_str());
  s.samples = std::uint64_t(info.grid_width) * std::uint64_t(info.grid_height);
  if (info.grid_width >= 2 && info.grid_height >= 2 && is_valid_block_size(info.block_size)) {
    const BlockLayout l = partition(info.grid_width, info.grid_height, info.block_size);
    s.blocks_x = l.blocks_x;
    s.blocks_y = l.blocks_y;
  }
  for (BlockKey k : db.blocks()) {
    ++s.blocks;
    if (const auto r = read_block_record(db, k)) {
      s.pm_vertices += r->vertices;
      s.block_bytes += r->bytes;
      s.max_block_error = std::max(s.max_block_error, r->error);
    }
  }
  if (const auto t = db.read_blob("tree")) {
    const ApproximationTree tree = decode_tree(*t, db.path() + ": tree");
    s.tree_bytes = t->size();
    s.nodes = tree.size();
    s.nodes_per_strategy = tree.count_by_strategy();
    s.tree_depth = tree.depth();
    if (tree.size()) s.root_error = tree.root().error;
  }
  if (!with_standins) {
  } else if (const auto b = db.read_blob(kBlockSummariesBlob); b && s.blocks_x > 0) {
    s.summaries_bytes = b->size();
    StandinTally tally;  // one summary decoded at a time: memory holds the blob alone
    for_each_block_summary(BlockGrid::from_info(info), *b, db.path(),
                           [&](std::size_t, BlockSummary&& x) { tally.add(s, x); });
    tally.finish(s);
  }
  s.bytes_per_vertex = s.samples ? double(s.block_bytes + s.tree_bytes) / double(s.samples) : 0.0;
  if (const auto sec = db.get_meta("build_seconds")) s.seconds = std::atof(sec->c_str());
  s.complete = db.get_meta("build_complete").value_or("") == "1";
  return s;
}

}  // namespace

DatabaseSummary summarize_database(const BlockDatabase& db) { return summarize(db, true); }

BuiltBlock build_block(const pm::Heightfield& hf, BlockKey key, const DatabaseBuildOptions& opt) {
  return build_block(*heightfield_source(hf), key, opt);
}

BuiltBlock build_block(const DemSource& src, BlockKey key, const DatabaseBuildOptions& opt) {
  const DemGrid& g = src.grid();
  const BlockLayout layout = partition(g.width, g.height, opt.block_size);
  if (!layout.contains(key))
    throw BuildError("block (" + std::to_string(key.col) + "," + std::to_string(key.row) +
                     ") is not a block of a " + std::to_string(g.width) + " x " + std::to_string(g.height) +
                     " terrain in blocks of " + std::to_string(opt.block_size));
  const pm::ProgressiveMesh pm = build_block_pm(src.read(layout.rect(key)), opt.metric);
  BuiltBlock b;
  b.key = key;
  b.pm = pm::encode_pm(pm);
  b.summary =
      encode_block_summary_record(summarize_block(pm, key, standin_options(opt)));  // holes take no part
  b.base_error = base_mesh_error(pm);
  b.vertices = pm.full_vertex_count();
  return b;
}

DatabaseSummary build_database(const pm::Heightfield& hf, const std::string& path,
                               const DatabaseBuildOptions& opt) {
  const std::string source = hf.source.empty() ? std::string("(in memory)") : hf.source;
  if (hf.width() < 2 || hf.height() < 2)
    throw BuildError(source + ": a " + std::to_string(hf.width()) + " x " + std::to_string(hf.height()) +
                     " grid is too small to build a terrain (at least 2 x 2 samples)");
  bool any_valid = !hf.has_holes();
  for (std::size_t i = 0; !any_valid && i < hf.size(); ++i) any_valid = hf.valid(i);
  if (!any_valid) throw BuildError(source + ": every sample is void; there is no terrain to build");
  return build_database(*heightfield_source(hf), path, opt);
}

DatabaseSummary build_database(const DemSource& src, const std::string& path,
                               const DatabaseBuildOptions& opt) {
  const auto t0 = std::chrono::steady_clock::now();
  const DemGrid& g = src.grid();
  const std::string source = g.source.empty() ? std::string("(in memory)") : g.source;
  if (g.width < 2 || g.height < 2)
    throw BuildError(source + ": a " + std::to_string(g.width) + " x " + std::to_string(g.height) +
                     " grid is too small to build a terrain (at least 2 x 2 samples)");
  if (!is_valid_block_size(opt.block_size))
    throw BuildError(path + ": block size must be 2^k + 1 (3, 5, 9, ..., 257, ...), not " +
                     std::to_string(opt.block_size));
  const BlockLayout layout = partition(g.width, g.height, opt.block_size);
  const BlockGrid bgrid(g.width, g.height, opt.block_size, g.transform);

  DatabaseInfo info;
  info.grid_width = g.width;
  info.grid_height = g.height;
  info.transform = g.transform;
  info.crs_wkt = g.crs_wkt;
  info.block_size = opt.block_size;
  info.build_parameters = build_parameters_json(src, opt);
  info.source = g.source;

  std::optional<BlockDatabase> dbo;
  bool created = false;
  if (BlockDatabase::is_interrupted_create(path)) {
    // A create() that was killed: nothing to resume, start again (create() discards the
    // journal files left beside it).
    std::filesystem::remove(path);
  }
  if (std::filesystem::exists(path)) {
    dbo.emplace(BlockDatabase::open(path, BlockDatabase::Mode::ReadWrite));
    const DatabaseInfo& have = dbo->info();
    if (have.build_parameters != info.build_parameters || have.grid_width != info.grid_width ||
        have.grid_height != info.grid_height || have.kind != info.kind)
      throw BuildError(path + ": exists and was built with other parameters or input (stored " +
                       have.build_parameters + ", requested " + info.build_parameters +
                       "); use the same options and input to resume, or remove it");
  } else {
    dbo.emplace(BlockDatabase::create(path, info));
    created = true;
  }
  BlockDatabase& db = *dbo;
  if (g.crs_transform) db.put_georeference({*g.crs_transform, g.vertical_datum});
  {  // the world frame, for 'terralod info DB'
    const std::optional<double>& e = g.scale_error;
    char buf[40] = "";
    if (e) std::snprintf(buf, sizeof buf, "%.9g", *e);
    BlockDatabase::Transaction tx(db);
    db.set_meta(kFrameMeta, g.frame);
    db.set_meta(kFrameScaleErrorMeta, buf);
    tx.commit();
  }

  // Blocks still to build.
  const std::vector<BlockKey> keys = layout.keys();
  std::vector<BlockKey> todo;
  for (BlockKey k : keys)
    if (!db.has_block(k) || !read_block_record(db, k)) todo.push_back(k);
  const std::size_t already = keys.size() - todo.size();

  // Bytes of each block's summary record in the database (0: none yet; a record has >= 40).
  std::vector<std::uint32_t> summary_bytes(bgrid.block_count(), 0);  // 4 bytes a block
  std::mutex m;
  std::condition_variable cv;
  std::deque<BuiltBlock> queue;
  std::atomic<bool> cancel{false};
  std::exception_ptr worker_error;
  std::atomic<std::size_t> next{0};
  auto claim = [&]() -> std::optional<BlockKey> {
    if (cancel) return std::nullopt;
    const std::size_t i = next.fetch_add(1);
    return i < todo.size() ? std::optional<BlockKey>(todo[i]) : std::nullopt;
  };
  auto push = [&](BuiltBlock d) {
    std::lock_guard<std::mutex> lock(m);
    queue.push_back(std::move(d));
    cv.notify_all();
  };
  auto fail = [&] {
    std::lock_guard<std::mutex> lock(m);
    if (!worker_error) worker_error = std::current_exception();
    cancel = true;
  };
  int threads = pm::thread_count(opt.threads);
  threads = int(std::min<std::size_t>(std::size_t(threads), std::max<std::size_t>(1, todo.size())));
  std::size_t finished_workers = 0;
  std::vector<std::thread> pool;
  auto run_worker = [&](const std::function<void()>& work) {
    pool.emplace_back([&, work] {
      try {
        work();
      } catch (...) {
        fail();
      }
      std::lock_guard<std::mutex> lock(m);
      ++finished_workers;
      cv.notify_all();
    });
  };
  for (int t = 0; t < threads && !todo.empty(); ++t)
    run_worker([&] {
      for (std::optional<BlockKey> k; (k = claim());) push(build_block(src, *k, opt));
    });
  // Remote builders run even with nothing to build: they must tell their builders so.
  for (const RemoteBuilder& remote : opt.remote_builders)
    run_worker([&, remote] {
      // A delivered block is written as it comes, not decoded: its PM, stand-in and record
      // were made by build_block, as the local ones are. Decoding it here and making its
      // stand-in (about 15 + 8 ms a block of 257 on this machine) was serial work on the
      // writer's process for every block another rank built. Checked: its place in the layout,
      // and its summary record and build record, which decode in microseconds.
      remote(claim, [&](BuiltBlock b) {
        const std::string where = path + ": block (" + std::to_string(b.key.col) + "," +
                                  std::to_string(b.key.row) + ") from a remote builder";
        if (!layout.contains(b.key)) throw BuildError(where + " is not a block of this terrain");
        try {
          decode_block_summary_record(bgrid, bgrid.index(b.key), b.summary, where);
        } catch (const DatabaseError& e) {
          throw BuildError(e.what());
        }
        if (b.pm.empty() || !(b.base_error >= 0) || !std::isfinite(b.base_error) || b.vertices == 0)
          throw BuildError(where + ": an empty PM or a bad build record");
        push(std::move(b));
      });
    });
  auto stop_workers = [&] {
    cancel = true;
    for (auto& t : pool)
      if (t.joinable()) t.join();
  };

  std::size_t written = 0;
  // A database this call created and wrote no block into holds nothing worth resuming (a read
  // error in the first blocks, an all-void DEM): it is removed rather than left half-made.
  auto discard_if_new_and_empty = [&] {
    if (!created || written > 0) return;
    dbo.reset();
    for (const std::string& f : {path, path + "-wal", path + "-shm"}) std::filesystem::remove(f);
  };
  const auto tb = std::chrono::steady_clock::now();
  try {
    if (opt.progress && !keys.empty()) opt.progress(double(already) / double(keys.size()), -1.0);
    while (written < todo.size()) {
      BuiltBlock d;
      {
        std::unique_lock<std::mutex> lock(m);
        cv.wait(lock, [&] { return !queue.empty() || finished_workers == pool.size() || worker_error; });
        if (worker_error) break;
        if (queue.empty()) break;
        d = std::move(queue.front());
        queue.pop_front();
      }
      {
        BlockDatabase::Transaction tx(db);
        db.put_block(d.key, d.pm);
        db.set_meta(block_meta_key(d.key), format_record({d.base_error, d.vertices, d.pm.size()}));
        db.put_blob(summary_blob_name(d.key), d.summary);
        tx.commit();
      }
      summary_bytes[bgrid.index(d.key)] = std::uint32_t(d.summary.size());
      ++written;
      if (opt.progress) {
        const double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - tb).count();
        opt.progress(double(already + written) / double(keys.size()),
                     el / double(written) * double(todo.size() - written));
      }
      if (opt.stop_after_blocks && written >= opt.stop_after_blocks && written < todo.size()) {
        stop_workers();
        throw BuildError(path + ": build stopped after " + std::to_string(written) +
                         " blocks (stop_after_blocks)");
      }
    }
  } catch (...) {
    stop_workers();
    discard_if_new_and_empty();
    throw;
  }
  stop_workers();
  if (worker_error) {
    discard_if_new_and_empty();
    std::rethrow_exception(worker_error);
  }
  if (written != todo.size()) throw BuildError(path + ": internal error: not every block was built");

  // The tree above the blocks, written with the completion mark in one transaction.
  std::vector<double> errors(keys.size());
  std::uint64_t vertices = 0;
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const auto r = read_block_record(db, keys[i]);
    if (!r)
      throw DatabaseError(path, "block (" + std::to_string(keys[i].col) + "," + std::to_string(keys[i].row) +
                                    "): no build record");
    errors[i] = r->error;
    vertices += r->vertices;
  }
  // A windowed source does not scan its samples before the build: an all-void DEM shows here,
  // and so does one whose valid samples (voids kept) have no valid neighbours to make a triangle.
  if (vertices == 0) {
    written = 0;  // nothing but empty blocks: nothing worth keeping either
    discard_if_new_and_empty();
    throw BuildError(
        source +
        ": no triangle of valid samples (every sample is void, or no valid sample has two valid "
        "neighbours to make one with); there is no terrain to build" +
        (g.warped ? std::string(" in the frame it was warped to (" + g.frame.substr(0, g.frame.find(" (")) +
                                "), whose cells outside the input are holes: a DEM of a few samples may "
                                "keep no whole cell; --crs native builds the DEM's own grid")
                  : std::string()));
  }
  TreeBuildOptions topt = opt.tree;
  topt.pm_leaves = true;
  topt.metric = opt.metric;
  topt.threads = threads;
  // Only its encoding is kept: summarize_database decodes it again once it is written.
  std::vector<std::uint8_t> tree_bytes = encode_tree(build_tree(src, layout, topt, errors));

  // Block summaries with their stand-ins: the blocks built now were summarized by the workers;
  // those of an earlier run have their record stored too, unless that run predates stored
  // records: those blocks are read back and summarized here.
  std::vector<BlockKey> resumed;
  for (BlockKey k : keys) {
    std::uint32_t& n = summary_bytes[bgrid.index(k)];
    if (n) continue;
    if (const auto r = db.read_blob(summary_blob_name(k)))
      n = std::uint32_t(r->size());
    else
      resumed.push_back(k);
  }
  std::mutex db_mutex;
  BlockDatabase::Transaction resumed_tx(db);
  parallel_for(resumed.size(), threads, [&](std::size_t i) {
    const BlockKey k = resumed[i];
    std::vector<std::uint8_t> blob;
    {
      std::lock_guard<std::mutex> lock(db_mutex);
      blob = db.read_block(k);
    }
    const pm::ProgressiveMesh pm =
        pm::decode_pm(blob, path + ": block (" + std::to_string(k.col) + "," + std::to_string(k.row) + ")");
    const std::vector<std::uint8_t> record =
        encode_block_summary_record(summarize_block(pm, k, standin_options(opt)));
    std::lock_guard<std::mutex> lock(db_mutex);
    db.put_blob(summary_blob_name(k), record);
    summary_bytes[bgrid.index(k)] = std::uint32_t(record.size());
  });
  resumed_tx.commit();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  DatabaseSummary standins;
  StandinTally tally;
  {
    BlockDatabase::Transaction tx(db);
    db.put_blob("tree", tree_bytes);
    // The records are streamed into the blob and removed: a complete database holds the blob
    // alone, and memory holds one record at a time, not the blob (1.6 kB a block).
    std::uint64_t blob_bytes = kBlockSummariesFraming;
    for (std::uint32_t n : summary_bytes) blob_bytes += n;
    auto record = [&](std::size_t i) {
      const std::string name = summary_blob_name(bgrid.key(i));
      std::optional<std::vector<std::uint8_t>> r = db.read_blob(name);
      if (!r) throw DatabaseError(path, name + ": missing");
      return std::move(*r);
    };
    // First pass: the blob's CRC, which its row is written with (records are read twice, the
    // row written once).
    std::uint32_t crc = 0;
    join_block_summary_records(bgrid, record,
                               [&](std::span<const std::uint8_t> piece) { crc = pm::crc32_of(piece, crc); });
    db.put_blob_in_pieces(
        kBlockSummariesBlob, blob_bytes, crc, [&](const BlockDatabase::BlobPieceWriter& write) {
          join_block_summary_records(
              bgrid,
              [&](std::size_t i) {
                std::vector<std::uint8_t> r = record(i);
                db.remove_blob(summary_blob_name(bgrid.key(i)));
                tally.add(standins, decode_block_summary_record(
                                        bgrid, i, r, path + ": block summary " + std::to_string(i)));
                return r;
              },
              write);
        });
    standins.summaries_bytes = blob_bytes;
    tally.finish(standins);
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.6f", seconds);
    db.set_meta("build_seconds", buf);
    db.set_meta("build_complete", "1");
    tx.commit();
  }
  std::vector<std::uint8_t>().swap(tree_bytes);
  DatabaseSummary s = summarize(db, false);
  s.summaries_bytes = standins.summaries_bytes;
  s.standin = standins.standin;
  s.mean_standin_error = standins.mean_standin_error;
  s.mean_tm_error = standins.mean_tm_error;
  s.blocks_built = written;
  s.seconds = seconds;
  return s;
}

}  // namespace terralod::blocks
