// The contrast stretch of imagery deeper than 8 bits (image_stretch.hpp).
#include "terralod/blocks/image_stretch.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace terralod::blocks {

StretchOptions parse_stretch(const std::string& text) {
  StretchOptions s;
  const auto bad = [&] {
    return std::invalid_argument("--stretch '" + text +
                                 "': expected auto, none, P% (a percentage below 50 cut at each end of "
                                 "every colour band) or LO,HI (the values drawn as 0 and 255)");
  };
  if (text == "auto") return s;
  if (text == "none") {
    s.mode = StretchOptions::Mode::None;
    return s;
  }
  char tail = 0;
  if (!text.empty() && text.back() == '%') {
    double p = 0;
    if (std::sscanf(text.c_str(), "%lf%%%c", &p, &tail) != 1 || !(p >= 0.0 && p < 50.0)) throw bad();
    s.mode = StretchOptions::Mode::Cut;
    s.cut_percent = p;
    return s;
  }
  double lo = 0, hi = 0;
  if (std::sscanf(text.c_str(), "%lf,%lf%c", &lo, &hi, &tail) != 2 || !std::isfinite(lo) ||
      !std::isfinite(hi) || !(lo < hi))
    throw bad();
  s.mode = StretchOptions::Mode::Values;
  s.lo = lo, s.hi = hi;
  return s;
}

std::string describe(const StretchOptions& s) {
  char buf[96];
  switch (s.mode) {
    case StretchOptions::Mode::Auto:
      return "auto";
    case StretchOptions::Mode::None:
      return "none";
    case StretchOptions::Mode::Cut:
      std::snprintf(buf, sizeof buf, "%g %% cut", s.cut_percent);
      return buf;
    case StretchOptions::Mode::Values:
      std::snprintf(buf, sizeof buf, "values %.9g..%.9g", s.lo, s.hi);
      return buf;
  }
  return "";
}

std::uint8_t BandRange::to_byte(double v) const {
  const double t = (v - lo) * (255.0 / (hi - lo));
  if (!(t > 0.0)) return 0;  // NaN too
  return t >= 255.0 ? 255 : std::uint8_t(std::lround(t));
}

BandHistogram::BandHistogram(double lo, double hi, std::size_t bins)
    : lo_(lo), counts_(std::max<std::size_t>(bins, 2), 0) {
  if (!(hi > lo)) hi = lo + 1.0;  // a band of one value
  step_ = (hi - lo) / double(counts_.size() - 1);
  scale_ = 1.0 / step_;
}

BandRange type_range(int bits, bool is_signed, bool is_float) {
  if (is_float) return {0, 1};
  return {0, std::ldexp(1.0, is_signed ? bits - 1 : bits) - 1.0};
}

StretchStep stretch_step(const StretchOptions& s, bool deep) {
  switch (s.mode) {
    case StretchOptions::Mode::Values:
      return StretchStep::Fixed;
    case StretchOptions::Mode::None:
      return deep ? StretchStep::Fixed : StretchStep::AsIs;
    case StretchOptions::Mode::Cut:
      return StretchStep::Cut;
    case StretchOptions::Mode::Auto:
      break;
  }
  return deep ? StretchStep::Cut : StretchStep::AsIs;
}

BandRange fixed_range(const StretchOptions& s, const BandRange& type) {
  return s.mode == StretchOptions::Mode::Values ? BandRange{s.lo, s.hi} : type;
}

std::optional<BandHistogram> exact_histogram(int bits, bool is_signed, bool is_float) {
  if (is_float || bits > 16) return std::nullopt;
  const double lo = is_signed ? -std::ldexp(1.0, bits - 1) : 0.0;
  const double n = std::ldexp(1.0, bits);
  return BandHistogram(lo, lo + n - 1.0, std::size_t(n));
}

BandRange BandHistogram::cut(double percent) const {
  if (total_ == 0) return {};
  const auto reach = [&](double fraction) {
    // The first bin at which the running count reaches fraction * total (at least one value).
    const double need = std::max(1.0, std::ceil(fraction * double(total_) - 1e-9));
    std::size_t run = 0;
    for (std::size_t i = 0; i < counts_.size(); ++i)
      if (double(run += counts_[i]) >= need) return i;
    return counts_.size() - 1;
  };
  const std::size_t a = reach(percent / 100.0), b = reach(1.0 - percent / 100.0);
  BandRange r{value(a), value(b)};
  if (!(r.hi > r.lo)) r.hi = r.lo + step_;
  return r;
}

}  // namespace terralod::blocks
