// Image pyramids through OpenImageIO: tiled MIP-mapped TIFFs written level by level in bands of
// rows, read back through an ImageCache, sub-image by sub-image at any level
// (approximation-tree.txt section 3.3).
#include "terralod/render/image_pyramid.hpp"

#include <OpenImageIO/imagecache.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <array>
#include <cassert>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "image_channels.hpp"
#include "terralod/pm/atomic_file.hpp"

namespace terralod::render {
namespace {

// The spec of level (w x h) of every pyramid file this writes (convert and write_levels alike):
// RGBA8 with straight alpha, tiled, zip-compressed, marked "textureformat" so that OIIO reads
// the file's further directories (AppendMIPLevel) back as MIP levels. Deflate's fastest level:
// the file is a temporary of the texture commands, and its default level was a third of the CPU
// of 'texture shade' (a 3601^2 shade with shadows: 7.3-7.5 s -> 4.4-4.7 s, the file 20.0 -> 21.7 MB).
OIIO::ImageSpec level_spec(int w, int h, const PyramidOptions& o) {
  OIIO::ImageSpec spec(w, h, 4, OIIO::TypeDesc::UINT8);
  spec.alpha_channel = 3;
  spec.tile_width = spec.tile_height = o.tile_size;
  spec.tile_depth = 1;
  spec.attribute("compression", "zip:1");
  spec.attribute("wrapmodes", "clamp,clamp");
  spec.attribute("textureformat", "Plain Texture");
  spec.attribute("oiio:UnassociatedAlpha", 1);
  return spec;
}

// An ImageCache of its own (not OIIO's shared one) of `cache_mb` MiB, keeping straight alpha
// (PNG) straight and reading untiled files in 64 x 64 pieces too: convert's source and a
// pyramid's file are read through one each.
std::shared_ptr<OIIO::ImageCache> make_image_cache(std::size_t cache_mb) {
  std::shared_ptr<OIIO::ImageCache> cache(OIIO::ImageCache::create(/*shared=*/false),
                                          [](OIIO::ImageCache* c) { OIIO::ImageCache::destroy(c); });
  cache->attribute("max_memory_MB", float(cache_mb));
  cache->attribute("unassociatedalpha", 1);
  cache->attribute("autotile", 64);
  return cache;
}

// The TIFF file a pyramid is written into level after level, through out_path + ".tmp" (removed
// unless finish() renamed it into place): level 0 creates the file, each further level is
// appended as a MIP level, or as a subimage where the writer has no MIP levels (OIIO's reader
// presents those as MIP levels of a file marked "textureformat", level_spec). `fail` throws
// with the caller's message; write_pyramid and write_levels both write through this.
class PyramidFile {
 public:
  using Fail = std::function<void(const std::string& why)>;
  PyramidFile(const std::string& out_path, const PyramidOptions& o, std::size_t levels, Fail fail)
      : out_path_(out_path), tmp_(out_path + ".tmp"), remove_tmp_(tmp_), o_(o), fail_(std::move(fail)) {
    out_ = OIIO::ImageOutput::create("tiff");
    if (!out_) fail_(OIIO::geterror());
    mip_ = out_->supports("mipmap");
    if (levels > 1 && !mip_ && !out_->supports("multiimage"))
      fail_("the TIFF writer stores neither MIP levels nor subimages");
  }
  // Starts level k, w x h pixels.
  void open_level(int k, int w, int h) {
    const auto mode = k == 0 ? OIIO::ImageOutput::Create
                      : mip_ ? OIIO::ImageOutput::AppendMIPLevel
                             : OIIO::ImageOutput::AppendSubimage;
    k_ = k, w_ = w;
    if (!out_->open(tmp_, level_spec(w, h, o_), mode))
      fail_("level " + std::to_string(k) + ": " + out_->geterror());
  }
  // Rows y .. y + n - 1 of the level open (RGBA8, whole rows of tiles but the last).
  void write_rows(int y, int n, const std::uint8_t* rgba) {
    if (!out_->write_tiles(0, w_, y, y + n, 0, 1, OIIO::TypeDesc::UINT8, rgba))
      fail_("level " + std::to_string(k_) + ": " + out_->geterror());
  }
  void finish() {
    if (!out_->close()) fail_(out_->geterror());
    out_.reset();
    pm::rename_into_place(tmp_, out_path_);
    remove_tmp_.keep();
  }

