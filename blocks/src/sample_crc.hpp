// Private to terralod::blocks: DemSource::samples_crc over rows streamed in order (dem_source.hpp):
// one running CRC-32 of the samples as doubles, one of the mask bytes, joined at the end by zlib's
// crc32_combine64 when a row had a hole, so that a grid read band by band gives the CRC of the
// whole grid held at once (pm::crc32_of of the samples, continued over the mask).
#pragma once

#include <zlib.h>

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "terralod/pm/byte_io.hpp"

namespace terralod::blocks::detail {

class SampleCrc {
 public:
  /// One row of n samples; valid[i] == 0 marks a hole (nullptr: none).
  void add_row(const double* z, const std::uint8_t* valid, std::size_t n) {
    crc_ = pm::crc32_of({reinterpret_cast<const std::uint8_t*>(z), n * sizeof(double)}, crc_);
    if (valid == nullptr && ones_.size() != n) ones_.assign(n, 1);
    const std::uint8_t* m = valid != nullptr ? valid : ones_.data();
    for (std::size_t i = 0; i < n && !holes_; ++i) holes_ = m[i] == 0;
    mask_crc_ = pm::crc32_of({m, n}, mask_crc_);
    samples_ += n;
  }
  std::uint32_t value() const {
    return holes_ ? std::uint32_t(crc32_combine64(crc_, mask_crc_, z_off64_t(samples_))) : crc_;
  }

 private:
  std::uint32_t crc_ = 0, mask_crc_ = 0;
  bool holes_ = false;
  std::uint64_t samples_ = 0;
  std::vector<std::uint8_t> ones_;  ///< the mask of a row without holes, kept between rows
};

}  // namespace terralod::blocks::detail
