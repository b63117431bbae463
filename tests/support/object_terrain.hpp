// The map-object tests' terrain (test_object_placement, test_object_shapes, test_object_drape):
// a generated 129 x 129 heightfield of 30 m samples, 900 m of relief in whole metres, in UTM
// zone 33N (sample (col, row) at easting 500015 + 30 col, northing 5001935 - 30 row), built
// into a block database of 4 x 4 PM blocks of 33 samples in the process's temporary folder; and
// cameras placed over it by sample.
//
// Usage:
//   static const terralod::test::ObjectTerrain t = terralod::test::make_object_terrain("drape", 33);
//   tp::Camera c = terralod::test::camera_over(t.hf, 15, 110, 250.0, 45.0, -20.0);
#pragma once

#include <gtest/gtest.h>

#include <string>

#include "geographic_tiff.hpp"  // epsg_wkt
#include "run_command.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/terrain_generator.hpp"
#include "terralod/pm/view.hpp"

namespace terralod::test {

/// EPSG:32633 (WGS 84 / UTM zone 33N) as WKT.
inline std::string utm33_wkt() { return epsg_wkt(32633); }

/// The terrain's sample -> world (UTM 33N) map.
inline pm::GridTransform object_terrain_transform() {
  return pm::GridTransform::north_up(500015.0, 5001935.0, 30.0, 30.0);
}

struct ObjectTerrain {
  pm::Heightfield hf;  ///< with its CRS, so object layers in any CRS can be added
  std::string db;      ///< the block database
};

/// The terrain of generator seed `seed`, its database in process_temp_dir(name).
inline ObjectTerrain make_object_terrain(const std::string& name, unsigned seed) {
  ObjectTerrain r;
  pm::TerrainOptions to;
  to.width = to.height = 129;
  to.seed = seed;
  to.spacing = 30.0;
  to.relief = 900.0;
  to.quantize_to_metres = true;
  r.hf = pm::generate_terrain(to);
  r.hf.transform = object_terrain_transform();
  r.hf.crs_transform = r.hf.transform;
  r.hf.crs_wkt = utm33_wkt();
  r.db = (process_temp_dir(name) / "t.db").string();
  blocks::DatabaseBuildOptions o;
  o.block_size = 33;
  o.threads = 2;
  blocks::build_database(r.hf, r.db, o);
  return r;
}

/// A 320 x 240 camera over sample (col, row), `above` metres over the sample there, looking
/// `yaw` degrees clockwise from north and `pitch` degrees above the horizon.
inline pm::Camera camera_over(const pm::Heightfield& hf, double col, double row, double above, double yaw,
                              double pitch) {
  pm::Camera c;
  const auto [x, y] = hf.transform.to_world(col, row);
  c.x = x, c.y = y;
  c.z = hf.at(int(col), int(row)) + above;
  c.yaw_deg = yaw, c.pitch_deg = pitch;
  c.width_px = 320, c.height_px = 240;
  return c;
}

}  // namespace terralod::test