 private:
  std::string out_path_, tmp_;
  pm::FileRemover remove_tmp_;
  PyramidOptions o_;
  Fail fail_;
  std::unique_ptr<OIIO::ImageOutput> out_;
  bool mip_ = false;
  int k_ = 0, w_ = 0;
};

// Fills rows row0 .. row0 + rows - 1 (RGBA8, asked top to bottom) of the level being written
// into `rgba`; throws naming the source on a read error.
using RowSource = ImagePyramid::RowSource;

// One level halved row by row: the rows of a w x h level go in, in order; the rows of the next
// level (max(1, w/2) x max(1, h/2)) come out. Next-level pixel (x, y) is the rounded mean of
// the block of columns 2x, 2x+1 and rows 2y, 2y+1; along an odd side (> 1) the last block
// takes the third column or row too, along a side of 1 the one pixel. Colour and alpha are
// averaged alike (straight alpha, as the file keeps it).
class Halver {
 public:
  Halver(int w, int h)
      : w_(w), h_(h), nw_(std::max(1, w / 2)), nh_(std::max(1, h / 2)), acc_(std::size_t(nw_) * 4) {}
  int width() const { return nw_; }
  int height() const { return nh_; }
  // Adds the next row of the level; true when it completes a row of the next one (in `out`).
  bool add(const std::uint8_t* row, std::uint8_t* out) {
    for (int x = 0; x < nw_; ++x)
      for (int xx = 2 * x; xx < end(x, nw_, w_); ++xx)
        for (int c = 0; c < 4; ++c) acc_[std::size_t(4 * x + c)] += row[std::size_t(4 * xx + c)];
    const int r = r_++, j = std::min(r / 2, nh_ - 1);
    if (r + 1 < end(j, nh_, h_)) return false;
    const std::uint32_t rows = std::uint32_t(end(j, nh_, h_) - 2 * j);
    for (int x = 0; x < nw_; ++x) {
      const std::uint32_t n = std::uint32_t(end(x, nw_, w_) - 2 * x) * rows;
      for (int c = 0; c < 4; ++c) {
        std::uint32_t& a = acc_[std::size_t(4 * x + c)];
        out[4 * x + c] = std::uint8_t((a + n / 2) / n);
        a = 0;
      }
    }
    return true;
  }

