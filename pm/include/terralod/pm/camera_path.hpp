// Camera paths: the PATH.csv files of scripted flights (one camera pose per frame), read and
// written by `terralod fly`, `terralod-fly --headless` and the benchmarks.
//
// Usage:
//   std::vector<terralod::pm::Camera> path = terralod::pm::read_camera_path("flight.csv", 1280, 720);
//   terralod::pm::write_camera_path(path, "copy.csv");
//
// Format (text, UTF-8 or ASCII): a header line `x,y,z,yaw,pitch,fovy` (exactly these names in
// this order, spaces around names allowed), then one row per frame with six decimal numbers,
// frames 1/60 s apart. Conventions are those of `terralod view` (view.hpp): x east, y north,
// z up, metres in the world frame of the terrain; yaw in degrees clockwise from north; pitch in
// degrees above the horizon, in [-90, 90]; fovy the vertical field of view in degrees, in
// (0, 180). Empty lines and lines starting with '#' are skipped; a trailing '\r' and a UTF-8 byte
// order mark at the start (Excel's "CSV UTF-8") are ignored.
//
// Contract:
//   - read_camera_path returns at least one pose; width/height (>= 1) and near/far (0 < near <
//     far) are applied to every pose. Every other problem — a missing or unreadable file, a
//     wrong header, a row without six fields, a field that is not a finite number, a pitch or
//     fovy out of range, a file of more than max_rows rows — throws std::runtime_error
//     "<path>: line N: <what>" and nothing is returned. Never crashes on arbitrary bytes.
//   - parse_camera_path does the same on text in memory (name is used in messages).
//   - write_camera_path writes the header and one row per pose with the shortest decimal
//     that reads back to the same double, to path + ".tmp", renamed onto path; on failure
//     nothing is left at path and std::runtime_error names the file.
//   - Memory: the file's text plus 80 bytes per pose.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "terralod/pm/view.hpp"

namespace terralod::pm {

struct CameraPathOptions {
  int width_px = 1280, height_px = 720;  ///< viewport of every pose, >= 1
  double near_m = 1.0, far_m = 1.0e6;    ///< clip depths of every pose, 0 < near < far
  std::size_t max_rows = 10'000'000;     ///< refuse longer files (a guard against junk)
};

std::vector<Camera> read_camera_path(const std::string& path, const CameraPathOptions& options = {});
std::vector<Camera> parse_camera_path(std::string_view text, const std::string& name,
                                      const CameraPathOptions& options = {});
void write_camera_path(const std::vector<Camera>& path, const std::string& file);

}  // namespace terralod::pm
