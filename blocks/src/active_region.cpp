// Block grid geometry, block summaries (two-triangle stand-ins) and the active region (paper
// section 4.1-4.2, Eq. 2); see active_region.hpp.
#include "terralod/blocks/active_region.hpp"

#include <zlib.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include "terralod/pm/linf_error.hpp"

namespace terralod::blocks {

BlockGrid::BlockGrid(int grid_width, int grid_height, int block_size, const pm::GridTransform& transform)
    : w_(grid_width), h_(grid_height), b_(block_size), t_(transform) {
  if (grid_width < 2 || grid_height < 2)
    throw std::invalid_argument("BlockGrid: terrain needs at least 2 x 2 samples, not " + std::to_string(grid_width) +
                                " x " + std::to_string(grid_height));
  if (block_size < 3) throw std::invalid_argument("BlockGrid: block_size must be >= 3, not " + std::to_string(block_size));
  if (!(transform.determinant() != 0.0) || !std::isfinite(transform.determinant()))
    throw std::invalid_argument("BlockGrid: the grid transform is singular");
  cols_ = (w_ - 1 + b_ - 2) / (b_ - 1);
  rows_ = (h_ - 1 + b_ - 2) / (b_ - 1);
}

BlockGrid BlockGrid::from_info(const DatabaseInfo& info) {
  if (info.block_size == 0) throw std::invalid_argument("the database is not blocked (block_size 0)");
  return BlockGrid(info.grid_width, info.grid_height, info.block_size, info.transform);
}

SampleRect BlockGrid::domain(BlockKey k) const {
  assert(contains(k));
  SampleRect r;
  r.col0 = k.col * (b_ - 1);
  r.row0 = k.row * (b_ - 1);
  r.col1 = std::min(r.col0 + b_ - 1, w_ - 1);
  r.row1 = std::min(r.row0 + b_ - 1, h_ - 1);
  return r;
}

double BlockGrid::block_extent_m() const { return (b_ - 1) * std::min(t_.spacing_x(), t_.spacing_y()); }

std::pair<double, double> BlockGrid::to_grid(double x, double y) const {
  const double det = t_.determinant();
  const double dx = x - t_.x0, dy = y - t_.y0;
  return {(t_.yr * dx - t_.xr * dy) / det, (-t_.yc * dx + t_.xc * dy) / det};
}

BlockKey BlockGrid::block_at(double x, double y) const {
  const auto [col, row] = to_grid(x, y);
  auto clampi = [](double v, int hi) {
    if (!(v >= 0)) return 0;  // NaN too
    if (v >= hi) return hi - 1;
    return int(v);
  };
  return {clampi(std::floor(col / (b_ - 1)), cols_), clampi(std::floor(row / (b_ - 1)), rows_)};
}

pm::Vec3 BlockGrid::world(int col, int row, double z) const {
  const auto [x, y] = t_.to_world(col, row);
  return {x, y, z};
}

BlockSummary summarize_block(const pm::ProgressiveMesh& pm, BlockKey k) {
  const pm::Heightfield& hf = pm.heightfield();
  const std::string name = "block (" + std::to_string(k.col) + "," + std::to_string(k.row) + ")";
  if (hf.has_holes()) {
    for (std::size_t i = 0; i < hf.size(); ++i)
      if (!hf.valid(i)) throw std::invalid_argument(name + ": has voids; blocks need complete samples");
  }
  const int w = hf.width(), h = hf.height();
  BlockSummary s;
  s.z00 = hf.at(0, 0);
  s.z10 = hf.at(w - 1, 0);
  s.z01 = hf.at(0, h - 1);
  s.z11 = hf.at(w - 1, h - 1);
  const auto [lo, hi] = std::minmax_element(hf.samples().begin(), hf.samples().end());
  s.zmin = *lo;
  s.zmax = *hi;
  const pm::LInfError err(hf, pm::ErrorMetric::Continuous);
  s.tm_error = std::max(err.triangle({0, 0}, {w - 1, 0}, {w - 1, h - 1}), err.triangle({0, 0}, {w - 1, h - 1}, {0, h - 1}));
  const pm::TriangleMesh base = pm.extract_after(pm.vsplit_count());
  if (base.triangles.size() == 2) {
    const std::uint32_t c00 = 0, c10 = std::uint32_t(w - 1), c01 = std::uint32_t((h - 1) * w), c11 = c01 + c10;
    auto sorted = [&](const std::array<std::uint32_t, 3>& t) {
      std::array<std::uint32_t, 3> v{base.vertices[t[0]], base.vertices[t[1]], base.vertices[t[2]]};
      std::sort(v.begin(), v.end());
      return v;
    };
    std::array<std::uint32_t, 3> a{c00, c10, c11}, b{c00, c01, c11};
    std::sort(a.begin(), a.end());
    std::sort(b.begin(), b.end());
    const auto t0 = sorted(base.triangles[0]), t1 = sorted(base.triangles[1]);
    s.base_is_tm = (t0 == a && t1 == b) || (t0 == b && t1 == a);
  }
  return s;
}

namespace {

constexpr std::uint32_t kMagic = 0x53424C54u;  // "TLBS"
constexpr std::size_t kRecord = 7 * 8 + 8;

void put_u32(std::vector<std::uint8_t>& o, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) o.push_back(std::uint8_t(v >> (8 * i)));
}
void put_f64(std::vector<std::uint8_t>& o, double d) {
  std::uint64_t v;
  std::memcpy(&v, &d, 8);
  for (int i = 0; i < 8; ++i) o.push_back(std::uint8_t(v >> (8 * i)));
}
std::uint32_t get_u32(const std::uint8_t* p) {
  return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
}
double get_f64(const std::uint8_t* p) {
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= std::uint64_t(p[i]) << (8 * i);
  double d;
  std::memcpy(&d, &v, 8);
  return d;
}
std::uint32_t crc(const std::uint8_t* p, std::size_t n) {
  return std::uint32_t(::crc32(::crc32(0L, Z_NULL, 0), p, uInt(n)));
}

}  // namespace

