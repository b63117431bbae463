// libFuzzer target for the PM decoder: decode_pm on arbitrary bytes must either throw
// PmFormatError or give a PM that re-encodes losslessly, extracts and builds a hierarchy.
//
// Every input is decoded twice: as given (exercising magic, version, size and checksum
// checks) and with its size field and CRC-32 patched to be right (so that mutations reach the
// sections behind the checksum). Anything other than a PmFormatError from decoding, or a
// broken invariant on a decoded PM, aborts (a finding).
//
// Bounded work: inputs whose header declares more than 2^16 samples are skipped before any
// decoding (returning -1 keeps them out of the corpus), so one run costs O(2^16) at most.
#include <zlib.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "dag_hierarchy_check.hpp"
#include "fuzz_support.hpp"
#include "terralod/pm/collapse_dag.hpp"
#include "terralod/pm/pm_io.hpp"
#include "terralod/pm/progressive_mesh.hpp"

namespace {

namespace pm = terralod::pm;

constexpr std::uint64_t kMaxFuzzSamples = std::uint64_t(1) << 16;

[[noreturn]] void finding(const std::string& what) { terralod::fuzz::finding("fuzz_pm_decoder", what); }
#define REQUIRE(cond)                                 \
  do {                                                \
    if (!(cond)) finding("invariant broken: " #cond); \
  } while (0)

std::uint32_t le32(const std::uint8_t* p) {
  return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 |
         std::uint32_t(p[3]) << 24;
}

bool same_pm(const pm::ProgressiveMesh& a, const pm::ProgressiveMesh& b) {
  const pm::Heightfield &ha = a.heightfield(), &hb = b.heightfield();
  if (!(a == b) || ha.source != hb.source || ha.frame != hb.frame || ha.crs_wkt != hb.crs_wkt ||
      ha.voids.voids != hb.voids.voids || ha.voids.filled != hb.voids.filled)
    return false;
  // operator== compares heights with ==; the format promises the bits.
  for (std::size_t i = 0; i < ha.size(); ++i)
    if (std::bit_cast<std::uint64_t>(ha[i]) != std::bit_cast<std::uint64_t>(hb[i])) return false;
  return true;
}

/// Invariants of a mesh extracted at `e` from a decoded PM.
void check_extract(const pm::ProgressiveMesh& p, double e) {
  const pm::TriangleMesh m = p.extract(e);
  REQUIRE(m.error_bound <= e && m.error_bound >= 0.0 && std::isfinite(m.error_bound));
  const pm::Heightfield& hf = p.heightfield();
  for (std::uint32_t v : m.vertices) REQUIRE(v < hf.size() && hf.valid(v));
  for (const auto& t : m.triangles)
    for (std::uint32_t k : t) REQUIRE(k < m.vertices.size());
}

void check_decoded(const pm::ProgressiveMesh& p) {
  const pm::Heightfield& hf = p.heightfield();
  REQUIRE(hf.width() >= 2 && hf.height() >= 2);
  REQUIRE(hf.size() == std::size_t(hf.width()) * std::size_t(hf.height()));
  for (std::size_t i = 0; i < hf.size(); ++i)
    if (hf.valid(i)) REQUIRE(std::isfinite(hf[i]));
  const pm::GridTransform& t = hf.transform;
  for (double v : {t.x0, t.xc, t.xr, t.y0, t.yc, t.yr}) REQUIRE(std::isfinite(v));
  REQUIRE(std::isfinite(p.max_error()) && p.max_error() >= 0.0);
  REQUIRE(p.vsplit_count() <= p.full_vertex_count());

  // Lossless: decode(encode(p)) == p, and encoding is a fixed point from there on.
  const std::vector<std::uint8_t> again = pm::encode_pm(p);
  const pm::ProgressiveMesh back = pm::decode_pm(again, "re-encoded");
  REQUIRE(same_pm(p, back));
  REQUIRE(pm::encode_pm(back) == again);

  // Extraction at a few errors: nothing, half, everything.
  check_extract(p, 0.0);
  check_extract(p, 0.5 * p.max_error());
  check_extract(p, p.max_error());
  REQUIRE(p.extract(p.max_error()).triangles.size() == p.extract(1e300).triangles.size());

  // The hierarchy a runtime builds on load (the collapse DAG): either the collapses do not
  // replay (a corrupt PM, rejected with std::invalid_argument) or the hierarchy's invariants
  // hold. Not checked: created faces inside volumes (absurd but finite coordinates may overflow
  // to infinity there; NaN never passes the nesting checks) and the builder's corner and border
  // rules (a file need not follow them to replay).
  std::unique_ptr<pm::CollapseDag> dag;
  try {
    dag = std::make_unique<pm::CollapseDag>(p);
  } catch (const std::invalid_argument&) {
    return;
  }
  const std::string why =
      terralod::test::dag_hierarchy_violation(*dag, {.created_faces_inside = false, .builder_rules = false});
  if (!why.empty()) finding("decoded PM breaks the hierarchy: " + why);
}

void decode_one(const std::vector<std::uint8_t>& bytes) {
  try {
    const pm::ProgressiveMesh p = pm::decode_pm(bytes, "fuzz.pm");
    check_decoded(p);
  } catch (const pm::PmFormatError& e) {
    const std::string_view what = e.what();
    REQUIRE(what.starts_with("fuzz.pm: ") && what.size() > 9);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // Width and height sit at offsets 20 and 24 of the header (see pm_io.cpp).
  if (size >= 28 && std::uint64_t(le32(data + 20)) * le32(data + 24) > kMaxFuzzSamples) return -1;
  std::vector<std::uint8_t> bytes(data, data + size);
  decode_one(bytes);
  // The same bytes with the size field and checksum made right.
  if (size >= 24) {
    for (int i = 0; i < 8; ++i) bytes[12 + std::size_t(i)] = std::uint8_t(std::uint64_t(size) >> (8 * i));
    const auto crc = std::uint32_t(crc32(0L, bytes.data(), uInt(size - 4)));
    for (int i = 0; i < 4; ++i) bytes[size - 4 + std::size_t(i)] = std::uint8_t(crc >> (8 * i));
    if (!std::equal(bytes.begin(), bytes.end(), data)) decode_one(bytes);
  }
  return 0;
}
