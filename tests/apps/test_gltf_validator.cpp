// The official glTF validator (Khronos glTF-Validator through `gltf-transform validate`, pinned
// in tools/gltf/package-lock.json) on the .glb and .gltf files `terralod extract` writes from a
// generated terrain: no errors and no warnings. A missing validator fails the test (it is
// installed by scripts/install-deps.sh), and a corrupted copy checks that the validator runs.
// `terralod export --format 3dtiles` is checked by tools/gltf/check_3dtiles.mjs: every glb
// through the same validator, and the tileset's tree.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "run_command.hpp"

namespace {

namespace fs = std::filesystem;
using terralod::test::lines_of;
using terralod::test::quote;
using terralod::test::run_command;
using terralod::test::slurp;

const fs::path& tmp_dir() { return terralod::test::process_temp_dir("gltf-validator"); }

struct Issue {
  std::string code, line;
  int severity = -1;  // 0 error, 1 warning, 2 info, 3 hint
};

struct Report {
  int status = -1;
  std::vector<Issue> issues;
  std::string raw;  // both streams, for failure messages

  std::size_t count(int severity) const {
    std::size_t n = 0;
    for (const Issue& i : issues) n += i.severity == severity;
    return n;
  }
};

/// Runs `gltf-transform validate FILE --format csv`. Its stdout is a CSV table: the header
/// "code,message,severity,pointer", then one row per issue, then a blank line; the message may
/// hold commas (then quoted), the pointer (a JSON pointer) does not, so severity is the second
/// field from the right. When an error was found, "error: Validation detected errors." follows
/// the table and the exit status is 1.
Report validate(const fs::path& file) {
  Report r;
  const terralod::test::CommandResult c =
      run_command(quote(TERRALOD_GLTF_VALIDATOR) + " validate " + quote(file.string()) + " --format csv");
  r.status = c.status;
  r.raw = "stdout:\n" + c.out + "\nstderr:\n" + c.err;
  const std::vector<std::string> lines = lines_of(c.out);
  if (lines.empty() || lines[0] != "code,message,severity,pointer") {
    ADD_FAILURE() << "unexpected validator output (no CSV header):\n" << r.raw;
    return r;
  }
  for (std::size_t i = 1; i < lines.size(); ++i) {
    const std::string& l = lines[i];
    if (l.empty()) break;  // the table's end; "error: Validation detected errors." may follow
    const std::size_t last = l.rfind(','), before = last == std::string::npos ? last : l.rfind(',', last - 1);
    if (before == std::string::npos) {
      ADD_FAILURE() << "unparsable validator row '" << l << "':\n" << r.raw;
      continue;
    }
    Issue issue;
    issue.code = l.substr(0, l.find(','));
    issue.severity = std::atoi(l.substr(before + 1, last - before - 1).c_str());
    issue.line = l;
    r.issues.push_back(issue);
  }
  return r;
}

/// Fails the test when the validator is not installed (a missing tool is a failure, not a skip).
void require_validator() {
  ASSERT_TRUE(fs::exists(TERRALOD_GLTF_VALIDATOR)) << "the glTF validator " << TERRALOD_GLTF_VALIDATOR
                                                   << " is missing: run scripts/install-deps.sh (it installs "
                                                      "Node.js and runs 'npm ci --prefix tools/gltf')";
}

terralod::test::CommandResult terralod(const std::string& args) {
  return terralod::test::run_tool(TERRALOD_CLI, args);
}

/// A generated terrain (30 m spacing, no CRS) written once per process.
const fs::path& dem() {
  static const fs::path path = [] {
    const fs::path p = tmp_dir() / "terrain.tif";
    const auto r = terralod("generate --size 97 --seed 7 --out " + quote(p.string()));
    EXPECT_EQ(r.status, 0) << r.err;
    return p;
  }();
  return path;
}

TEST(GltfValidator, ExtractedMeshesHaveNoErrorsOrWarnings) {
  ASSERT_NO_FATAL_FAILURE(require_validator());
  struct Case {
    std::string name, options;
  };
  for (const Case& c :
       {Case{"world.glb", "--max-error 2"}, Case{"world.gltf", "--max-error 2"},
        Case{"samples.glb", "--max-error 2 --units samples"}, Case{"full.glb", "--max-error 0"}}) {
    SCOPED_TRACE(c.name);
    const fs::path out = tmp_dir() / c.name;
    const auto e = terralod("extract --threads 1 --input " + quote(dem().string()) + " " + c.options +
                            " --out " + quote(out.string()));
    ASSERT_EQ(e.status, 0) << e.err;
    const Report r = validate(out);
    EXPECT_EQ(r.status, 0) << r.raw;
    EXPECT_EQ(r.count(0), 0u) << "errors:\n" << r.raw;
    EXPECT_EQ(r.count(1), 0u) << "warnings:\n" << r.raw;
    for (const Issue& i : r.issues) std::printf("%s: %s\n", c.name.c_str(), i.line.c_str());
  }
}

// The validator must see the file: a copy whose POSITION minimum is changed (same length, so
// the GLB stays well-formed) is reported as an error with a non-zero exit status.
TEST(GltfValidator, ReportsABrokenFile) {
  ASSERT_NO_FATAL_FAILURE(require_validator());
  const fs::path good = tmp_dir() / "control.glb", bad = tmp_dir() / "control_broken.glb";
  const auto e = terralod("extract --threads 1 --input " + quote(dem().string()) + " --max-error 5 --out " +
                          quote(good.string()));
  ASSERT_EQ(e.status, 0) << e.err;
  std::string bytes = slurp(good);
  const std::size_t min = bytes.find("\"min\":[");
  ASSERT_NE(min, std::string::npos);
  for (std::size_t i = min + 7; i < bytes.size() && bytes[i] != ','; ++i)
    if (bytes[i] == '-' || (bytes[i] >= '0' && bytes[i] <= '9')) bytes[i] = '9';
  std::ofstream(bad, std::ios::binary) << bytes;
  const Report r = validate(bad);
  EXPECT_NE(r.status, 0) << r.raw;
  bool min_mismatch = false;
  for (const Issue& i : r.issues)
    min_mismatch = min_mismatch || (i.code == "ACCESSOR_MIN_MISMATCH" && i.severity == 0);
  EXPECT_TRUE(min_mismatch) << r.raw;
}

/// A 97 x 97 Esri ASCII grid in WGS 84 longitude/latitude (1/1200 degree, across tile edges of
/// the geographic tiling) with its .prj: a small DEM with a CRS, written once per process.
const fs::path& geographic_dem() {
  static const fs::path path = [] {
    const fs::path p = tmp_dir() / "geographic.asc";
    std::ofstream a(p);
    a << "ncols 97\nnrows 97\nxllcenter -71.52\nyllcenter 44.47\ncellsize 0.000833333333333333\n";
    for (int r = 0; r < 97; ++r) {
      for (int c = 0; c < 97; ++c)
        a << 600 + 250 * std::sin(c * 0.11) * std::cos(r * 0.07) + 3.0 * ((c * 7 + r * 13) % 5)
          << (c < 96 ? " " : "\n");
    }
    std::ofstream(tmp_dir() / "geographic.prj")
        << R"(GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]],)"
           R"(PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433]])";
    return p;
  }();
  return path;
}

TEST(GltfValidator, ThreeDTilesExportIsValidTileByTile) {
  ASSERT_NO_FATAL_FAILURE(require_validator());
  const fs::path db = tmp_dir() / "geographic.db", out = tmp_dir() / "3dtiles";
  // --crs native: the tiles are exported from the DEM's own lon/lat samples (levels as asserted).
  auto r = terralod("build --threads 1 --block-size 33 --crs native --input " +
                    quote(geographic_dem().string()) + " --out " + quote(db.string()));
  ASSERT_EQ(r.status, 0) << r.err;
  r = terralod("export --threads 1 --format 3dtiles --db " + quote(db.string()) + " --out " +
               quote(out.string()));
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("3dtiles, levels 0..12"), std::string::npos) << r.out;
  const std::string check = "node " + quote(TERRALOD_3DTILES_CHECK) + " " + quote(out.string());
  const auto c = run_command(check);
  EXPECT_EQ(c.status, 0) << c.out << c.err;
  EXPECT_NE(c.out.find("\"problems\":[]"), std::string::npos) << c.out;
  EXPECT_NE(c.out.find("\"max_depth\":13"), std::string::npos) << c.out;  // root + levels 0..12
  // The checker sees the files: one glb with a changed POSITION minimum fails it.
  const fs::path victim = out / "12" / "2469" / "3060.glb";
  std::string bytes = slurp(victim);
  ASSERT_FALSE(bytes.empty()) << victim;
  const std::size_t min = bytes.find("\"min\":[");
  ASSERT_NE(min, std::string::npos);
  bytes[min + 7] = bytes[min + 7] == '1' ? '2' : '1';
  std::ofstream(victim, std::ios::binary | std::ios::trunc) << bytes;
  const auto bad = run_command(check);
  EXPECT_EQ(bad.status, 1) << bad.out;
  EXPECT_NE(bad.out.find("12/2469/3060.glb"), std::string::npos) << bad.out;
}

