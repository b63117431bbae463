// frames.csv of the flight tools (see flight_log.hpp).
#include "flight_log.hpp"

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <stdexcept>

namespace terralod::cli {

std::string flight_log_header(bool drawing) {
  std::string h =
      "frame,time_s,x,y,z,yaw,pitch,fovy,tau_px,triangles,bound_px,missing_in_view,update_ms,update_cpu_ms,"
      "resident_bytes,blocks_resident,blocks_loading,blocks_evicted,nodes_resident,nodes_loading,nodes_"
      "evicted,"
      "prefetch_misses,bytes_read,nodes_visited,nodes_culled,coarse_nodes,pm_blocks,standin_blocks,fallback_"
      "nodes,"
      "moving_vertices,clamped_vertices,seam_triangles,standins_held,standin_reads";
  if (drawing) h += ",vertices,draw_ms,upload_ms,wait_ms,texture_bytes,texture_patches,textures_from_parent";
  return h + ",ground_xx,ground_xy,ground_yy";
}

FlightLog::FlightLog(const std::string& dir, bool drawing)
    : path_((std::filesystem::path(dir) / "frames.csv").string()), tmp_(path_ + ".tmp"), drawing_(drawing) {
  f_ = std::fopen(tmp_.c_str(), "w");
  if (!f_) throw std::runtime_error(path_ + ": cannot write (" + std::strerror(errno) + ")");
  std::fprintf(f_, "%s\n", flight_log_header(drawing).c_str());
}

FlightLog::~FlightLog() {
  if (f_) {
    std::fclose(f_);
    std::remove(tmp_.c_str());
  }
}

void FlightLog::row(const FlightRow& r) {
  const blocks::RuntimeFrameStats& s = r.stats;
  const pm::Camera& c = r.camera;
  // Nodes of the tree are all resident (terrain_runtime.hpp): never loading or evicted.
  std::fprintf(f_,
               "%zu,%.6f,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%zu,%.17g,%zu,%.6f,%.6f,%zu,%zu,%zu,%zu,%"
               "zu,0,0,%zu,"
               "%llu,%zu,%zu,%zu,%zu,%zu,%zu,%zu,%zu,%zu,%zu,%zu",
               r.frame, r.time_s, c.x, c.y, c.z, c.yaw_deg, c.pitch_deg, c.fovy_deg, s.tolerance_px,
               s.triangles, s.bound_px, s.missing_in_view, s.update_ms, s.update_cpu_ms, s.resident_bytes,
               s.blocks_resident, s.blocks_loading, s.blocks_evicted, s.nodes_resident,
               s.prefetch_misses_total, static_cast<unsigned long long>(s.bytes_read_total), s.nodes_visited,
               s.nodes_culled, s.coarse_nodes, s.pm_blocks, s.standin_blocks, s.fallback_nodes,
               s.moving_vertices, s.clamped_vertices, s.seam_triangles, s.standins_held,
               s.standin_reads_total);
  if (drawing_)
    std::fprintf(f_, ",%zu,%.4f,%.4f,%.4f,%zu,%zu,%zu", r.vertices, r.draw_ms, r.upload_ms, r.wait_ms,
                 r.texture_bytes, r.texture_patches, r.textures_from_parent);
  std::fprintf(f_, ",%.17g,%.17g,%.17g\n", c.ground.xx, c.ground.xy, c.ground.yy);
}

void FlightLog::commit() {
  std::FILE* f = f_;
  f_ = nullptr;
  const bool ok = std::ferror(f) == 0;
  if (std::fclose(f) != 0 || !ok) {
    std::remove(tmp_.c_str());
    throw std::runtime_error(path_ + ": cannot write (" + std::strerror(errno) + ")");
  }
  if (std::rename(tmp_.c_str(), path_.c_str()) != 0) {
    std::remove(tmp_.c_str());
    throw std::runtime_error(path_ + ": cannot rename " + tmp_ + " onto it (" + std::strerror(errno) + ")");
  }
}

}  // namespace terralod::cli
