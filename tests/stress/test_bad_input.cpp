// Bad input (issue 9, part 2): every case gets a clear error naming the file and the problem,
// nothing hangs, and no half-written output is left behind.
//
// Already covered elsewhere, not repeated here:
//   tests/blocks/test_dem_reader.cpp  missing files and a folder (MissingFiles); wrong-size,
//     truncated, odd, empty, 1 x 1, unnamed and all-void .hgt (BadHgtFiles); garbage .tif/.png,
//     an RGB PNG, a 3-band GeoTIFF, 1 x 1 and 5 x 1 rasters, all-void and beyond-the-pole
//     rasters (BadRastersAndImages); 15 malformed ASCII grids and a bad .prj (BadAsciiGrids);
//     random flips, insertions and truncations (CorruptedFilesGiveSoundResultsOrDemErrors).
//   tests/pm/test_pm_io.cpp  every truncation and every byte flip of a PM, bad magic, format
//     version 7, a missing file, forged headers with a valid checksum, encoding PMs outside the
//     contract, a write into a missing folder leaving nothing (WriteFailureNamesTheFileAndLeavesNothing).
//   tests/pm/test_mesh_io.cpp  mesh writes into a missing folder, unknown extensions, every
//     truncation of a PLY file.
//   tests/apps/test_cli.cpp  missing inputs and a missing output folder through the CLI.
// Added here: files that are not regular files (FIFO, device, folder) for every reader, which
// must not block; headers that declare far more data than the file holds; grey+alpha PNGs;
// PM format versions 0 and 2; writes that fail half-way (the temporary file is a link to
// /dev/full, which fails every write with ENOSPC) for write_pm, write_mesh and the CLI, which
// must leave neither the output nor its temporary, and must leave an older file intact.
#include <OpenImageIO/imageio.h>
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "build_threads.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/pm/mesh_io.hpp"
#include "terralod/pm/pm_io.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace {

namespace fs = std::filesystem;
namespace pm = terralod::pm;
namespace tb = terralod::blocks;

/// A fresh scratch folder for the current test (per process: ctest runs tests in parallel).
fs::path scratch() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir = fs::path(TERRALOD_TEST_TMP) /
                       ("bad_input_" + std::string(info->name()) + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

void write_bytes(const fs::path& path, const std::vector<std::uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  ASSERT_TRUE(out.good()) << path;
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
  ASSERT_TRUE(out.good()) << path;
}

std::string slurp(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

pm::ProgressiveMesh small_pm() {
  pm::TerrainOptions o;
  o.width = 17, o.height = 13, o.seed = 3, o.quantize_to_metres = true;
  pm::Heightfield hf = pm::generate_terrain(o);
  hf.source = "generated 17x13";
  return pm::ProgressiveMesh::build(hf, terralod::test::build_threads(1));
}

/// Runs f and fails unless it throws E whose what() starts with "<path>: " and contains every
/// needle; also fails if f takes more than 20 s (a read that blocks would hang instead; the
/// ctest timeout is the backstop).
template <class E, class F>
void expect_error(F&& f, const std::string& path, const std::vector<std::string>& needles) {
  const auto t0 = std::chrono::steady_clock::now();
  try {
    f();
    ADD_FAILURE() << "no error for " << path;
  } catch (const E& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind(path + ": ", 0), 0u) << "message does not start with the path: " << what;
    for (const std::string& n : needles)
      EXPECT_NE(what.find(n), std::string::npos) << "lacks '" << n << "': " << what;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "wrong exception type for " << path << ": " << e.what();
  }
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(20)) << path;
}

// ------------------------------------------------------------------------------------------
// Files that are not regular files: a FIFO (opening it for reading would block until a writer
// came), a character device that never ends, a folder. Root ignores chmod 000, so these are
// the unreadable files a test can make for real.

TEST(BadInput, NonRegularFilesAreRejectedWithoutBlocking) {
  const fs::path dir = scratch();
  for (const char* name : {"N10E020.hgt", "grid.asc", "image.png", "raster.tif", "terrain.pm", "mesh.ply"}) {
    SCOPED_TRACE(name);
    const fs::path fifo = dir / (std::string("fifo_") + name);
    // The .hgt reader takes the tile corner from the name; keep it first.
    const fs::path fifo_path = std::string(name).ends_with(".hgt") ? dir / "fifo" / name : fifo;
    fs::create_directories(fifo_path.parent_path());
    ASSERT_EQ(::mkfifo(fifo_path.c_str(), 0600), 0) << fifo_path;
    const fs::path dev = dir / "dev" / name;  // a link to /dev/zero: endless zeros
    fs::create_directories(dev.parent_path());
    fs::create_symlink("/dev/zero", dev);
    const fs::path folder = dir / "folders" / name;
    fs::create_directories(folder);
    for (const fs::path& p : {fifo_path, dev, folder}) {
      const std::string s = p.string();
      if (s.ends_with(".pm")) {
        expect_error<pm::PmFormatError>([&] { (void)pm::read_pm(s); }, s, {"not a regular file"});
      } else if (s.ends_with(".ply")) {
        continue;  // see ReadMeshRejectsNonRegularFiles below
      } else {
        expect_error<tb::DemError>([&] { (void)tb::read_dem(s); }, s, {"not a regular file"});
      }
    }
  }
}

