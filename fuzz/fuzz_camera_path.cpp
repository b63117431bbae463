// libFuzzer target for the camera-path CSV reader: parse_camera_path on arbitrary bytes must
// either throw std::runtime_error naming the input and a line, or return poses that are all
// finite, in range, and survive a write/parse round trip bit for bit.
//
// Bounded work: inputs over 64 KiB are skipped (returning -1 keeps them out of the corpus).
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "fuzz_support.hpp"
#include "terralod/pm/camera_path.hpp"

namespace {

namespace pm = terralod::pm;

[[noreturn]] void finding(const std::string& what) { terralod::fuzz::finding("fuzz_camera_path", what); }
#define REQUIRE(cond)                                 \
  do {                                                \
    if (!(cond)) finding("invariant broken: " #cond); \
  } while (0)

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > 65536) return -1;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  std::vector<pm::Camera> path;
  try {
    path = pm::parse_camera_path(text, "fuzz.csv");
  } catch (const std::runtime_error& e) {
    REQUIRE(std::string_view(e.what()).substr(0, 15) == "fuzz.csv: line ");
    return 0;
  }
  REQUIRE(!path.empty());
  std::string again = "x,y,z,yaw,pitch,fovy\n";
  for (const pm::Camera& c : path) {
    REQUIRE(std::isfinite(c.x) && std::isfinite(c.y) && std::isfinite(c.z) && std::isfinite(c.yaw_deg));
    REQUIRE(c.pitch_deg >= -90.0 && c.pitch_deg <= 90.0);
    REQUIRE(c.fovy_deg > 0.0 && c.fovy_deg < 180.0);
    char buf[256];
    std::snprintf(buf, sizeof buf, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", c.x, c.y, c.z, c.yaw_deg,
                  c.pitch_deg, c.fovy_deg);
    again += buf;
  }
  const std::vector<pm::Camera> back = pm::parse_camera_path(again, "again.csv");
  REQUIRE(back.size() == path.size());
  for (std::size_t i = 0; i < path.size(); ++i)
    REQUIRE(back[i].x == path[i].x && back[i].y == path[i].y && back[i].z == path[i].z &&
            back[i].yaw_deg == path[i].yaw_deg && back[i].pitch_deg == path[i].pitch_deg &&
            back[i].fovy_deg == path[i].fovy_deg);
  return 0;
}
