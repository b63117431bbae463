// libFuzzer target for the "block_summaries" blob decoder (active_region.hpp,
// decode_block_summaries, format versions 1 and 2): on arbitrary bytes it must either throw
// DatabaseError whose message starts with the name given, or give summaries that keep the
// contract of BlockSummary; a decoded version 2 blob must re-encode to the same bytes.
//
// Input layout:
//   byte 0    grid selector: bits 0-2 = k, block_size B = 2^(k+1) + 1 (3, 5, 9, ..., 257);
//             bit 7 set = decode with the fixed grid (9 x 5 samples, B = 5: 2 x 1 blocks)
//             whatever the header says; bits 3-6 ignored.
//   byte 1    narrow last blocks: the last column of blocks is 2 + (low nibble mod (B-1))
//             samples wide, the last row 2 + (high nibble mod (B-1)) samples high.
//   byte 2..  the blob. Its header (u32 magic, version, cols, rows) picks the grid: cols x rows
//             blocks of B samples with the narrow last ones above, so that the records are
//             reached; when cols or rows is 0 or the grid's samples do not fit an int, the
//             fixed grid is used (the decoder must then reject the mismatch).
// Inputs shorter than 2 bytes are decoded as a blob with the fixed grid.
//
// Every blob is decoded twice: as given (magic, version, grid and checksum checks) and with
// its CRC-32 trailer patched to be right, so that mutations reach the block records.
// Invariants of a decoded result: one summary per block; stand-in points inside the block
// (0 <= col < the block's width <= B, likewise rows) at heights in [zmin, zmax]; the 4 block
// corners among them, at heights z00, z10, z01, z11; at least one triangle, indices < points;
// one error per triangle, every error finite and >= 0, their max >= standin_error; every
// number finite; zmin <= zmax.
// Bounded work: the decoder checks every count against the bytes left, so one run costs
// O(input size) besides the summaries of the grid's blocks.
#include <zlib.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdint>
#include <exception>
#include <span>
#include <string>
#include <vector>

#include "fuzz_support.hpp"
#include "terralod/blocks/active_region.hpp"
#include "terralod/blocks/block_database.hpp"

