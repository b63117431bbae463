// Test support for dynamic loading: blocked generated terrains (block PMs and summaries with
// their stand-ins, one kind or a mix of kinds), an in-memory block source with controllable
// latency (a stalled reader), and an independent watertightness checker of a drawn mesh.
#pragma once

#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cmath>
#include <map>
#include <mutex>
#include <numeric>
#include <set>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "terralod/blocks/active_region.hpp"
#include "terralod/blocks/block_loader.hpp"
#include "terralod/blocks/partition.hpp"
#include "terralod/blocks/terrain_session.hpp"
#include "terralod/pm/pm_io.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace terralod::test {

/// A terrain cut into blocks: the blobs (pm::encode_pm of each block PM) and summaries.
/// Stand-ins: blocks::StandinOptions{} (the database default), or with a list of options, block
/// (col,row) uses list[(col + 2 row) % size] so that neighbours differ.
struct BlockedTerrain {
  pm::Heightfield hf;
  blocks::BlockGrid grid;
  std::map<blocks::BlockKey, std::vector<std::uint8_t>> blobs;
  std::vector<blocks::BlockSummary> summaries;
};

inline BlockedTerrain block_terrain(pm::Heightfield hf, int block_size,
                                    const std::vector<blocks::StandinOptions>& standins = {});

/// A generated terrain (heights in whole metres) cut into blocks.
inline BlockedTerrain make_blocked_terrain(int width, int height, int block_size, std::uint64_t seed,
                                           double spacing = 30.0, double relief = 1200.0,
                                           const std::vector<blocks::StandinOptions>& standins = {}) {
  pm::TerrainOptions to;
  to.width = width;
  to.height = height;
  to.seed = seed;
  to.spacing = spacing;
  to.relief = relief;
  to.quantize_to_metres = true;
  return block_terrain(pm::generate_terrain(to), block_size, standins);
}

/// Cuts `hf` into blocks (partition.hpp) and builds every block's PM.
inline BlockedTerrain block_terrain(pm::Heightfield hf, int block_size,
                                    const std::vector<blocks::StandinOptions>& standins) {
  const int width = hf.width(), height = hf.height();
  BlockedTerrain t;
  t.hf = std::move(hf);
  t.grid = blocks::BlockGrid(width, height, block_size, t.hf.transform);
  const blocks::BlockLayout layout = blocks::partition(width, height, block_size);
  t.summaries.resize(t.grid.block_count());
  for (blocks::BlockKey k : layout.keys()) {
    const pm::ProgressiveMesh pm = blocks::build_block_pm(t.hf, layout.rect(k));
    t.blobs[k] = pm::encode_pm(pm);
    const blocks::StandinOptions o =
        standins.empty() ? blocks::StandinOptions{} : standins[std::size_t(k.col + 2 * k.row) % standins.size()];
    t.summaries[t.grid.index(k)] = blocks::summarize_block(pm, k, o);
  }
  return t;
}

/// A copy of `t` whose summaries get other stand-ins (block PMs decoded from the blobs, not
/// rebuilt; `standins` as in block_terrain).
inline BlockedTerrain with_standins(const BlockedTerrain& t, const std::vector<blocks::StandinOptions>& standins) {
  BlockedTerrain c = t;
  for (const auto& [k, blob] : c.blobs) {
    const blocks::StandinOptions o =
        standins.empty() ? blocks::StandinOptions{} : standins[std::size_t(k.col + 2 * k.row) % standins.size()];
    c.summaries[c.grid.index(k)] = blocks::summarize_block(pm::decode_pm(blob, "blob"), k, o);
  }
  return c;
}

/// Shared state of MemorySource objects: the blobs, a gate that can stall every read until
/// the frame counter reaches a value, and counters.
struct MemoryStore {
  const BlockedTerrain* terrain = nullptr;
  std::mutex mutex;
  std::condition_variable cv;
  bool stalled = false;              ///< reads wait while true
  std::uint64_t frame = 0;           ///< advanced by the test's frame loop
  std::uint64_t latency_frames = 0;  ///< each read waits until `frame` has advanced this much
  bool released = false;             ///< reads never wait once set (see ReleaseAtExit)
  std::atomic<int> reads{0};
  std::atomic<bool> reading{false};

