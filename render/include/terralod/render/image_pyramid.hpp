// ImagePyramid: an image of any size, larger than memory included, as a list of levels that
// halve down to the renderer's maximum texture size, read sub-image by sub-image.
//
// Usage:
//   terralod::render::PyramidOptions po;  po.max_texture_size = 1024;
//   terralod::render::ImagePyramid::convert("ortho.tif", "ortho.tx", po);  // streamed, bands of rows
//   terralod::render::ImagePyramid pyr("ortho.tx", po);
//   pyr.levels();                          // e.g. 5: 16000^2, 8000^2, ..., 1000^2
//   terralod::render::PixelRect r{/*level=*/2, /*x0=*/0, /*y0=*/0, /*width=*/512, /*height=*/256};
//   terralod::render::RgbaImage px = pyr.read(r);   // 512 x 256 RGBA8, top row first
//   // Levels rendered by the caller (a design rule per level of detail), not box-filtered:
//   std::vector<terralod::render::RgbaImage> lv;  // sizes exactly pyramid_levels(w, h, 1024)
//   terralod::render::ImagePyramid::write_levels(lv, "thematic.tx", po);
//   // Rows computed band by band (a shading texture of a terrain larger than memory):
//   terralod::render::ImagePyramid::convert(w, h, [&](int rows, std::uint8_t* rgba) { ... }, "shade.tx", po);
//
// Implementation: convert reads the source in bands of rows through an OpenImageIO ImageCache
// (tiles on demand, bounded memory) and writes a tiled (64 x 64), zip-compressed, MIP-mapped
// TIFF level by level: each level goes to the file band by band while it is halved into the
// next, which waits in a raw spool file beside the output (the TIFF takes one level after the
// other). The whole image is never in memory (OpenImageIO's make_texture, used before, held the
// source as floats: 4 GB for a 16000 x 16000 RGB image). Reads go through an ImageCache too (a
// bounded cache of PyramidOptions::cache_mb). This is the "image pyramid" of
// approximation-tree.txt section 3.3 and dynamic-3d-maps-texture-layers.txt section 3.1: all
// levels cover the same geo-referenced domain; level k+1 is level k scaled by 1/2
// (max(1, floor(w/2)) per axis): each pixel the rounded mean of its 2 x 2 block, the last block
// along an odd side taking the third column or row too.
// write_levels writes the same kind of TIFF through OIIO's ImageOutput, one directory per
// level (the TIFF writer appends them as subimages; OIIO reads a file marked "textureformat"
// back as MIP levels).
//
// Contract:
//   - Pixel coordinates: (x, y), x to the right, y DOWN from the top row of the image, at the
//     given level. A PixelRect may reach outside the level's image (power-of-two padding);
//     those pixels read as transparent black (0,0,0,0).
//   - Channels: any number in the file; read() always returns RGBA8. Alpha is the channel the
//     file marks as alpha (a PNG's, a TIFF extra sample marked alpha), 255 where none is; a
//     band is never alpha by its position (RGB + near infrared is RGB). Colour: the first three
//     other channels, or the first one repeated into R, G, B (grey) when there are fewer. A file
//     whose only channel is alpha is refused (runtime_error naming it).
//   - Alpha stays straight (not premultiplied) from the source file to read(), at every level;
//     coarser levels average colour and alpha independently (box filter).
//   - levels(): the finest level 0, down to and including the first level whose width and
//     height are both <= max_texture_size (the file may hold coarser ones; they are not used).
//   - write_levels(levels, out_path, options): levels[k] becomes MIP level k, byte for byte
//     (RGBA8, straight alpha), in the same kind of file convert writes (tiled tile_size x
//     tile_size, zip, TIFF); levels.size() and every level's size must equal
//     pyramid_levels(levels[0].width, levels[0].height, options.max_texture_size), else
//     std::invalid_argument naming the first level that does not, before anything is written.
//   - Writers go through out_path + ".tmp", renamed onto out_path when complete: on any error
//     out_path is untouched and no ".tmp" is left.
//   - Errors (unreadable file, not an image, write failure) throw std::runtime_error naming
//     the file and the reason. read() is thread-safe (the ImageCache is).
//   - Memory: convert, the cache (cache_mb, default 64 MiB) + two bands of tile_size rows of
//     level 0 (RGBA8 and the source's channels, as floats when they are stretched; a stretch's
//     histograms: 512 kB a colour channel, read in bands of 2^20 pixels); read, the cache +
//     the returned pixels (4 bytes each). On disk: the file (zip-compressed tiles, every level
//     down to 1 x 1) and, while convert runs, a quarter of level 0's RGBA8 at most (the spool
//     files, out_path + ".tmp.level-a" and "-b", removed when it ends, also on an error).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "terralod/blocks/image_stretch.hpp"
#include "terralod/render/rgba_image.hpp"