// read_ply and read_obj (through read_mesh) refuse anything that exists and is not a regular
// file before opening it: a FIFO would block them, a link to /dev/zero would feed them until
// memory runs out, and a folder made the stream throw without the path.
TEST(BadInput, ReadMeshRejectsNonRegularFiles) {
  const fs::path dir = scratch();
  for (const char* ext : {".ply", ".obj"}) {
    const fs::path folder = dir / ("folder" + std::string(ext)), fifo = dir / ("fifo" + std::string(ext)),
                   dev = dir / ("zero" + std::string(ext));
    fs::create_directories(folder);
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    fs::create_symlink("/dev/zero", dev);
    for (const fs::path& p : {folder, fifo, dev})
      expect_error<std::runtime_error>([&] { (void)pm::read_mesh(p.string()); }, p.string(),
                                       {"not a regular file"});
  }
}

// ------------------------------------------------------------------------------------------
// Headers that promise more than the file holds must fail before allocating for the promise.

TEST(BadInput, AsciiGridDeclaringMoreValuesThanTheFileHoldsFailsFast) {
  const fs::path dir = scratch();
  // 30000 x 30000 = 9e8 values (7.2 GB of doubles) declared in a 90-byte file.
  const fs::path asc = dir / "huge.asc";
  write_text(asc, "ncols 30000\nnrows 30000\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2 3 4\n");
  // Before the fix this allocated (and zeroed) 7.2 GB, then reported "data ends after 4 of ...".
  expect_error<tb::DemError>([&] { (void)tb::read_dem(asc.string()); }, asc.string(),
                             {"header declares 30000 x 30000 = 900000000 values", "only 67 bytes"});
}

TEST(BadInput, TruncatedHgtTilesNameTheExpectedSize) {
  const fs::path dir = scratch();
  // An SRTM1 tile (3601 x 3601) cut after 1000 bytes, and an SRTM3 tile missing one byte.
  const fs::path cut = dir / "N45E007.hgt";
  write_bytes(cut, std::vector<std::uint8_t>(1000, 0));
  expect_error<tb::DemError>([&] { (void)tb::read_dem(cut.string()); }, cut.string(),
                             {"1000 bytes", "not that of a square grid"});
  const fs::path odd = dir / "N46E007.hgt";
  write_bytes(odd, std::vector<std::uint8_t>(std::size_t(1201) * 1201 * 2 - 1, 0));
  expect_error<tb::DemError>([&] { (void)tb::read_dem(odd.string()); }, odd.string(), {"2884801 bytes"});
}

TEST(BadInput, ImagesThatAreNotHeightmaps) {
  const fs::path dir = scratch();
  auto write_png = [&](const fs::path& path, int channels) {
    auto out = OIIO::ImageOutput::create(path.string());
    ASSERT_TRUE(out);
    OIIO::ImageSpec spec(4, 3, channels, OIIO::TypeDesc::UINT16);
    std::vector<std::uint16_t> px(std::size_t(12 * channels), 300);
    ASSERT_TRUE(out->open(path.string(), spec));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT16, px.data()));
    ASSERT_TRUE(out->close());
  };
  for (int channels : {4}) {  // RGBA (RGB is in test_dem_reader; grey + alpha is read there)
    const fs::path png = dir / ("c" + std::to_string(channels) + ".png");
    write_png(png, channels);
    expect_error<tb::DemError>([&] { (void)tb::read_dem(png.string()); }, png.string(),
                               {"has " + std::to_string(channels) + " channels", "heightmap must have one"});
  }
  // A PM file renamed to .png.
  const fs::path fake = dir / "terrain.png";
  write_bytes(fake, pm::encode_pm(small_pm()));
  expect_error<tb::DemError>([&] { (void)tb::read_dem(fake.string()); }, fake.string(),
                             {"cannot read it as an image"});
}

