// Which channels of an image file are drawn as red, green, blue and alpha: one rule for the
// texture layers (image_pyramid.cpp), the icons (object_renderer.cpp) and the plain images
// (image.cpp); and the one whole-file read of those channels the last two share.
//
// Alpha is the channel the file marks as alpha (OpenImageIO's alpha_channel: a PNG's, a TIFF
// extra sample marked so), never a band by its position: a fourth band is often near infrared
// (RGBN aerial imagery), a second one anything. Colour is the first three other channels, or
// the first one repeated into R, G and B (grey) when there are fewer. A file whose only channel
// is alpha is refused: std::runtime_error naming it.
#pragma once

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace terralod::render::detail {

struct ImageChannels {
  std::array<int, 3> colour{};  // the file's channels read as R, G, B
  int alpha = -1;               // the file's alpha channel; -1: none (opaque)
  int read = 0;                 // channels [0, read) hold them all: what a read needs

  /// One pixel of `read` channels (s) as RGBA (d).
  void to_rgba(const std::uint8_t* s, std::uint8_t* d) const {
    d[0] = s[colour[0]], d[1] = s[colour[1]], d[2] = s[colour[2]];
    d[3] = alpha >= 0 ? s[alpha] : 255;
  }
};

inline ImageChannels image_channels(const OIIO::ImageSpec& spec, const std::string& path) {
  ImageChannels c;
  const int n = spec.nchannels;
  c.alpha = spec.alpha_channel >= 0 && spec.alpha_channel < n ? spec.alpha_channel : -1;
  int found = 0;
  for (int k = 0; k < n && found < 3; ++k)
    if (k != c.alpha) c.colour[std::size_t(found++)] = k;
  if (found == 0)
    throw std::runtime_error(path + ": its only channel is alpha; an image needs colour or grey");
  if (found < 3) c.colour = {c.colour[0], c.colour[0], c.colour[0]};
  c.read = std::max(*std::max_element(c.colour.begin(), c.colour.end()), c.alpha) + 1;
  return c;
}

/// An image file read whole: each pixel's channels [0, channels.read), 8 bits each.
struct ChannelPixels {
  int width = 0, height = 0;
  ImageChannels channels;
  std::vector<std::uint8_t> pixels;
};

/// Reads `path` through OpenImageIO (image.cpp). Errors: std::runtime_error
/// "<path>: cannot read <what>: <why>" (what: "image", "the icon image", ...), and
/// image_channels' for a file of alpha alone.
ChannelPixels read_channel_pixels(const std::string& path, const std::string& what);

}  // namespace terralod::render::detail
