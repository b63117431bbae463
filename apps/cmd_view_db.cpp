// terralod view --db terrain.db: one frame of a block database's runtime (blocks::TerrainRuntime:
// the approximation tree from its root, coarse nodes, stand-ins and refined PM blocks, every
// load this view needs finished) rendered offscreen into a PNG, with texture layers per patch and
// map objects (--objects) placed on and drawn over the drawn terrain.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "cli_common.hpp"
#include "commands.hpp"
#include "flight_objects.hpp"
#include "layer_options.hpp"
#include "object_drawing.hpp"
#include "terralod/blocks/terrain_runtime.hpp"
#include "terralod/pm/mesh_io.hpp"
#include "terralod/pm/view.hpp"
#include "terralod/render/camera.hpp"
#include "terralod/render/draw_mesh.hpp"
#include "terralod/render/gl_context.hpp"
#include "terralod/render/image.hpp"
#include "terralod/render/layered_renderer.hpp"
#include "terralod/render/terrain_renderer.hpp"
#include "terralod/render/texture_store.hpp"
#include "view_camera.hpp"

namespace terralod::cli {

int view_blocks(const Args& a, const pm::Camera& camera, double tau) {
  namespace fs = std::filesystem;
  namespace tb = terralod::blocks;
  namespace rd = terralod::render;
  using Clock = std::chrono::steady_clock;
  const std::string path = a.get("--db"), out = a.get("--out"), dump = a.get("--dump-mesh");
  const std::string stats_path = a.get("--stats");
  const std::vector<std::string> specs = a.get_all("--layer");

  auto t = Clock::now();
  tb::RuntimeOptions ro;
  ro.tolerance_px = tau;
  ro.morph_seconds = 0;  // one frame: nothing to blend from
  tb::TerrainRuntime rt(path, ro);
  const double open_ms = ms_since(t);
  const tb::BlockGrid& g = rt.grid();
  print_line(strf("read %s: %d x %d samples in %d x %d blocks of %d, tree of %zu nodes, %s", path.c_str(),
                  g.grid_width(), g.grid_height(), g.cols(), g.rows(), g.block_size(), rt.tree().size(),
                  format_duration(open_ms).c_str()));

  // The camera, with the clip planes of the terrain's box (the selection's frustum is the
  // picture's, so the bound is true of the picture).
  pm::Camera pc = camera;
  const int width = camera.width_px, height = camera.height_px;
  rt.fit_camera(pc);
  const pm::View view(pc);
  t = Clock::now();
  const tb::RuntimeFrameStats first = rt.update_until_loaded(view, 0.0);
  const double select_ms = ms_since(t);
  const tb::RuntimeFrameStats& s = rt.stats();
  print_line(strf(
      "select tau=%g px: %zu nodes visited, %zu culled; drawn %zu PM blocks, %zu stand-ins, %zu coarse "
      "nodes, "
      "%zu ancestors for missing blocks; %zu blocks read (%s) in %s",
      tau, s.nodes_visited, s.nodes_culled, s.pm_blocks, s.standin_blocks, s.coarse_nodes, s.fallback_nodes,
      s.blocks_resident, format_bytes(s.bytes_read_total).c_str(), format_duration(select_ms).c_str()));
  print_line(strf(
      "mesh: %zu triangles (%zu stitched at seams), bound %.4g px (tau %g)%s; update %s (first, loads "
      "excluded: %s)",
      s.triangles, s.seam_triangles, s.bound_px, tau,
      s.missing_in_view ? strf(", %zu needed blocks missing or too coarse", s.missing_in_view).c_str() : "",
      format_duration(s.update_ms).c_str(), format_duration(first.update_ms).c_str()));

  // Map objects (--objects): placed on this frame's drawn terrain, drawn after it.
  std::optional<tb::ObjectPlacer> objects = object_placer(a, path);
  if (objects) objects->place(rt, view);
  std::optional<ObjectDrawing> drawing;
  ObjectDrawStats drawn;

  // Texture layers per drawn patch, from the texture trees over the drawn tree.
  std::optional<LayerSetup> layers;
  if (!specs.empty()) {
    const LayerSetupOptions lo = layer_setup_options(a);
    const std::vector<rd::PatchDomain> domains = rd::patch_domains(rt.tree().nodes());
    layers.emplace(LayerSetup::open(
        a.get("--texture-db", path), specs,
        a.has("--lens") ? std::optional(parse_lens("--lens", a.get("--lens"))) : std::nullopt, lo, &domains));
  }

  t = Clock::now();
  auto ctx = rd::create_offscreen_context({width, height});
  const rd::Camera& cam = pc;  // the selection's camera is the renderer's
  const pm::Box& box = rt.terrain_box();
  const glm::dvec3 origin(0.5 * (box.lo.x + box.hi.x), 0.5 * (box.lo.y + box.hi.y),
                          0.5 * (box.lo.z + box.hi.z));
  rd::DrawMesh dm;
  rd::fill_draw_mesh(rt.drawn_mesh(), origin, g.transform().determinant() < 0, dm);
  rd::Image img;
  double draw_ms = 0;
  std::size_t texture_bytes = 0, texture_patches = 0;
  double gamma_used = 0;
  if (layers) {
    rd::LayeredRenderer r(*ctx);
    layers->attach(r);
    // Every wanted patch loaded (the picture shows what gamma asks for).
    const rd::PatchTextureFrame& f = layers->patch_frame(view, rt.drawn_mesh().triangle_node, /*wait=*/true);
    rd::DrawMesh sorted;
    rd::order_triangles(dm, f.triangle_order, sorted);
    const rd::MeshId id = r.upload(sorted);
    const std::vector<rd::LayeredItem> items = layers->items(r, id, f);
    draw_ms = r.draw(cam, layers->styles(), layers->lens(), items).draw_ms;
    if (objects) drawn = drawing.emplace(*ctx, *objects).draw(r, *objects, rt, view);
    img = r.read_color();
    drawing.reset();  // before its renderer
    texture_bytes = layers->resident_bytes(), texture_patches = f.stats.wanted, gamma_used = f.stats.gamma_px;
    print_line(strf("textures: %zu patches in %zu groups, gamma %g px^2%s, %s resident (budget %s)",
                    texture_patches, f.groups.size(), gamma_used,
                    gamma_used > layers->gamma_px() ? " (raised for the budget)" : "",
                    format_bytes(texture_bytes).c_str(), format_bytes(layers->budget_bytes()).c_str()));
  } else {
    rd::RendererOptions o;
    o.wireframe = a.has("--wireframe");
    rd::TerrainRenderer r(*ctx, o);
    const rd::MeshId id = r.upload(dm);
    draw_ms = r.draw(cam, {{id, 0.0f}}).draw_ms;
    if (objects) drawn = drawing.emplace(*ctx, *objects).draw(r, *objects, rt, view);
    img = r.read_color();
    drawing.reset();  // before its renderer
  }
  if (objects)
    print_line(objects_line(*objects, /*timings=*/true) + "; " + drawn_line(drawn, /*timings=*/true));
  rd::write_png(img, out);
  print_line(strf("render %d x %d on %s (draw %s): write %s, %s, %s", width, height,
                  ctx->info().renderer.c_str(), format_duration(draw_ms).c_str(), out.c_str(),
                  format_bytes(fs::file_size(out)).c_str(), format_duration(ms_since(t)).c_str()));
  if (!dump.empty()) {
    pm::write_mesh(rd::world_mesh(dm), dump);
    print_line(strf("write %s: %s, world units", dump.c_str(), format_bytes(fs::file_size(dump)).c_str()));
  }
  if (!stats_path.empty()) {
    JsonWriter j;
    j.begin_object();
    j.field("db", path);
    j.field("output", out);
    j.field("selection", "runtime");
    write_view_json(j, pc, tau);
    j.field("bound_px", s.bound_px);
    j.field("missing_in_view", std::uint64_t(s.missing_in_view));
    j.field("triangles", std::uint64_t(s.triangles));
    j.field("vertices", std::uint64_t(rt.drawn_mesh().positions.size()));
    j.field("pm_blocks", std::uint64_t(s.pm_blocks));
    j.field("standin_blocks", std::uint64_t(s.standin_blocks));
    j.field("coarse_nodes", std::uint64_t(s.coarse_nodes));
    j.field("fallback_nodes", std::uint64_t(s.fallback_nodes));
    j.field("resident_bytes", std::uint64_t(s.resident_bytes));
    j.field("bytes_read", std::uint64_t(s.bytes_read_total));
    if (objects) {
      j.begin_object("objects");
      j.field("placed", std::uint64_t(objects->placed().size()));
      j.field("icons", std::uint64_t(drawn.icons));
      j.field("labels_shown", std::uint64_t(drawn.labels_shown));
      j.field("label_candidates", std::uint64_t(drawn.label_candidates));
      j.field("line_triangles", std::uint64_t(drawn.line_triangles));
      j.field("shape_triangles", std::uint64_t(drawn.shape_triangles));
      j.end_object();
    }
    if (layers) {
      j.field("texture_bytes", std::uint64_t(texture_bytes));
      j.field("texture_patches", std::uint64_t(texture_patches));
      j.field("gamma_px", gamma_used);
    }
    j.field("renderer", ctx->info().renderer);
    j.begin_object("timings_ms");
    j.field("open", open_ms);
    j.field("update", first.update_ms);
    j.field("update_with_loads", select_ms);
    j.field("draw", draw_ms);
    j.end_object();
    j.end_object();
    write_statistics(stats_path, j);
  }
  return 0;
}

}  // namespace terralod::cli
