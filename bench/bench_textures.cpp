// Texture benchmark: texture memory resident and bytes uploaded per frame versus the visual
// texture error threshold gamma, along a scripted flight over N44W072.hgt (a generated
// 1025 x 1025 terrain when the tile is absent).
//
// Usage: terralod-bench-textures [--data DIR] [--frames N] [--max-texture-size N] [--budget-mb M]
//
// Setup: the CPU Lambert hillshade of the terrain (one texel per sample) becomes an image
// pyramid (max texture size 256 by default) and a texture tree over a quadtree of domains
// (leaves of at most 65 x 65 samples, like 65-sample blocks). Flight: 300 frames at 1280 x 720,
// 100 m/s, 600 m above the start, looking 25 degrees down, heading north-east with a gentle
// turn. Per frame: select_patches (gamma only; alpha ignored), choose_textures (ancestor
// reuse), then every chosen texture is requested from a TextureCache (budget --budget-mb,
// default 64 MiB) whose loader reads the pyramid; the benchmark waits for the loads after
// each frame so the numbers do not depend on thread timing (a real frame never waits).
// Reported per gamma: patches selected and distinct textures used (median), bytes uploaded
// per frame (median, p99, max; an upload = a texture newly resident), resident bytes (max),
// loads and evictions in total. Exit status 0, 1 if anything throws, 2 for a bad command line.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

#include "terralod/blocks/dem_reader.hpp"
#include "terralod/pm/terrain_generator.hpp"
#include "terralod/pm/view.hpp"
#include "terralod/render/image_pyramid.hpp"
#include "terralod/render/texture_cache.hpp"
#include "terralod/render/texture_tree.hpp"
#include "terralod/render/topographic_texture.hpp"
#include "timing.hpp"

namespace {

namespace pm = terralod::pm;
namespace tr = terralod::render;
using namespace terralod::bench;

// Quadtree domains over the grid down to leaves of <= leaf samples per side.
void split(const pm::Heightfield& hf, std::vector<tr::PatchDomain>& out, std::int64_t parent,
           terralod::blocks::SampleRect r, int leaf) {
  tr::PatchDomain d;
  d.id = std::int64_t(out.size());
  d.parent = parent;
  d.domain = r;
  double lo = 1e300, hi = -1e300;
  for (int row = r.row0; row <= r.row1; ++row)
    for (int col = r.col0; col <= r.col1; ++col)
      lo = std::min(lo, hf.at(col, row)), hi = std::max(hi, hf.at(col, row));
  const auto [xa, ya] = hf.transform.to_world(r.col0, r.row0);
  const auto [xb, yb] = hf.transform.to_world(r.col1, r.row1);
  d.bbox = pm::Box{{std::min(xa, xb), std::min(ya, yb), lo}, {std::max(xa, xb), std::max(ya, yb), hi}};
  out.push_back(d);
  if (parent >= 0) out[std::size_t(parent)].children.push_back(d.id);
  if (r.width() <= leaf && r.height() <= leaf) return;
  const int cm = (r.col0 + r.col1) / 2, rm = (r.row0 + r.row1) / 2;
  const std::int64_t me = d.id;
  split(hf, out, me, {r.col0, r.row0, cm, rm}, leaf);
  split(hf, out, me, {cm, r.row0, r.col1, rm}, leaf);
  split(hf, out, me, {r.col0, rm, cm, r.row1}, leaf);
  split(hf, out, me, {cm, rm, r.col1, r.row1}, leaf);
}

}  // namespace

