// Builds approximation trees (node strategies behind one interface) and whole block databases:
// partition, per-block PMs in parallel, the tree above them, all written crash-consistently and
// resumable.
//
// Usage:
//   namespace tb = terralod::blocks;
//   terralod::pm::Heightfield hf = tb::read_dem("N44W072.hgt");
//   tb::DatabaseBuildOptions opt;                  // 257-sample blocks, grid levels above PM blocks
//   opt.threads = 2;
//   tb::DatabaseSummary s = tb::build_database(hf, "terrain.db", opt);   // resumes if interrupted
//   std::puts(s.to_json().c_str());
//
//   // A tree on its own (no database): TIN nodes of at most 25 points down to 1 m.
//   tb::TreeBuildOptions t;
//   t.levels = {tb::StrategyChoice::Tin};
//   t.pm_leaves = false; t.leaf_error = 1.0;
//   tb::ApproximationTree tree = tb::build_tree(hf, tb::partition(hf.width(), hf.height(), 257), t);
//
// Node strategies: node_strategy.hpp.
// Splits: while a domain spans several blocks, children are aligned to block borders (the
// first part gets the largest power of two of blocks smaller than the count, so a 2^m-block
// tree is a classic quadtree/k-d tree); inside one block (pm_leaves = false) the domain is cut
// at its middle sample. With pm_leaves a domain of exactly one block is a PmBlock leaf; without,
// splitting stops when error <= leaf_error or the domain is a single cell.
// StrategyChoice::Auto builds the grid, TIN, non-regular and hybrid candidates for the node and keeps
// the one with the smallest error x bytes (bytes = encoded_node_bytes: "error per byte").
//
// Errors: every node's error is measured exactly with pm::LInfError over its own triangles
// (max over triangles), never estimated; bad data (a 1 x 1 grid, an all-void terrain, a file
// that exists with other parameters) throws std::invalid_argument / BuildError naming the file.
// Memory: the tree (see approximation_tree.hpp) plus, while building a database, one block
// heightfield and PM per worker thread (~250 bytes per block sample) and the encoded blocks
// waiting to be written; the tree's nodes each hold at most about 513^2 samples (their domain,
// or a lattice of it) and scan their exact error in 513^2-sample windows. Through a windowed
// DemSource (dem_source.hpp) nothing holds the whole DEM, so memory does not grow with its size
// beyond the per-block records (a stand-in summary and a tree node: a few KB a block).
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "terralod/blocks/active_region.hpp"
#include "terralod/blocks/approximation_tree.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/dem_source.hpp"
#include "terralod/blocks/node_strategy.hpp"
#include "terralod/blocks/partition.hpp"
#include "terralod/pm/heightfield.hpp"

