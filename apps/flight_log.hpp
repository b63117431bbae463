// The per-frame statistics file of every flight tool: `terralod fly` and `terralod-fly
// --headless` write frames.csv through this one writer, with the same columns (the demo adds
// its drawing columns at the end), to a temporary renamed onto DIR/frames.csv only by commit():
// a flight that fails leaves no partial file.
//
// Usage:
//   terralod::cli::FlightLog log(out_dir, /*drawing=*/false);
//   for (...) log.row({frame, time_s, camera, runtime.stats()});
//   log.commit();
//
// Columns (each documented in the tools' --help): frame, time_s, x, y, z, yaw, pitch, fovy,
// tau_px, triangles, bound_px, missing_in_view, update_ms, update_cpu_ms, resident_bytes,
// blocks_resident, blocks_loading, blocks_evicted, nodes_resident, nodes_loading, nodes_evicted,
// prefetch_misses, bytes_read, nodes_visited, nodes_culled, coarse_nodes, pm_blocks,
// fallback_nodes, moving_vertices, clamped_vertices, seam_triangles; with drawing: vertices,
// draw_ms, upload_ms, wait_ms, texture_bytes, texture_patches, textures_from_parent.
#pragma once

#include <cstdio>
#include <string>

#include "terralod/blocks/terrain_runtime.hpp"
#include "terralod/pm/view.hpp"

namespace terralod::cli {

/// One frame of a flight.
struct FlightRow {
  std::size_t frame = 0;
  double time_s = 0;
  pm::Camera camera;
  blocks::RuntimeFrameStats stats;
  // Drawing columns (FlightLog with drawing only).
  std::size_t vertices = 0, texture_bytes = 0, texture_patches = 0, textures_from_parent = 0;
  double draw_ms = 0, upload_ms = 0, wait_ms = 0;
};

/// The column names, comma-separated, without a newline.
std::string flight_log_header(bool drawing);

class FlightLog {
 public:
  /// Opens DIR/frames.csv.tmp (the folder must exist); std::runtime_error naming the file.
  FlightLog(const std::string& dir, bool drawing);
  ~FlightLog();  ///< removes the temporary unless committed
  FlightLog(const FlightLog&) = delete;
  FlightLog& operator=(const FlightLog&) = delete;
  void row(const FlightRow& r);
  /// Closes and renames onto DIR/frames.csv; std::runtime_error naming the file on failure.
  void commit();
  const std::string& path() const { return path_; }

 private:
  std::string path_, tmp_;
  std::FILE* f_ = nullptr;
  bool drawing_ = false;
};

}  // namespace terralod::cli
