// Exports a built terrain to the tilesets CesiumJS (and Cesium for Unreal/Unity, and other
// clients of Cesium's formats) load: quantized-mesh-1.0 tiles with a layer.json, or 3D Tiles 1.1
// with glTF 2.0 content.
//
// Usage:
//   namespace tb = terralod::blocks;
//   tb::ExportReport r = tb::export_terrain("terrain.db", "tiles", {.max_level = 12});
//   // tiles/layer.json, tiles/<z>/<x>/<y>.terrain; r.levels[z].max_error <= r.levels[z].bound
//   // CesiumJS: terrainProvider: await Cesium.CesiumTerrainProvider.fromUrl("http://host/tiles")
//
// What is written (quantized_mesh.hpp has the format):
//   - The geographic TMS tiling of EPSG:4326 (two tiles at level 0, y from the south), levels
//     0..max_level. Level 0's two tiles always exist; at level z >= 1 the tiles that overlap the
//     terrain (its samples plus two rings, see below). layer.json lists them in `available`, one
//     rectangle per level, and carries a "terralod" member: per level the bound and the measured
//     error (metres), the vertical datum, and the height step.
//   - Tile z/x/y: an L-infinity mesh (tile_mesher.hpp) of the terrain's samples inside the tile,
//     heights on the WGS 84 ellipsoid (geo_grid.hpp: the source's vertical datum converted
//     through PROJ, EGM96 by default). Its bound is Cesium's level maximum geometric error
//     (level_max_geometric_error(z), what CesiumJS assumes when it picks tiles), and at the
//     deepest level min(that, 1 m). The measured error is the largest |mesh - sample| over the
//     samples in the closed tile, the mesh as a client decodes it (quantized positions and
//     heights) and interpolated linearly in (longitude, latitude), as CesiumJS's
//     sampleTerrainMostDetailed does. When it exceeds the bound the tile is remeshed tighter
//     (down to 1/8 of the bound); the report and layer.json give what was reached.
//   - Neighbouring tiles of one level share their edge vertices exactly: the same quantized
//     positions and, through one height step per level (a power of two), the same decoded
//     heights; edge vertices take their normal from the terrain's gradient at the vertex, the
//     same on both sides (inside a tile, normals are the mesh's area-weighted ones). So a level's
//     tiles join without skirts (the edge lists are written; no skirt is needed).
//   - Beyond the terrain the surface is the ellipsoid (height 0, CesiumJS's own default globe):
//     one lattice ring continues the terrain's edge, and the next is the ellipsoid, so the terrain
//     ends in a one-sample apron and a cliff, not a slope across the tile.
//   - Large tiles get a regular grid of forced vertices (sag_divisions) so that the flat
//     triangles a client draws stay within a quarter of the level's error of the curved Earth,
//     up to 256 x 256 a tile: a deepest level cut at 8 degrees or wider (--max-level 4 or less)
//     may sag more between its vertices (up to 120 m on a level-0 tile), which the heights a
//     client samples (linear in longitude and latitude) do not show; 3D Tiles' geometricError and
//     skirts include it.
//   - Metadata extension: {"terralod": {"max_error": measured, "bound": bound}}, and on tiles of
//     levels 0, 10, 20, ... also "available": the next 10 levels of their subtree, as Cesium World
//     Terrain does (layer.json says "metadataAvailability": 10; CesiumJS needs it to record any
//     tile's metadata). Oct-encoded normals extension.
//
// 3D Tiles (ExportFormat::Tiles3D): the same tiling and the same tile meshes, as DIR/z/x/y.glb
// (glb_tile.hpp: decoded vertices in ECEF relative to the tile centre, KHR_mesh_quantization)
// under DIR/tileset.json: a content-less root over the Earth, the two level-0 tiles, and below
// every tile over the terrain its four children (REPLACE refinement draws children instead of
// the parent, so none may be missing), to max_level. Each tile's boundingVolume is a region
// (radians, heights of what is drawn, chord sag included) and its geometricError the tile's
// measured bound: the error at the samples as above, plus the glTF quantization's largest vertex
// displacement, plus the largest sag of a flat triangle below the curved surface through its
// corners; raised where needed so that it shrinks strictly from parent to child. All tiles of a
// level quantize on one lattice (shared vertices land on one point) and carry skirts 3 x the
// level bound deep, so neighbours of different levels show no crack. `meshopt` compresses the
// content losslessly (EXT_meshopt_compression).
//
// Resume: tiles are written atomically (temporary + rename) and journaled in
// DIR/.terralod-export (the export's parameters, then one line per finished tile). A killed
// export run again with the same database and options reuses the journaled tiles; with other
// parameters it starts over. The index (layer.json, tileset.json) is removed when an export
// starts and written last, so
// no tile of an unfinished export is ever listed as available. An output folder that is not
// empty and holds no journal is refused (ExportError), so nothing of the user's is overwritten.
//
// Errors: ExportError naming the file or folder (unwritable folder, a terrain without a CRS,
// an unknown vertical datum, an incomplete database); DatabaseError for corrupt databases.
// Costs: the terrain in memory as a GeoGrid (floats: 4 bytes per sample, 5 with holes; the
// database is read a row of blocks at a time; a terrain not on a north-up WGS 84
// longitude/latitude grid, such as one built in the default --crs auto frame, is warped to one
// through GDAL, which reads the database window by window into its chunks of 8 MiB and writes
// straight into the grid), plus one tile's greedy mesh per thread, whose measured points are the
// samples the tile covers (at the coarse levels, every sample of the terrain); each level reads
// every sample about once per greedy pass. Measured peaks (2 cores): N44W072 (1201^2) 61 MB built
// with --crs native, 82 MB in the default frame; its 3 x 3 mirror mosaic in the default frame
// (3690 x 3613 samples) 144 MB (196 MB with the grid in doubles, 444 MB when the warp held the
// source, its output and a copy at once).
#pragma once

