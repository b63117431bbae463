// Active region of dynamic block loading: the block grid of a blocked terrain, the small
// per-block summaries that stand in for blocks that are not loaded, and the
// (2(n+p)+1) x (2(n+p)+1) set of active blocks around the block under the viewpoint.
//
// Usage:
//   terralod::blocks::BlockGrid grid(db.info().grid_width, db.info().grid_height,
//                                    db.info().block_size, db.info().transform);
//   std::vector<terralod::blocks::BlockSummary> summaries = read_block_summaries(db, grid);
//   terralod::blocks::ActiveRegionOptions opt;                 // theta 20 deg, p = 1
//   terralod::blocks::ActiveRegion r = terralod::blocks::active_region(grid, summaries, eye, opt);
//   for (BlockKey k : r.inner) { /* view-dependent PM */ }
//   for (BlockKey k : r.outer) { /* stand-in: summaries[grid.index(k)].points / triangles */ }
//
// Paper: seeds/view-dependent-pm-dynamic-loading.txt, section 4.1 (centre block, the inner
// (2n+1)^2 blocks as view-dependent PMs, the outer p rings as two-triangle meshes) and 4.2,
// Eq. 2: b = a cot(theta). Here a is the height of the eye above the centre block's
// two-triangle surface under it (>= 0), b the farthest visible ground distance, and
//     n = clamp(ceil(b / L), n_min, n_max),   L = (block_size - 1) * min(dx, dy)
// (L: the ground extent of a block side): the eye lies in the centre block, so every ground
// point within b of it lies in the inner (2n+1)^2 blocks.
//
// Block layout: the terrain has grid_width x grid_height samples; block (col,row) covers the
// samples col0 = col (B-1) .. min(col0 + B - 1, grid_width - 1) and likewise for rows
// (B = block_size = 2^k + 1); neighbouring blocks share their border samples; the last
// column/row of blocks may be narrower. BlockGrid::cols() = ceil((grid_width - 1) / (B - 1)).
//
// Block summaries ("block_summaries" blob of the block database, format below): for each
// block its four corner heights (fixed samples of every PM of the block), the exact L-infinity
// error of its two-triangle mesh (split along (col0,row0)-(col1,row1), the grid's diagonal
// direction), its height range, whether the PM's base mesh is exactly those two triangles, and
// its stand-in surface: a small surface over the block's domain made by one node strategy of
// tree_builder.hpp (greedy TIN, regular grid, non-regular grid) or the two triangles, whose
// points are block samples at their true heights, with its exact L-infinity error
// (pm::LInfError with the database's metric). They let a block that is not resident be drawn
// as its stand-in with an honest error bound, without reading it. summarize_block() computes
// one from a block's PM.
//
// Contract: grid sizes >= 2, block_size >= 3 (else std::invalid_argument); a transform with a
// non-zero determinant. Memory: 150 bytes per block summary plus 16 bytes per stand-in point
// and 20 per stand-in triangle (about 3.6 KB per block at 64 TIN points); active_region
// allocates the key lists only.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/sample_rect.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/linf_error.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "terralod/pm/view.hpp"

namespace terralod::blocks {

/// Geometry of the block partition of a terrain grid (see the header comment).
class BlockGrid {
 public:
  BlockGrid() = default;
  BlockGrid(int grid_width, int grid_height, int block_size, const pm::GridTransform& transform);
  /// From a block database's metadata (std::invalid_argument when it is not blocked).
  static BlockGrid from_info(const DatabaseInfo& info);