namespace {

namespace tb = terralod::blocks;

constexpr const char* kName = "fuzz.db";

[[noreturn]] void finding(const std::string& what) { terralod::fuzz::finding("fuzz_block_summaries", what); }

std::uint32_t u32_at(std::span<const std::uint8_t> b, std::size_t off) {
  return std::uint32_t(b[off]) | std::uint32_t(b[off + 1]) << 8 | std::uint32_t(b[off + 2]) << 16 |
         std::uint32_t(b[off + 3]) << 24;
}

tb::BlockGrid fixed_grid() { return tb::BlockGrid(9, 5, 5, terralod::pm::GridTransform::identity()); }

/// The grid the input selects (see the header comment).
tb::BlockGrid grid_for(std::uint8_t selector, std::uint8_t narrow, std::span<const std::uint8_t> blob) {
  if ((selector & 0x80) || blob.size() < 16) return fixed_grid();
  const std::int64_t b = (std::int64_t(1) << ((selector & 7) + 1)) + 1;
  const std::int64_t cols = u32_at(blob, 8), rows = u32_at(blob, 12);
  if (cols < 1 || rows < 1) return fixed_grid();
  const std::int64_t w = (cols - 1) * (b - 1) + 2 + (narrow & 15) % (b - 1);
  const std::int64_t h = (rows - 1) * (b - 1) + 2 + (narrow >> 4) % (b - 1);
  if (w > INT_MAX || h > INT_MAX) return fixed_grid();
  return tb::BlockGrid(int(w), int(h), int(b), terralod::pm::GridTransform::identity());
}

void check_summary(const tb::BlockGrid& grid, std::size_t i, const tb::BlockSummary& s) {
  const std::string at = "block " + std::to_string(i) + ": ";
  const tb::SampleRect d = grid.domain(grid.key(i));
  const int w = d.width(), h = d.height();
  for (double v : {s.z00, s.z10, s.z01, s.z11, s.zmin, s.zmax, s.tm_error, s.standin_error})
    if (!std::isfinite(v)) finding(at + "a non-finite number");
  if (!(s.zmin <= s.zmax)) finding(at + "zmin > zmax");
  if (!(s.tm_error >= 0) || !(s.standin_error >= 0)) finding(at + "a negative error");
  if (s.points.size() < 4) finding(at + "fewer than 4 stand-in points");
  if (w > grid.block_size() || h > grid.block_size()) finding(at + "domain wider than the block size");
  unsigned corners = 0;
  for (const tb::StandinPoint& p : s.points) {
    if (p.col < 0 || p.row < 0 || p.col >= w || p.row >= h) finding(at + "stand-in point outside the block");
    if (!std::isfinite(p.z) || p.z < s.zmin || p.z > s.zmax)
      finding(at + "stand-in point height outside [zmin, zmax]");
    const double corner_z[4] = {s.z00, s.z10, s.z01, s.z11};
    for (int c = 0; c < 4; ++c)
      if (p.col == (c & 1 ? w - 1 : 0) && p.row == (c & 2 ? h - 1 : 0) && p.z == corner_z[c])
        corners |= 1u << c;
  }
  if (corners != 15) finding(at + "a block corner (at its corner height) is not among the stand-in points");
  if (s.triangles.empty()) finding(at + "a stand-in without triangles");
  for (const auto& t : s.triangles)
    for (std::uint32_t v : t)
      if (v >= s.points.size()) finding(at + "stand-in triangle index out of range");
  if (s.triangle_errors.size() != s.triangles.size())
    finding(at + "triangle_errors.size() != triangles.size()");
  double emax = 0;
  for (double e : s.triangle_errors) {
    if (!std::isfinite(e) || !(e >= 0)) finding(at + "a non-finite or negative triangle error");
    emax = std::max(emax, e);
  }
  if (emax < s.standin_error) finding(at + "triangle errors below the stand-in's error");
}

void check(const tb::BlockGrid& grid, std::span<const std::uint8_t> blob) {
  std::vector<tb::BlockSummary> out;
  try {
    out = tb::decode_block_summaries(grid, blob, kName);
  } catch (const tb::DatabaseError& e) {
    if (std::string(e.what()).rfind(std::string(kName) + ": block_summaries: ", 0) != 0)
      finding(std::string("DatabaseError not naming the blob: ") + e.what());
    return;
  } catch (const std::exception& e) {
    finding(std::string("unexpected exception: ") + e.what());
  }
  if (out.size() != grid.block_count()) finding("not one summary per block");
  for (std::size_t i = 0; i < out.size(); ++i) check_summary(grid, i, out[i]);
  if (u32_at(blob, 4) == 2 &&
      tb::encode_block_summaries(grid, out) != std::vector<std::uint8_t>(blob.begin(), blob.end()))
    finding("decoded version 2 blob does not re-encode to the same bytes");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::uint8_t selector = 0x80, narrow = 0;
  std::span<const std::uint8_t> blob(data, size);
  if (size >= 2) {
    selector = data[0];
    narrow = data[1];
    blob = blob.subspan(2);
  }
  const tb::BlockGrid grid = grid_for(selector, narrow, blob);
  check(grid, blob);
  if (blob.size() >= 20) {
    std::vector<std::uint8_t> fixed(blob.begin(), blob.end());
    const std::size_t n = fixed.size();
    const auto crc = std::uint32_t(crc32(0L, fixed.data(), uInt(n - 4)));
    for (int i = 0; i < 4; ++i) fixed[n - 4 + std::size_t(i)] = std::uint8_t(crc >> (8 * i));
    check(grid, fixed);
  }
  return 0;
}
