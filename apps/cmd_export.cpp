// terralod export: a built terrain as a tileset for CesiumJS and the other clients of Cesium's
// formats (blocks/terrain_export.hpp does the work).
#include <cstdio>
#include <string>

#include "commands.hpp"
#include "terralod/blocks/terrain_export.hpp"

namespace terralod::cli {

CommandSpec export_spec() {
  CommandSpec s;
  s.name = "export";
  s.summary = "Export a terrain database as quantized-mesh tiles (layer.json) or 3D Tiles (CesiumJS).";
  s.description =
      "Writes a quantized-mesh-1.0 tileset in the geographic TMS tiling CesiumJS expects (EPSG:4326,\n"
      "two tiles at level 0, y from the south): OUT/layer.json and OUT/z/x/y.terrain (gzip; serve\n"
      "them with 'Content-Encoding: gzip'). Load it with Cesium.CesiumTerrainProvider.fromUrl(URL).\n"
      "Each tile is an L-infinity mesh of the terrain's samples inside it, within CesiumJS's maximum\n"
      "geometric error for its level (6378137 * 2 pi * 0.25 / 130 / 2^z m) and at the deepest level\n"
      "within min(that, 1 m), measured on the tile as a client decodes it; layer.json's 'terralod'\n"
      "member gives each level's bound and measured error. A level that cannot meet its bound (its\n"
      "heights span more than 32,767 steps of twice it, or its tiles' 32768 x 32768 lattice of\n"
      "positions is coarser than the samples) is still written: the export warns which level and why,\n"
      "and exits with status 1. Neighbouring tiles of a level share\n"
      "their edge vertices exactly (no skirts needed). Heights are above the WGS 84 ellipsoid: the\n"
      "input's vertical datum (EGM96 for SRTM and when the input states none) is converted through\n"
      "PROJ; --vertical-datum overrides it. A DEM in a projected CRS is warped to longitude/latitude\n"
      "through GDAL (bilinear) on a grid no coarser than its samples (rows its north-south step\n"
      "apart, columns its east-west step apart where they are widest; around a pole, a polar\n"
      "stereographic DEM, every longitude from the pole to its farthest latitude), the terrain\n"
      "continued a sample beyond its edge so that its outermost samples are drawn as the others;\n"
      "a terrain without a CRS is refused. A database built with --crs\n"
      "auto (the default) or a named CRS is so resampled twice (DEM -> its warped grid ->\n"
      "longitude/latitude): on N44W072 the exported heights are 1.7 m from the DEM's samples on\n"
      "average, up to 31 m at cliffs and peaks; one built with --crs native exports the DEM's own\n"
      "samples, but its world frame is off by up to 1.1 % over a 1-degree tile at 44 N (0.9 %\n"
      "east-west at its edges).\n"
      "Beyond the terrain the surface is the ellipsoid. A killed export run again resumes\n"
      "(OUT/.terralod-export journals finished tiles); layer.json is written last, so an unfinished\n"
      "export lists no tile. Memory: the terrain as longitude/latitude samples (floats: 4 bytes a\n"
      "sample, 5 with holes, whatever the frame: a database in a projected or the default auto\n"
      "frame is warped to them by GDAL in chunks of 8 MiB, each reading the database's window, so\n"
      "the source is never held whole) plus one tile's mesh a thread.\n"
      "--format 3dtiles writes the same tile meshes as 3D Tiles 1.1: OUT/tileset.json (REPLACE\n"
      "refinement, bounding regions, each tile's geometricError its measured bound: the error at the\n"
      "samples plus the glTF quantization and the flat triangles' sag) and OUT/z/x/y.glb (glTF 2.0,\n"
      "ECEF relative to the tile centre, KHR_mesh_quantization); load it with\n"
      "Cesium.Cesium3DTileset.fromUrl(URL + '/tileset.json'). --meshopt compresses the glb content\n"
      "losslessly with EXT_meshopt_compression (CesiumJS, three.js and Babylon.js decode it; the\n"
      "extension is required by each file, so a client without it cannot draw the tiles).";
  s.options = {
      {"--db", "DB", "terrain database made by 'terralod build'", true},
      {"--out", "DIR", "output folder (created; must be empty or hold an earlier export)", true},
      {"--format", "FORMAT",
       "quantized-mesh (default: layer.json + .terrain) or 3dtiles (tileset.json + .glb)"},
      {"--max-level", "Z", "deepest level, 0..24 (default: the first whose tiles span <= 64 samples)"},
      {"--threads", "N", "worker threads (default: every core)"},
      {"--meshopt", "", "3dtiles only: compress the glb content with EXT_meshopt_compression"},
      {"--vertical-datum", "NAME",
       "the input heights' datum: egm96, egm2008, ellipsoid or a PROJ vertical CRS such as EPSG:5703\n"
       "(default: what the input states, else egm96)"},
  };
  return s;
}

int cmd_export(const Args& a) {
  blocks::ExportOptions o;
  const std::string format = a.get_choice("--format", {"quantized-mesh", "3dtiles"}, "quantized-mesh");
  o.format = format == "3dtiles" ? blocks::ExportFormat::Tiles3D : blocks::ExportFormat::QuantizedMesh;
  o.max_level = int(a.get_int("--max-level", -1, 0, 24));
  o.threads = int(a.get_int("--threads", 0, 1, 1024));
  o.vertical_datum = a.get("--vertical-datum");
  o.meshopt = a.has("--meshopt");
  const std::string db = a.get("--db"), out = a.get("--out");
  ProgressBar bar("export");
  o.progress = [&bar](const blocks::ExportProgress& p) {
    bar.update(p.tiles_total ? double(p.tiles_done) / double(p.tiles_total) : 1.0);
  };
  const blocks::ExportReport r = blocks::export_terrain(db, out, o);
  bar.finish();
  std::printf("export %s -> %s: %s, levels 0..%d, %zu tiles written, %zu reused, %s\n", db.c_str(),
              out.c_str(), format.c_str(), int(r.levels.size()) - 1, r.tiles_written, r.tiles_reused,
              format_duration(r.seconds * 1000.0).c_str());
  std::printf("  bounds %.9g, %.9g .. %.9g, %.9g degrees; samples: %s\n", r.bounds.west, r.bounds.south,
              r.bounds.east, r.bounds.north, r.horizontal.c_str());
  if (!r.heights_converted)
    std::printf("  heights above the WGS 84 ellipsoid, as the source gives them\n");
  else
    std::printf("  heights above the WGS 84 ellipsoid, converted from %s\n", r.vertical_datum.c_str());
  std::printf(
      "  level  tiles  vertices  triangles  bytes  bound(m)  max_error(m)  geometric_error(m)  "
      "height_step(m)\n");
  bool over = false;
  for (const blocks::ExportLevel& L : r.levels) {
    std::printf("  %5d  %5zu  %8zu  %9zu  %5zu  %8.4g  %12.4g  %18.4g  %14.4g\n", L.z, L.tiles, L.vertices,
                L.triangles, L.bytes, L.bound, L.max_error, L.geometric_error, L.height_step);
    over = over || L.max_error > L.bound;
  }
  // Why a level can miss its bound: a tile's heights are 16-bit steps of the level's height_step,
  // and its positions a 32768 x 32768 lattice (quantized-mesh); the mesh meets the bound where both
  // are fine enough.
  for (const blocks::ExportLevel& L : r.levels) {
    if (!(L.max_error > L.bound)) continue;
    if (0.5 * L.height_step > L.bound)
      std::printf(
          "  warning: level %d is measured above its bound: half its height step (%g m) is, since a tile's\n"
          "  heights are 32,767 steps and the widest tile of the level spans more than that many steps of\n"
          "  twice the bound (spikes or a fill value read as heights?)\n",
          L.z, 0.5 * L.height_step);
    else
      std::printf(
          "  warning: level %d is measured above its bound: a tile places its vertices on a 32768 x 32768\n"
          "  lattice, too coarse there for the samples (a step wider than their spacing, or the heights\n"
          "  change by more than the bound within one, as a deepest level far coarser than the automatic\n"
          "  --max-level, or spikes)\n",
          L.z);
  }
  return over ? 1 : 0;
}

}  // namespace terralod::cli
