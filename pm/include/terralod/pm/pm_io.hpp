// Compact, checksummed, lossless binary file format for progressive meshes (".pm", version 1).
//
// Usage:
//   terralod::pm::ProgressiveMesh pm = terralod::pm::ProgressiveMesh::build(hf);
//   terralod::pm::write_pm(pm, "terrain.pm");                  // atomic: temp file + rename
//   terralod::pm::ProgressiveMesh back = terralod::pm::read_pm("terrain.pm");
//   assert(back == pm);                                         // bit-exact round trip
//   try { read_pm("broken.pm"); }
//   catch (const terralod::pm::PmFormatError& e) { /* "broken.pm: checksum mismatch" */ }
//
// Contract:
//   - Lossless: decode_pm(encode_pm(pm)) == pm, including the heightfield's source, frame,
//     crs_wkt and VoidReport, and encode_pm of the result gives the same bytes again.
//   - Size: heights that are all integer multiples of a power of two (SRTM metres) are stored
//     as predicted integer residuals, otherwise as their raw bits; collapses as small varints;
//     every section is deflated. On SRTM data about 2.7-2.9 bytes per vertex in all (3.8 MB
//     for the 1201 x 1201 tile N44W072, against 35 MB for 8-byte heights plus 16-byte
//     collapses); about 11 bytes per vertex when heights are arbitrary doubles.
//   - The byte layout is documented in pm_io.cpp, next to the writer.
//   - encode_pm/write_pm throw std::invalid_argument for a PM that breaks the ProgressiveMesh
//     contract (error quantum not a power of two, an error that is not a multiple of it,
//     a non-finite height at a valid sample); write_pm throws std::runtime_error naming the
//     file when it cannot be written. Nothing is left at `path` unless the write succeeded.
//   - decode_pm/read_pm throw PmFormatError for every problem (missing file, bad magic,
//     unsupported version, truncation, checksum mismatch, inconsistent contents); the message
//     starts with the file name then ": ". The decoder is safe on hostile input: every length
//     is checked against the bytes that remain before anything is allocated, grids are capped
//     at kMaxPmSamples samples, and allocations stay within ~8 KiB per input byte.
//   - Memory: encode_pm holds the output plus the raw streams and one deflate buffer (about 6
//     bytes per vertex for SRTM, 16 for raw-double heights); decode_pm the input, the decoded
//     PM, and one inflated section at a time (at most 8 bytes per sample).
//   - Time: about 0.5 s to encode and 0.1 s to decode a 1201 x 1201 tile.
#pragma once

#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "terralod/pm/progressive_mesh.hpp"

namespace terralod::pm {

/// Thrown by decode_pm/read_pm; what() is "<file>: <problem>".
class PmFormatError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Version of the format that this build writes and reads.
inline constexpr std::uint32_t kPmFormatVersion = 1;
/// Largest grid (width * height) the decoder accepts: 2^28 samples (2 GiB of heights).
inline constexpr std::uint64_t kMaxPmSamples = std::uint64_t(1) << 28;

/// Serializes a PM to bytes (format version kPmFormatVersion). Deterministic.
std::vector<std::uint8_t> encode_pm(const ProgressiveMesh& pm);

/// Parses bytes produced by encode_pm. `name_for_errors` prefixes every error message.
ProgressiveMesh decode_pm(std::span<const std::uint8_t> bytes, const std::string& name_for_errors);

/// The heightfield of bytes that decode_pm reads (heights, void mask, transform, source, frame,
/// CRS, VoidReport), without decoding the collapses: about a tenth of decode_pm's time (the 25
/// blocks of N44W072: 15 ms against 230 ms, 25 ms against 210 ms where heights are raw doubles). The checksum
/// and every header field are checked as decode_pm checks them; the collapse sections are not, so a file
/// whose collapses alone are inconsistent gives its heightfield here and fails decode_pm.
Heightfield decode_pm_heightfield(std::span<const std::uint8_t> bytes, const std::string& name_for_errors);

/// Writes encode_pm(pm) to path + ".tmp", flushes it to disk, then renames it onto `path`.
void write_pm(const ProgressiveMesh& pm, const std::string& path);

/// Reads a file written by write_pm.
ProgressiveMesh read_pm(const std::string& path);

}  // namespace terralod::pm
