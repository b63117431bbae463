// The small block database the texture command-line tests start from, built by the real tool.
//
// Usage (in a test that gets TERRALOD_CLI from terralod_add_tool_test):
//   terralod::test::CliRunner cli{TERRALOD_CLI};
//   terralod::test::build_cli_database(cli, dir / "dem.asc", dir / "t.db");   // gtest-asserts
//   std::string err;
//   EXPECT_EQ(cli.run("texture shade " + quote(db) + " --layer hill", &err), 0);
//
// Contract: the terrain is pm::generate_terrain's 65 x 65 of seed 11, relief 600 m, quantised
// to metres, written as an ESRI ASCII grid with 30 m cells at (0, 0) and built with 33-sample
// blocks. run() merges stderr into stdout (the text `out` gets) and prints it when the tool
// fails, so a failing test shows why.
#pragma once

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "run_command.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace terralod::test {

struct CliRunner {
  std::string tool;  ///< path of the terralod executable
  /// Runs `tool args` (args shell-quoted where needed); returns the exit status.
  int run(const std::string& args, std::string* out = nullptr) const {
    const CommandResult r = run_tool(tool, args, {.merge_stderr = true, .no_display = true});
    if (out) *out = r.err;
    if (r.status != 0) std::fprintf(stderr, "terralod %s:\n%s\n", args.c_str(), r.err.c_str());
    return r.status;
  }
};

/// Writes the terrain to `asc` and builds it into `db` with `terralod build` (gtest-asserts).
inline void build_cli_database(const CliRunner& cli, const std::filesystem::path& asc,
                               const std::filesystem::path& db) {
  pm::TerrainOptions to;
  to.width = to.height = 65;
  to.seed = 11;
  to.relief = 600;
  to.quantize_to_metres = true;
  const pm::Heightfield gen = pm::generate_terrain(to);
  {
    std::ofstream f(asc);
    f << "ncols 65\nnrows 65\nxllcorner 0\nyllcorner 0\ncellsize 30\nNODATA_value -9999\n";
    for (int r = 0; r < 65; ++r)
      for (int c = 0; c < 65; ++c) f << gen.at(c, r) << (c + 1 < 65 ? " " : "\n");
  }
  ASSERT_EQ(
      cli.run("build --input " + quote(asc.string()) + " --out " + quote(db.string()) + " --block-size 33"),
      0);
}

}  // namespace terralod::test
