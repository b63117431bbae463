// Writes the seed corpora of the fuzz targets: small valid inputs of every format they read.
//
// Usage: terralod_fuzz_seeds CORPUS_DIR   (writes CORPUS_DIR/fuzz_pm_decoder/seed_*,
// CORPUS_DIR/fuzz_dem_reader/seed_*, CORPUS_DIR/fuzz_block_database/seed_* and
// CORPUS_DIR/fuzz_block_summaries/seed_*; existing seeds are overwritten, other files are kept).
// DEM seeds start with the selector byte of fuzz_dem_reader.cpp (0 .hgt, 1 .asc, 2 .png, 3 .tif,
// +4 = keep voids as holes). Block-summaries seeds start with the two grid selector bytes of
// fuzz_block_summaries.cpp. Mesh seeds start with the selector byte of fuzz_mesh_reader.cpp
// (0 .ply, 1 .obj). JSON seeds (CORPUS_DIR/fuzz_json/seed_*) are plain text.
#include <OpenImageIO/imageio.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>
#include <sqlite3.h>
#include <zlib.h>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "terralod/blocks/active_region.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/pm/mesh_io.hpp"
#include "terralod/pm/pm_io.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace {

namespace fs = std::filesystem;
namespace pm = terralod::pm;
using Bytes = std::vector<std::uint8_t>;

