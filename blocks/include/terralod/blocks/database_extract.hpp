// Library entry point for using a built terrain: open a block database and extract the whole
// terrain as one watertight mesh within a given L-infinity error.
//
// Usage:
//   #include <terralod/blocks/database_extract.hpp>
//   namespace tb = terralod::blocks;
//   tb::ExtractedMesh m = tb::extract_mesh("terrain.db", /*max_error=*/2.0);   // metres
//   // m.measured_error <= 2.0, exact; m.mesh.vertices are sample indices of m.heightfield
//   terralod::pm::write_mesh(m.mesh, m.heightfield, "terrain.ply", terralod::pm::Units::World);
//
// Method: every block's PM is extracted at its own error e_b (first E), the seams are stitched
// (seam_stitch.hpp: the neighbours' border vertices are inserted, so shared vertices are the
// same samples and the mesh is watertight), the triangles created by stitching are measured
// exactly (pm::LInfError), and every block with a stitched triangle above E is extracted again
// at E/2 (then the stitched error is <= E/2 + E/2 = E, the bound proved in seam_stitch.hpp);
// this repeats until every triangle is within E. Finally every triangle of the result is
// measured exactly and the maximum is reported as measured_error (= mesh.error_bound).
//
// Contract: max_error finite and >= 0 (std::invalid_argument otherwise). The database must be
// complete (BuildError naming the file otherwise); corrupt blocks throw DatabaseError or
// pm::PmFormatError naming the block. The returned heightfield is the whole terrain assembled
// from the blocks, with the database's GridTransform (world metres).
// Memory: all block PMs decoded at once (about 12 bytes per sample plus 8 per sample for the
// assembled heightfield) plus the mesh.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/database_terrain.hpp"  // read_database_terrain
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/progressive_mesh.hpp"

namespace terralod::blocks {

struct ExtractedMesh {
  pm::Heightfield heightfield;  ///< the whole terrain (samples from the blocks)
  pm::TriangleMesh mesh;        ///< vertices: sample indices of heightfield; error_bound = measured_error
  double max_error = 0;         ///< requested E, metres
  double measured_error = 0;    ///< exact L-infinity error of the mesh (max over its triangles), metres
  std::size_t blocks = 0;
  std::size_t blocks_refined = 0;     ///< blocks re-extracted below E because of their seams
  std::size_t iterations = 0;         ///< extract + stitch rounds
  std::size_t inserted_vertices = 0;  ///< border vertices inserted by the final stitch
  std::size_t split_triangles = 0;    ///< triangles split by the final stitch
  double ms = 0;                      ///< wall time
};

/// Extracts the terrain of an open database at L-infinity error <= max_error (see above).
ExtractedMesh extract_mesh(const BlockDatabase& db, double max_error);

/// Opens `path` read-only and extracts (see above).
ExtractedMesh extract_mesh(const std::string& path, double max_error);

}  // namespace terralod::blocks