TEST(BadInput, MultiBandFloatGeoTiffWithNaN) {
  const fs::path dir = scratch();
  GDALAllRegister();
  GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GTiff");
  ASSERT_NE(drv, nullptr);
  const fs::path tif = dir / "two_bands.tif";
  {
    GDALDatasetUniquePtr ds(drv->Create(tif.c_str(), 6, 5, 2, GDT_Float32, nullptr));
    ASSERT_TRUE(ds);
    double gt[6] = {500000.0, 10.0, 0.0, 5000050.0, 0.0, -10.0};
    ds->SetGeoTransform(gt);
  }
  expect_error<tb::DemError>([&] { (void)tb::read_dem(tif.string()); }, tif.string(),
                             {"has 2 bands", "a DEM must have one"});
}

// ------------------------------------------------------------------------------------------
// PM files of other versions and kinds (version 7, bad magic, truncation and flips are in
// tests/pm/test_pm_io.cpp).

TEST(BadInput, PmFilesOfOtherFormatVersions) {
  const fs::path dir = scratch();
  const std::vector<std::uint8_t> good = pm::encode_pm(small_pm());
  for (std::uint32_t version : {0u, 2u, 0xffffffffu}) {
    std::vector<std::uint8_t> b = good;
    for (int i = 0; i < 4; ++i) b[8 + std::size_t(i)] = std::uint8_t(version >> (8 * i));
    const fs::path path = dir / ("v" + std::to_string(version) + ".pm");
    write_bytes(path, b);
    expect_error<pm::PmFormatError>(
        [&] { (void)pm::read_pm(path.string()); }, path.string(),
        {"format version " + std::to_string(version) + " is not supported", "this build reads version 1"});
  }
  // A DEM given where a PM is expected.
  const fs::path hgt = dir / "N10E020.pm";
  write_bytes(hgt, std::vector<std::uint8_t>(50, 0));
  expect_error<pm::PmFormatError>([&] { (void)pm::read_pm(hgt.string()); }, hgt.string(), {"bad magic"});
}

// ------------------------------------------------------------------------------------------
// Writes that fail half-way leave nothing behind, and never damage an older file.

/// Makes `path`.tmp a symbolic link to /dev/full, so that the writer's temporary file opens
/// fine and every write or flush to it fails with ENOSPC.
bool tmp_to_dev_full(const fs::path& path) {
  if (!fs::exists("/dev/full")) return false;
  fs::create_symlink("/dev/full", path.string() + ".tmp");
  return true;
}

void expect_nothing_left(const fs::path& path) {
  EXPECT_FALSE(fs::exists(fs::symlink_status(path))) << path << " was left behind";
  EXPECT_FALSE(fs::exists(fs::symlink_status(path.string() + ".tmp"))) << path << ".tmp was left behind";
}

TEST(BadInput, WritePmThatFailsHalfWayLeavesNothing) {
  const fs::path dir = scratch();
  const pm::ProgressiveMesh p = small_pm();
  const fs::path out = dir / "full_disk.pm";
  if (!tmp_to_dev_full(out)) GTEST_SKIP() << "/dev/full absent";
  expect_error<std::runtime_error>([&] { pm::write_pm(p, out.string()); }, out.string(), {"No space left"});
  expect_nothing_left(out);

  // An older file at the path survives a failed write untouched.
  const fs::path old = dir / "old.pm";
  pm::write_pm(p, old.string());
  const std::string before = slurp(old);
  ASSERT_TRUE(tmp_to_dev_full(old));
  EXPECT_THROW(pm::write_pm(small_pm(), old.string()), std::runtime_error);
  EXPECT_EQ(slurp(old), before);
  EXPECT_FALSE(fs::exists(fs::symlink_status(old.string() + ".tmp")));
  EXPECT_TRUE(pm::read_pm(old.string()) == p);

  // A folder where the file should go: the rename fails, the temporary is removed.
  const fs::path taken = dir / "taken.pm";
  fs::create_directories(taken / "inside");
  expect_error<std::runtime_error>([&] { pm::write_pm(p, taken.string()); }, taken.string(),
                                   {"cannot rename"});
  EXPECT_TRUE(fs::is_directory(taken / "inside"));
  EXPECT_FALSE(fs::exists(taken.string() + ".tmp"));
}

TEST(BadInput, WriteMeshThatFailsHalfWayLeavesNothing) {
  const fs::path dir = scratch();
  const pm::ProgressiveMesh p = small_pm();
  const pm::TriangleMesh m = p.extract(1.0);
  for (const char* name : {"full_disk.ply", "full_disk.obj", "full_disk.glb", "full_disk.gltf"}) {
    const fs::path out = dir / name;
    if (!tmp_to_dev_full(out)) GTEST_SKIP() << "/dev/full absent";
    expect_error<std::runtime_error>(
        [&] { pm::write_mesh(m, p.heightfield(), out.string(), pm::Units::World); }, out.string(), {});
    expect_nothing_left(out);
  }
}