int main(int argc, char** argv) {
  std::string data = TERRALOD_DATA_DIR;
  int frames = 300, max_tex = 256;
  double budget_mb = 64;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "terralod-bench-textures: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--data")
      data = next();
    else if (a == "--frames")
      frames = std::max(1, std::atoi(next().c_str()));
    else if (a == "--max-texture-size")
      max_tex = std::max(1, std::atoi(next().c_str()));
    else if (a == "--budget-mb")
      budget_mb = std::max(0.001, std::atof(next().c_str()));
    else if (a == "--help" || a == "-h") {
      std::puts(
          "usage: terralod-bench-textures [--data DIR] [--frames N] [--max-texture-size N] [--budget-mb M]");
      return 0;
    } else {
      std::fprintf(stderr, "terralod-bench-textures: unknown option %s\n", a.c_str());
      return 2;
    }
  }
  try {
    auto t = Clock::now();
    const std::filesystem::path tile = std::filesystem::path(data) / "N44W072.hgt";
    pm::Heightfield hf;
    std::string what;
    if (!data.empty() && std::filesystem::exists(tile)) {
      hf = terralod::blocks::read_dem(tile.string());
      what = tile.string();
    } else {
      pm::TerrainOptions o;
      o.width = o.height = 1025;
      hf = pm::generate_terrain(o);
      what = "generated 1025 x 1025 terrain (N44W072.hgt not found)";
    }
    std::printf("terrain %s: %d x %d samples, %.0f ms\n", what.c_str(), hf.width(), hf.height(), ms_since(t));
    t = Clock::now();
    const tr::RgbaImage shade = tr::shading_texture(hf);
    std::printf("shade  CPU Lambert hillshade %d x %d, %.0f ms\n", shade.width, shade.height, ms_since(t));
    t = Clock::now();
    const std::string tx = (std::filesystem::temp_directory_path() / "terralod-bench-textures.tx").string();
    tr::PyramidOptions po;
    po.max_texture_size = max_tex;
    tr::ImagePyramid::convert(shade, tx, po);
    const tr::ImagePyramid pyr(tx, po);
    std::printf("pyramid %d levels down to %d x %d (max texture %d), %.0f ms\n", pyr.levels(),
                pyr.level_sizes().back().width, pyr.level_sizes().back().height, max_tex, ms_since(t));
    std::vector<tr::PatchDomain> doms;
    split(hf, doms, -1, {0, 0, hf.width() - 1, hf.height() - 1}, 65);
    const tr::GeoRect geo{
        doms[0].bbox.lo.x - hf.transform.spacing_x() / 2, doms[0].bbox.lo.y - hf.transform.spacing_y() / 2,
        doms[0].bbox.hi.x + hf.transform.spacing_x() / 2, doms[0].bbox.hi.y + hf.transform.spacing_y() / 2};
    const tr::TextureTree tree(doms, pyr.level_sizes(), geo, tr::TextureConstraints{max_tex, false});
    std::printf("tree   %zu nodes, %zu texture patches\n", tree.node_count(), tree.patch_count());

    const pm::Box& root = doms[0].bbox;
    const double ex = root.hi.x - root.lo.x, ey = root.hi.y - root.lo.y;
    std::printf("\n%8s %9s %9s %12s %12s %12s %12s %7s %9s\n", "gamma", "patches", "textures", "upload_med",
                "upload_p99", "upload_max", "resident_max", "loads", "evictions");
    for (double gamma : {0.5, 1.0, 2.0, 4.0, 8.0, 16.0}) {
      tr::TextureCacheOptions co;
      co.budget_bytes = std::size_t(budget_mb * 1024 * 1024);
      tr::TextureCache cache([&](const tr::TextureKey& k) { return pyr.read(tree.patch(k.node).rect); }, co);
      std::vector<double> upload, patches, textures;
      std::size_t resident_max = 0;
      for (int f = 0; f < frames; ++f) {
        const double s = double(f) / 60.0 * 100.0;  // metres flown
        const double heading = 45.0 + 30.0 * f / std::max(1, frames - 1);
        pm::Camera cam;
        cam.x = root.lo.x + 0.2 * ex + s * std::sin(heading * std::numbers::pi / 180);
        cam.y = root.lo.y + 0.2 * ey + s * std::cos(heading * std::numbers::pi / 180);
        cam.z = root.hi.z + 600.0;
        cam.yaw_deg = heading;
        cam.pitch_deg = -25.0;
        cam.width_px = 1280;
        cam.height_px = 720;
        const pm::View view(cam);
        tr::PatchSelectionOptions so;
        so.gamma_px = gamma;
        const tr::PatchSelection sel = tr::select_patches(tree, view, so);
        const auto groups = tr::choose_textures(tree, view, sel.selected, gamma);
        const std::size_t before = cache.stats().loaded_bytes;
        cache.begin_frame();
        for (const tr::TextureGroup& g : groups)
          if (g.texture_node >= 0) cache.request({0, g.texture_node});
        cache.wait_idle(600000);
        const tr::TextureCacheStats st = cache.stats();
        upload.push_back(double(st.loaded_bytes - before));  // each newly resident texture is uploaded once
        patches.push_back(double(sel.selected.size()));
        textures.push_back(double(groups.size()));
        resident_max = std::max(resident_max, st.resident_bytes);
      }
      const tr::TextureCacheStats st = cache.stats();
      std::printf("%8.1f %9.0f %9.0f %12.0f %12.0f %12.0f %12zu %7zu %9zu\n", gamma, median(patches),
                  median(textures), median(upload), quantile(upload, 0.99),
                  *std::max_element(upload.begin(), upload.end()), resident_max, st.loads, st.evictions);
    }
    std::error_code ec;
    std::filesystem::remove(tx, ec);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "terralod-bench-textures: %s\n", e.what());
    return 1;
  }
}
