// Image pyramids through OpenImageIO: make_texture writes tiled MIP-mapped TIFFs, an
// ImageCache reads sub-images of any level (approximation-tree.txt section 3.3).
#include "terralod/render/image_pyramid.hpp"

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imagecache.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cassert>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <stdexcept>

#include "image_channels.hpp"
#include "terralod/pm/atomic_file.hpp"

namespace terralod::render {
namespace {

OIIO::ImageSpec texture_config(const PyramidOptions& o) {
  assert(o.tile_size >= 1 && (o.tile_size & (o.tile_size - 1)) == 0);
  OIIO::ImageSpec config;
  config.tile_width = o.tile_size;
  config.tile_height = o.tile_size;
  config.tile_depth = 1;
  config.set_format(OIIO::TypeDesc::UINT8);
  config.attribute("compression", "zip");
  config.attribute("wrapmodes", "clamp,clamp");
  config.attribute("maketx:filtername", "box");
  config.attribute("maketx:fileformatname", "tiff");
  config.attribute("maketx:constant_color_detect", 0);
  config.attribute("maketx:opaque_detect", 0);
  config.attribute("maketx:monochrome_detect", 0);
  config.attribute("oiio:UnassociatedAlpha", 1);  // straight alpha (see convert)
  return config;
}

void finish_convert(bool ok, const std::string& source, const std::string& tmp, const std::string& out,
                    const std::ostringstream& log) {
  std::error_code ec;
  if (!ok) {
    std::filesystem::remove(tmp, ec);
    std::string why = OIIO::geterror();
    if (why.empty()) why = log.str();
    throw std::runtime_error(source + ": cannot build the image pyramid " + out + ": " + why);
  }
  pm::rename_into_place(tmp, out);
}

}  // namespace

std::vector<LevelSize> pyramid_levels(int width, int height, int max_texture_size) {
  assert(width >= 1 && height >= 1 && max_texture_size >= 1);
  std::vector<LevelSize> out{{width, height}};
  while (out.back().width > max_texture_size || out.back().height > max_texture_size)
    out.push_back({std::max(1, out.back().width / 2), std::max(1, out.back().height / 2)});
  return out;
}

struct ImagePyramid::Impl {
  std::string path;
  OIIO::ustring upath;
  std::shared_ptr<OIIO::ImageCache> cache;
  detail::ImageChannels rgba;  // which of the file's channels read() returns as R, G, B, A
  ~Impl() {
    if (cache) cache->invalidate(upath, true);
  }
};

void ImagePyramid::convert(const std::string& image_path, const std::string& out_path,
                           const PyramidOptions& options) {
  {
    auto in = OIIO::ImageInput::open(image_path);
    if (!in) throw std::runtime_error(image_path + ": cannot read the image: " + OIIO::geterror());
  }
  // The source is read lazily through an ImageCache of its own (tiles on demand, bounded
  // memory) that keeps straight alpha as it is: maketx's own reader would premultiply PNGs.
  std::shared_ptr<OIIO::ImageCache> cache(OIIO::ImageCache::create(/*shared=*/false),
                                          [](OIIO::ImageCache* c) { OIIO::ImageCache::destroy(c); });
  cache->attribute("unassociatedalpha", 1);
  cache->attribute("max_memory_MB", float(options.cache_mb));
  cache->attribute("autotile", 64);
  OIIO::ImageBuf src(image_path, 0, 0, cache.get());
  if (!src.init_spec(image_path, 0, 0))
    throw std::runtime_error(image_path + ": cannot read the image: " + src.geterror());
  const std::string tmp = out_path + ".tmp";
  std::ostringstream log;
  const bool ok = OIIO::ImageBufAlgo::make_texture(OIIO::ImageBufAlgo::MakeTxTexture, src, tmp,
                                                   texture_config(options), &log);
  finish_convert(ok, image_path, tmp, out_path, log);
}

void ImagePyramid::convert(const RgbaImage& image, const std::string& out_path,
                           const PyramidOptions& options) {
  assert(image.width >= 1 && image.height >= 1 &&
         image.rgba.size() == std::size_t(image.width) * image.height * 4);
  OIIO::ImageSpec spec(image.width, image.height, 4, OIIO::TypeDesc::UINT8);
  spec.alpha_channel = 3;
  const OIIO::ImageBuf buf(spec, const_cast<std::uint8_t*>(image.rgba.data()));
  const std::string tmp = out_path + ".tmp";
  std::ostringstream log;
  const bool ok = OIIO::ImageBufAlgo::make_texture(OIIO::ImageBufAlgo::MakeTxTexture, buf, tmp,
                                                   texture_config(options), &log);
  finish_convert(ok, "(pixels in memory)", tmp, out_path, log);
}

void ImagePyramid::write_levels(const std::vector<RgbaImage>& levels, const std::string& out_path,
                                const PyramidOptions& options) {
  assert(options.tile_size >= 1 && (options.tile_size & (options.tile_size - 1)) == 0);
  if (levels.empty() || levels[0].width < 1 || levels[0].height < 1)
    throw std::invalid_argument(out_path + ": write_levels needs level 0 of at least 1 x 1 pixels");
  const std::vector<LevelSize> want =
      pyramid_levels(levels[0].width, levels[0].height, options.max_texture_size);
  for (std::size_t k = 0; k < std::max(want.size(), levels.size()); ++k) {
    const auto size = [](int w, int h) { return std::to_string(w) + " x " + std::to_string(h); };
    if (k >= levels.size() || k >= want.size())
      throw std::invalid_argument(out_path + ": write_levels got " + std::to_string(levels.size()) +
                                  " levels; a pyramid over " + size(levels[0].width, levels[0].height) +
                                  " down to " + std::to_string(options.max_texture_size) + " pixels has " +
                                  std::to_string(want.size()) + " (level " + std::to_string(k) +
                                  (k >= levels.size() ? " is missing)" : " is one too many)"));
    const RgbaImage& l = levels[k];
    assert(l.rgba.size() == std::size_t(std::max(l.width, 0)) * std::size_t(std::max(l.height, 0)) * 4);
    if (l.width != want[k].width || l.height != want[k].height)
      throw std::invalid_argument(out_path + ": write_levels level " + std::to_string(k) + " is " +
                                  size(l.width, l.height) + " pixels, the pyramid needs " +
                                  size(want[k].width, want[k].height));
  }
  const std::string tmp = out_path + ".tmp";
  const auto fail = [&](const std::string& why) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw std::runtime_error(out_path + ": cannot write the image pyramid: " + why);
  };
  std::unique_ptr<OIIO::ImageOutput> out = OIIO::ImageOutput::create("tiff");
  if (!out) fail(OIIO::geterror());
  // OIIO's TIFF writer stores MIP levels as further directories (AppendSubimage), which its
  // reader presents as MIP levels of a file marked "textureformat" (what make_texture does).
  const bool mip = out->supports("mipmap");
  if (levels.size() > 1 && !mip && !out->supports("multiimage"))
    fail("the TIFF writer stores neither MIP levels nor subimages");
  for (std::size_t k = 0; k < levels.size(); ++k) {
    const RgbaImage& l = levels[k];
    // The attributes of make_texture's output (texture_config), so both writers' files read alike.
    OIIO::ImageSpec spec(l.width, l.height, 4, OIIO::TypeDesc::UINT8);
    spec.alpha_channel = 3;
    spec.tile_width = spec.tile_height = options.tile_size;
    spec.tile_depth = 1;
    spec.attribute("compression", "zip");
    spec.attribute("wrapmodes", "clamp,clamp");
    spec.attribute("textureformat", "Plain Texture");
    spec.attribute("oiio:UnassociatedAlpha", 1);  // straight alpha, as convert keeps it
    const auto mode = k == 0 ? OIIO::ImageOutput::Create
                      : mip  ? OIIO::ImageOutput::AppendMIPLevel
                             : OIIO::ImageOutput::AppendSubimage;
    if (!out->open(tmp, spec, mode) || !out->write_image(OIIO::TypeDesc::UINT8, l.rgba.data()))
      fail("level " + std::to_string(k) + ": " + out->geterror());
  }
  if (!out->close()) fail(out->geterror());
  out.reset();
  pm::rename_into_place(tmp, out_path);
}

