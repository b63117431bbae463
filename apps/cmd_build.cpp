// terralod build: a DEM -> a block database (per-block PMs built in parallel, the approximation
// tree above them), resumable, with progress and a one-line-per-stage summary.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <thread>

#include "build_mpi.hpp"
#include "commands.hpp"
#include "dem_options.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/dem_source.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/timing.hpp"

namespace terralod::cli {

CommandSpec build_spec() {
  CommandSpec s;
  s.name = "build";
  s.summary = "Build a block database (block PMs + approximation tree) from a DEM; resumes if interrupted.";
  s.description =
      "The terrain is cut into square blocks of --block-size samples (2^k + 1) that share their\n"
      "border samples; every block becomes a progressive mesh (corners fixed, borders kept on the\n"
      "border), built in parallel and written in its own transaction. Then the approximation tree\n"
      "is built above the blocks: --strategy gives the node strategy per level from the root\n"
      "(comma-separated, the last one repeats): grid ((P+1)^2 points, quadtree), tin (greedy TIN of\n"
      "at most --max-points points, k-d tree), nonregular (non-regular grid, k-d tree), hybrid (the\n"
      "grid plus a TIN microstructure of at most --max-points points in the 2 x 2 cells where the\n"
      "grid is worst, joined by local convexification; quadtree) or auto (per node, the one with\n"
      "the smallest error x bytes). The leaves are the blocks' PMs. 'terralod fly' draws every kind.\n"
      "Every block also gets a stand-in, drawn by 'terralod fly' where the block is not refined\n"
      "(outer rings, blocks still loading): --standin tin (greedy TIN, default), grid, nonregular\n"
      "or two-triangle, of at most --standin-points samples (default 64) at their true heights,\n"
      "with its exact error; they are stored as the 'block_summaries' blob (format version 2).\n"
      "Running the same command again after an interruption resumes it; an existing database\n"
      "built with other options is an error. 'terralod info DB' prints the summary as JSON.\n"
      "Under MPI ('mpirun -np N terralod build ...', when terralod was built with MPI) every rank\n"
      "reads the input and builds blocks on --threads threads; rank 0 hands the blocks out, writes\n"
      "the database (only rank 0 touches it: no shared folder is needed beyond the input) and\n"
      "shows the progress. The database is the same as a single-process build's, byte for byte; a\n"
      "killed rank ends the job and the same command resumes it.\n"
      "Several inputs need not be alike: files in other CRSs are warped (bilinear) to the CRS that\n"
      "holds most samples, on its cells; mixed sample types are read as Float32 (or Float64); mixed\n"
      "spacings are read on the finest, the coarser resampled bilinearly; a file with an alpha band\n"
      "beside files without is read with the alpha as its voids; files whose nodata values differ\n"
      "keep their voids and heights (the mosaic's nodata is NaN); files in feet or of scaled\n"
      "integers (band unit, scale, offset) are read in metres. The first line says so.\n"
      "A folder gives its elevation files (its subfolders are then not searched; the first line\n"
      "counts them), or when it holds none, those of its subfolders at any depth (Copernicus\n"
      "DEM, DTED trees); an archive (.zip .tar .tar.gz .tgz), given or in the\n"
      "folder, gives those it holds, read in place (ASTER GDEM zips, Copernicus DEM tars); the\n"
      "quality layers beside the heights (ASTER's _num, Copernicus's AUXFILES) are left out; two\n"
      "files on the same cells are refused by name.\n"
      "Memory: every input is read window by window. GDAL rasters, VRT mosaics and .hgt tiles are\n"
      "read in place, in every frame (a warp to --crs auto or a named CRS reads the native window\n"
      "under each warped one); heightmap images and ASCII grids, which can only be read from their\n"
      "first row on, are decoded once to an unnamed file in TMPDIR (4 bytes a sample for 8- and\n"
      "16-bit and float images, 8 for others and for ASCII grids) and read from there. Each block\n"
      "reads its own samples, tree nodes read a lattice of at most 513 x 513 samples and measure\n"
      "their exact error in 513 x 513 windows, GDAL's cache is capped at 64 MiB, so memory does not\n"
      "grow with the samples, and by about 1 kB a block with the number of blocks (each block's\n"
      "stand-in record goes through the database into the block_summaries blob; measured in blocks\n"
      "of 33: 283 MB peak for 16,384 blocks, 337 MB for 65,536). Filling a void region takes about\n"
      "115 bytes a void sample while it is solved (regions within 4096 x 4096 samples are filled,\n"
      "wide ones one at a time); filled regions of 1,024 samples or more are kept, up to 256 MiB,\n"
      "for the other blocks that meet them (the 'voids' line counts what was solved and reused; a\n"
      "region of 2^20 samples or more, about a second to solve, is told on stderr before and after:\n"
      "'voids filling a region of N samples (input cols, rows)...'). The first line says how the\n"
      "input is read ('read window by window'); the last one gives the peak resident memory of the\n"
      "build.";
  s.options = {
      {"--input", "DEM",
       "elevation file (.hgt, .hgt.zip, .asc, GeoTIFF, VRT, PNG, ...); repeat it or name a folder or an "
       "archive: one mosaic",
       true, true},
      {"--out", "DB", "database file to create or resume (.db)", true},
      {"--block-size", "N", "samples per block side, 2^k + 1 (default 257)"},
      {"--threads", "N", "blocks built in parallel, 0 = all cores (default 0)"},
      {"--strategy", "LIST", "per level from the root: grid|tin|nonregular|hybrid|auto[,...] (default grid)"},
      {"--patch", "P", "grid nodes have (P+1)^2 points (default 4)"},
      {"--max-points", "S",
       "TIN and non-regular nodes (and hybrid microstructures) have at most S points (default 25)"},
      {"--metric", "NAME", "error metric: continuous (default) or samples"},
      {"--standin", "KIND", "block stand-in surface: tin (default), grid, nonregular or two-triangle"},
      {"--standin-points", "N", "stand-ins have at most N points, 4..4096 (default 64)"},
  };
  s.options = with_dem_options(std::move(s.options));
  return s;
}

int cmd_build(const Args& a) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::string out = a.get("--out");
  blocks::DatabaseBuildOptions opt;
  opt.block_size = int(a.get_int("--block-size", 257, 3, 1 << 20));
  if (!blocks::is_valid_block_size(opt.block_size))
    throw UsageError("option '--block-size' must be 2^k + 1 (3, 5, 9, ..., 257, ...), not '" +
                     a.get("--block-size") + "'");
  opt.threads = int(a.get_int("--threads", 0, 0, 1024));
  opt.tree.patch = int(a.get_int("--patch", 4, 1, 255));
  opt.tree.max_points = std::size_t(a.get_int("--max-points", 25, 4, 1 << 20));
  opt.metric = metric_from(a);
  opt.tree.levels.clear();
  {
    std::stringstream ss(a.get("--strategy", "grid"));
    for (std::string item; std::getline(ss, item, ',');) {
      try {
        opt.tree.levels.push_back(blocks::parse_strategy_choice(item));
      } catch (const std::invalid_argument& e) {
        throw UsageError(std::string("option '--strategy': ") + e.what());
      }
    }
    if (opt.tree.levels.empty()) throw UsageError("option '--strategy' needs at least one strategy");
  }
  opt.standin.kind = blocks::parse_standin_kind(
      a.get_choice("--standin", {"tin", "grid", "nonregular", "two-triangle"}, "tin"));
  opt.standin.max_points = std::size_t(a.get_int("--standin-points", 64, 4, 4096));
  blocks::DemOptions dem = dem_options_from(a);
  if (launched_rank() != 0) dem.on_large_void = {};  // under MPI every rank reads; rank 0 speaks