  int grid_width() const { return w_; }
  int grid_height() const { return h_; }
  int block_size() const { return b_; }
  const pm::GridTransform& transform() const { return t_; }
  int cols() const { return cols_; }  ///< blocks per row
  int rows() const { return rows_; }  ///< block rows
  std::size_t block_count() const { return std::size_t(cols_) * rows_; }
  bool contains(BlockKey k) const { return k.col >= 0 && k.row >= 0 && k.col < cols_ && k.row < rows_; }
  /// Dense index row * cols + col of a block inside the grid.
  std::size_t index(BlockKey k) const { return std::size_t(k.row) * cols_ + k.col; }
  BlockKey key(std::size_t index) const { return {int(index % cols_), int(index / cols_)}; }
  /// Samples of block k (inclusive, terrain grid indices).
  SampleRect domain(BlockKey k) const;
  /// Ground extent of a block side, metres: (block_size - 1) * min(dx, dy).
  double block_extent_m() const;
  /// Grid (col,row) of a world point (x,y) (the inverse of the transform; may be outside).
  std::pair<double, double> to_grid(double x, double y) const;
  /// Block containing the grid point of world (x,y), clamped to the grid (the nearest block
  /// when the point is outside the terrain).
  BlockKey block_at(double x, double y) const;
  /// World position of terrain sample (col,row) at height z: the one expression every block
  /// uses, so a sample shared by blocks gets bit-identical coordinates.
  pm::Vec3 world(int col, int row, double z) const;