namespace terralod::render {

struct PyramidOptions {
  int max_texture_size = 2048;  ///< renderer limit, pixels per side, >= 1
  int tile_size = 64;           ///< tile side of the converted file, pixels (power of two)
  std::size_t cache_mb = 64;    ///< ImageCache budget for reading, MiB, >= 1
};

/// A rectangle of pixels of one pyramid level; may extend beyond the level's image.
struct PixelRect {
  int level = 0;
  int x0 = 0, y0 = 0;         ///< top-left pixel
  int width = 0, height = 0;  ///< >= 1
  bool operator==(const PixelRect&) const = default;
};

/// Size of one level.
struct LevelSize {
  int width = 0, height = 0;
  bool operator==(const LevelSize&) const = default;
};

/// Level sizes of a pyramid over a width x height image (both >= 1): level 0 is the image,
/// each next one max(1, floor(w/2)) x max(1, floor(h/2)), the last the first that fits
/// max_texture_size on both sides.
std::vector<LevelSize> pyramid_levels(int width, int height, int max_texture_size);

class ImagePyramid {
 public:
  /// Converts any image OpenImageIO reads into a tiled, MIP-mapped TIFF at `out_path`
  /// (written to out_path + ".tmp" and renamed), every level down to 1 x 1. Streams: the
  /// source is read in bands of rows through an ImageCache. Throws std::runtime_error naming
  /// the file on failure.
  /// Its colour channels become bytes by `stretch` (blocks/image_stretch.hpp: 8-bit images as
  /// they are, deeper ones each channel's 2 % to 98 % cut over the pixels that are not
  /// transparent, by default); returns the ranges of the image's values drawn as 0..255 in R,
  /// G and B (empty when 8-bit channels were taken as they are). A cut reads the image once
  /// more before (twice for 32-bit and floating point, whose range is measured first).
  /// `progress`, when given, gets the fraction done so far, (0, 1] (a cut's reading the first 0.3).
  static std::vector<blocks::BandRange> convert(const std::string& image_path, const std::string& out_path,
                                                const PyramidOptions& options = {},
                                                const std::function<void(double)>& progress = {},
                                                const blocks::StretchOptions& stretch = {});
  /// Same from pixels in memory (generated textures, tests).
  static void convert(const RgbaImage& image, const std::string& out_path,
                      const PyramidOptions& options = {});
  /// Fills rows row0 .. row0 + rows - 1 of level 0 (RGBA8, straight alpha) into `rgba`; asked
  /// for top to bottom, each call going on where the last one ended.
  using RowSource = std::function<void(int row0, int rows, std::uint8_t* rgba)>;
  /// Same from rows the caller computes in order, never all at once (a texture computed from a
  /// terrain larger than memory): `rows` is asked for bands of at most tile_size rows. `what`
  /// names the source in error messages; what `rows` throws goes through, nothing left behind.
  static void convert(int width, int height, const RowSource& rows, const std::string& out_path,
                      const PyramidOptions& options = {}, const std::function<void(double)>& progress = {},
                      const std::string& what = "(computed rows)");

  /// Writes given levels (not box-filtered from level 0) as a tiled, MIP-mapped TIFF at
  /// `out_path` (through out_path + ".tmp"): level k of the file is levels[k] exactly. Sizes
  /// must be exactly pyramid_levels(levels[0].width, levels[0].height,
  /// options.max_texture_size), else std::invalid_argument naming the level; write failures
  /// throw std::runtime_error naming the file. Memory: OIIO's tile buffers beyond the
  /// caller's levels.
  static void write_levels(const std::vector<RgbaImage>& levels, const std::string& out_path,
                           const PyramidOptions& options = {});
  /// Fills rows row0 .. row0 + rows - 1 of level `level` (RGBA8, its width per row) into
  /// `rgba`; asked level by level, each top to bottom.
  using LevelRowSource = std::function<void(int level, int row0, int rows, std::uint8_t* rgba)>;
  /// The same file from rows computed level by level (level 0 first, each level top to bottom,
  /// bands of at most tile_size rows), never a level whole in memory: the levels are
  /// pyramid_levels(width, height, options.max_texture_size). What `rows` throws goes through,
  /// nothing is left behind. `progress` gets the fraction of the pixels written.
  static void write_levels(int width, int height, const LevelRowSource& rows, const std::string& out_path,
                           const PyramidOptions& options = {},
                           const std::function<void(double)>& progress = {});

  /// Opens a converted file (or any image; a flat one is a one-level pyramid if it fits).
  explicit ImagePyramid(const std::string& path, const PyramidOptions& options = {});
  ~ImagePyramid();
  ImagePyramid(ImagePyramid&&) noexcept;
  ImagePyramid& operator=(ImagePyramid&&) noexcept;

  const std::string& path() const;
  int levels() const { return int(sizes_.size()); }
  const std::vector<LevelSize>& level_sizes() const { return sizes_; }
  LevelSize level(int k) const { return sizes_.at(std::size_t(k)); }
  int channels() const { return channels_; }

  /// The pixels of `r` as RGBA8 (outside the image: 0,0,0,0). 0 <= r.level < levels().
  RgbaImage read(const PixelRect& r) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::vector<LevelSize> sizes_;
  int channels_ = 0;
};

}  // namespace terralod::render
