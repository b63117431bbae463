// How an image's values become the 8-bit texels of a texture layer: the contrast stretch of
// imagery deeper than 8 bits (16-bit satellite and aerial images, 12-bit values in 16-bit files,
// floating-point reflectances), one rule for the images GDAL warps (image_warp.hpp) and the
// ones OpenImageIO reads (render/image_pyramid.hpp).
//
// Usage:
//   namespace tb = terralod::blocks;
//   const tb::StretchOptions s = tb::parse_stretch("2%");      // or "auto", "none", "100,4000"
//   tb::BandHistogram h(0, 65535, 65536);                        // one colour band's values
//   for (double v : values) h.add(v);
//   const tb::BandRange r = h.cut(s.cut_percent);                // the 2 % and 98 % points
//   std::uint8_t texel = r.to_byte(v);                          // lo -> 0, hi -> 255, clamped
//
// Contract:
//   StretchOptions  Auto (the default): 8-bit images as they are; deeper ones (16 or 32 bits,
//                   floating point) get Cut at 2 % in each colour band, as QGIS shows
//                   multiband imagery. None: as they are: 8 bits as stored, deeper integer
//                   types scaled from their whole range (0..65535 -> 0..255), floating point
//                   from 0..1. Cut: in each colour band, the values at or below its P-th
//                   percentile go to 0 and those at or above its (100 - P)-th to 255, linear
//                   between. Values: lo..hi (the image's own values) to 0..255 in every colour
//                   band. Alpha is never stretched (its type's whole range is 0..255). Pixels
//                   that are transparent or nodata (GDAL's mask) count in no histogram.
//   parse_stretch   "auto", "none", "P%" (0 <= P < 50) or "LO,HI" (LO < HI, finite);
//                   std::invalid_argument saying what it expects otherwise.
//   BandHistogram   counts of values on `bins` equally spaced values from lo to hi (bin i holds
//                   the values nearest lo + i (hi - lo) / (bins - 1)); so an integer band with
//                   bins = hi - lo + 1 is counted exactly, one bin a value. NaN is not counted,
//                   values outside lo..hi count in the end bins.
//   cut(P)          the range from the smallest bin value at which the count reaches P % of the
//                   values to the smallest at which it reaches (100 - P) %; hi = lo + the bins'
//                   step when they meet (a band of one value), {0, 1} when nothing was counted.
//   BandRange       to_byte(v) = round(255 (v - lo) / (hi - lo)) clamped to 0..255, NaN -> 0,
//                   as GDAL's -scale lo hi 0 255 -ot Byte rounds.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace terralod::blocks {

struct StretchOptions {
  enum class Mode { Auto, None, Cut, Values };
  Mode mode = Mode::Auto;
  double cut_percent = 2.0;  ///< Cut (and Auto for images deeper than 8 bits)
  double lo = 0, hi = 0;     ///< Values
};

/// See the header comment.
StretchOptions parse_stretch(const std::string& text);

/// A colour band's values lo..hi drawn as 0..255.
struct BandRange {
  double lo = 0, hi = 1;
  std::uint8_t to_byte(double v) const;
};

class BandHistogram {
 public:
  BandHistogram(double lo, double hi, std::size_t bins);
  void add(double v) {
    if (v == v) ++counts_[bin(v)], ++total_;
  }
  std::size_t total() const { return total_; }
  BandRange cut(double percent) const;

 private:
  std::size_t bin(double v) const {
    const double t = (v - lo_) * scale_ + 0.5;
    return t <= 0.0 ? 0 : t >= double(counts_.size() - 1) ? counts_.size() - 1 : std::size_t(t);
  }
  double value(std::size_t i) const { return lo_ + double(i) * step_; }
  double lo_, step_, scale_;
  std::vector<std::size_t> counts_;
  std::size_t total_ = 0;
};

/// The values of a sample type (`bits` wide, signed or not, floating point or integer) that
/// StretchOptions::None draws as 0..255: an unsigned integer type's whole range, a signed one's
/// non-negative half (as OpenImageIO converts them), 0..1 for floating point.
BandRange type_range(int bits, bool is_signed, bool is_float);

/// What `s` does to an image whose colour bands are `deep` (wider than 8 bits, signed or
/// floating point): AsIs, its 8-bit values as they are; Fixed, each band drawn from
/// fixed_range(); Cut, each band from its histogram's cut(s.cut_percent). Both readers (the
/// GDAL warp and OpenImageIO's pyramid) decide by this.
enum class StretchStep { AsIs, Fixed, Cut };
StretchStep stretch_step(const StretchOptions& s, bool deep);
/// The range StretchStep::Fixed draws a band from: Values' lo..hi, None's the band type's own
/// range `type` (type_range).
BandRange fixed_range(const StretchOptions& s, const BandRange& type);

/// The histogram a cut counts a band of that type on when it is known before any value is read:
/// integer types of up to 16 bits, one bin a value. Others (wider integers, floating point) are
/// counted on BandHistogram(minimum, maximum, 65536) after a pass for their range: nullopt.
std::optional<BandHistogram> exact_histogram(int bits, bool is_signed, bool is_float);

/// "2 % cut", "none", "values 100..4000": how `s` reads in the commands' reports.
std::string describe(const StretchOptions& s);

}  // namespace terralod::blocks
