// terralod view --db hybrid.db: renders the selection of a hybrid database's approximation tree
// (TIN microstructure near the camera, grid alone far away) offscreen into a PNG.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "commands.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/ground_scale.hpp"
#include "terralod/blocks/hybrid/hybrid_tree.hpp"
#include "terralod/pm/mesh_io.hpp"
#include "terralod/pm/view.hpp"
#include "terralod/render/camera.hpp"
#include "terralod/render/draw_mesh.hpp"
#include "terralod/render/gl_context.hpp"
#include "terralod/render/image.hpp"
#include "terralod/render/terrain_renderer.hpp"
#include "view_camera.hpp"

namespace terralod::cli {

int view_hybrid(const std::string& path, const pm::Camera& camera, double tau, const std::string& out,
                const std::string& dump, bool wireframe) {
  namespace hy = blocks::hybrid;
  namespace fs = std::filesystem;
  using Clock = std::chrono::steady_clock;
  auto t = Clock::now();
  const blocks::BlockDatabase db = blocks::BlockDatabase::open(path);
  if (db.info().kind != "hybrid")
    throw std::runtime_error(path + ": not a hybrid database (kind '" + db.info().kind + "')");
  const auto hblob = db.read_blob("hybrid");
  const auto tblob = db.read_blob("hybrid_tree");
  if (!hblob) throw std::runtime_error(path + ": no 'hybrid' blob");
  if (!tblob)
    throw std::runtime_error(path +
                             ": no 'hybrid_tree' blob (made by an older 'terralod hybrid'; build it again)");
  const hy::HybridTerrain h = hy::HybridTerrain::decode(*hblob, path);
  const hy::HybridTree tree =
      hy::HybridTree::attach(h, blocks::decode_tree(*tblob, path + ": hybrid_tree"), path);
  print_line(strf("read %s: hybrid tree of %zu nodes over %d x %d coarsest cells, %s", path.c_str(),
                  tree.tree().size(), tree.cells_x(), tree.cells_y(), format_duration(ms_since(t)).c_str()));

  // The frame's ground scale at the eye and clip planes from the root's box, as for 'view --input'.
  const pm::Box& box = tree.tree().root().bbox;
  const glm::dvec3 lo(box.lo.x, box.lo.y, box.lo.z), hi(box.hi.x, box.hi.y, box.hi.z);
  render::Camera cam = camera;
  if (const auto geo = db.georeference())
    cam.ground = blocks::GroundScaleMap(db.info().crs_wkt, geo->crs_transform, db.info().transform, box)
                     .at(cam.x, cam.y);
  fit_clip_to_box(cam, lo, hi);
  const int width = cam.width_px, height = cam.height_px;

  t = Clock::now();
  const hy::HybridSelection s = tree.select(pm::View(cam), {.alpha_px = tau});
  const double select_ms = ms_since(t);
  std::vector<std::size_t> per_level(std::size_t(h.levels()) + 2, 0);
  for (int l : s.cell_level) ++per_level[std::size_t(l + 2)];
  std::string levels = strf("grid alone %zu", per_level[1]);
  for (int l = 0; l < h.levels(); ++l)
    levels += strf(", hybrid level %d %zu", l, per_level[std::size_t(l + 2)]);
  levels += strf(", culled %zu", per_level[0]);
  print_line(
      strf("select tau=%g px: %zu visited, %zu culled, %zu selected; drawn %zu nodes (%zu hybrid, %zu grid; "
           "%zu grid "
           "nodes refined and %zu culled cells added to keep TINs whole), %s",
           tau, s.selection.visited, s.selection.culled, s.selection.selected.size(), s.nodes.size(),
           s.hybrid_nodes, s.grid_nodes, s.forced, s.added, format_duration(select_ms).c_str()));
  print_line(strf("coarsest cells: %s", levels.c_str()));
  print_line(
      strf("mesh: %zu triangles (%zu TIN, %zu from grid nodes, %zu split at T-junctions), %zu vertices; node "
           "error "
           "<= %.3f m, bound %.3g px (tau %g)",
           s.mesh.triangles.size(), s.tin_triangles, s.mesh.grid_triangles, s.mesh.split_edges,
           s.mesh.points.size(), s.error_m, s.bound_px, tau));

  const pm::TriangleMeshData world = hy::to_world(s.mesh, db.info().transform);
  render::DrawMesh dm;
  dm.origin = (lo + hi) * 0.5;
  for (const auto& p : world.positions)
    for (int k = 0; k < 3; ++k) dm.xyz.push_back(float(p[std::size_t(k)] - dm.origin[k]));
  for (const auto& tri : world.triangles) dm.indices.insert(dm.indices.end(), tri.begin(), tri.end());
  t = Clock::now();
  auto ctx = render::create_offscreen_context({width, height});
  render::RendererOptions ropt;
  ropt.wireframe = wireframe;
  render::TerrainRenderer renderer(*ctx, ropt);
  const render::MeshId id = renderer.upload(dm);
  const render::FrameStats frame = renderer.draw(cam, {{id, 0.0f}});
  const render::Image img = renderer.read_color();
  render::write_png(img, out);
  print_line(strf("render %d x %d on %s (draw %s): write %s, %s, %s", width, height,
                  ctx->info().renderer.c_str(), format_duration(frame.draw_ms).c_str(), out.c_str(),
                  format_bytes(fs::file_size(out)).c_str(), format_duration(ms_since(t)).c_str()));
  if (!dump.empty()) {
    pm::write_mesh(world, dump);
    print_line(strf("write %s: %s, world units", dump.c_str(), format_bytes(fs::file_size(dump)).c_str()));
  }
  return 0;
}

}  // namespace terralod::cli
