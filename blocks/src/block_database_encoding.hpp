// The bytes and checksums of the block database (private to its files): the CRC-32 of every
// stored blob, the 48-byte grid transform of the info table, the canonical encoding of
// DatabaseInfo behind the info row's info_crc32, and the "georeference" blob (layout in
// block_database.hpp, Georeference).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "terralod/blocks/block_database.hpp"

namespace terralod::blocks::detail {

constexpr std::size_t kTransformBytes = 48;

/// x0, xc, xr, y0, yc, yr as IEEE-754 binary64 little-endian: kTransformBytes bytes.
std::vector<std::uint8_t> encode_transform(const pm::GridTransform& t);
/// Reads kTransformBytes bytes at p.
pm::GridTransform decode_transform(const std::uint8_t* p);
bool transform_is_finite(const pm::GridTransform& t);

/// CRC-32 of the canonical encoding of (format_version, info): the info row's info_crc32.
std::uint32_t info_crc(int format_version, const DatabaseInfo& info);

std::vector<std::uint8_t> encode_georeference(const Georeference& g);
/// DatabaseError "<path>: blob 'georeference' is malformed" unless `bytes` is a georeference
/// blob with a finite transform.
Georeference decode_georeference(std::span<const std::uint8_t> bytes, const std::string& path);

}  // namespace terralod::blocks::detail