// --meshopt: every glb is EXT_meshopt_compression, valid as it is and, decoded by meshoptimizer's
// own decoder, valid in full and equal to the uncompressed export's tile (the same vertex bytes,
// the same triangles in the same order and winding): lossless. A changed compressed byte is seen.
TEST(GltfValidator, MeshoptExportDecodesToTheUncompressedTiles) {
  ASSERT_NO_FATAL_FAILURE(require_validator());
  const fs::path db = tmp_dir() / "geographic_meshopt.db", plain = tmp_dir() / "3dtiles_plain",
                 packed = tmp_dir() / "3dtiles_meshopt";
  // --crs native: the tiles are exported from the DEM's own lon/lat samples (levels as asserted).
  auto r = terralod("build --threads 1 --block-size 33 --crs native --input " +
                    quote(geographic_dem().string()) + " --out " + quote(db.string()));
  ASSERT_EQ(r.status, 0) << r.err;
  for (const auto& [dir, flag] : {std::pair{plain, ""}, std::pair{packed, " --meshopt"}}) {
    fs::remove_all(dir);
    r = terralod("export --threads 1 --format 3dtiles" + std::string(flag) + " --db " + quote(db.string()) +
                 " --out " + quote(dir.string()));
    ASSERT_EQ(r.status, 0) << r.out << r.err;
  }
  // The same tree, regions and geometricErrors: the compression changes no vertex.
  EXPECT_EQ(slurp(packed / "tileset.json"), slurp(plain / "tileset.json"));
  const std::string check = "node " + quote(TERRALOD_3DTILES_CHECK) + " " + quote(packed.string()) +
                            " --same-as " + quote(plain.string());
  const auto c = run_command(check);
  EXPECT_EQ(c.status, 0) << c.out << c.err;
  EXPECT_NE(c.out.find("\"problems\":[]"), std::string::npos) << c.out;
  const std::size_t glb = c.out.find("\"glb\":"), meshopt = c.out.find("\"meshopt\":");
  ASSERT_TRUE(glb != std::string::npos && meshopt != std::string::npos) << c.out;
  const long n = std::strtol(c.out.c_str() + glb + 6, nullptr, 10);
  EXPECT_GT(n, 50) << c.out;
  EXPECT_EQ(std::strtol(c.out.c_str() + meshopt + 10, nullptr, 10), n) << c.out;  // every glb compressed
  EXPECT_LT(fs::file_size(packed / "12" / "2469" / "3060.glb"),
            fs::file_size(plain / "12" / "2469" / "3060.glb"));
  // One byte of a compressed vertex stream changed: the decoded tile differs (or does not decode).
  const fs::path victim = packed / "12" / "2469" / "3060.glb";
  std::string bytes = slurp(victim);
  ASSERT_GT(bytes.size(), 200u) << victim;
  const std::size_t json_length = std::size_t(static_cast<unsigned char>(bytes[12])) |
                                  std::size_t(static_cast<unsigned char>(bytes[13])) << 8;
  const std::size_t at = 20 + json_length + 8 + 40;  // 40 bytes into the BIN chunk: the positions
  ASSERT_LT(at, bytes.size());
  bytes[at] = char(bytes[at] ^ 0x5a);
  std::ofstream(victim, std::ios::binary | std::ios::trunc) << bytes;
  const auto bad = run_command(check);
  EXPECT_EQ(bad.status, 1) << bad.out;
  EXPECT_NE(bad.out.find("12/2469/3060.glb"), std::string::npos) << bad.out;
}

}  // namespace