  void set_stalled(bool s) {
    {
      std::lock_guard l(mutex);
      stalled = s;
    }
    cv.notify_all();
  }
  void release() {
    {
      std::lock_guard l(mutex);
      released = true;
    }
    cv.notify_all();
  }
  void advance_frame() {
    {
      std::lock_guard l(mutex);
      ++frame;
    }
    cv.notify_all();
  }
};

/// Declared after a session that reads from `store`: releases every waiting read before the
/// session's loader is joined (a loader waits for the read in progress when it stops).
struct ReleaseAtExit {
  MemoryStore& store;
  ~ReleaseAtExit() { store.release(); }
};

class MemorySource final : public blocks::BlockSource {
 public:
  explicit MemorySource(MemoryStore& s) : s_(&s) {}
  std::vector<std::uint8_t> read(blocks::BlockKey k) override {
    s_->reading = true;
    {
      std::unique_lock l(s_->mutex);
      const std::uint64_t until = s_->frame + s_->latency_frames;
      s_->cv.wait(l, [&] { return s_->released || (!s_->stalled && s_->frame >= until); });
    }
    ++s_->reads;
    s_->reading = false;
    const auto it = s_->terrain->blobs.find(k);
    if (it == s_->terrain->blobs.end())
      throw blocks::DatabaseError("memory", "block (" + std::to_string(k.col) + "," + std::to_string(k.row) +
                                                "): not in the database");
    return it->second;
  }
  std::string name() const override { return "memory"; }

 private:
  MemoryStore* s_;
};

inline blocks::BlockSourceFactory memory_source(MemoryStore& s) {
  return [&s]() -> std::unique_ptr<blocks::BlockSource> { return std::make_unique<MemorySource>(s); };
}

/// Result of the independent watertightness check of a drawn mesh over a rectangle of
/// samples (the active region): welding is by exact equality of the world positions.
struct WatertightCheck {
  std::size_t triangles = 0, vertices = 0;
  std::size_t degenerate_or_flipped = 0;  ///< plan-view orientation <= 0 (CCW in (col,row))
  std::size_t bad_interior_edges = 0;     ///< used other than once in each direction
  std::size_t inner_boundary_edges = 0;   ///< used once but not on the region's outer border
  std::size_t t_junctions = 0;            ///< a vertex strictly inside another triangle's edge
  std::size_t split_vertices = 0;         ///< one sample at two different positions
  double area = 0, region_area = 0;       ///< plan view, cells
  bool ok() const {
    return degenerate_or_flipped == 0 && bad_interior_edges == 0 && inner_boundary_edges == 0 && t_junctions == 0 &&
           split_vertices == 0 && area == region_area;
  }
  std::string describe() const {
    return "triangles " + std::to_string(triangles) + ", vertices " + std::to_string(vertices) + ", flipped " +
           std::to_string(degenerate_or_flipped) + ", bad interior edges " + std::to_string(bad_interior_edges) +
           ", inner boundary edges " + std::to_string(inner_boundary_edges) + ", T-junctions " +
           std::to_string(t_junctions) + ", split vertices " + std::to_string(split_vertices) + ", area " +
           std::to_string(area) + " of " + std::to_string(region_area);
  }
};