 private:
  // One past the last index of block i of the n blocks over a side of s.
  static int end(int i, int n, int s) { return i + 1 == n ? s : 2 * i + 2; }
  int w_, h_, nw_, nh_, r_ = 0;
  std::vector<std::uint32_t> acc_;
};

// Writes the pyramid of the w x h image whose rows `level0` gives: every level down to 1 x 1,
// streamed. Each level is written to the file in bands of tile_size rows while it is halved
// into the next, which goes to a raw spool file beside the output and is read back in bands
// for its turn (the TIFF takes one level after the other): memory is two bands and a row per
// level, disk a quarter of level 0's RGBA at most besides the output. Through out_path + ".tmp",
// renamed when complete; on any error nothing is left. `what` names the source in errors.
void write_pyramid(const RowSource& level0, int w, int h, const std::string& out_path,
                   const PyramidOptions& o, const std::string& what,
                   const std::function<void(double)>& progress) {
  assert(w >= 1 && h >= 1 && o.tile_size >= 1 && (o.tile_size & (o.tile_size - 1)) == 0);
  const std::string spool[2] = {out_path + ".tmp.level-a", out_path + ".tmp.level-b"};
  pm::FileRemover remove_spool_a(spool[0]), remove_spool_b(spool[1]);
  const auto fail = [&](const std::string& why) -> void {
    throw std::runtime_error(what + ": cannot build the image pyramid " + out_path + ": " + why);
  };
  double total = 0.0, done = 0.0;  // pixels, for the progress
  std::size_t levels = 0;
  for (int lw = w, lh = h;; lw = std::max(1, lw / 2), lh = std::max(1, lh / 2)) {
    total += double(lw) * lh;
    ++levels;
    if (lw == 1 && lh == 1) break;
  }
  PyramidFile file(out_path, o, levels, fail);
  RowSource src = level0;
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> in(nullptr, &std::fclose);
  const std::size_t band_rows = std::size_t(o.tile_size);
  std::vector<std::uint8_t> band, next;
  for (int k = 0;; ++k) {
    file.open_level(k, w, h);
    const bool last = w == 1 && h == 1;
    Halver halver(w, h);
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> to(nullptr, &std::fclose);
    if (!last) {
      to.reset(std::fopen(spool[(k + 1) % 2].c_str(), "wb"));
      if (!to) fail("cannot write " + spool[(k + 1) % 2]);
    }
    band.resize(band_rows * std::size_t(w) * 4);
    next.resize(std::size_t(halver.width()) * 4);
    for (int y = 0; y < h; y += int(band_rows)) {
      const int n = std::min(int(band_rows), h - y);
      src(y, n, band.data());
      file.write_rows(y, n, band.data());
      if (!last)
        for (int r = 0; r < n; ++r)
          if (halver.add(band.data() + std::size_t(r) * w * 4, next.data()) &&
              std::fwrite(next.data(), 1, next.size(), to.get()) != next.size())
            fail("cannot write " + spool[(k + 1) % 2]);
      done += double(n) * w;
      if (progress) progress(std::min(1.0, done / total));
    }
    if (last) break;
    if (std::fflush(to.get()) != 0) fail("cannot write " + spool[(k + 1) % 2]);
    to.reset();
    // The next level is read back from its spool file.
    in.reset(std::fopen(spool[(k + 1) % 2].c_str(), "rb"));
    if (!in) fail("cannot read " + spool[(k + 1) % 2]);
    const std::size_t row_bytes = next.size();
    src = [&in, row_bytes, &fail, name = spool[(k + 1) % 2]](int, int rows, std::uint8_t* rgba) {
      if (std::fread(rgba, 1, row_bytes * std::size_t(rows), in.get()) != row_bytes * std::size_t(rows))
        fail("cannot read " + name);
    };
    w = halver.width(), h = halver.height();
  }
  in.reset();
  file.finish();
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

namespace {

// A channel's OpenImageIO type as image_stretch.hpp's (bits, signed, floating point); `unit`:
// what its values read as FLOAT (0..1 for unsigned integers, -1..1 for signed) are multiplied
// by to give the image's own values.
struct ChannelType {
  int bits = 8;
  bool is_signed = false, is_float = false;
  double unit = 255;
};

ChannelType channel_type(OIIO::TypeDesc t) {
  ChannelType c;
  c.bits = int(t.basesize()) * 8;
  c.is_float = t.is_floating_point();
  c.is_signed = t.is_signed();
  c.unit = c.is_float ? 1.0 : blocks::type_range(c.bits, c.is_signed, false).hi;
  return c;
}

// The ranges of the colour channels' values drawn as 0..255 (image_stretch.hpp; empty: 8-bit
// channels as they are). A cut reads the image in bands of about 2^20 pixels through
// read_rows(row0, n, type, out): one pass to count each channel over the pixels that are not
// transparent, after one for the range of those not counted on exact bins. progress: 0..1.
std::vector<blocks::BandRange> channel_ranges(
    const blocks::StretchOptions& stretch, bool deep, const detail::ImageChannels& ch,
    const std::array<ChannelType, 3>& types, int width, int height,
    const std::function<void(int, int, OIIO::TypeDesc, void*)>& read_rows,
    const std::function<void(double)>& progress) {
  const blocks::StretchStep step = blocks::stretch_step(stretch, deep);
  if (step == blocks::StretchStep::AsIs) return {};
  std::vector<blocks::BandRange> ranges(3);
  if (step == blocks::StretchStep::Fixed) {
    for (std::size_t c = 0; c < 3; ++c)
      ranges[c] = blocks::fixed_range(
          stretch, blocks::type_range(types[c].bits, types[c].is_signed, types[c].is_float));
    return ranges;
  }
  std::array<std::optional<blocks::BandHistogram>, 3> hists;
  for (std::size_t c = 0; c < 3; ++c)
    hists[c] = blocks::exact_histogram(types[c].bits, types[c].is_signed, types[c].is_float);
  const bool measure = std::any_of(hists.begin(), hists.end(), [](const auto& h) { return !h; });
  std::array<double, 3> lo{}, hi{};
  lo.fill(std::numeric_limits<double>::infinity());
  hi.fill(-std::numeric_limits<double>::infinity());
  const int band_rows = std::max(1, (1 << 20) / width), passes = measure ? 2 : 1;
  std::vector<float> px;
  for (int pass = 2 - passes; pass < 2; ++pass) {
    for (int y = 0; y < height; y += band_rows) {
      const int n = std::min(band_rows, height - y);
      px.resize(std::size_t(width) * std::size_t(n) * std::size_t(ch.read));
      read_rows(y, n, OIIO::TypeDesc::FLOAT, px.data());
      for (std::size_t p = 0; p < std::size_t(width) * std::size_t(n); ++p) {
        const float* v = px.data() + p * std::size_t(ch.read);
        if (ch.alpha >= 0 && !(v[ch.alpha] > 0.0f)) continue;
        for (std::size_t c = 0; c < 3; ++c) {
          const double x = double(v[ch.colour[c]]) * types[c].unit;
          if (pass == 1)
            hists[c]->add(x);
          else if (x == x)
            lo[c] = std::min(lo[c], x), hi[c] = std::max(hi[c], x);
        }
      }
      if (progress) progress((double(pass - (2 - passes)) + double(y + n) / height) / double(passes));
    }
    if (pass == 0)
      for (std::size_t c = 0; c < 3; ++c)
        if (!hists[c]) hists[c].emplace(lo[c] <= hi[c] ? lo[c] : 0.0, lo[c] <= hi[c] ? hi[c] : 1.0, 65536);
  }
  for (std::size_t c = 0; c < 3; ++c) ranges[c] = hists[c]->cut(stretch.cut_percent);
  return ranges;
}

}  // namespace

std::vector<blocks::BandRange> ImagePyramid::convert(const std::string& image_path,
                                                     const std::string& out_path,
                                                     const PyramidOptions& options,
                                                     const std::function<void(double)>& progress,
                                                     const blocks::StretchOptions& stretch) {
  // A file that is no image is told by ImageInput first: an ImageCache asked for it would also
  // print its own "Invalid image file" line on stderr beside the error thrown here.
  {
    auto in = OIIO::ImageInput::open(image_path);
    if (!in) throw std::runtime_error(image_path + ": cannot read the image: " + OIIO::geterror());
  }
  // The source is read in bands of rows through an ImageCache (tiles on demand, bounded memory).
  const std::shared_ptr<OIIO::ImageCache> cache = make_image_cache(options.cache_mb);
  const OIIO::ustring upath(image_path);
  OIIO::ImageSpec spec;
  if (!cache->get_imagespec(upath, spec, 0, 0))
    throw std::runtime_error(image_path + ": cannot read the image: " + cache->geterror());
  if (spec.width < 1 || spec.height < 1)
    throw std::runtime_error(image_path + ": cannot read the image: it has no pixels");
  const detail::ImageChannels ch = detail::image_channels(spec, image_path);
  const std::size_t width = std::size_t(spec.width);
  // Reads rows [row0, row0 + n) of channels [0, ch.read) as `type` into `out`.
  const auto read_rows = [&](int row0, int n, OIIO::TypeDesc type, void* out) {
    const int y = spec.y + row0;
    if (!cache->get_pixels(upath, 0, 0, spec.x, spec.x + spec.width, y, y + n, spec.z, spec.z + 1, 0, ch.read,
                           type, out))
      throw std::runtime_error(image_path + ": cannot read rows " + std::to_string(row0) + ".." +
                               std::to_string(row0 + n - 1) + ": " + cache->geterror());
  };
  // Whether and how the colour channels are stretched (image_stretch.hpp).
  std::array<ChannelType, 3> types;
  bool deep = false;
  for (std::size_t c = 0; c < 3; ++c) {
    types[c] = channel_type(spec.channelformat(ch.colour[c]));
    deep = deep || types[c].bits != 8 || types[c].is_float || types[c].is_signed;
  }
  const double cut_share = blocks::stretch_step(stretch, deep) == blocks::StretchStep::Cut ? 0.3 : 0.0;
  const std::vector<blocks::BandRange> ranges =
      channel_ranges(stretch, deep, ch, types, spec.width, spec.height, read_rows, [&](double f) {
        if (progress) progress(cut_share * f);
      });

  const auto pyramid_progress = [&](double f) {
    if (progress) progress(cut_share + (1.0 - cut_share) * f);
  };
  if (ranges.empty()) {
    std::vector<std::uint8_t> raw;
    const RowSource rows = [&](int row0, int n, std::uint8_t* rgba) {
      raw.resize(width * std::size_t(n) * std::size_t(ch.read));
      read_rows(row0, n, OIIO::TypeDesc::UINT8, raw.data());
      for (std::size_t p = 0; p < width * std::size_t(n); ++p)
        ch.to_rgba(raw.data() + p * std::size_t(ch.read), rgba + 4 * p);
    };
    write_pyramid(rows, spec.width, spec.height, out_path, options, image_path, pyramid_progress);
  } else {
    std::vector<float> raw;
    const RowSource rows = [&](int row0, int n, std::uint8_t* rgba) {
      raw.resize(width * std::size_t(n) * std::size_t(ch.read));
      read_rows(row0, n, OIIO::TypeDesc::FLOAT, raw.data());
      for (std::size_t p = 0; p < width * std::size_t(n); ++p) {
        const float* v = raw.data() + p * std::size_t(ch.read);
        std::uint8_t* d = rgba + 4 * p;
        for (std::size_t c = 0; c < 3; ++c) d[c] = ranges[c].to_byte(double(v[ch.colour[c]]) * types[c].unit);
        d[3] = ch.alpha < 0 ? 255 : blocks::BandRange{0, 1}.to_byte(double(v[ch.alpha]));
      }
    };
    write_pyramid(rows, spec.width, spec.height, out_path, options, image_path, pyramid_progress);
  }
  cache->invalidate(upath, true);
  return ranges;
}

void ImagePyramid::convert(const RgbaImage& image, const std::string& out_path,
                           const PyramidOptions& options) {
  assert(image.width >= 1 && image.height >= 1 &&
         image.rgba.size() == std::size_t(image.width) * image.height * 4);
  const RowSource rows = [&](int row0, int n, std::uint8_t* rgba) {
    std::copy_n(image.pixel(0, row0), std::size_t(image.width) * std::size_t(n) * 4, rgba);
  };
  write_pyramid(rows, image.width, image.height, out_path, options, "(pixels in memory)", {});
}

void ImagePyramid::convert(int width, int height, const RowSource& rows, const std::string& out_path,
                           const PyramidOptions& options, const std::function<void(double)>& progress,
                           const std::string& what) {
  if (width < 1 || height < 1)
    throw std::invalid_argument(what + ": cannot build the image pyramid " + out_path + ": " +
                                std::to_string(width) + " x " + std::to_string(height) + " pixels");
  write_pyramid(rows, width, height, out_path, options, what, progress);
}

void ImagePyramid::write_levels(const std::vector<RgbaImage>& levels, const std::string& out_path,
                                const PyramidOptions& options) {
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
  write_levels(
      levels[0].width, levels[0].height,
      [&](int k, int row0, int rows, std::uint8_t* rgba) {
        const RgbaImage& l = levels[std::size_t(k)];
        std::copy_n(l.rgba.data() + std::size_t(row0) * l.width * 4, std::size_t(l.width) * rows * 4, rgba);
      },
      out_path, options);
}

void ImagePyramid::write_levels(int width, int height, const LevelRowSource& rows,
                                const std::string& out_path, const PyramidOptions& options,
                                const std::function<void(double)>& progress) {
  assert(options.tile_size >= 1 && (options.tile_size & (options.tile_size - 1)) == 0);
  if (width < 1 || height < 1)
    throw std::invalid_argument(out_path + ": write_levels needs level 0 of at least 1 x 1 pixels");
  const std::vector<LevelSize> sizes = pyramid_levels(width, height, options.max_texture_size);
  PyramidFile file(out_path, options, sizes.size(), [&](const std::string& why) {
    throw std::runtime_error(out_path + ": cannot write the image pyramid: " + why);
  });
  double total = 0.0, done = 0.0;  // pixels, for the progress
  for (const LevelSize& l : sizes) total += double(l.width) * l.height;
  std::vector<std::uint8_t> band;
  for (std::size_t k = 0; k < sizes.size(); ++k) {
    const int w = sizes[k].width, h = sizes[k].height;
    file.open_level(int(k), w, h);
    for (int y = 0; y < h; y += options.tile_size) {
      const int n = std::min(options.tile_size, h - y);
      band.resize(std::size_t(w) * std::size_t(n) * 4);
      rows(int(k), y, n, band.data());
      file.write_rows(y, n, band.data());
      done += double(w) * n;
      if (progress) progress(std::min(1.0, done / total));
    }
  }
  file.finish();
}

ImagePyramid::ImagePyramid(const std::string& path, const PyramidOptions& options)
    : impl_(std::make_unique<Impl>()) {
  assert(options.max_texture_size >= 1 && options.cache_mb >= 1);
  impl_->path = path;
  impl_->upath = OIIO::ustring(path);
  impl_->cache = make_image_cache(options.cache_mb);
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
