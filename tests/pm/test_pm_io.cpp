// Tests for the PM file format: bit-exact round trips, size on real SRTM data, and hostile input.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "screen_error_checker.hpp"
#include "terralod/pm/pm_io.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace {

namespace fs = std::filesystem;
using namespace terralod::pm;

std::string tmp_path(const std::string& name) {
  fs::create_directories(TERRALOD_TEST_TMP);
  return std::string(TERRALOD_TEST_TMP) + "/pm_io_" + name;
}

Heightfield generated(int w, int h, bool metres, std::uint64_t seed = 7) {
  Heightfield hf = generate_terrain({.width = w, .height = h, .seed = seed, .quantize_to_metres = metres});
  hf.source = "generated " + std::to_string(w) + "x" + std::to_string(h);
  hf.frame = "test frame";
  return hf;
}

/// Punches void blocks into a heightfield (holes hold 0, as the contract says).
void punch_holes(Heightfield& hf) {
  std::vector<std::uint8_t> mask(hf.size(), 1);
  const int W = hf.width(), H = hf.height();
  auto block = [&](int c0, int r0, int w, int h) {
    for (int r = r0; r < r0 + h && r < H; ++r)
      for (int c = c0; c < c0 + w && c < W; ++c) {
        mask[std::size_t(r) * W + c] = 0;
        hf.at(c, r) = 0.0;
      }
  };
  block(W / 4, H / 4, 4, 3);
  block(W / 2, H / 2 + 2, 2, 5);
  block(3 * W / 4, H / 5, 1, 1);
  hf.set_mask(std::move(mask));
  hf.voids.voids = 4 * 3 + 2 * 5 + 1;
  hf.voids.filled = 0;
}

void expect_same(const ProgressiveMesh& a, const ProgressiveMesh& b) {
  EXPECT_TRUE(a == b);
  EXPECT_EQ(a.heightfield().source, b.heightfield().source);
  EXPECT_EQ(a.heightfield().frame, b.heightfield().frame);
  EXPECT_EQ(a.heightfield().crs_wkt, b.heightfield().crs_wkt);
  EXPECT_EQ(a.heightfield().voids.voids, b.heightfield().voids.voids);
  EXPECT_EQ(a.heightfield().voids.filled, b.heightfield().voids.filled);
  EXPECT_EQ(a.heightfield().has_holes(), b.heightfield().has_holes());
  // operator== compares heights with ==; bit-exactness needs the bits (-0.0, NaN payloads).
  ASSERT_EQ(a.heightfield().size(), b.heightfield().size());
  for (std::size_t i = 0; i < a.heightfield().size(); ++i)
    ASSERT_EQ(std::bit_cast<std::uint64_t>(a.heightfield()[i]),
              std::bit_cast<std::uint64_t>(b.heightfield()[i]))
        << i;
}

/// Round trip in memory and through a file; returns the encoded bytes.
std::vector<std::uint8_t> check_round_trip(const ProgressiveMesh& pm, const std::string& name) {
  const std::vector<std::uint8_t> bytes = encode_pm(pm);
  const ProgressiveMesh back = decode_pm(bytes, name);
  expect_same(pm, back);
  EXPECT_EQ(encode_pm(back), bytes) << "re-encoding must give identical bytes";

  const std::string path = tmp_path(name);
  write_pm(pm, path);
  EXPECT_FALSE(fs::exists(path + ".tmp"));
  EXPECT_EQ(fs::file_size(path), bytes.size());
  expect_same(pm, read_pm(path));
  fs::remove(path);
  return bytes;
}

bool quantized_flag(const std::vector<std::uint8_t>& bytes) { return bytes.at(77) & 2; }

std::string message_of(const std::vector<std::uint8_t>& bytes, const std::string& name) {
  try {
    decode_pm(bytes, name);
  } catch (const PmFormatError& e) {
    return e.what();
  }
  return "(no error)";
}

/// Recomputes the trailing CRC so that a deliberately forged file passes the checksum.
void fix_checksum(std::vector<std::uint8_t>& b) {
  std::uint32_t crc = 0xffffffffu;  // CRC-32 (zlib), bitwise
  for (std::size_t i = 0; i + 4 < b.size(); ++i) {
    crc ^= b[i];
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1)));
  }
  crc ^= 0xffffffffu;
  for (int k = 0; k < 4; ++k) b[b.size() - 4 + std::size_t(k)] = std::uint8_t(crc >> (8 * k));
}

