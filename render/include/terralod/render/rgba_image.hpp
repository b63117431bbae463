// GL-free raster types for texture layers: an RGBA8 image and a single-channel float raster.
//
// Usage:
//   terralod::render::RgbaImage img(/*width=*/4, /*height=*/2);      // transparent black
//   img.set(/*x=*/1, /*y=*/0, {255, 0, 0, 255});                       // top row, opaque red
//   std::uint8_t* p = img.pixel(1, 0);                                 // p[0..3] = R, G, B, A
//
//   terralod::render::FloatRaster r(4, 2);                             // zeros
//   r.at(3, 1) = 0.5f;
//   terralod::render::RgbaImage grey = terralod::render::grey_to_rgba(r);  // 0.5 -> 128
//
// Contract:
//   - RgbaImage::rgba holds width * height * 4 bytes, row-major, row 0 = the TOP row (for a
//     north-up layer: the northern edge, i.e. heightfield row 0), channels R, G, B, A with
//     straight (not premultiplied) alpha; pixel (x, y) starts at rgba[4 * (y * width + x)].
//   - FloatRaster::v holds width * height floats in the same order. What the values mean is
//     up to the producer (shading in [0, 1], slope in degrees, class ids, ...); NaN means
//     "no data" (for example a hole in the DEM).
//   - Sizes are >= 0; a default-constructed value is 0 x 0 and empty. Both types own their
//     pixels (plain values: copy, move, compare with ==).
//   - grey_to_rgba maps v in [0, 1] to grey g = round(255 * v) (values outside [0, 1] are
//     clamped, since the caller asked for a grey picture of them) with alpha 255; NaN becomes
//     (0, 0, 0, 0). It is the conversion used for every shading texture terralod writes.
//   - Memory: 4 bytes per pixel (RgbaImage), 4 bytes per sample (FloatRaster).
#pragma once

#include <array>
#include <cassert>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace terralod::render {

/// RGBA8 image, top row first, straight alpha.
struct RgbaImage {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgba;  ///< width * height * 4 bytes

  RgbaImage() = default;
  /// A width x height image of (0, 0, 0, 0). Sizes >= 0.
  RgbaImage(int w, int h) : width(w), height(h), rgba(std::size_t(w) * std::size_t(h) * 4, 0) {
    assert(w >= 0 && h >= 0);
  }

  std::uint8_t* pixel(int x, int y) {
    assert(x >= 0 && x < width && y >= 0 && y < height);
    return rgba.data() + 4 * (std::size_t(y) * width + x);
  }
  const std::uint8_t* pixel(int x, int y) const {
    assert(x >= 0 && x < width && y >= 0 && y < height);
    return rgba.data() + 4 * (std::size_t(y) * width + x);
  }
  std::array<std::uint8_t, 4> get(int x, int y) const {
    const std::uint8_t* p = pixel(x, y);
    return {p[0], p[1], p[2], p[3]};
  }
  void set(int x, int y, std::array<std::uint8_t, 4> c) {
    std::uint8_t* p = pixel(x, y);
    p[0] = c[0], p[1] = c[1], p[2] = c[2], p[3] = c[3];
  }
  bool operator==(const RgbaImage&) const = default;
};

/// Single-channel float raster, top row first; NaN = no data.
struct FloatRaster {
  int width = 0;
  int height = 0;
  std::vector<float> v;  ///< width * height values

  FloatRaster() = default;
  /// A width x height raster filled with `fill`. Sizes >= 0.
  FloatRaster(int w, int h, float fill = 0.0f)
      : width(w), height(h), v(std::size_t(w) * std::size_t(h), fill) {
    assert(w >= 0 && h >= 0);
  }

  float& at(int x, int y) {
    assert(x >= 0 && x < width && y >= 0 && y < height);
    return v[std::size_t(y) * width + x];
  }
  float at(int x, int y) const {
    assert(x >= 0 && x < width && y >= 0 && y < height);
    return v[std::size_t(y) * width + x];
  }
  bool operator==(const FloatRaster&) const = default;
};

/// Grey value of a shading value s in [0, 1]: round(255 * s), clamped to 0..255.
inline std::uint8_t grey_level(float s) {
  const float c = s < 0.0f ? 0.0f : (s > 1.0f ? 1.0f : s);
  return static_cast<std::uint8_t>(std::lround(c * 255.0f));
}

/// Grey RGBA picture of a raster of values in [0, 1] (see the contract above).
inline RgbaImage grey_to_rgba(const FloatRaster& r) {
  RgbaImage out(r.width, r.height);
  for (std::size_t i = 0; i < r.v.size(); ++i) {
    std::uint8_t* p = out.rgba.data() + 4 * i;
    if (std::isnan(r.v[i])) continue;  // stays (0, 0, 0, 0)
    const std::uint8_t g = grey_level(r.v[i]);
    p[0] = p[1] = p[2] = g;
    p[3] = 255;
  }
  return out;
}

}  // namespace terralod::render
