// PNG writing and image reading for screenshots, through OpenImageIO (see image.hpp).
#include "terralod/render/image.hpp"

#include <OpenImageIO/imageio.h>

#include <cassert>
#include <filesystem>
#include <stdexcept>
#include <system_error>

#include "image_channels.hpp"
#include "terralod/pm/atomic_file.hpp"

namespace terralod::render {

void write_png(const Image& img, const std::string& path) {
  assert(img.width >= 1 && img.height >= 1 && img.rgb.size() == std::size_t(img.width) * img.height * 3);
  const std::string tmp = path + ".tmp";
  auto fail = [&](const std::string& why) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw std::runtime_error(path + ": cannot write PNG: " + why);
  };
  // The format is named explicitly: the temporary file's extension is ".tmp".
  auto out = OIIO::ImageOutput::create("png");
  if (!out) fail("OpenImageIO has no PNG writer (" + OIIO::geterror() + ")");
  const OIIO::ImageSpec spec(img.width, img.height, 3, OIIO::TypeDesc::UINT8);
  if (!out->open(tmp, spec)) fail(out->geterror());
  if (!out->write_image(OIIO::TypeDesc::UINT8, img.rgb.data())) {
    out->close();
    fail(out->geterror());
  }
  if (!out->close()) fail(out->geterror());
  pm::rename_into_place(tmp, path);
}

namespace detail {

ChannelPixels read_channel_pixels(const std::string& path, const std::string& what) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) {
    const std::string msg = OIIO::geterror();
    throw std::runtime_error(path + ": cannot read " + what + ": " + (msg.empty() ? "unknown format" : msg));
  }
  const OIIO::ImageSpec& spec = in->spec();
  if (spec.width < 1 || spec.height < 1 || spec.nchannels < 1)
    throw std::runtime_error(path + ": cannot read " + what + ": it has no pixels");
  ChannelPixels out{spec.width, spec.height, image_channels(spec, path), {}};
  out.pixels.resize(std::size_t(spec.width) * spec.height * out.channels.read);
  if (!in->read_image(0, 0, 0, out.channels.read, OIIO::TypeDesc::UINT8, out.pixels.data()))
    throw std::runtime_error(path + ": cannot read " + what + ": " + in->geterror());
  in->close();
  return out;
}

}  // namespace detail

Image read_image(const std::string& path) {
  const detail::ChannelPixels in = detail::read_channel_pixels(path, "image");
  const int n = in.channels.read;
  Image img;
  img.width = in.width;
  img.height = in.height;
  img.rgb.resize(std::size_t(img.width) * img.height * 3);
  for (std::size_t p = 0; p < std::size_t(img.width) * img.height; ++p)
    for (int c = 0; c < 3; ++c) img.rgb[3 * p + c] = in.pixels[p * n + in.channels.colour[std::size_t(c)]];
  return img;
}

}  // namespace terralod::render
