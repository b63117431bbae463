// Partitioning into (2^k + 1)-sample blocks sharing their borders, and per-block PMs.
#include "terralod/blocks/partition.hpp"

#include <algorithm>
#include <cassert>
#include <stdexcept>
#include <string>

#include "terralod/pm/linf_error.hpp"

namespace terralod::blocks {

bool is_valid_block_size(int n) {
  if (n < 3) return false;
  const unsigned m = unsigned(n - 1);
  return (m & (m - 1)) == 0;
}

BlockLayout partition(int width, int height, int block_size) {
  if (!is_valid_block_size(block_size))
    throw std::invalid_argument("block size must be 2^k + 1 (3, 5, 9, ..., 257, ...), not " +
                                std::to_string(block_size));
  if (width < 2 || height < 2)
    throw std::invalid_argument("a terrain of " + std::to_string(width) + " x " + std::to_string(height) +
                                " samples cannot be partitioned: at least 2 x 2 are needed");
  BlockLayout l;
  l.grid_width = width;
  l.grid_height = height;
  l.block_size = block_size;
  const int cells = block_size - 1;
  l.blocks_x = (width - 1 + cells - 1) / cells;
  l.blocks_y = (height - 1 + cells - 1) / cells;
  return l;
}

SampleRect BlockLayout::rect(int c0, int r0, int c1, int r1) const {
  assert(c0 >= 0 && r0 >= 0 && c0 <= c1 && r0 <= r1 && c1 < blocks_x && r1 < blocks_y);
  const int cells = block_size - 1;
  return SampleRect{c0 * cells, r0 * cells, std::min((c1 + 1) * cells, grid_width - 1),
                    std::min((r1 + 1) * cells, grid_height - 1)};
}

SampleRect BlockLayout::rect(BlockKey k) const { return rect(k.col, k.row, k.col, k.row); }

std::vector<BlockKey> BlockLayout::keys() const {
  std::vector<BlockKey> k;
  k.reserve(count());
  for (int c = 0; c < blocks_x; ++c)
    for (int r = 0; r < blocks_y; ++r) k.push_back({c, r});
  return k;
}

pm::Heightfield block_heightfield(const pm::Heightfield& hf, SampleRect r) {
  assert(r.col0 >= 0 && r.row0 >= 0 && r.col1 < hf.width() && r.row1 < hf.height());
  assert(r.col0 <= r.col1 && r.row0 <= r.row1);
  pm::Heightfield b(r.width(), r.height());
  std::vector<std::uint8_t> mask;
  if (hf.has_holes()) mask.resize(b.size());
  for (int j = 0; j < r.height(); ++j)
    for (int i = 0; i < r.width(); ++i) {
      b.at(i, j) = hf.at(r.col0 + i, r.row0 + j);
      if (!mask.empty()) mask[std::size_t(j) * b.width() + i] = hf.valid(r.col0 + i, r.row0 + j) ? 1 : 0;
    }
  if (!mask.empty() && std::find(mask.begin(), mask.end(), std::uint8_t(0)) != mask.end())
    b.set_mask(std::move(mask));
  b.transform = hf.transform;
  const auto [x0, y0] = hf.transform.to_world(r.col0, r.row0);
  b.transform.x0 = x0;
  b.transform.y0 = y0;
  b.crs_wkt = hf.crs_wkt;
  b.source = hf.source;
  b.frame = hf.frame;
  return b;
}

pm::ProgressiveMesh build_block_pm(const pm::Heightfield& hf, SampleRect rect, pm::ErrorMetric metric) {
  return build_block_pm(block_heightfield(hf, rect), metric);
}

pm::ProgressiveMesh build_block_pm(const pm::Heightfield& block, pm::ErrorMetric metric) {
  pm::BuildOptions opt;
  opt.metric = metric;
  opt.threads = 1;
  opt.parallel_strips = false;  // no full-resolution cut column: blocks run in parallel instead
  return pm::ProgressiveMesh::build(block, opt);
}

double base_mesh_error(const pm::ProgressiveMesh& pm) {
  const pm::TriangleMesh m = pm.extract_after(pm.vsplit_count());
  const pm::Heightfield& hf = pm.heightfield();
  const pm::LInfError err(hf, pm.metric());
  const auto gp = [&](std::uint32_t s) { return pm::GridPoint{int(s % hf.width()), int(s / hf.width())}; };
  double worst = 0.0;
  for (const auto& t : m.triangles)
    worst = std::max(worst, err.triangle(gp(m.vertices[t[0]]), gp(m.vertices[t[1]]), gp(m.vertices[t[2]])));
  return worst;
}

}  // namespace terralod::blocks
