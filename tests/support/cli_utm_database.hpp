// The small georeferenced block database the object command-line tests start from
// (test_cmd_objects, test_texture_symbols), built by the real tool: 65 x 65 samples of 30 m in
// UTM zone 33N, lower-left corner (500000, 5000000), heights 100 + (7 row + 3 col) mod 50 m,
// written as an ESRI ASCII grid with its .prj and built with 33-sample blocks.
//
// Usage:
//   terralod::test::build_utm_cli_database(cli, dir);   // dir/dem.asc, dem.prj, t.db; gtest-asserts
#pragma once

#include <cpl_conv.h>
#include <gtest/gtest.h>
#include <ogr_spatialref.h>

#include <filesystem>
#include <fstream>

#include "cli_texture_database.hpp"

namespace terralod::test {

inline void build_utm_cli_database(const CliRunner& cli, const std::filesystem::path& dir) {
  {
    std::ofstream f(dir / "dem.asc");
    f << "ncols 65\nnrows 65\nxllcorner 500000\nyllcorner 5000000\ncellsize 30\n";
    for (int r = 0; r < 65; ++r)
      for (int c = 0; c < 65; ++c) f << 100 + (r * 7 + c * 3) % 50 << (c + 1 < 65 ? " " : "\n");
  }
  OGRSpatialReference utm;
  ASSERT_EQ(utm.importFromEPSG(32633), OGRERR_NONE);
  char* wkt = nullptr;
  utm.exportToWkt(&wkt);
  std::ofstream(dir / "dem.prj") << wkt;
  CPLFree(wkt);
  ASSERT_EQ(cli.run("build --input " + quote((dir / "dem.asc").string()) + " --out " +
                    quote((dir / "t.db").string()) + " --block-size 33"),
            0);
}

}  // namespace terralod::test