std::vector<std::uint8_t> encode_block_summaries(const BlockGrid& grid, std::span<const BlockSummary> s) {
  assert(s.size() == grid.block_count());
  std::vector<std::uint8_t> o;
  o.reserve(16 + s.size() * kRecord + 4);
  put_u32(o, kMagic);
  put_u32(o, 1);
  put_u32(o, std::uint32_t(grid.cols()));
  put_u32(o, std::uint32_t(grid.rows()));
  for (const BlockSummary& b : s) {
    for (double d : {b.z00, b.z10, b.z01, b.z11, b.zmin, b.zmax, b.tm_error}) put_f64(o, d);
    o.push_back(b.base_is_tm ? 1 : 0);
    o.insert(o.end(), 7, 0);
  }
  put_u32(o, crc(o.data(), o.size()));
  return o;
}

std::vector<BlockSummary> decode_block_summaries(const BlockGrid& grid, std::span<const std::uint8_t> bytes,
                                                 const std::string& name_for_errors) {
  auto fail = [&](const std::string& what) {
    throw DatabaseError(name_for_errors, std::string(kBlockSummariesBlob) + ": " + what);
  };
  const std::size_t expect = 16 + grid.block_count() * kRecord + 4;
  if (bytes.size() < 20) fail("truncated (" + std::to_string(bytes.size()) + " bytes)");
  if (get_u32(bytes.data()) != kMagic) fail("bad magic");
  if (get_u32(bytes.data() + 4) != 1) fail("unsupported version " + std::to_string(get_u32(bytes.data() + 4)));
  if (get_u32(bytes.data() + 8) != std::uint32_t(grid.cols()) || get_u32(bytes.data() + 12) != std::uint32_t(grid.rows()))
    fail("block grid " + std::to_string(get_u32(bytes.data() + 8)) + " x " + std::to_string(get_u32(bytes.data() + 12)) +
         " does not match the database's " + std::to_string(grid.cols()) + " x " + std::to_string(grid.rows()));
  if (bytes.size() != expect) fail("size " + std::to_string(bytes.size()) + " bytes, expected " + std::to_string(expect));
  if (crc(bytes.data(), bytes.size() - 4) != get_u32(bytes.data() + bytes.size() - 4)) fail("checksum mismatch");
  std::vector<BlockSummary> out(grid.block_count());
  const std::uint8_t* p = bytes.data() + 16;
  for (BlockSummary& b : out) {
    b.z00 = get_f64(p);
    b.z10 = get_f64(p + 8);
    b.z01 = get_f64(p + 16);
    b.z11 = get_f64(p + 24);
    b.zmin = get_f64(p + 32);
    b.zmax = get_f64(p + 40);
    b.tm_error = get_f64(p + 48);
    b.base_is_tm = p[56] != 0;
    if (!(b.zmin <= b.zmax) || !(b.tm_error >= 0) || !std::isfinite(b.zmax - b.zmin + b.tm_error + b.z00 + b.z10 + b.z01 + b.z11))
      fail("block record " + std::to_string((p - bytes.data() - 16) / kRecord) + " is inconsistent");
    p += kRecord;
  }
  return out;
}