 private:
  int w_ = 0, h_ = 0, b_ = 0, cols_ = 0, rows_ = 0;
  pm::GridTransform t_;
};

/// Surface of a block's stand-in: the node strategies of tree_builder.hpp, or two triangles.
enum class StandinKind : std::uint8_t { TwoTriangles = 0, Grid = 1, Tin = 2, NonRegularGrid = 3 };
/// "two-triangle", "grid", "tin", "nonregular"; parse throws std::invalid_argument otherwise.
const char* standin_kind_name(StandinKind k);
StandinKind parse_standin_kind(const std::string& name);

/// How stand-ins are made. The default kind has the smallest error x bytes (blob v2 bytes) on
/// N44W072 in 257-sample blocks among TIN, grid and non-regular grid at 16, 32 and 64 points;
/// the size trades the flight's bound against bytes (tables in tree_builder.hpp,
/// DatabaseBuildOptions::standin).
struct StandinOptions {
  StandinKind kind = StandinKind::Tin;
  /// At most this many points, >= 4. Tin: greedy insertion of the sample of largest error
  /// (make_tin_strategy); NonRegularGrid: rows x cols <= max_points (make_nonregular_strategy);
  /// Grid: the largest (P+1)^2 <= max_points evenly spaced samples (make_grid_strategy(P));
  /// TwoTriangles: ignored (the 4 corners).
  std::size_t max_points = 64;
  pm::ErrorMetric metric = pm::ErrorMetric::Continuous;  ///< of standin_error
};

/// A stand-in point: block-local sample (col - col0, row - row0) and its true height, metres.
struct StandinPoint {
  int col = 0, row = 0;
  double z = 0;
  bool operator==(const StandinPoint&) const = default;
};

/// What a non-resident block needs: its stand-in surface and its error (see above).
struct BlockSummary {
  /// Heights of the corners (col0,row0), (col1,row0), (col0,row1), (col1,row1), metres.
  double z00 = 0, z10 = 0, z01 = 0, z11 = 0;
  double zmin = 0, zmax = 0;  ///< height range of the block's samples
  double tm_error = 0;        ///< exact L-infinity error of the two-triangle mesh (continuous), metres
  bool base_is_tm = false;    ///< the PM's base mesh is exactly the two-triangle mesh
  StandinKind standin = StandinKind::TwoTriangles;
  double standin_error = 0;  ///< exact L-infinity error of the stand-in surface, metres
  /// The stand-in surface: points include the 4 corners; triangles index points, are CCW in
  /// (col,row) and cover the block's domain exactly once. Empty in a summary filled by hand
  /// (set_two_triangle_standin gives it the two triangles of its corners with tm_error).
  std::vector<StandinPoint> points;
  std::vector<std::array<std::uint32_t, 3>> triangles;
  /// Per triangle: its exact error (same metric) rounded up to the next float, metres; the
  /// runtime bounds each triangle in its own box with it (standin_bound_px). Two-triangle stand-ins decoded
  /// from a version 1 blob have tm_error for both.
  std::vector<double> triangle_errors;
  /// The block has no valid sample (all holes): no stand-in (points and triangles empty), the
  /// other fields 0; nothing is drawn there.
  bool empty = false;
  bool operator==(const BlockSummary&) const = default;
};

/// Summary of block `k` from its PM (whose heightfield is the block's samples), with a stand-in
/// made by `standin`. With holes (mask 0) the stand-in still covers the block's rectangle, but
/// zmin..zmax (widened to the stand-in's points), tm_error and the stand-in's errors are those
/// of the existing samples only; a block without any valid sample gets an `empty` summary. Cost: the
/// strategy's build (a greedy TIN of s points over a 257^2 block: a few milliseconds) plus one exact error
/// measure.
BlockSummary summarize_block(const pm::ProgressiveMesh& pm, BlockKey k, const StandinOptions& standin = {});

/// Replaces s's stand-in by the two triangles of its corners (error tm_error for both) over a
/// block of width x height samples.
void set_two_triangle_standin(BlockSummary& s, int width, int height);

/// The "block_summaries" blob, format version 2 (documented byte by byte beside
/// encode_block_summaries in active_region.cpp; version 1, two-triangle summaries only, is still
/// decoded: its blocks get two-triangle stand-ins). Stand-in coordinates need block_size <=
/// 65537 (std::invalid_argument otherwise).
inline constexpr std::uint32_t kBlockSummariesVersion = 2;
inline constexpr std::uint32_t kBlockSummariesMagic = 0x53424C54u;  ///< "TLBS" in memory
std::vector<std::uint8_t> encode_block_summaries(const BlockGrid& grid, std::span<const BlockSummary> s);
/// One block's record of the blob (about 1.6 kB for a 64-point TIN stand-in, half a BlockSummary
/// in memory) and back; decoding checks it as decode_block_summaries does (DatabaseError).
std::vector<std::uint8_t> encode_block_summary_record(const BlockSummary& s);
BlockSummary decode_block_summary_record(const BlockGrid& grid, std::size_t index,
                                         std::span<const std::uint8_t> record,
                                         const std::string& name_for_errors);
/// A version 2 record's fixed header; an empty (all-void) block's record is only this.
inline constexpr std::size_t kBlockSummaryRecordHeader = 40;
/// Bytes of the version 2 record that starts with these header bytes (its stand-in's size
/// follows from n and m), or 0 when the header is not one decode_block_summary_record accepts.
/// Lets a reader find record boundaries without decoding (the runtime's summary store).
std::size_t block_summary_record_bytes(std::span<const std::uint8_t, kBlockSummaryRecordHeader> header);
/// Offset of the first record in the blob (after its 16-byte header).
inline constexpr std::size_t kBlockSummariesHeader = 16;
/// The blob's version (1 or 2) from its first bytes `head` (at least kBlockSummariesHeader) and
/// its size: DatabaseError("<name>: block_summaries: <problem>") when it is truncated, has a bad
/// magic or version, another block grid than `grid`, or a size that cannot hold the grid's
/// records (checked before a reader allocates anything per block). decode_block_summaries checks
/// the same.
std::uint32_t check_block_summaries_header(const BlockGrid& grid, std::span<const std::uint8_t> head,
                                           std::uint64_t blob_size, const std::string& name_for_errors);
/// The blob, written piece by piece through write(): the header, record(i) for every block in
/// BlockGrid::index order, the CRC. Its size is kBlockSummariesFraming plus the records'. A build
/// stores each block's record as the block is built and streams them into the database at the
/// end (BlockDatabase::put_blob_in_pieces), so it never holds the blob.
inline constexpr std::size_t kBlockSummariesFraming = kBlockSummariesHeader + 4;
void join_block_summary_records(const BlockGrid& grid,
                                const std::function<std::vector<std::uint8_t>(std::size_t)>& record,
                                const std::function<void(std::span<const std::uint8_t>)>& write);
/// Throws DatabaseError("<name>: block_summaries: <problem>") on any mismatch or corruption.
std::vector<BlockSummary> decode_block_summaries(const BlockGrid& grid, std::span<const std::uint8_t> bytes,
                                                 const std::string& name_for_errors);
/// decode_block_summaries one block at a time: visit(index, summary) in index order, holding one
/// summary at once. Throws as decode_block_summaries does, after visiting the records before
/// the problem (the CRC is checked before any visit).
void for_each_block_summary(const BlockGrid& grid, std::span<const std::uint8_t> bytes,
                            const std::string& name_for_errors,
                            const std::function<void(std::size_t, BlockSummary&&)>& visit);
/// Name of the blob in the block database.
inline constexpr const char* kBlockSummariesBlob = "block_summaries";

/// The block summaries of a database: its "block_summaries" blob when present (and matching
/// the grid; a version 1 blob gives two-triangle stand-ins), otherwise computed by reading every
/// block once (progress in [0, 1] if given) with stand-ins made by `standin`'s kind and
/// max_points and each block PM's own metric (standin.metric is not used). Throws DatabaseError /
/// pm::PmFormatError naming the file and the problem. Defined in block_source_db.cpp.
std::vector<BlockSummary> read_block_summaries(const BlockDatabase& db, const BlockGrid& grid,
                                               const std::function<void(double)>& progress = {},
                                               const StandinOptions& standin = {});

/// The two-triangle surface of a block at grid point (col,row) inside its domain.
double tm_height(const BlockGrid& grid, BlockKey k, const BlockSummary& s, double col, double row);
/// The stand-in surface of s at block-local point (col,row) inside the block's domain (the
/// first triangle containing it; s must have a surface).
double standin_height(const BlockSummary& s, double col, double row);
/// The guaranteed screen-space error of block k drawn as its stand-in, pixels: the max over
/// its triangles T whose box is not outside the view of View::vertical_error_px(box_T, e_T),
/// box_T = T's plan rectangle x [min corner z - e_T, max corner z + e_T] (it holds the
/// stand-in and the terrain over T, which lies within e_T of it); 0 when all are culled.
double standin_bound_px(const BlockGrid& grid, BlockKey k, const BlockSummary& s, const pm::View& view);
/// World box of block k: its plan rectangle x [zmin, zmax].
pm::Box block_box(const BlockGrid& grid, BlockKey k, const BlockSummary& s);

struct ActiveRegionOptions {
  double theta_deg = 20.0;  ///< minimum visible angle of Eq. 2, degrees, in (0, 90)
  int p = 1;                ///< rings of two-triangle blocks around the inner blocks, >= 0
  int n_min = 1;            ///< inner radius range, 0 <= n_min <= n_max
  int n_max = 8;
};

struct ActiveRegion {
  BlockKey centre;
  int n = 0, p = 0;
  double height_m = 0;          ///< a: eye height above the centre block's two-triangle surface
  double visible_m = 0;         ///< b = a cot(theta)
  std::vector<BlockKey> inner;  ///< the (2n+1)^2 blocks (clipped to the grid), sorted
  std::vector<BlockKey> outer;  ///< the p rings around them (clipped to the grid), sorted
  /// Inclusive block range of the whole region (clipped to the grid).
  int col0 = 0, row0 = 0, col1 = 0, row1 = 0;
  bool is_inner(BlockKey k) const;
  bool is_active(BlockKey k) const;
};

/// n from the eye height a (metres, >= 0) by Eq. 2 (see the header comment).
int inner_radius(double height_m, double block_extent_m, const ActiveRegionOptions& opt);

/// The active region for an eye position (world metres). `summaries` has grid.block_count()
/// entries (BlockGrid::index order).
ActiveRegion active_region(const BlockGrid& grid, std::span<const BlockSummary> summaries,
                           const pm::Vec3& eye, const ActiveRegionOptions& opt = {});

}  // namespace terralod::blocks