#include <cstddef>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "terralod/blocks/quantized_mesh.hpp"

namespace terralod::blocks {

class ExportError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct ExportProgress {
  int level = 0;
  std::size_t tiles_done = 0, tiles_total = 0;  ///< over all levels
  double seconds = 0;                           ///< since the export started
};

enum class ExportFormat {
  QuantizedMesh,  ///< layer.json + z/x/y.terrain
  Tiles3D,        ///< tileset.json (3D Tiles 1.1) + z/x/y.glb
};

struct ExportOptions {
  ExportFormat format = ExportFormat::QuantizedMesh;
  /// Deepest level; -1: the first whose tiles span <= 64 samples (of the grid's ground spacing:
  /// its rows', or its columns' where they are widest, as on a grid around a pole).
  int max_level = -1;
  int threads = 0;                  ///< 0: every core
  std::string vertical_datum = {};  ///< the input heights' datum (geo_grid.hpp); "" = the source's
  /// Tiles3D only: glb content compressed with EXT_meshopt_compression (required by each file;
  /// CesiumJS, three.js and Babylon.js decode it). The decoded tile is the uncompressed one, bit
  /// for bit, so bounds and geometricErrors are unchanged. With QuantizedMesh: ExportError.
  bool meshopt = false;
  std::function<void(const ExportProgress&)> progress = {};
};

struct ExportLevel {
  int z = 0;
  std::size_t tiles = 0, vertices = 0, triangles = 0, bytes = 0;  ///< bytes gzipped
  double bound = 0;        ///< metres: what each tile of the level must meet
  double max_error = 0;    ///< metres: measured, the largest over the level's tiles
  double height_step = 0;  ///< metres: the level's height quantum
  /// metres: 3D Tiles, the largest tile geometricError before it is raised to shrink from parent
  /// to child (max_error + glTF quantization + chord sag); quantized-mesh: max_error.
  double geometric_error = 0;
};

struct ExportReport {
  std::vector<ExportLevel> levels;  ///< levels[z]
  GeoRect bounds;                   ///< the terrain's samples, degrees
  std::size_t tiles_written = 0, tiles_reused = 0;
  std::string vertical_datum;      ///< as resolved
  bool heights_converted = false;  ///< false: the heights were ellipsoidal already, and kept
  std::string horizontal;          ///< how the samples were placed in longitude/latitude
  double seconds = 0;
};

ExportReport export_terrain(const std::string& db_path, const std::string& out_dir,
                            const ExportOptions& options = {});

}  // namespace terralod::blocks