/// A small PM that has every section: holes (mask), quantized heights, collapses.
ProgressiveMesh small_pm() {
  Heightfield hf = generated(13, 11, /*metres=*/true, /*seed=*/3);
  punch_holes(hf);
  return ProgressiveMesh::build(hf);
}

// ---------------------------------------------------------------------------------------------

TEST(PmIo, RoundTripGeneratedFractionalHeights) {
  const ProgressiveMesh pm = ProgressiveMesh::build(generated(65, 65, /*metres=*/false));
  ASSERT_GT(pm.vsplit_count(), 0u);
  const auto bytes = check_round_trip(pm, "frac65.pm");
  EXPECT_FALSE(quantized_flag(bytes)) << "fractional heights are stored as raw doubles";
  std::printf("65x65 fractional heights: %zu bytes, %.3f bytes/vertex\n", bytes.size(),
              double(bytes.size()) / double(pm.full_vertex_count()));
}

TEST(PmIo, RoundTripGeneratedMetres) {
  const ProgressiveMesh pm = ProgressiveMesh::build(generated(129, 97, /*metres=*/true));
  const auto bytes = check_round_trip(pm, "metres129x97.pm");
  EXPECT_TRUE(quantized_flag(bytes)) << "whole-metre heights are stored as integers";
  const double bpv = double(bytes.size()) / double(pm.full_vertex_count());
  std::printf("129x97 whole-metre heights: %zu bytes, %.3f bytes/vertex\n", bytes.size(), bpv);
  EXPECT_LE(bpv, 8.0);
}

TEST(PmIo, RoundTripWithHoles) {
  for (bool metres : {false, true}) {
    Heightfield hf = generated(129, 97, metres, /*seed=*/11);
    punch_holes(hf);
    const ProgressiveMesh pm = ProgressiveMesh::build(hf);
    EXPECT_TRUE(pm.heightfield().has_holes());
    check_round_trip(pm, metres ? "holes_m.pm" : "holes_f.pm");
  }
}

TEST(PmIo, RoundTripMaskWithoutHolesAndEmptyStrings) {
  // A mask that is present but all ones must stay present; empty strings stay empty.
  Heightfield hf = generated(9, 7, /*metres=*/true);
  hf.set_mask(std::vector<std::uint8_t>(hf.size(), 1));
  hf.source.clear();
  hf.frame.clear();
  const ProgressiveMesh pm = ProgressiveMesh::build(hf);
  check_round_trip(pm, "allones.pm");
}

TEST(PmIo, HeightQuantizationIsExactOrNotUsed) {
  // Heights chosen to probe the integer-or-raw decision; from_parts with no collapses keeps
  // them verbatim. Each case: heights, whether the integer coding applies.
  struct Case {
    std::vector<double> z;
    bool quantized;
  };
  const double tiny = std::numeric_limits<double>::denorm_min();
  const std::vector<Case> cases = {
      {{0, 1, -2, 1908, 115, 0}, true},                // SRTM-like whole metres
      {{0.5, 0.25, -1.75, 3, 0, 1000.125}, true},      // multiples of 1/8
      {{0, 0, 0, 0, 0, 0}, true},                      // flat
      {{1e9, -1e9, 2e9, 0, 1, 2}, true},               // |k| < 2^31
      {{4e9, -1, 0, 0, 1, 1}, false},                  // needs more than 31 bits
      {{0.1, 0.2, 0.3, 0, 0, 0}, false},               // not dyadic
      {{-0.0, 1, 2, 3, 4, 5}, false},                  // -0.0 must survive bit-exactly
      {{tiny, 3 * tiny, 0, 0, 0, 0}, true},            // subnormal multiples of 2^-1074
      {{1e300, -1e300, 0, 1, 2, 3}, false},            // huge range
      {{std::ldexp(1.0, 1000), 0, 0, 0, 0, 0}, true},  // a single large power of two
  };
  int index = 0;
  for (const Case& c : cases) {
    Heightfield hf(3, 2);
    for (std::size_t i = 0; i < 6; ++i) hf[i] = c.z[i];
    const ProgressiveMesh pm = ProgressiveMesh::from_parts(hf, ErrorMetric::Continuous, 1.0, {}, {});
    const auto bytes = check_round_trip(pm, "quant" + std::to_string(index) + ".pm");
    EXPECT_EQ(quantized_flag(bytes), c.quantized) << "case " << index;
    ++index;
  }
}

