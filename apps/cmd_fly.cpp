// terralod fly: the headless flight runner. Replays a camera path over a block database
// through the whole per-frame pipeline of blocks::TerrainSession (active region, background
// loading with prefetch, selective refinement, seams, geomorphs) without drawing, and writes
// per-frame statistics and, optionally, every frame's drawn mesh.
#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "commands.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/terrain_session.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/camera_path.hpp"
#include "terralod/pm/mesh_io.hpp"

namespace terralod::cli {

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

void say(const std::string& s) {
  std::fputs((s + "\n").c_str(), stdout);
  std::fflush(stdout);
}

struct PathRow {
  double x, y, z, yaw, pitch, fovy;
};

// The shared PATH.csv reader (pm/camera_path.hpp): same format and errors as every tool.
std::vector<PathRow> read_path(const std::string& path) {
  std::vector<PathRow> rows;
  for (const pm::Camera& c : pm::read_camera_path(path)) rows.push_back({c.x, c.y, c.z, c.yaw_deg, c.pitch_deg, c.fovy_deg});
  return rows;
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const std::size_t i = std::min(v.size() - 1, std::size_t(std::ceil(q * double(v.size()))) - (q > 0 ? 1 : 0));
  return v[i];
}

}  // namespace

CommandSpec fly_spec() {
  CommandSpec s;
  s.name = "fly";
  s.summary = "Replay a camera path over a block database headlessly; per-frame statistics as CSV.";
  s.description =
      "Runs the per-frame pipeline of dynamic block loading without drawing, one frame per row of\n"
      "--path (60 frames per second): the active region of (2(n+p)+1)^2 blocks around the block\n"
      "under the camera (n from the height: b = a cot(theta)), background loading with flight-path\n"
      "prefetch, view-dependent refinement of the inner blocks at --tau pixels, two-triangle outer\n"
      "rings, watertight seams, geomorphs. The frame never waits for the disk: a block that has\n"
      "not arrived is drawn as two triangles and morphs in when it does.\n\n"
      "PATH.csv: a header 'x,y,z,yaw,pitch,fovy', then one camera per frame in the conventions of\n"
      "'terralod view': world metres (x east, y north, z up), yaw degrees clockwise from north,\n"
      "pitch degrees above the horizon (-90..90), fovy the vertical field of view (0..180).\n\n"
      "Writes DIR/frames.csv (only once the whole flight succeeded: a flight stopped by an error,\n"
      "such as a corrupt block, leaves none): frame, time_s, x, y, z, yaw, pitch, fovy, tau_px,\n"
      "triangles, bound_px (the guaranteed screen-space error of everything drawn), update_ms, resident,\n"
      "loading, evicted, prefetch_misses (cumulative: blocks needed in view before they were\n"
      "resident), bytes_read (cumulative), then centre_col, centre_row, n, missing_in_view,\n"
      "stand_ins, morphing_blocks, seam_triangles, resident_bytes. --dump-meshes also writes each\n"
      "frame's drawn mesh as DIR/frame_NNNNN.ply (binary little-endian, double x y z in the world\n"
      "frame, int faces, counter-clockwise seen from above).\n\n"
      "--speed-factor K paces frame f to start no earlier than f / (60 K) seconds after the first\n"
      "(K = 1: real time, 2: twice as fast; 0: no pacing, as fast as the CPU goes). Loading runs in\n"
      "real time, so K decides how much time the loader gets per frame.";
  s.options = {
      {"--db", "FILE", "block database (from 'terralod build')", true},
      {"--path", "PATH.csv", "camera path, one row per frame at 60 fps", true},
      {"--out", "DIR", "output folder (created if missing)", true},
      {"--size", "WxH", "viewport in pixels (default 1280x720, each 1..16384)"},
      {"--tau", "PIXELS", "screen-space error tolerance, pixels (> 0, default 1)"},
      {"--dump-meshes", "", "also write every frame's drawn mesh as DIR/frame_NNNNN.ply"},
      {"--no-prefetch", "", "load only the blocks in the active region (no flight-path prediction)"},
      {"--speed-factor", "K", "replay speed relative to real time, >= 0 (default 1; 0 = unpaced)"},
      {"--morph", "SECONDS", "geomorph duration, >= 0 (default 0.5; 0 pops)"},
      {"--theta", "DEGREES", "minimum visible angle of b = a cot(theta), (0, 90) (default 20)"},
      {"--rings", "P", "rings of two-triangle blocks around the inner blocks (default 1)"},
      {"--budget", "MB", "resident block memory budget, megabytes (default 512)"},
      {"--skirts", "", "vertical skirts under the block borders instead of re-triangulated seams"},
      {"--merge-tolerance", "SAMPLES",
       "merge unmatched seam vertices fewer than this many samples apart, >= 0 (default 3; 0 = off)"},
  };
  return s;
}