namespace terralod::blocks {

enum class StrategyChoice : std::uint8_t { Grid, Tin, NonRegularGrid, Auto, Hybrid };
/// "grid", "tin", "nonregular", "auto", "hybrid"; parse throws std::invalid_argument for anything else.
const char* strategy_choice_name(StrategyChoice c);
StrategyChoice parse_strategy_choice(const std::string& name);

struct TreeBuildOptions {
  /// Strategy per level from the root; the last entry repeats for deeper levels. Not empty.
  std::vector<StrategyChoice> levels = {StrategyChoice::Grid};
  int patch = 4;                ///< P of grid nodes ((P+1)^2 points), >= 1
  std::size_t max_points = 25;  ///< s of TIN and non-regular nodes, >= 4
  bool pm_leaves = true;        ///< one PmBlock leaf per block (else strategy nodes inside blocks)
  double leaf_error = 0.0;      ///< pm_leaves = false: stop splitting at this error, metres >= 0
  pm::ErrorMetric metric = pm::ErrorMetric::Continuous;
  int threads = 1;  ///< nodes of one level built in parallel; 0 = hardware
};

/// Builds the tree over `layout` (which must match hf's size). With pm_leaves, block_errors[i]
/// is the PmBlock leaf error of layout.keys()[i] (base_mesh_error of its PM); otherwise it is
/// ignored. `progress` (optional) gets the fraction of the terrain's area finished per level.
ApproximationTree build_tree(const pm::Heightfield& hf, const BlockLayout& layout,
                             const TreeBuildOptions& options, std::span<const double> block_errors = {},
                             const std::function<void(double)>& progress = {});
/// The same over a DemSource read window by window: a node's strategy sees its domain whole
/// when it has at most 513^2 samples, else a lattice of about that many (every 2^k-th row and
/// column plus the last ones); every node's error and box are then measured exactly over all
/// the samples of its domain, streamed in 513^2-sample windows. No step holds the whole grid.
ApproximationTree build_tree(const DemSource& source, const BlockLayout& layout,
                             const TreeBuildOptions& options, std::span<const double> block_errors = {},
                             const std::function<void(double)>& progress = {});

/// A block as build_database writes it, made by build_block in any process (another rank,
/// another machine) or by the build's own threads: its PM encoded by pm::encode_pm, its record of
/// the block_summaries blob (encode_block_summary_record of its stand-in), and its build record
/// (the PM's base mesh error and full-resolution vertex count). The writer only writes it: it
/// never decodes a block it is given.
struct BuiltBlock {
  BlockKey key;
  std::vector<std::uint8_t> pm;
  std::vector<std::uint8_t> summary;
  double base_error = 0;
  std::uint64_t vertices = 0;
};

/// Builds blocks beside build_database's own threads, for instance on the other ranks of an MPI
/// job (apps/build_mpi.cpp). build_database runs it on a thread of its own once it knows the
/// blocks still to build; it calls claim() for the next block to build (nullopt when none is
/// left, or when the build is being stopped) and deliver() with every block built, on any of
/// its threads and in any order, and returns when every block it claimed has been delivered.
/// An exception it throws stops the build (BuildError's rules: the blocks written so far stay).
using RemoteBuilder = std::function<void(const std::function<std::optional<BlockKey>()>& claim,
                                         const std::function<void(BuiltBlock)>& deliver)>;

/// The build parameters as the JSON text stored in DatabaseInfo::build_parameters.
struct DatabaseBuildOptions {
  int block_size = 257;  ///< 2^k + 1
  int threads = 0;       ///< block builders in parallel; 0 = hardware concurrency
  pm::ErrorMetric metric = pm::ErrorMetric::Continuous;
  TreeBuildOptions tree;  ///< levels above the blocks (pm_leaves is forced on)
  /// Stand-in surface of every block (BlockSummary, written as the "block_summaries" blob with
  /// the tree; metric is forced to `metric`). Not part of the build parameters: a resumed
  /// build may change it. Default TIN of 64 points. Kind chosen on N44W072 (257-sample blocks,
  /// 25 blocks, continuous metric) by error x bytes, bytes = the blob v2 record:
  ///   kind        points  mean error m  max error m  bytes/block  error x bytes  ms/block
  ///   two-tri          4        673.5       1465.2           94          63310       0.4
  ///   grid            16        504.3        819.1          286         144239       0.2
  ///   grid        25 (32)       476.6        966.3          436         207793       0.3
  ///   grid            64        382.5        616.7         1102         421525       0.3
  ///   tin             16        406.1        630.2          304         123510       1.5
  ///   tin             32        322.4        534.3          586         188890       2.1
  ///   tin             64        237.0        387.8         1150         272597       3.5
  ///   nonregular  14.7 (16)     513.8        961.5          264         135733       0.9
  ///   nonregular  27.5 (32)     440.0        683.8          478         210416       1.4
  ///   nonregular  59.2 (64)     334.6        536.9         1019         340970       1.4
  /// TIN has the best error x bytes at every size. Size: the median guaranteed bound of
  /// 'terralod fly' at tau = 1 px, 1280x720, along a 60 s S-curve 700 m above the highest
  /// sample of N44W072 (the bench_fly path), two triangles -> TIN 32 / 64 / 128 points: 95.3 ->
  /// 46.2 / 27.6 / 19.9 px (grid 64: 40.2, non-regular 64: 38.0); 64 points, 1.2 KB a block,
  /// takes most of the gain.
  StandinOptions standin;
  /// Optional: fraction of the blocks done in [0,1] and an estimate of the seconds left
  /// (negative while unknown). Called from the writing thread.
  std::function<void(double fraction, double seconds_left)> progress;
  /// Testing aid: stop (throw BuildError) after writing this many blocks in this run; 0 = never.
  std::size_t stop_after_blocks = 0;
  /// Builders beside the local threads (see RemoteBuilder); the blocks they deliver are written
  /// exactly as the local ones, so the database is the same whoever built which block.
  std::vector<RemoteBuilder> remote_builders = {};
};

/// Block `key` of hf cut into opt.block_size blocks, exactly what build_database writes for it
/// (deterministic: any process on any machine makes the same bytes from the same samples and
/// options). BuildError when key is not a block of the layout.
BuiltBlock build_block(const pm::Heightfield& hf, BlockKey key, const DatabaseBuildOptions& opt);
BuiltBlock build_block(const DemSource& source, BlockKey key, const DatabaseBuildOptions& opt);

/// A build that cannot proceed: what() = "<file>: <problem>".
class BuildError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// What a database holds (build_database returns it; summarize_database reads it back).
/// Per block, meta "block/<col>,<row>" = "<base mesh error> <pm vertices> <bytes>" is written in
/// the block's own transaction; meta "build_seconds" and "build_complete" = "1" with the tree.
struct DatabaseSummary {
  std::string path, source;
  int grid_width = 0, grid_height = 0, block_size = 0, blocks_x = 0, blocks_y = 0;
  std::size_t blocks = 0;  ///< blocks in the database
  /// Built by this run (the others were resumed); nullopt from summarize_database, which reads
  /// a database and ran no build (to_json then leaves the field out).
  std::optional<std::size_t> blocks_built;
  std::size_t nodes = 0;  ///< tree nodes
  std::array<std::size_t, kStrategyCount> nodes_per_strategy{};
  int tree_depth = 0;
  std::uint64_t samples = 0;      ///< grid samples (unique vertices of the full terrain)
  std::uint64_t pm_vertices = 0;  ///< sum over blocks of their PM vertices (borders counted twice)
  std::uint64_t block_bytes = 0, tree_bytes = 0;
  std::uint64_t summaries_bytes = 0;  ///< the "block_summaries" blob (0 when absent)
  std::string standin;                ///< stand-in kind of the blob's first non-empty block ("" when absent)
  double mean_standin_error = 0;      ///< mean over non-empty blocks of the stand-in error, metres
  double mean_tm_error = 0;           ///< mean over non-empty blocks of the two-triangle error, metres
  double bytes_per_vertex = 0;        ///< (block_bytes + tree_bytes) / samples
  double max_block_error = 0;         ///< largest PmBlock leaf error (base meshes), metres
  double root_error = 0;              ///< exact error of the root surface, metres
  double seconds = 0;            ///< wall time of this run (summarize_database: of the run that completed it)
  std::string build_parameters;  ///< JSON
  /// Where the terrain lies on the Earth (absent for sources without a CRS, or databases built
  /// before it was recorded): to_json writes it as "georeference" with the frame convention.
  std::optional<Georeference> georeference;
  /// The world frame the terrain was built in (meta "frame": Heightfield::frame, how read_dem
  /// made it) and its worst scale error (meta "frame_scale_error", frame_scale_error; empty
  /// without a CRS); nullopt for databases built before they were recorded. to_json writes
  /// "frame" {description, scale_error, vertical_datum} or the string "not recorded (...)".
  std::optional<std::string> frame;
  std::optional<double> frame_scale_error;
  bool complete = false;
  /// One JSON object (the fields above).
  std::string to_json() const;
};

/// Builds (or resumes) the database at `path` for hf: creates it if absent; if it exists with
/// the same build parameters (and the same input samples, compared by CRC-32, and the same
/// PM builder revision, pm::ProgressiveMesh::kBuilderRevision), keeps its
/// blocks and builds only the missing ones; a database with other parameters -> BuildError
/// naming the file and the differing parameters. Blocks are built on `threads` threads and
/// each is written in its own transaction; the tree, the summary and "build_complete" = "1"
/// are written together last. hf must have >= 2 x 2 samples and at least one valid sample.
DatabaseSummary build_database(const pm::Heightfield& hf, const std::string& path,
                               const DatabaseBuildOptions& options);
/// The same read through `source` (dem_source.hpp): with a windowed source nothing holds the
/// whole DEM (blocks read their own windows; the tree reads as build_tree's DemSource overload
/// says). The database is the same whichever way the same samples are read... except that the
/// build parameters record source.samples_crc().
DatabaseSummary build_database(const DemSource& source, const std::string& path,
                               const DatabaseBuildOptions& options);

/// The summary of what a database holds (from its metadata, per-block records and tree); for
/// an unfinished build, what is there so far with complete = false. DatabaseError / TreeFormatError
/// for corrupt content.
DatabaseSummary summarize_database(const BlockDatabase& db);

/// Throws BuildError("<file>: the build is not complete (...)") unless build_database (or the
/// hybrid build) finished writing the database: every reader that needs all blocks and the tree
/// calls it before using them.
void require_complete_build(const BlockDatabase& db);

}  // namespace terralod::blocks
