// terralod hybrid: builds a hybrid grid + TIN terrain (reference grid every K samples of a DEM
// joined to TIN microstructures by local convexification) into hybrid.db, prints the paper's
// Table 2 storage figures; and the `terralod extract --db hybrid.db --grid-level L` branch.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "commands.hpp"
#include "dem_options.hpp"
#include "terrain_input.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/hybrid/hybrid_terrain.hpp"
#include "terralod/blocks/hybrid/hybrid_tree.hpp"
#include "terralod/pm/json.hpp"
#include "terralod/pm/mesh_io.hpp"

namespace terralod::cli {
namespace {

namespace fs = std::filesystem;
namespace hy = blocks::hybrid;
using Clock = std::chrono::steady_clock;

std::vector<std::string> split_list(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream in(s);
  for (std::string item; std::getline(in, item, ',');)
    if (!item.empty()) out.push_back(item);
  return out;
}

}  // namespace

static std::string hybrid_report_text(const hy::StorageReport& r) {
  std::string s = strf("TIN boundary: %zu vertices in %zu ring(s); TIN %zu vertices, %zu triangles\n",
                       r.tb_vertices, r.rings, r.tin_vertices, r.tin_triangles);
  s += strf("connectivity: max %u -> %d bits per TB vertex; A (TB address) %d bits\n", r.max_connectivity,
            r.connectivity_bits, r.address_bits);
  s += "Table 2  level   cells     NC     CC    PC (%)          conn.max  L max  bits/section  GC bits  "
       "VC bits  tree bits/PC (max)\n";
  for (const hy::LevelReport& l : r.levels)
    s += strf("         LOD %d  %6d  %5d  %5d  %4d (%6.2f%%)  %8u  %5u  %12d  %7llu  %7llu  %6.2f (%llu)\n",
              l.level, l.cells, l.nc, l.cc, l.pc, l.pc_percent, l.max_connectivity, l.l_max,
              l.bits_per_section, (unsigned long long)l.gc_bits, (unsigned long long)l.vc_bits,
              l.tree_bits_per_pc, (unsigned long long)l.tree_bits_max);
  return s;
}

CommandSpec hybrid_spec() {
  CommandSpec s;
  s.name = "hybrid";
  s.summary = "Build a hybrid grid + TIN terrain (local convexification) into a database.";
  s.description =
      "The reference grid takes every K-th sample of --grid (K = --grid-step) and has --levels levels of\n"
      "detail (level l: cells of K * 2^l samples). Each --tin is a TIN in the DEM's world frame (x east,\n"
      "y north, metres): a PLY (ascii, binary little- or big-endian; as written by 'terralod tin') or a\n"
      "Wavefront OBJ ('v x y z', 'f' with a, a/b, a/b/c or a//c corners, negative indices, polygons\n"
      "fan-triangulated); several TINs are given comma-separated and must not overlap.\n"
      "Per level the cells are classified (GC list: 0 NC, 10 CC, 11 PC), the TIN boundary is\n"
      "convexified inside every PC cell from the finest to the coarsest level (one connectivity\n"
      "index per boundary vertex, VC list per PC cell) and the sub-cell trees of section 5 are stored.\n"
      "The build decodes every level again and checks it against the direct convexification.\n"
      "Writes DB (must not exist): DatabaseInfo kind 'hybrid' plus the named blob 'hybrid', and the\n"
      "approximation tree 'hybrid_tree' (grid-only quadtree above one hybrid node per coarsest cell and\n"
      "level, exact errors) that 'terralod view --db DB' selects from.\n"
      "Prints the storage figures of the paper's Table 2 per level.\n\n" +
      std::string(kDemFormats);
  s.options =
      concat({{"--grid", "DEM", "the reference DEM (any format 'terralod info' reads)", true},
              {"--grid-step", "K", "samples between grid nodes of the finest level, >= 1 (default 4)"},
              {"--levels", "N", "grid levels of detail, 1..10 (default 3)"},
              {"--tin", "MESH[,MESH...]", "TIN microstructure(s) in the world frame: .ply or .obj", true},
              {"--out", "DB", "hybrid database to create (.db)", true}},
             dem_option_specs());
  return s;
}

int cmd_hybrid(const Args& a) {
  const std::string dem_path = a.get("--grid"), out = a.get("--out");
  const int step = int(a.get_int("--grid-step", 4, 1, 4096));
  const int levels = int(a.get_int("--levels", 3, 1, 10));
  const std::vector<std::string> tins = split_list(a.get("--tin"));
  if (tins.empty()) throw UsageError("option '--tin' names no file");
  if (fs::exists(out))
    throw std::runtime_error(out + ": already exists (the hybrid database is created new)");
  auto t = Clock::now();
  const pm::Heightfield dem = blocks::read_dem(dem_path, dem_options_from(a));  // --crs as every command
  warn_about_frame(blocks::DemGrid::of(dem));
  print_line(strf("read %s: %dx%d samples, %s", dem_path.c_str(), dem.width(), dem.height(),
                  format_duration(ms_since(t)).c_str()));
  std::vector<hy::TinMesh> parts;
  for (const std::string& p : tins) {
    t = Clock::now();
    parts.push_back(hy::tin_from_world(pm::read_mesh(p), dem.transform, p));
    print_line(strf("read %s: %zu vertices, %zu triangles, %s", p.c_str(), parts.back().points.size(),
                    parts.back().triangles.size(), format_duration(ms_since(t)).c_str()));
  }
  t = Clock::now();
  const hy::HybridTerrain h =
      hy::HybridTerrain::build(dem, hy::merge_tins(parts), {.grid_step = step, .levels = levels});
  const hy::StorageReport r = h.storage_report();
  print_line(strf("hybrid: grid step %d, %d levels, domain %dx%d samples, %zu TB vertices, %s", step, levels,
                  h.domain_width(), h.domain_height(), r.tb_vertices, format_duration(ms_since(t)).c_str()));
  std::fputs(hybrid_report_text(r).c_str(), stdout);
  t = Clock::now();
  const hy::HybridTree tree = hy::HybridTree::build(h, dem);
  const std::vector<std::uint8_t> tree_blob = blocks::encode_tree(tree.tree());
  const auto per = tree.tree().count_by_strategy();
  print_line(strf("hybrid tree: %zu nodes (%zu grid, %zu hybrid), depth %d, root error %.2f m, %s, %s",
                  tree.tree().size(), per[std::size_t(blocks::Strategy::Grid)],
                  per[std::size_t(blocks::Strategy::Hybrid)], tree.tree().depth(), tree.tree().root().error,
                  format_bytes(tree_blob.size()).c_str(), format_duration(ms_since(t)).c_str()));
  t = Clock::now();
  const std::vector<std::uint8_t> blob = h.encode();
  blocks::DatabaseInfo info;
  info.kind = "hybrid";
  info.grid_width = dem.width();
  info.grid_height = dem.height();
  info.transform = dem.transform;
  info.crs_wkt = dem.crs_wkt;
  info.block_size = 0;
  info.build_parameters = strf("{\"grid_step\": %d, \"levels\": %d, \"tin\": %s}", step, levels,
                               pm::json_quote(a.get("--tin")).c_str());
  info.source = dem_path;
  {
    blocks::BlockDatabase db = blocks::BlockDatabase::create(out, info);
    blocks::BlockDatabase::Transaction tx(db);
    db.put_blob("hybrid", blob);
    db.put_blob("hybrid_tree", tree_blob);
    db.set_meta("build_complete", "1");
    tx.commit();
  }
  print_line(strf("write %s: hybrid blob %s, %s", out.c_str(), format_bytes(blob.size()).c_str(),
                  format_duration(ms_since(t)).c_str()));
  return 0;
}

int info_hybrid(const std::string& path) {
  const blocks::BlockDatabase db = blocks::BlockDatabase::open(path);
  const auto blob = db.read_blob("hybrid");
  if (!blob) throw std::runtime_error(path + ": no 'hybrid' blob");
  const hy::HybridTerrain h = hy::HybridTerrain::decode(*blob, path);
  const hy::StorageReport r = h.storage_report();
  JsonWriter j;
  j.begin_object();
  j.field("file", path);
  j.field("kind", "hybrid");
  j.field("grid_step", h.grid_step());
  j.field("levels", h.levels());
  j.field("domain_width", h.domain_width());
  j.field("domain_height", h.domain_height());
  j.field("tb_vertices", std::uint64_t(r.tb_vertices));
  j.field("rings", std::uint64_t(r.rings));
  j.field("tin_vertices", std::uint64_t(r.tin_vertices));
  j.field("tin_triangles", std::uint64_t(r.tin_triangles));
  j.field("max_connectivity", std::uint64_t(r.max_connectivity));
  j.field("connectivity_bits", r.connectivity_bits);
  j.field("address_bits", r.address_bits);
  for (const hy::LevelReport& l : r.levels) {
    j.begin_object("level_" + std::to_string(l.level));
    j.field("cells", l.cells);
    j.field("nc", l.nc);
    j.field("cc", l.cc);
    j.field("pc", l.pc);
    j.field("pc_percent", l.pc_percent);
    j.field("max_connectivity", std::uint64_t(l.max_connectivity));
    j.field("l_max", std::uint64_t(l.l_max));
    j.field("bits_per_section", l.bits_per_section);
    j.field("sections", std::uint64_t(l.sections));
    j.field("gc_bits", l.gc_bits);
    j.field("vc_bits", l.vc_bits);
    j.field("tree_bits_per_pc", l.tree_bits_per_pc);
    j.field("tree_bits_max", l.tree_bits_max);
    j.end_object();
  }
  j.end_object();
  std::fputs((j.str() + "\n").c_str(), stdout);
  return 0;
}

int cmd_extract_hybrid(const Args& a) {
  const std::string path = a.get("--db"), out = a.get("--out");
  const std::string scheme = a.get_choice("--scheme", {"triangles", "subcells"}, "triangles");
  auto t = Clock::now();
  const blocks::BlockDatabase db = blocks::BlockDatabase::open(path);
  if (db.info().kind != "hybrid")
    throw std::runtime_error(path + ": not a hybrid database (kind '" + db.info().kind + "')");
  const auto blob = db.read_blob("hybrid");
  if (!blob) throw std::runtime_error(path + ": no 'hybrid' blob");
  const hy::HybridTerrain h = hy::HybridTerrain::decode(*blob, path);
  const int level = int(a.get_int("--grid-level", 0, 0, h.levels() - 1));
  const hy::HybridMesh m =
      h.extract(level, scheme == "subcells" ? hy::Scheme::SubCells : hy::Scheme::Triangles);
  print_line(strf(
      "extract %s grid level %d (%s): %zu triangles (grid %zu, TIN %zu, convexification %zu, corner %zu, "
      "%zu split at T-junctions), %zu vertices, %s",
      path.c_str(), level, scheme.c_str(), m.triangles.size(), m.grid_triangles, m.tin_triangles,
      m.convexification_triangles, m.corner_triangles, m.split_edges, m.points.size(),
      format_duration(ms_since(t)).c_str()));
  write_mesh_stage(hy::to_world(m, db.info().transform), out);
  return 0;
}

}  // namespace terralod::cli