ImagePyramid::ImagePyramid(const std::string& path, const PyramidOptions& options)
    : impl_(std::make_unique<Impl>()) {
  assert(options.max_texture_size >= 1 && options.cache_mb >= 1);
  impl_->path = path;
  impl_->upath = OIIO::ustring(path);
  impl_->cache = std::shared_ptr<OIIO::ImageCache>(OIIO::ImageCache::create(/*shared=*/false),
                                                   [](OIIO::ImageCache* c) { OIIO::ImageCache::destroy(c); });
  impl_->cache->attribute("max_memory_MB", float(options.cache_mb));
  impl_->cache->attribute("unassociatedalpha", 1);  // keep straight alpha (PNG) straight
  impl_->cache->attribute("autotile", 64);          // untiled sources are read in 64 x 64 pieces too
  OIIO::ImageSpec spec;
  if (!impl_->cache->get_imagespec(impl_->upath, spec, 0, 0)) {
    const std::string why = impl_->cache->geterror();
    throw std::runtime_error(path + ": cannot open the image pyramid: " + why);
  }
  channels_ = spec.nchannels;
  impl_->rgba = detail::image_channels(spec, path);
  const std::vector<LevelSize> wanted = pyramid_levels(spec.width, spec.height, options.max_texture_size);
  for (int k = 0; k < int(wanted.size()); ++k) {
    OIIO::ImageSpec ls;
    if (!impl_->cache->get_imagespec(impl_->upath, ls, 0, k)) {
      (void)impl_->cache->geterror();
      throw std::runtime_error(path + ": has " + std::to_string(k) + " MIP level(s) but " +
                               std::to_string(wanted.size()) + " are needed to reach " +
                               std::to_string(options.max_texture_size) +
                               " pixels per side; convert it with ImagePyramid::convert");
    }
    sizes_.push_back({ls.width, ls.height});
    if (ls.width <= options.max_texture_size && ls.height <= options.max_texture_size) break;
  }
}