int cmd_fly(const Args& a) {
  const auto t_start = Clock::now();
  const std::string db_path = a.get("--db"), path_csv = a.get("--path"), out = a.get("--out");
  int width = 1280, height = 720;
  if (a.has("--size")) {
    const std::string sz = a.get("--size");
    int consumed = 0;
    if (std::sscanf(sz.c_str(), "%dx%d%n", &width, &height, &consumed) != 2 || consumed != int(sz.size()) || width < 1 ||
        height < 1 || width > 16384 || height > 16384)
      throw UsageError("option '--size' needs WxH with each in 1..16384, not '" + sz + "'");
  }
  const double tau = a.get_double("--tau", 1.0);
  if (!(tau > 0)) throw UsageError("option '--tau' must be > 0 pixels, not '" + a.get("--tau") + "'");
  const double speed = a.get_double("--speed-factor", 1.0);
  if (!(speed >= 0)) throw UsageError("option '--speed-factor' must be >= 0, not '" + a.get("--speed-factor") + "'");
  const double morph = a.get_double("--morph", 0.5);
  if (!(morph >= 0)) throw UsageError("option '--morph' must be >= 0 seconds, not '" + a.get("--morph") + "'");
  const double theta = a.get_double("--theta", 20.0);
  if (!(theta > 0 && theta < 90)) throw UsageError("option '--theta' must be in (0, 90) degrees, not '" + a.get("--theta") + "'");
  const int rings = int(a.get_int("--rings", 1, 0, 64));
  const double budget_mb = a.get_double("--budget", 512.0);
  if (!(budget_mb > 0)) throw UsageError("option '--budget' must be > 0 megabytes, not '" + a.get("--budget") + "'");
  const bool dump = a.has("--dump-meshes");
  const double merge_tol = a.get_double("--merge-tolerance", blocks::SessionOptions{}.merge_tolerance_samples);
  if (!(merge_tol >= 0))
    throw UsageError("option '--merge-tolerance' must be >= 0 samples, not '" + a.get("--merge-tolerance") + "'");

  const std::vector<PathRow> path = read_path(path_csv);
  say(strf("read  %s: %zu frames (%.1f s at 60 fps)", path_csv.c_str(), path.size(), path.size() / 60.0));
  std::error_code ec;
  fs::create_directories(out, ec);
  if (!fs::is_directory(out)) throw std::runtime_error(out + ": cannot create the output folder");

  auto t = Clock::now();
  const blocks::BlockDatabase db = blocks::BlockDatabase::open(db_path);
  if (db.info().block_size <= 0)
    throw blocks::DatabaseError(db_path, "not a blocked database (kind '" + db.info().kind + "'): nothing to fly over");
  blocks::require_complete_build(db);
  const blocks::BlockGrid grid = blocks::BlockGrid::from_info(db.info());
  std::vector<blocks::BlockSummary> sums;
  {
    const bool stored = db.read_blob(blocks::kBlockSummariesBlob).has_value();
    ProgressBar bar(stored ? "summaries" : "summaries (reading every block once)");
    sums = blocks::read_block_summaries(db, grid, [&](double f) { bar.update(f); });
  }
  say(strf("open  %s: %d x %d samples, %d x %d blocks of %d, summaries in %s", db_path.c_str(), grid.grid_width(),
            grid.grid_height(), grid.cols(), grid.rows(), grid.block_size(), format_duration(ms_since(t)).c_str()));

  // Clip planes as in 'terralod view': near from the distance to the terrain's box, far beyond it.
  pm::Box box{{1e300, 1e300, 1e300}, {-1e300, -1e300, -1e300}};
  for (std::size_t i = 0; i < sums.size(); ++i) {
    const pm::Box b = blocks::block_box(grid, grid.key(i), sums[i]);
    box.lo = {std::min(box.lo.x, b.lo.x), std::min(box.lo.y, b.lo.y), std::min(box.lo.z, b.lo.z)};
    box.hi = {std::max(box.hi.x, b.hi.x), std::max(box.hi.y, b.hi.y), std::max(box.hi.z, b.hi.z)};
  }

  blocks::SessionOptions opt;
  opt.refinement.tolerance_px = tau;
  opt.refinement.morph_seconds = morph;
  opt.region.theta_deg = theta;
  opt.region.p = rings;
  opt.cache.budget_bytes = std::size_t(budget_mb * 1e6);
  opt.prefetch = !a.has("--no-prefetch");
  opt.seams = a.has("--skirts") ? blocks::SeamMode::Skirts : blocks::SeamMode::Stitch;
  opt.merge_tolerance_samples = merge_tol;
  blocks::TerrainSession session(blocks::database_source(db_path), grid, std::move(sums), opt);

  // frames.csv is written to a temporary renamed onto it after the last frame: a flight that
  // fails (a corrupt block read by the loader, a full disk) leaves no partial frames.csv.
  const std::string csv_path = (fs::path(out) / "frames.csv").string(), csv_tmp = csv_path + ".tmp";
  struct CsvFile {
    std::FILE* f = nullptr;
    std::string tmp;
    ~CsvFile() {
      if (f) std::fclose(f);
      if (!tmp.empty()) std::remove(tmp.c_str());
    }
  } guard;
  std::FILE* csv = guard.f = std::fopen(csv_tmp.c_str(), "w");
  if (!csv) throw std::runtime_error(csv_path + ": cannot write (" + std::strerror(errno) + ")");
  guard.tmp = csv_tmp;
  std::fprintf(csv,
               "frame,time_s,x,y,z,yaw,pitch,fovy,tau_px,triangles,bound_px,update_ms,resident,loading,evicted,"
               "prefetch_misses,bytes_read,centre_col,centre_row,n,missing_in_view,stand_ins,morphing_blocks,"
               "seam_triangles,resident_bytes\n");
  std::vector<double> ms;
  ms.reserve(path.size());
  std::size_t max_resident = 0;
  const bool flip = grid.transform().determinant() < 0;
  ProgressBar bar("fly");
  const auto t_fly = Clock::now();
  for (std::size_t f = 0; f < path.size(); ++f) {
    if (speed > 0) std::this_thread::sleep_until(t_fly + std::chrono::duration<double>(double(f) / (60.0 * speed)));
    const PathRow& r = path[f];
    pm::Camera cam;
    cam.x = r.x;
    cam.y = r.y;
    cam.z = r.z;
    cam.yaw_deg = r.yaw;
    cam.pitch_deg = r.pitch;
    cam.fovy_deg = r.fovy;
    cam.width_px = width;
    cam.height_px = height;
    const pm::Vec3 e{r.x, r.y, r.z};
    double dmin = 0, dmax = 0;
    {
      const double dx = std::max({box.lo.x - e.x, 0.0, e.x - box.hi.x}), dy = std::max({box.lo.y - e.y, 0.0, e.y - box.hi.y}),
                   dz = std::max({box.lo.z - e.z, 0.0, e.z - box.hi.z});
      dmin = std::sqrt(dx * dx + dy * dy + dz * dz);
      const double fx = std::max(std::abs(e.x - box.lo.x), std::abs(e.x - box.hi.x)),
                   fy = std::max(std::abs(e.y - box.lo.y), std::abs(e.y - box.hi.y)),
                   fz = std::max(std::abs(e.z - box.lo.z), std::abs(e.z - box.hi.z));
      dmax = std::sqrt(fx * fx + fy * fy + fz * fz);
    }
    cam.near_m = std::clamp(0.5 * dmin, 0.05, 1000.0);
    cam.far_m = std::max(cam.near_m * 2.0, 1.01 * dmax + 1.0);
    const blocks::SessionFrameStats& s = session.update(pm::View(cam), double(f) / 60.0);
    ms.push_back(s.update_ms);
    max_resident = std::max(max_resident, s.resident_bytes);
    std::fprintf(csv, "%zu,%.6f,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%zu,%.17g,%.6f,%zu,%zu,%zu,%zu,%llu,%d,%d,%d,%zu,%zu,%zu,%zu,%zu\n",
                 f, s.time_s, r.x, r.y, r.z, r.yaw, r.pitch, r.fovy, s.tolerance_px, s.triangles, s.bound_px, s.update_ms,
                 s.resident, s.loading, s.evicted, s.prefetch_misses_total,
                 static_cast<unsigned long long>(s.bytes_read_total), s.centre.col, s.centre.row, s.n, s.missing_in_view,
                 s.stand_ins, s.morphing_blocks, s.seam_triangles, s.resident_bytes);
    if (dump) {
      const blocks::DrawnMesh& m = session.drawn_mesh();
      pm::TriangleMeshData d;
      d.positions.reserve(m.positions.size());
      for (const pm::Vec3& p : m.positions) d.positions.push_back({p.x, p.y, p.z});
      d.triangles = m.triangles;
      if (flip)
        for (auto& tri : d.triangles) std::swap(tri[1], tri[2]);
      pm::write_mesh(d, (fs::path(out) / strf("frame_%05zu.ply", f)).string());
    }
    bar.update(double(f + 1) / double(path.size()));
  }
  bar.finish();
  guard.f = nullptr;
  if (std::fclose(csv) != 0) throw std::runtime_error(csv_path + ": cannot write (" + std::strerror(errno) + ")");
  if (std::rename(csv_tmp.c_str(), csv_path.c_str()) != 0)
    throw std::runtime_error(csv_path + ": cannot rename " + csv_tmp + " onto it (" + std::strerror(errno) + ")");
  guard.tmp.clear();
  const blocks::SessionFrameStats& last = session.stats();
  say(strf("fly   %zu frames in %s (speed factor %g%s): update median %.2f ms, p99 %.2f ms, worst %.2f ms",
            path.size(), format_duration(ms_since(t_fly)).c_str(), speed, opt.prefetch ? ", prefetch" : ", no prefetch",
            percentile(ms, 0.5), percentile(ms, 0.99), percentile(ms, 1.0)));
  say(strf("load  %zu prefetch misses of %zu blocks needed in view, %s read, peak resident %s (budget %s), %zu evicted",
            last.prefetch_misses_total, last.prefetch_hits_total + last.prefetch_misses_total,
            format_bytes(last.bytes_read_total).c_str(), format_bytes(last.peak_resident_bytes).c_str(),
            format_bytes(opt.cache.budget_bytes).c_str(), last.evicted_total));
  say(strf("write %s%s in %s", csv_path.c_str(), dump ? " and the frame meshes" : "", format_duration(ms_since(t_start)).c_str()));
  return 0;
}

}  // namespace terralod::cli
