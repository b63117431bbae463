// Whole-terrain extraction from a block database: per-block PM extraction, seam stitching, exact
// measurement and re-extraction of offending blocks (the 2E argument is in seam_stitch.hpp).
// Memory: see database_extract.hpp.
#include "terralod/blocks/database_extract.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <unordered_map>

#include "terralod/blocks/partition.hpp"
#include "terralod/blocks/seam_stitch.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/linf_error.hpp"
#include "terralod/pm/pm_io.hpp"

namespace terralod::blocks {

ExtractedMesh extract_mesh(const BlockDatabase& db, double max_error) {
  if (!(max_error >= 0.0) || !std::isfinite(max_error))
    throw std::invalid_argument("extract: max_error must be finite and >= 0");
  const auto t0 = std::chrono::steady_clock::now();
  const DatabaseInfo& info = db.info();
  require_complete_build(db);
  const BlockLayout layout = partition(info.grid_width, info.grid_height, info.block_size);
  const std::vector<BlockKey> keys = layout.keys();

  ExtractedMesh out;
  out.max_error = max_error;
  out.blocks = keys.size();
  std::vector<pm::ProgressiveMesh> pms;
  out.heightfield = read_database_terrain(db, &pms);
  const pm::Heightfield& hf = out.heightfield;
  const pm::ErrorMetric metric = pms.empty() ? pm::ErrorMetric::Continuous : pms.back().metric();

  const pm::LInfError err(hf, metric);
  std::vector<double> level(keys.size(), max_error);
  std::vector<bool> refined(keys.size(), false);
  std::vector<StitchPatch> patches;
  StitchResult stitch;
  for (;;) {
    ++out.iterations;
    patches.assign(keys.size(), {});
    for (std::size_t b = 0; b < keys.size(); ++b) {
      const SampleRect r = layout.rect(keys[b]);
      const pm::TriangleMesh m = pms[b].extract(level[b]);
      const int bw = pms[b].heightfield().width();
      StitchPatch& p = patches[b];
      p.domain = r;
      p.vertices.reserve(m.vertices.size());
      for (std::uint32_t s : m.vertices) p.vertices.push_back({r.col0 + int(s % bw), r.row0 + int(s / bw)});
      p.triangles = m.triangles;
    }
    stitch = stitch_seams(patches);
    bool again = false;
    for (std::size_t b = 0; b < keys.size(); ++b) {
      const StitchPatch& p = patches[b];
      bool bad = false;
      for (std::uint32_t t : stitch.new_triangles[b]) {
        const auto& tri = p.triangles[t];
        if (err.triangle(p.vertices[tri[0]], p.vertices[tri[1]], p.vertices[tri[2]], max_error) > max_error) {
          bad = true;
          break;
        }
      }
      if (bad) {
        // E/2 is enough by the fan-split bound; halving again only guards against rounding.
        level[b] = std::min(level[b], max_error) * 0.5;
        refined[b] = true;
        again = true;
      }
    }
    if (!again) break;
  }
  out.blocks_refined = std::size_t(std::count(refined.begin(), refined.end(), true));
  out.inserted_vertices = stitch.inserted_vertices;
  out.split_triangles = stitch.split_triangles;

  // One mesh: vertices are whole-grid sample indices, shared seam vertices merge.
  std::unordered_map<std::uint32_t, std::uint32_t> index;
  pm::TriangleMesh& mesh = out.mesh;
  const int W = hf.width();
  for (const StitchPatch& p : patches) {
    std::vector<std::uint32_t> local(p.vertices.size());
    for (std::size_t v = 0; v < p.vertices.size(); ++v) {
      const std::uint32_t s =
          std::uint32_t(p.vertices[v].y) * std::uint32_t(W) + std::uint32_t(p.vertices[v].x);
      auto [it, inserted] = index.try_emplace(s, std::uint32_t(mesh.vertices.size()));
      if (inserted) mesh.vertices.push_back(s);
      local[v] = it->second;
    }
    for (const auto& t : p.triangles) mesh.triangles.push_back({local[t[0]], local[t[1]], local[t[2]]});
  }
  auto point = [&](std::uint32_t v) {
    return pm::GridPoint{int(mesh.vertices[v] % W), int(mesh.vertices[v] / W)};
  };
  double worst = 0.0;
  for (const auto& t : mesh.triangles)
    worst = std::max(worst, err.triangle(point(t[0]), point(t[1]), point(t[2])));
  out.measured_error = mesh.error_bound = worst;
  out.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

ExtractedMesh extract_mesh(const std::string& path, double max_error) {
  const BlockDatabase db = BlockDatabase::open(path, BlockDatabase::Mode::ReadOnly);
  return extract_mesh(db, max_error);
}

}  // namespace terralod::blocks