  const int ranks = launched_ranks();
  // The input stays open while the build reads its windows (a mosaic's VRT lives in `inputs`).
  std::optional<blocks::DemInputs> inputs;
  auto open = [&] {
    const auto t = std::chrono::steady_clock::now();
    inputs.emplace(a.get_all("--input"));
    // Opening reads samples to measure the frame, and fills the void regions they meet: on a
    // mosaic with wide gaps that takes seconds, so say what is going on.
    if (launched_rank() == 0) {
      std::fprintf(stderr, "read  %s: opening...\n", inputs->description().c_str());
      std::fflush(stderr);
    }
    std::unique_ptr<blocks::DemSource> src = blocks::open_dem_source(inputs->path(), dem);
    src->set_source(inputs->description());
    const blocks::DemGrid& g = src->grid();
    if (launched_rank() == 0) warn_about_frame(g);
    if (launched_rank() == 0)  // under MPI every rank reads; rank 0 speaks
      std::printf("read  %s: %d x %d samples, %s, %s\n", inputs->description().c_str(), g.width, g.height,
                  src->in_memory() ? "held in memory" : "read window by window",
                  format_duration(ms_since(t)).c_str());
    std::fflush(stdout);
    return src;
  };

  // Progress with an estimate of the time left: a redrawn line on a terminal, else every 10 %.
  const bool tty = isatty(fileno(stderr)) != 0;
  int last_decile = -1;
  auto last_draw = std::chrono::steady_clock::now() - std::chrono::seconds(1);
  opt.progress = [&](double f, double left) {
    const std::string eta = left < 0 ? std::string("estimating") : format_duration(left * 1000.0) + " left";
    if (tty) {
      const auto now = std::chrono::steady_clock::now();
      if (f < 1.0 && now - last_draw < std::chrono::milliseconds(100)) return;
      last_draw = now;
      const int filled = int(f * 40);
      std::fprintf(stderr, "\rblocks [%s%s] %5.1f%%, %s   ", std::string(std::size_t(filled), '#').c_str(),
                   std::string(std::size_t(40 - filled), '.').c_str(), f * 100.0, eta.c_str());
    } else {
      const int decile = int(f * 10.0 + 1e-9);
      if (decile <= last_decile) return;
      last_decile = decile;
      std::fprintf(stderr, "blocks: %d%%, %s\n", decile * 10, eta.c_str());
    }
    std::fflush(stderr);
  };
  const auto t = std::chrono::steady_clock::now();
  auto report = [&](const blocks::DatabaseSummary& s, int ranks_used, const blocks::DemSource& src) {
    if (tty) std::fputs("\r\033[K", stderr);
    const auto& n = s.nodes_per_strategy;
    std::printf("build %s: %zu blocks (%zu built now, %zu resumed) of %d x %d samples, %s%s\n", out.c_str(),
                s.blocks, *s.blocks_built, s.blocks - *s.blocks_built, s.block_size, s.block_size,
                format_duration(ms_since(t)).c_str(),
                ranks_used > 1 ? strf(", %d MPI ranks", ranks_used).c_str() : "");
    std::printf(
        "tree  %zu nodes, depth %d: grid %zu, tin %zu, nonregular %zu, hybrid %zu, pm_block %zu; root error "
        "%.2f m, largest block base error %.2f m\n",
        s.nodes, s.tree_depth, n[std::size_t(blocks::Strategy::Grid)], n[std::size_t(blocks::Strategy::Tin)],
        n[std::size_t(blocks::Strategy::NonRegularGrid)], n[std::size_t(blocks::Strategy::Hybrid)],
        n[std::size_t(blocks::Strategy::PmBlock)], s.root_error, s.max_block_error);
    const std::string standins = s.standin.empty() ? std::string("none (the blocks have voids)")
                                 : s.standin == "two-triangle"
                                     ? s.standin
                                     : strf("%s of <= %zu points", s.standin.c_str(), opt.standin.max_points);
    std::printf("stand-ins %s: mean error %.2f m (two triangles: %.2f m), %s of block summaries\n",
                standins.c_str(), s.mean_standin_error, s.mean_tm_error,
                format_bytes(s.summaries_bytes).c_str());
    std::printf(
        "size  %llu samples, %llu block PM vertices, %s of blocks + %s of tree = %.2f bytes/vertex, total "
        "%s\n",
        static_cast<unsigned long long>(s.samples), static_cast<unsigned long long>(s.pm_vertices),
        format_bytes(s.block_bytes).c_str(), format_bytes(s.tree_bytes).c_str(), s.bytes_per_vertex,
        format_duration(ms_since(t0)).c_str());
    // What filling voids cost this process (under MPI, rank 0's reads only).
    if (const auto v = src.void_fill_work(); v.solved + v.reused > 0)
      std::printf("voids %zu regions solved (%llu samples), %zu times a large filled region was reused%s\n",
                  v.solved, static_cast<unsigned long long>(v.solved_samples), v.reused,
                  ranks_used > 1 ? " (rank 0)" : "");
    // Peak resident set of this process over the whole command (under MPI: rank 0's, which also
    // writes the database); getrusage, so what the kernel counted, GDAL's block cache included.
    std::printf("memory peak resident %s%s\n", format_bytes(pm::peak_resident_bytes()).c_str(),
                ranks_used > 1 ? " (rank 0)" : "");
  };
  if (ranks > 1) {
#ifdef TERRALOD_HAVE_MPI
    return build_with_mpi(open, out, opt, report);
#else
    throw UsageError("started by mpirun with " + std::to_string(ranks) +
                     " ranks, but this terralod was built without MPI (install libopenmpi-dev and rebuild)");
#endif
  }
  const std::unique_ptr<blocks::DemSource> src = open();
  report(blocks::build_database(*src, out, opt), 1, *src);
  return 0;
}

}  // namespace terralod::cli