double tm_height(const BlockGrid& grid, BlockKey k, const BlockSummary& s, double col, double row) {
  const SampleRect d = grid.domain(k);
  const double u = (col - d.col0) / (d.col1 - d.col0), v = (row - d.row0) / (d.row1 - d.row0);
  // Lower triangle (0,0),(1,0),(1,1) where u >= v; upper (0,0),(1,1),(0,1) otherwise.
  if (u >= v) return s.z00 + u * (s.z10 - s.z00) + v * (s.z11 - s.z10);
  return s.z00 + v * (s.z01 - s.z00) + u * (s.z11 - s.z01);
}

pm::Box block_box(const BlockGrid& grid, BlockKey k, const BlockSummary& s) {
  const SampleRect d = grid.domain(k);
  pm::Box b{{1e300, 1e300, s.zmin}, {-1e300, -1e300, s.zmax}};
  for (auto [c, r] : {std::pair{d.col0, d.row0}, {d.col1, d.row0}, {d.col0, d.row1}, {d.col1, d.row1}}) {
    const pm::Vec3 p = grid.world(c, r, 0);
    b.lo.x = std::min(b.lo.x, p.x);
    b.lo.y = std::min(b.lo.y, p.y);
    b.hi.x = std::max(b.hi.x, p.x);
    b.hi.y = std::max(b.hi.y, p.y);
  }
  return b;
}

bool ActiveRegion::is_inner(BlockKey k) const { return std::binary_search(inner.begin(), inner.end(), k); }
bool ActiveRegion::is_active(BlockKey k) const { return k.col >= col0 && k.col <= col1 && k.row >= row0 && k.row <= row1; }

int inner_radius(double height_m, double block_extent_m, const ActiveRegionOptions& opt) {
  assert(opt.theta_deg > 0 && opt.theta_deg < 90 && opt.n_min >= 0 && opt.n_min <= opt.n_max && block_extent_m > 0);
  const double b = std::max(height_m, 0.0) / std::tan(opt.theta_deg * M_PI / 180.0);
  // 1e-9 absorbs the rounding of cot (cot 45 deg is not exactly 1 in doubles).
  const double n = std::ceil(b / block_extent_m - 1e-9);
  if (!(n < opt.n_max)) return opt.n_max;  // also NaN
  return std::max(opt.n_min, int(n));
}

ActiveRegion active_region(const BlockGrid& grid, std::span<const BlockSummary> summaries, const pm::Vec3& eye,
                           const ActiveRegionOptions& opt) {
  assert(summaries.size() == grid.block_count() && opt.p >= 0);
  ActiveRegion r;
  r.centre = grid.block_at(eye.x, eye.y);
  const SampleRect d = grid.domain(r.centre);
  auto [col, row] = grid.to_grid(eye.x, eye.y);
  col = std::clamp(col, double(d.col0), double(d.col1));
  row = std::clamp(row, double(d.row0), double(d.row1));
  const double ground = tm_height(grid, r.centre, summaries[grid.index(r.centre)], col, row);
  r.height_m = std::max(0.0, eye.z - ground);
  r.visible_m = r.height_m / std::tan(opt.theta_deg * M_PI / 180.0);
  r.n = inner_radius(r.height_m, grid.block_extent_m(), opt);
  r.p = opt.p;
  const int reach = r.n + r.p;
  r.col0 = std::max(0, r.centre.col - reach);
  r.col1 = std::min(grid.cols() - 1, r.centre.col + reach);
  r.row0 = std::max(0, r.centre.row - reach);
  r.row1 = std::min(grid.rows() - 1, r.centre.row + reach);
  for (int c = r.col0; c <= r.col1; ++c)
    for (int w = r.row0; w <= r.row1; ++w) {
      const bool inner = std::abs(c - r.centre.col) <= r.n && std::abs(w - r.centre.row) <= r.n;
      (inner ? r.inner : r.outer).push_back({c, w});
    }
  // (col, row) loops produce BlockKey order already (operator<=> compares col, then row).
  return r;
}

}  // namespace terralod::blocks