ImagePyramid::~ImagePyramid() = default;
ImagePyramid::ImagePyramid(ImagePyramid&&) noexcept = default;
ImagePyramid& ImagePyramid::operator=(ImagePyramid&&) noexcept = default;

const std::string& ImagePyramid::path() const { return impl_->path; }

RgbaImage ImagePyramid::read(const PixelRect& r) const {
  assert(r.level >= 0 && r.level < levels() && r.width >= 1 && r.height >= 1);
  const LevelSize ls = sizes_[std::size_t(r.level)];
  RgbaImage out(r.width, r.height);
  const int x0 = std::max(r.x0, 0), y0 = std::max(r.y0, 0);
  const int x1 = std::min(r.x0 + r.width, ls.width), y1 = std::min(r.y0 + r.height, ls.height);
  if (x0 >= x1 || y0 >= y1) return out;
  const int nc = impl_->rgba.read;  // only the channels up to the last one used (an image may have many)
  std::vector<std::uint8_t> raw(std::size_t(x1 - x0) * (y1 - y0) * nc);
  if (!impl_->cache->get_pixels(impl_->upath, 0, r.level, x0, x1, y0, y1, 0, 1, /*chbegin=*/0, /*chend=*/nc,
                                OIIO::TypeDesc::UINT8, raw.data()))
    throw std::runtime_error(impl_->path + ": cannot read level " + std::to_string(r.level) + " pixels [" +
                             std::to_string(x0) + "," + std::to_string(x1) + ") x [" + std::to_string(y0) +
                             "," + std::to_string(y1) + "): " + impl_->cache->geterror());
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) {
      const std::uint8_t* s = raw.data() + (std::size_t(y - y0) * (x1 - x0) + (x - x0)) * nc;
      std::uint8_t* d = out.rgba.data() + (std::size_t(y - r.y0) * r.width + (x - r.x0)) * 4;
      impl_->rgba.to_rgba(s, d);
    }
  return out;
}

}  // namespace terralod::render
