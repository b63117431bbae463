// The bytes and checksums of the block database: blob CRC-32s, the grid transform, the
// canonical DatabaseInfo encoding behind info_crc32 and the georeference blob (see
// block_database_encoding.hpp).
#include "block_database_encoding.hpp"

#include <cmath>

#include "terralod/pm/byte_io.hpp"

namespace terralod::blocks::detail {

namespace {

// A string: u64 byte length + its UTF-8 bytes.
void put_string(pm::ByteWriter& b, const std::string& s) {
  b.u64(s.size());
  b.raw(s.data(), s.size());
}

void put_transform(pm::ByteWriter& b, const pm::GridTransform& t) {
  for (double v : {t.x0, t.xc, t.xr, t.y0, t.yc, t.yr}) b.f64(v);
}

}  // namespace

std::vector<std::uint8_t> encode_transform(const pm::GridTransform& t) {
  pm::ByteWriter b;
  put_transform(b, t);
  return std::move(b.bytes);
}

pm::GridTransform decode_transform(const std::uint8_t* p) {
  double v[6];
  for (int k = 0; k < 6; ++k) v[k] = pm::load_f64(p + 8 * k);
  return pm::GridTransform{v[0], v[1], v[2], v[3], v[4], v[5]};
}

bool transform_is_finite(const pm::GridTransform& t) {
  for (double v : {t.x0, t.xc, t.xr, t.y0, t.yc, t.yr})
    if (!std::isfinite(v)) return false;
  return true;
}

// Canonical encoding of DatabaseInfo for info_crc32 (all integers little-endian):
//   u32 format_version, then for kind: u64 byte length + UTF-8 bytes, i32 grid_width,
//   i32 grid_height, 48 bytes transform (as the transform column), crs_wkt, i32 block_size,
//   build_parameters, source (strings as for kind).
std::uint32_t info_crc(int format_version, const DatabaseInfo& info) {
  pm::ByteWriter b;
  b.u32(std::uint32_t(format_version));
  put_string(b, info.kind);
  b.i32(info.grid_width);
  b.i32(info.grid_height);
  put_transform(b, info.transform);
  put_string(b, info.crs_wkt);
  b.i32(info.block_size);
  put_string(b, info.build_parameters);
  put_string(b, info.source);
  return pm::crc32_of(b.bytes);
}

std::vector<std::uint8_t> encode_georeference(const Georeference& g) {
  pm::ByteWriter b;
  put_transform(b, g.crs_transform);
  put_string(b, g.vertical_datum);
  return std::move(b.bytes);
}

Georeference decode_georeference(std::span<const std::uint8_t> bytes, const std::string& path) {
  auto bad = [&] { return DatabaseError(path, "blob 'georeference' is malformed"); };
  if (bytes.size() < kTransformBytes + 8) throw bad();
  Georeference g;
  g.crs_transform = decode_transform(bytes.data());
  if (!transform_is_finite(g.crs_transform)) throw bad();
  if (pm::load_u64(bytes.data() + kTransformBytes) != bytes.size() - kTransformBytes - 8) throw bad();
  g.vertical_datum.assign(bytes.begin() + kTransformBytes + 8, bytes.end());
  return g;
}

}  // namespace terralod::blocks::detail