// ------------------------------------------------------------------------------------------
// The command-line tool: exit 1, one line naming the file and the problem, no partial output.

#ifdef TERRALOD_CLI
struct CliResult {
  int status = -1;
  std::string out, err;
};

std::string quote(const std::string& s) {
  std::string q = "'";
  for (const char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

CliResult terralod(const fs::path& dir, const std::string& args) {
  const fs::path out = dir / "stdout.txt", err = dir / "stderr.txt";
  const std::string cmd = quote(TERRALOD_CLI) + " " + args + " >" + quote(out.string()) + " 2>" +
                          quote(err.string()) + " </dev/null";
  const int raw = std::system(cmd.c_str());
  CliResult r;
  r.status = (raw != -1 && WIFEXITED(raw)) ? WEXITSTATUS(raw) : -1;
  r.out = slurp(out);
  r.err = slurp(err);
  return r;
}

/// Exit status 1 and one error line "terralod: <file>: <problem>", the last on stderr (progress
/// lines of earlier stages may precede it).
void expect_cli_error(const CliResult& r, const std::string& file, const std::vector<std::string>& needles) {
  EXPECT_EQ(r.status, 1) << r.err;
  std::vector<std::string> errors;
  std::istringstream in(r.err);
  std::string last;
  for (std::string l; std::getline(in, l);) {
    if (l.rfind("terralod: ", 0) == 0) errors.push_back(l);
    last = l;
  }
  ASSERT_EQ(errors.size(), 1u) << r.err;
  EXPECT_EQ(errors[0], last) << r.err;
  EXPECT_EQ(errors[0].rfind("terralod: " + file + ": ", 0), 0u)
      << "does not name " << file << " first: " << r.err;
  for (const std::string& n : needles)
    EXPECT_NE(errors[0].find(n), std::string::npos) << "lacks '" << n << "': " << r.err;
}

TEST(BadInputCli, PmWhoseWriteFailsLeavesNoPartialFile) {
  const fs::path dir = scratch();
  const fs::path dem = dir / "grid.asc";
  write_text(dem, "ncols 4\nnrows 3\nxllcorner 0\nyllcorner 0\ncellsize 10\n1 2 3 4\n5 6 7 8\n9 10 11 12\n");
  const fs::path out = dir / "out.pm";
  if (!tmp_to_dev_full(out)) GTEST_SKIP() << "/dev/full absent";
  const CliResult r =
      terralod(dir, "pm --threads 1 --input " + quote(dem.string()) + " --out " + quote(out.string()));
  expect_cli_error(r, out.string(), {"No space left"});
  expect_nothing_left(out);

  const fs::path mesh = dir / "out.ply";
  ASSERT_TRUE(tmp_to_dev_full(mesh));
  const CliResult e = terralod(dir, "extract --threads 1 --input " + quote(dem.string()) +
                                        " --max-error 1 --out " + quote(mesh.string()));
  expect_cli_error(e, mesh.string(), {});
  expect_nothing_left(mesh);
}

TEST(BadInputCli, BadInputsNameTheFileAndTheProblem) {
  const fs::path dir = scratch();
  // A truncated PM, a PM of another version, an RGB-like image, a FIFO.
  const std::vector<std::uint8_t> good = pm::encode_pm(small_pm());
  const fs::path cut = dir / "cut.pm";
  write_bytes(cut, std::vector<std::uint8_t>(good.begin(), good.begin() + std::ptrdiff_t(good.size() / 2)));
  std::vector<std::uint8_t> v2 = good;
  v2[8] = 2;
  const fs::path future = dir / "future.pm";
  write_bytes(future, v2);
  const fs::path fifo = dir / "pipe.pm";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const fs::path huge = dir / "huge.asc";
  write_text(huge, "ncols 30000\nnrows 30000\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2 3 4\n");

  expect_cli_error(terralod(dir, "info " + quote(cut.string())), cut.string(), {"truncated"});
  expect_cli_error(terralod(dir, "extract --input " + quote(future.string()) + " --max-error 1 --out " +
                                     quote((dir / "x.ply").string())),
                   future.string(), {"format version 2 is not supported"});
  expect_cli_error(terralod(dir, "info " + quote(fifo.string())), fifo.string(), {"not a regular file"});
  const fs::path never = dir / "never.pm";
  expect_cli_error(terralod(dir, "pm --input " + quote(huge.string()) + " --out " + quote(never.string())),
                   huge.string(), {"30000 x 30000"});
  expect_nothing_left(never);
  EXPECT_FALSE(fs::exists(dir / "x.ply"));
}
#endif

}  // namespace
