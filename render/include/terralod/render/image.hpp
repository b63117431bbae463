// RGB8 images: screenshots read back from the renderer, written and read as PNG via OpenImageIO.
//
// Usage:
//   terralod::render::Image img = renderer.read_color();   // last frame, top row first
//   terralod::render::write_png(img, "shot.png");         // atomic: shot.png.tmp + rename
//   terralod::render::Image back = terralod::render::read_image("shot.png");
//   assert(back == img);
//
// Contract:
//   - rgb holds width * height * 3 bytes, row-major, row 0 = the TOP row of the picture,
//     channels R, G, B; pixel (x, y) starts at rgb[3 * (y * width + x)].
//   - write_png writes 8-bit RGB PNG to path + ".tmp" and renames it onto path; on failure
//     nothing is left at path and std::runtime_error names the file and the reason.
//   - read_image reads any image OpenImageIO can (PNG, TIFF, ...), keeping the first three
//     channels that are not its alpha (a grey image is repeated into R, G, B) converted to 8
//     bits; std::runtime_error names the file on failure.
//   - Memory: 3 bytes per pixel.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace terralod::render {

struct Image {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgb;  ///< width * height * 3 bytes, top row first

  std::uint8_t* pixel(int x, int y) { return rgb.data() + 3 * (std::size_t(y) * width + x); }
  const std::uint8_t* pixel(int x, int y) const { return rgb.data() + 3 * (std::size_t(y) * width + x); }
  bool operator==(const Image&) const = default;
};

/// Writes an 8-bit RGB PNG (see the contract above). img.rgb.size() must be width*height*3.
void write_png(const Image& img, const std::string& path);

/// Reads an image file as RGB8, top row first.
Image read_image(const std::string& path);

}  // namespace terralod::render