/// Checks `m` (vertices must be samples) over the inclusive sample rectangle `region`.
inline WatertightCheck check_watertight(const blocks::DrawnMesh& m, const blocks::BlockGrid& grid, blocks::SampleRect region) {
  WatertightCheck c;
  c.triangles = m.triangles.size();
  const std::uint64_t W = std::uint64_t(grid.grid_width());
  // Weld by position bits: two vertices are one only when x, y, z are bit-identical.
  std::map<std::tuple<double, double, double>, std::uint32_t> weld;
  std::vector<std::uint32_t> id(m.positions.size());
  std::map<std::uint64_t, std::tuple<double, double, double>> sample_pos;
  std::vector<std::array<std::int64_t, 2>> plan;  // per welded vertex: (col, row)
  for (std::size_t v = 0; v < m.positions.size(); ++v) {
    const auto key = std::make_tuple(m.positions[v].x, m.positions[v].y, m.positions[v].z);
    auto [it, fresh] = weld.try_emplace(key, std::uint32_t(plan.size()));
    if (fresh) plan.push_back({std::int64_t(m.samples[v] % W), std::int64_t(m.samples[v] / W)});
    id[v] = it->second;
    auto [sit, sfresh] = sample_pos.try_emplace(m.samples[v], key);
    if (!sfresh && sit->second != key) ++c.split_vertices;
  }
  c.vertices = plan.size();
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> edges;
  std::int64_t area2 = 0;
  for (const auto& t : m.triangles) {
    const auto &a = plan[id[t[0]]], &b = plan[id[t[1]]], &d = plan[id[t[2]]];
    const std::int64_t o = (b[0] - a[0]) * (d[1] - a[1]) - (b[1] - a[1]) * (d[0] - a[0]);
    if (o <= 0) ++c.degenerate_or_flipped;
    area2 += o;
    for (int e = 0; e < 3; ++e) ++edges[{id[t[e]], id[t[(e + 1) % 3]]}];
  }
  c.area = double(area2) / 2;
  c.region_area = double(region.col1 - region.col0) * double(region.row1 - region.row0);
  for (const auto& [e, n] : edges) {
    const auto rev = edges.find({e.second, e.first});
    const int back = rev == edges.end() ? 0 : rev->second;
    if (n > 1 || back > 1) {
      ++c.bad_interior_edges;
      continue;
    }
    if (back == 1) continue;
    const auto &a = plan[e.first], &b = plan[e.second];
    const bool outer = (a[0] == b[0] && (a[0] == region.col0 || a[0] == region.col1)) ||
                       (a[1] == b[1] && (a[1] == region.row0 || a[1] == region.row1));
    if (!outer) ++c.inner_boundary_edges;
  }
  // T-junctions: a vertex strictly inside a triangle edge (exact integer test on the grid).
  std::map<std::array<std::int64_t, 2>, int> at;
  for (const auto& p : plan) ++at[p];
  for (const auto& [e, n] : edges) {
    if (e.first > e.second && edges.count({e.second, e.first})) continue;  // each edge once
    const auto &a = plan[e.first], &b = plan[e.second];
    const std::int64_t dx = b[0] - a[0], dy = b[1] - a[1];
    const std::int64_t g = std::gcd(std::abs(dx), std::abs(dy));
    for (std::int64_t k = 1; k < g; ++k)
      if (at.count({a[0] + dx / g * k, a[1] + dy / g * k})) ++c.t_junctions;
  }
  return c;
}

/// The inclusive sample rectangle of a session's active region.
inline blocks::SampleRect region_rect(const blocks::TerrainSession& s) {
  const blocks::ActiveRegion& r = s.region();
  const blocks::SampleRect a = s.grid().domain({r.col0, r.row0}), b = s.grid().domain({r.col1, r.row1});
  return {a.col0, a.row0, b.col1, b.row1};
}

/// Runs frames of `s` at a fixed pose, advancing `t` by 1/60 s each, until every inner block
/// is refined, nothing morphs and nothing loads; fails the test after 20000 frames.
inline void settle(blocks::TerrainSession& s, const pm::Camera& cam, double& t) {
  for (int i = 0; i < 20000; ++i, t += 1.0 / 60) {
    const blocks::SessionFrameStats& st = s.update(pm::View(cam), t);
    if (st.refined == st.inner && st.morphing_blocks == 0 && st.loading == 0) return;
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  FAIL() << "session did not settle";
}

}  // namespace terralod::test