TEST(PmIo, RealTileCropIsCompact) {
  const auto crop = terralod::test::read_hgt_crop("N44W072.hgt", 720, 750, 257);
  if (!crop) GTEST_SKIP() << "N44W072.hgt not found in " << TERRALOD_DATA_DIR;
  const Heightfield& hf = *crop;
  const ProgressiveMesh pm = ProgressiveMesh::build(hf);
  const auto bytes = check_round_trip(pm, "srtm257.pm");
  EXPECT_TRUE(quantized_flag(bytes));
  const double bpv = double(bytes.size()) / double(pm.full_vertex_count());
  std::printf(
      "N44W072 257x257 crop: %zu vertices, %zu collapses, %zu bytes, %.3f bytes/vertex "
      "(raw: 8 bytes/sample + 16 bytes/collapse = %.1f)\n",
      pm.full_vertex_count(), pm.vsplit_count(), bytes.size(), bpv,
      (8.0 * double(hf.size()) + 16.0 * double(pm.vsplit_count())) / double(pm.full_vertex_count()));
  EXPECT_LE(bpv, 8.0);
}

TEST(PmIo, EveryTruncationIsAFormatError) {
  const std::vector<std::uint8_t> bytes = encode_pm(small_pm());
  for (std::size_t len = 0; len < bytes.size(); ++len) {
    const std::vector<std::uint8_t> prefix(bytes.begin(), bytes.begin() + std::ptrdiff_t(len));
    try {
      decode_pm(prefix, "small.pm");
      ADD_FAILURE() << "prefix of " << len << " bytes decoded";
    } catch (const PmFormatError& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.rfind("small.pm: ", 0), 0u) << what;
      if (len >= 20) {
        EXPECT_NE(what.find("truncated"), std::string::npos) << what;
      }
    }
  }
  // Appended bytes are an error too.
  std::vector<std::uint8_t> longer = bytes;
  longer.push_back(0);
  EXPECT_THROW(decode_pm(longer, "small.pm"), PmFormatError);
}

TEST(PmIo, EverySingleByteFlipIsAFormatError) {
  const std::vector<std::uint8_t> bytes = encode_pm(small_pm());
  for (std::size_t i = 0; i < bytes.size(); ++i)
    for (std::uint8_t flip : {std::uint8_t(0x01), std::uint8_t(0x80), std::uint8_t(0xff)}) {
      std::vector<std::uint8_t> bad = bytes;
      bad[i] ^= flip;
      EXPECT_THROW(decode_pm(bad, "flip.pm"), PmFormatError) << "byte " << i << " ^ " << int(flip);
    }
  // Away from the magic, version and size fields, the checksum is what catches it.
  std::vector<std::uint8_t> bad = bytes;
  bad[bytes.size() / 2] ^= 0x10;
  EXPECT_EQ(message_of(bad, "flip.pm"), "flip.pm: checksum mismatch (the file is corrupt)");
}

TEST(PmIo, ClearErrorsForWrongMagicVersionAndMissingFile) {
  std::vector<std::uint8_t> bytes = encode_pm(small_pm());
  std::vector<std::uint8_t> ply = {'p', 'l', 'y', '\n', 'f', 'o', 'r', 'm', 'a', 't', ' ', 'b'};
  EXPECT_EQ(message_of(ply, "mesh.ply"), "mesh.ply: not a terralod PM file (bad magic)");
  EXPECT_EQ(message_of({}, "empty.pm"), "empty.pm: not a terralod PM file (bad magic)");

  std::vector<std::uint8_t> future = bytes;
  future[8] = 7;
  EXPECT_EQ(message_of(future, "future.pm"),
            "future.pm: format version 7 is not supported (this build reads version 1)");

  const std::string missing = tmp_path("does_not_exist.pm");
  try {
    read_pm(missing);
    ADD_FAILURE() << "missing file read";
  } catch (const PmFormatError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(missing + ": cannot open", 0), 0u) << e.what();
  }

  const std::string path = tmp_path("future_on_disk.pm");
  {
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(future.data()), std::streamsize(future.size()));
  }
  try {
    read_pm(path);
    ADD_FAILURE() << "future version read";
  } catch (const PmFormatError& e) {
    EXPECT_EQ(std::string(e.what()),
              path + ": format version 7 is not supported (this build reads version 1)");
  }
  fs::remove(path);
}