void write(const fs::path& path, const Bytes& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

Bytes slurp(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return Bytes(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

Bytes with_selector(std::uint8_t selector, const Bytes& file) {
  Bytes b{selector};
  b.insert(b.end(), file.begin(), file.end());
  return b;
}

pm::Heightfield terrain(int w, int h, bool metres) {
  pm::TerrainOptions opt;
  opt.width = w;
  opt.height = h;
  opt.seed = 9;
  opt.relief = 50.0;
  opt.quantize_to_metres = metres;
  pm::Heightfield hf = pm::generate_terrain(opt);
  hf.source = "seed";
  hf.frame = "seed frame";
  return hf;
}

void pm_seeds(const fs::path& dir) {
  pm::BuildOptions one_thread;
  one_thread.threads = 1;
  // 9 x 9, whole metres (quantized heights), full hierarchy.
  write(dir / "seed_9x9_metres.pm",
        pm::encode_pm(pm::ProgressiveMesh::build(terrain(9, 9, true), one_thread)));
  // 9 x 9, arbitrary doubles (raw height planes).
  write(dir / "seed_9x9_doubles.pm",
        pm::encode_pm(pm::ProgressiveMesh::build(terrain(9, 9, false), one_thread)));
  // 8 x 7 with a 2 x 2 hole (void mask, dropped faces) and the samples-only metric.
  pm::Heightfield holes = terrain(8, 7, true);
  std::vector<std::uint8_t> mask(holes.size(), 1);
  for (int r = 3; r < 5; ++r)
    for (int c = 3; c < 5; ++c) {
      mask[std::size_t(r) * 8 + c] = 0;
      holes.at(c, r) = 0.0;
    }
  holes.set_mask(mask);
  holes.voids = {4, 0};
  pm::BuildOptions samples = one_thread;
  samples.metric = pm::ErrorMetric::Samples;
  write(dir / "seed_8x7_holes.pm", pm::encode_pm(pm::ProgressiveMesh::build(holes, samples)));
  // 2 x 2, the smallest grid.
  write(dir / "seed_2x2.pm", pm::encode_pm(pm::ProgressiveMesh::build(terrain(2, 2, true), one_thread)));
}

void dem_seeds(const fs::path& dir, const fs::path& tmp) {
  // .hgt: 5 x 5 big-endian int16, one void (-32768) in the middle.
  Bytes hgt;
  for (int i = 0; i < 25; ++i) {
    const auto v = std::uint16_t(i == 12 ? -32768 : 100 + 7 * i - (i % 5) * 3);
    hgt.push_back(std::uint8_t(v >> 8));
    hgt.push_back(std::uint8_t(v & 0xff));
  }
  write(dir / "seed_hgt", with_selector(0, hgt));
  write(dir / "seed_hgt_holes", with_selector(4, hgt));

  // .asc: 4 x 3 with NODATA, corner and centre variants.
  const std::string asc =
      "ncols 4\nnrows 3\nxllcorner 500000\nyllcorner 5000000\ncellsize 0.5\nNODATA_value -9999\n"
      "1 2 3 4\n5 -9999 7 8\n9.5 10 11 1e2\n";
  write(dir / "seed_asc", with_selector(1, Bytes(asc.begin(), asc.end())));
  const std::string asc2 = "NCOLS 3\nNROWS 2\nXLLCENTER -71.5\nYLLCENTER 44\nDX 0.1\nDY 0.2\n-1 0 1\n2 3 4\n";
  write(dir / "seed_asc_dxdy_holes", with_selector(5, Bytes(asc2.begin(), asc2.end())));

  // .png: 5 x 4 grey, 8 and 16 bits.
  auto png = [&](const char* name, OIIO::TypeDesc type, std::uint8_t selector) {
    const fs::path path = tmp / (std::string(name) + ".png");
    auto out = OIIO::ImageOutput::create(path.string());
    if (!out) throw std::runtime_error("OpenImageIO cannot write PNG: " + OIIO::geterror());
    std::vector<std::uint16_t> px(20);
    for (int i = 0; i < 20; ++i) px[std::size_t(i)] = std::uint16_t(i * 11 % 200);
    OIIO::ImageSpec spec(5, 4, 1, type);
    if (!out->open(path.string(), spec) || !out->write_image(OIIO::TypeDesc::UINT16, px.data()) ||
        !out->close())
      throw std::runtime_error("OpenImageIO cannot write " + path.string() + ": " + out->geterror());
    write(dir / (std::string("seed_") + name), with_selector(selector, slurp(path)));
  };
  png("png8", OIIO::TypeDesc::UINT8, 2);
  png("png16", OIIO::TypeDesc::UINT16, 2);

  // .tif: GeoTIFFs through GDAL: int16 UTM with nodata, float32 geographic, and a plain one.
  GDALAllRegister();
  auto tif = [&](const char* name, GDALDataType type, int epsg, bool nodata, bool georef,
                 std::uint8_t selector) {
    const fs::path path = tmp / (std::string(name) + ".tif");
    GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GTiff");
    if (!drv) throw std::runtime_error("GDAL has no GTiff driver");
    GDALDatasetUniquePtr ds(drv->Create(path.c_str(), 5, 4, 1, type, nullptr));
    if (!ds) throw std::runtime_error("GDAL cannot create " + path.string());
    if (georef) {
      double gt[6] = {500000.0, 30.0, 0.0, 5000120.0, 0.0, -30.0};
      if (epsg == 4326) {
        gt[0] = -72.0, gt[1] = 0.01, gt[3] = 45.0, gt[5] = -0.01;
      }
      ds->SetGeoTransform(gt);
      OGRSpatialReference srs;
      srs.importFromEPSG(epsg);
      srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
      ds->SetSpatialRef(&srs);
    }
    GDALRasterBand* band = ds->GetRasterBand(1);
    if (nodata) band->SetNoDataValue(-500.0);
    std::vector<double> z(20);
    for (int i = 0; i < 20; ++i) z[std::size_t(i)] = (i == 7 && nodata) ? -500.0 : 10.0 * i - 3.0;
    if (band->RasterIO(GF_Write, 0, 0, 5, 4, z.data(), 5, 4, GDT_Float64, 0, 0) != CE_None)
      throw std::runtime_error("GDAL cannot write " + path.string());
    ds.reset();
    write(dir / (std::string("seed_") + name), with_selector(selector, slurp(path)));
  };
  tif("tif_utm_int16", GDT_Int16, 32633, true, true, 3);
  tif("tif_geo_float32_holes", GDT_Float32, 4326, true, true, 7);
  tif("tif_plain_uint16", GDT_UInt16, 0, false, false, 3);
}

/// Small valid block databases: two block PMs, a named blob, two texture tiles and meta, as
/// written by BlockDatabase (WAL mode, 4096-byte pages), and the same content repacked by SQLite
/// into 512-byte pages, in WAL and in rollback-journal mode (ten times smaller: mutations reach
/// every table's pages more often).
void db_seeds(const fs::path& dir, const fs::path& tmp) {
  namespace tb = terralod::blocks;
  const fs::path path = tmp / "seed.db";
  for (const char* suffix : {"", "-wal", "-shm"}) fs::remove(path.string() + suffix);
  pm::BuildOptions one_thread;
  one_thread.threads = 1;
  {
    tb::DatabaseInfo info;
    info.grid_width = 9;
    info.grid_height = 5;
    info.transform = pm::GridTransform::north_up(500000.0, 5000000.0, 30.0, 30.0);
    info.crs_wkt = "LOCAL_CS[\"seed\"]";
    info.block_size = 5;
    info.build_parameters = R"({"block_size":5})";
    info.source = "seed.hgt";
    auto db = tb::BlockDatabase::create(path.string(), info);
    db.put_block({0, 0}, pm::encode_pm(pm::ProgressiveMesh::build(terrain(5, 5, true), one_thread)));
    db.put_block({1, 0}, pm::encode_pm(pm::ProgressiveMesh::build(terrain(2, 2, true), one_thread)));
    db.put_blob("tree", Bytes{1, 2, 3, 4, 5, 6, 7, 8});
    db.put_texture_tile("ortho", 0, 0, Bytes(40, 0x7f));
    db.put_texture_tile("ortho", 1, 1, Bytes{});
    db.set_meta("build_complete", "1");
  }  // closed: checkpointed into the main file, WAL removed
  write(dir / "seed_wal_4k.db", slurp(path));
  for (const char* mode : {"WAL", "DELETE"}) {
    sqlite3* db = nullptr;
    const std::string sql = std::string("PRAGMA journal_mode = DELETE; PRAGMA page_size = 512; VACUUM; ") +
                            "PRAGMA journal_mode = " + mode;
    char* err = nullptr;
    const bool ok = sqlite3_open(path.c_str(), &db) == SQLITE_OK &&
                    sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &err) == SQLITE_OK;
    const std::string msg = err ? err : sqlite3_errmsg(db);
    sqlite3_free(err);
    sqlite3_close(db);
    if (!ok) throw std::runtime_error("cannot repack " + path.string() + ": " + msg);
    write(dir / (std::string("seed_") + (mode[0] == 'W' ? "wal" : "rollback") + "_512.db"), slurp(path));
  }
  // Check that the repacked seeds still open and read.
  for (const char* name : {"seed_wal_512.db", "seed_rollback_512.db"}) {
    const fs::path copy = tmp / name;
    fs::copy_file(dir / name, copy, fs::copy_options::overwrite_existing);
    const auto db = tb::BlockDatabase::open(copy.string());
    if (db.blocks().size() != 2 || !db.check_integrity().ok)
      throw std::runtime_error("bad seed " + copy.string());
  }
}

/// Summaries of every block of hf in blocks of block_size samples, stand-ins made by `o`.
std::vector<terralod::blocks::BlockSummary> summaries(const pm::Heightfield& hf,
                                                      const terralod::blocks::BlockGrid& g,
                                                      const terralod::blocks::StandinOptions& o) {
  namespace tb = terralod::blocks;
  pm::BuildOptions one_thread;
  one_thread.threads = 1;
  std::vector<tb::BlockSummary> out;
  for (std::size_t i = 0; i < g.block_count(); ++i) {
    const tb::SampleRect d = g.domain(g.key(i));
    pm::Heightfield block(d.width(), d.height());
    for (int r = 0; r < d.height(); ++r)
      for (int c = 0; c < d.width(); ++c) block.at(c, r) = hf.at(d.col0 + c, d.row0 + r);
    out.push_back(tb::summarize_block(pm::ProgressiveMesh::build(block, one_thread), g.key(i), o));
  }
  return out;
}

/// "block_summaries" blobs (active_region.cpp) behind fuzz_block_summaries.cpp's selector bytes:
/// version 2 with TIN, grid and two-triangle stand-ins of a 17 x 13 terrain in 9-sample blocks
/// (2 x 2 blocks, the last row 5 samples high), a 289-point grid stand-in (u16 indices) of a
/// 17 x 17 block, and the 17 x 13 terrain's two-triangle summaries as a version 1 blob.
void summaries_seeds(const fs::path& dir) {
  namespace tb = terralod::blocks;
  const pm::Heightfield hf = terrain(17, 13, false);
  const tb::BlockGrid g(17, 13, 9, pm::GridTransform::identity());
  // Selector: B = 9 (k = 2); last column 2 + 7 = 9 samples wide, last row 2 + 3 = 5 high.
  const Bytes sel{2, 0x37};
  auto opt = [](tb::StandinKind kind, std::size_t points) {
    tb::StandinOptions o;
    o.kind = kind;
    o.max_points = points;
    return o;
  };
  Bytes tin = sel, grid = sel, two = sel;
  const Bytes tin_blob = tb::encode_block_summaries(g, summaries(hf, g, opt(tb::StandinKind::Tin, 12)));
  tin.insert(tin.end(), tin_blob.begin(), tin_blob.end());
  write(dir / "seed_v2_tin", tin);
  const Bytes grid_blob = tb::encode_block_summaries(g, summaries(hf, g, opt(tb::StandinKind::Grid, 9)));
  grid.insert(grid.end(), grid_blob.begin(), grid_blob.end());
  write(dir / "seed_v2_grid", grid);
  const auto two_sums = summaries(hf, g, opt(tb::StandinKind::TwoTriangles, 4));
  const Bytes two_blob = tb::encode_block_summaries(g, two_sums);
  two.insert(two.end(), two_blob.begin(), two_blob.end());
  write(dir / "seed_v2_two_triangle", two);

  // One 17 x 17 block (B = 17, k = 3, both nibbles 15 -> 17 samples) with a 289-point grid.
  const tb::BlockGrid g17(17, 17, 17, pm::GridTransform::identity());
  Bytes big{3, 0xff};
  const Bytes big_blob =
      tb::encode_block_summaries(g17, summaries(terrain(17, 17, true), g17, opt(tb::StandinKind::Grid, 289)));
  big.insert(big.end(), big_blob.begin(), big_blob.end());
  write(dir / "seed_v2_grid_u16", big);

  // Version 1: header, 64-byte records (7 f64 z00 z10 z01 z11 zmin zmax tm_error, u8 base_is_tm,
  // 7 zero bytes), CRC-32.
  Bytes v1;
  auto u32 = [&](std::uint32_t v) {
    for (int i = 0; i < 4; ++i) v1.push_back(std::uint8_t(v >> (8 * i)));
  };
  u32(0x53424C54u);
  u32(1);
  u32(std::uint32_t(g.cols()));
  u32(std::uint32_t(g.rows()));
  for (const tb::BlockSummary& s : two_sums) {
    for (double d : {s.z00, s.z10, s.z01, s.z11, s.zmin, s.zmax, s.tm_error}) {
      std::uint64_t bits;
      std::memcpy(&bits, &d, 8);
      for (int i = 0; i < 8; ++i) v1.push_back(std::uint8_t(bits >> (8 * i)));
    }
    v1.push_back(s.base_is_tm ? 1 : 0);
    v1.insert(v1.end(), 7, 0);
  }
  u32(std::uint32_t(crc32(0L, v1.data(), uInt(v1.size()))));
  if (tb::decode_block_summaries(g, v1, "seed").size() != g.block_count())
    throw std::runtime_error("bad v1 seed");
  v1.insert(v1.begin(), sel.begin(), sel.end());
  write(dir / "seed_v1", v1);
}

/// Mesh files: our binary PLY (write_mesh), an ascii PLY with an extra property and element, a
/// big-endian PLY with float vertices, and an OBJ with every face form, each behind its
/// selector byte.
void mesh_seeds(const fs::path& dir, const fs::path& tmp) {
  fs::create_directories(dir);
  pm::TriangleMeshData m;
  m.positions = {{0, 0, 1.5}, {30, 0, 2.25}, {30, 30, -1}, {0, 30, 0.1}};
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  const fs::path ply = tmp / "mesh.ply";
  pm::write_mesh(m, ply.string());
  std::ifstream in(ply, std::ios::binary);
  Bytes le{0};
  le.insert(le.end(), std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  write(dir / "seed_le.ply", le);
  auto text = [](std::uint8_t selector, const std::string& s) {
    Bytes b{selector};
    b.insert(b.end(), s.begin(), s.end());
    return b;
  };
  write(dir / "seed_ascii.ply",
        text(0,
             "ply\r\nformat ascii 1.0\r\ncomment seed\r\nelement vertex 4\r\nproperty double x\r\n"
             "property double y\r\nproperty double z\r\nproperty uchar red\r\nelement face 2\r\n"
             "property list uchar int vertex_indices\r\nelement edge 1\r\nproperty list uchar uint "
             "vertex_pair\r\n"
             "end_header\r\n0 0 1.5 7\r\n30 0 2.25 7\r\n30 30 -1 7\r\n0 30 0.1 7\r\n3 0 1 2\r\n3 0 2 3\r\n"
             "2 0 1\r\n"));
  Bytes be =
      text(0,
           "ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
           "property float z\nelement face 1\nproperty list uchar ushort vertex_indices\nend_header\n");
  const std::uint8_t one_be[4] = {0x3f, 0x80, 0, 0};  // 1.0f big-endian
  for (int v = 0; v < 3; ++v)
    for (int k = 0; k < 3; ++k)
      for (std::uint8_t byte : one_be) be.push_back(k == v ? byte : 0);
  for (std::uint8_t byte : {3, 0, 0, 0, 1, 0, 2}) be.push_back(byte);
  write(dir / "seed_be.ply", be);
  write(dir / "seed.obj",
        text(1,
             "# seed\nmtllib a.mtl\nv 0 0 1.5\nv 30 0 2.25\nv 30 30 -1 1\nv 0 30 0.1 0.5 0.5 0.5\n"
             "vt 0 0\nvn 0 0 1\ng g\nf 1 2 3 4\nf 1/1 2/1 3/1\nf 1/1/1 3/1/1 4/1/1\n"
             "f 1//1 3//1 4//1\nf -4 -3 -2\n"));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s CORPUS_DIR\n", argv[0]);
    return 2;
  }
  try {
    const fs::path root = argv[1];
    const fs::path pm_dir = root / "fuzz_pm_decoder", dem_dir = root / "fuzz_dem_reader",
                   tmp = root / ".seed_tmp";
    const fs::path db_dir = root / "fuzz_block_database";
    for (const fs::path& d : {pm_dir, dem_dir, db_dir, tmp}) fs::create_directories(d);
    pm_seeds(pm_dir);
    dem_seeds(dem_dir, tmp);
    db_seeds(db_dir, tmp);
    fs::create_directories(root / "fuzz_block_summaries");
    summaries_seeds(root / "fuzz_block_summaries");
    // Camera paths: a valid flight with a comment, CRLF line ends and a blank line.
    fs::create_directories(root / "fuzz_camera_path");
    const std::string path_csv =
        "# seed\r\nx,y,z,yaw,pitch,fovy\r\n1,2,3,45,-15,60\r\n\r\n-1.5e3,+2,3.25,-370,90,179.5\n";
    write(root / "fuzz_camera_path" / "seed_flight.csv", Bytes(path_csv.begin(), path_csv.end()));
    mesh_seeds(root / "fuzz_mesh_reader", tmp);
    // JSON: a texture layer record as the block database stores it (fuzz/regressions/fuzz_json/
    // holds more: a rules file, every escape, the limits).
    fs::create_directories(root / "fuzz_json");
    const std::string record =
        "{\"format\": 1, \"name\": \"pattern\", \"kind\": \"image\", \"source\": \"a\\u00e9.tif\", "
        "\"georef\": [0, 0, 100, 100], \"levels\": [[100, 100], [50, 50]], \"tile_size\": 16, "
        "\"power_of_two\": false, \"parameters\": {\"note\": \"a, b\", \"stops\": [[0.5, 1, 2, 3, 255]]}}";
    write(root / "fuzz_json" / "seed_record.json", Bytes(record.begin(), record.end()));
    fs::remove_all(tmp);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "terralod_fuzz_seeds: %s\n", e.what());
    return 1;
  }
  return 0;
}
