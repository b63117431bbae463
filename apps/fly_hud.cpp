// The text of terralod-fly's heads-up display (see fly_hud.hpp).
#include "fly_hud.hpp"

#include <cstdint>

#include "cli_common.hpp"

namespace terralod::fly {

using namespace terralod::cli;

std::vector<std::string> lod_lines(const FrameRecord& r, const pm::RefinementOptions& now, bool timings) {
  const blocks::RuntimeFrameStats& l = r.lod;
  return {
      // One PM (no --db): its bound is the selection's; the display lags it while vertices morph.
      r.streamed
          ? strf(
                "tau %.2f px%s   drawn within %.3f px%s", l.tolerance_px,
                now.target_triangles ? strf(" (budget %zu)", now.target_triangles).c_str() : "", l.bound_px,
                l.missing_in_view
                    ? strf(" (%zu blocks missing or too coarse: over tau allowed)", l.missing_in_view).c_str()
                    : "")
          : strf("tau %.2f px%s   selection within %.3f px%s", l.tolerance_px,
                 now.target_triangles ? strf(" (budget %zu)", now.target_triangles).c_str() : "", l.bound_px,
                 l.moving_vertices ? strf(" (display lags: %zu vertices morphing)", l.moving_vertices).c_str()
                                   : ""),
      timings ? strf("%zu triangles   update %.2f ms   draw %.2f ms", l.triangles, l.update_ms, r.draw_ms)
              : strf("%zu triangles", l.triangles),
      r.streamed
          ? strf("nodes drawn %zu (%zu PM blocks, %zu stand-ins, %zu coarse, %zu for missing blocks)   "
                 "culled %zu",
                 l.pm_blocks + l.standin_blocks + l.coarse_nodes, l.pm_blocks, l.standin_blocks,
                 l.coarse_nodes, l.fallback_nodes, l.nodes_culled)
          : std::string("nodes drawn 1 (one PM)"),
      r.streamed
          ? strf("blocks resident %zu, loading %zu, evicted %zu   prefetch misses %zu   read %s   memory %s",
                 l.blocks_resident, l.blocks_loading, l.evicted_total, l.prefetch_misses_total,
                 format_bytes(l.bytes_read_total).c_str(), format_bytes(l.resident_bytes).c_str())
          : std::string("blocks resident 1, loading 0"),
      strf("texture memory %s%s", format_bytes(r.texture_bytes).c_str(),
           r.texture_patches ? strf(" (%zu patches wanted, %zu drawn with a parent's)", r.texture_patches,
                                    r.textures_from_parent)
                                   .c_str()
                             : "")};
}

void overlay_text(render::Image& img, const render::TextImage& t, int margin) {
  for (int y = 0; y < t.height && y + margin < img.height; ++y)
    for (int x = 0; x < t.width && x + margin < img.width; ++x) {
      const std::uint8_t* s = &t.rgba[(std::size_t(y) * t.width + x) * 4];
      std::uint8_t* d = img.pixel(x + margin, y + margin);
      for (int c = 0; c < 3; ++c) d[c] = std::uint8_t((s[c] * s[3] + d[c] * (255 - s[3]) + 127) / 255);
    }
}

}  // namespace terralod::fly