TEST(PmIo, ForgedHeadersWithValidChecksumAreRejected) {
  // An attacker can recompute the CRC; the decoder must still refuse absurd sizes before it
  // allocates. Field offsets are those of the format comment in pm_io.cpp.
  const std::vector<std::uint8_t> good = encode_pm(small_pm());
  auto forge = [&](std::size_t offset, std::vector<std::uint8_t> value) {
    std::vector<std::uint8_t> b = good;
    for (std::size_t i = 0; i < value.size(); ++i) b[offset + i] = value[i];
    fix_checksum(b);
    return message_of(b, "forged.pm");
  };
  const std::vector<std::uint8_t> big32 = {0xff, 0xff, 0x00, 0x00};                        // 65535
  EXPECT_NE(forge(20, big32).find("forged.pm: "), std::string::npos);                      // width
  EXPECT_NE(forge(24, {0xff, 0xff, 0xff, 0x7f}).find("out of range"), std::string::npos);  // height
  EXPECT_NE(forge(102, {0xff, 0xff, 0xff, 0xff}).find("collapses"), std::string::npos);    // count
  EXPECT_NE(forge(106, {0xff, 0xff, 0xff, 0x0f}).find("dropped faces"), std::string::npos);
  EXPECT_NE(forge(77, {0x80}).find("unknown flags"), std::string::npos);
  EXPECT_NE(forge(76, {0x02}).find("unknown error metric"), std::string::npos);
  EXPECT_NE(forge(82, {0x00, 0x10, 0x00, 0x00}).find("error exponent"), std::string::npos);
  EXPECT_NE(forge(110, {0xff, 0xff, 0xff, 0x7f}).find("source name"), std::string::npos);  // string length
  for (const std::string& m : {forge(20, big32), forge(24, big32)})
    EXPECT_EQ(m.rfind("forged.pm: ", 0), 0u) << m;

  // Random mutations with a valid checksum: every outcome is a clean PmFormatError or a PM.
  const unsigned seed = 20240611;
  std::printf("mutation seed %u\n", seed);
  std::mt19937 rng(seed);
  int rejected = 0;
  for (int iter = 0; iter < 3000; ++iter) {
    std::vector<std::uint8_t> b = good;
    const int edits = 1 + int(rng() % 4);
    for (int e = 0; e < edits; ++e) {
      const std::size_t at = 20 + rng() % (b.size() - 24);  // keep magic, version, size, CRC slot
      b[at] = std::uint8_t(rng());
    }
    fix_checksum(b);
    try {
      decode_pm(b, "mutant.pm");
    } catch (const PmFormatError&) {
      ++rejected;
    }
  }
  EXPECT_GT(rejected, 0);
}

TEST(PmIo, EncodingRefusesPmsOutsideTheContract) {
  Heightfield hf = generated(5, 5, /*metres=*/true);
  // Error quantum not a power of two.
  EXPECT_THROW(encode_pm(ProgressiveMesh::from_parts(hf, ErrorMetric::Continuous, 3.0, {}, {})),
               std::invalid_argument);
  // An error that is not a multiple of the quantum.
  const std::vector<Collapse> cs = {Collapse{6, 7, 0.3}};
  EXPECT_THROW(encode_pm(ProgressiveMesh::from_parts(hf, ErrorMetric::Continuous, 0.25, cs, {})),
               std::invalid_argument);
  // A mask value other than 0 or 1.
  std::vector<std::uint8_t> mask(hf.size(), 1);
  mask[12] = 2;
  hf.set_mask(mask);
  EXPECT_THROW(encode_pm(ProgressiveMesh::from_parts(hf, ErrorMetric::Continuous, 1.0, {}, {})),
               std::invalid_argument);
}

TEST(PmIo, WriteFailureNamesTheFileAndLeavesNothing) {
  const ProgressiveMesh pm = small_pm();
  const std::string path = tmp_path("no_such_dir/out.pm");
  try {
    write_pm(pm, path);
    ADD_FAILURE() << "write into a missing folder succeeded";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(path + ": ", 0), 0u) << e.what();
  }
  EXPECT_FALSE(fs::exists(path));
  EXPECT_FALSE(fs::exists(path + ".tmp"));

  // Overwriting an existing file replaces it whole.
  const std::string target = tmp_path("overwrite.pm");
  { std::ofstream(target) << "old contents"; }
  write_pm(pm, target);
  expect_same(pm, read_pm(target));
  fs::remove(target);
}

}  // namespace
