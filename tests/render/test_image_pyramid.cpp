// Tests of ImagePyramid: level sizes by hand, exact round trips of level 0 through the tiled
// MIP-mapped file, box-filtered coarser levels, reads beyond the image, which channels are
// colour and which alpha (also for read_image), bad files, and
// pyramids of given levels (write_levels): exact round trips, wrong sizes refused.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <array>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "peak_memory.hpp"
#include "terralod/render/image.hpp"
#include "terralod/render/image_pyramid.hpp"
#include "terralod/render/texture_store.hpp"

namespace {

namespace fs = std::filesystem;
using namespace terralod::render;

std::string tmp_path(const std::string& name) { return std::string(TERRALOD_TEST_TMP) + "/pyramid_" + name; }

// A w x h image whose 2x2 blocks are uniform: pixel (x, y) = (x/2 * 10, y/2 * 20, 7, 200).
RgbaImage blocky(int w, int h) {
  RgbaImage img(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) img.set(x, y, {std::uint8_t(x / 2 * 10), std::uint8_t(y / 2 * 20), 7, 200});
  return img;
}

TEST(ImagePyramid, LevelSizesHalveDownToTheMaximumTextureSize) {
  // 1000 x 600, max 256: 1000x600 -> 500x300 -> 250x150 (fits): 3 levels.
  const std::vector<LevelSize> a = pyramid_levels(1000, 600, 256);
  ASSERT_EQ(a.size(), 3u);
  EXPECT_EQ(a[1], (LevelSize{500, 300}));
  EXPECT_EQ(a[2], (LevelSize{250, 150}));
  // Odd sizes floor, never below 1: 5x3 with max 1 -> 5x3, 2x1, 1x1.
  const std::vector<LevelSize> b = pyramid_levels(5, 3, 1);
  ASSERT_EQ(b.size(), 3u);
  EXPECT_EQ(b[1], (LevelSize{2, 1}));
  EXPECT_EQ(b[2], (LevelSize{1, 1}));
  // Already small enough: one level.
  EXPECT_EQ(pyramid_levels(64, 64, 64).size(), 1u);
}

TEST(ImagePyramid, ConvertedFileRoundTripsLevelZeroAndBoxFiltersTheNext) {
  // 100 x 60 with max 32: levels 100x60, 50x30, 25x15.
  const RgbaImage src = blocky(100, 60);
  const std::string path = tmp_path("blocky.tx");
  PyramidOptions po;
  po.max_texture_size = 32;
  ImagePyramid::convert(src, path, po);
  EXPECT_FALSE(fs::exists(path + ".tmp"));
  const ImagePyramid pyr(path, po);
  ASSERT_EQ(pyr.levels(), 3);
  EXPECT_EQ(pyr.level(0), (LevelSize{100, 60}));
  EXPECT_EQ(pyr.level(1), (LevelSize{50, 30}));
  EXPECT_EQ(pyr.level(2), (LevelSize{25, 15}));
  EXPECT_EQ(pyr.channels(), 4);
  EXPECT_EQ(pyr.read({0, 0, 0, 100, 60}), src);  // lossless, every tile
  // Level 1 pixel (x, y) is the 2x2 block (2x..2x+1, 2y..2y+1) of level 0, all equal.
  const RgbaImage l1 = pyr.read({1, 10, 5, 20, 10});
  for (int y = 0; y < 10; ++y)
    for (int x = 0; x < 20; ++x) {
      const auto want = src.get(2 * (x + 10), 2 * (y + 5));
      EXPECT_EQ(l1.get(x, y), want) << "level 1 pixel " << x + 10 << "," << y + 5;
    }
}

TEST(ImagePyramid, OddSidesFoldTheirLastColumnAndRowIntoTheLastBlock) {
  // 7 x 5 -> 3 x 2 -> 1 x 1: a pixel of the next level is the rounded mean of its block of
  // columns {2x, 2x+1} and rows {2y, 2y+1}, the last block along an odd side taking the third.
  RgbaImage src(7, 5);
  std::uint32_t seed = 12345;
  for (std::uint8_t& v : src.rgba) v = std::uint8_t((seed = seed * 1664525u + 1013904223u) >> 24);
  const std::string tx = tmp_path("odd.tx");
  PyramidOptions po;
  po.max_texture_size = 1;  // every level down to 1 x 1 is used
  ImagePyramid::convert(src, tx, po);
  const ImagePyramid pyr(tx, po);
  ASSERT_EQ(pyr.levels(), 3);
  EXPECT_EQ(pyr.level(1), (LevelSize{3, 2}));
  EXPECT_EQ(pyr.level(2), (LevelSize{1, 1}));
  const auto halve = [](const RgbaImage& a) {
    RgbaImage b(std::max(1, a.width / 2), std::max(1, a.height / 2));
    const auto block = [](int i, int n, int s) { return std::pair{2 * i, i + 1 == n ? s : 2 * i + 2}; };
    for (int y = 0; y < b.height; ++y)
      for (int x = 0; x < b.width; ++x) {
        const auto [x0, x1] = block(x, b.width, a.width);
        const auto [y0, y1] = block(y, b.height, a.height);
        std::array<std::uint8_t, 4> v{};
        for (int c = 0; c < 4; ++c) {
          unsigned sum = 0, n = 0;
          for (int yy = y0; yy < y1; ++yy)
            for (int xx = x0; xx < x1; ++xx) sum += a.get(xx, yy)[std::size_t(c)], ++n;
          v[std::size_t(c)] = std::uint8_t((sum + n / 2) / n);
        }
        b.set(x, y, v);
      }
    return b;
  };
  const RgbaImage l1 = halve(src), l2 = halve(l1);
  EXPECT_EQ(pyr.read({0, 0, 0, 7, 5}), src);
  EXPECT_EQ(pyr.read({1, 0, 0, 3, 2}), l1);
  EXPECT_EQ(pyr.read({2, 0, 0, 1, 1}), l2);
}

TEST(ImagePyramid, ConvertHoldsBandsOfRowsNotTheImage) {
  // A 6000 x 4000 RGB TIFF (72 MB of pixels, 96 MB as RGBA) written row by row: converting it
  // holds the read cache (16 MB here) and a few bands of rows; 21 MB measured. OpenImageIO's
  // make_texture, used before, held the image as floats (288 MB here; 4 GB for 16000 x 16000).
  const int w = 6000, h = 4000;
  const std::string tif = tmp_path("large.tif"), tx = tmp_path("large.tx");
  {
    auto out = OIIO::ImageOutput::create(tif);
    ASSERT_TRUE(out);
    OIIO::ImageSpec spec(w, h, 3, OIIO::TypeDesc::UINT8);
    spec.attribute("compression", "zip");
    ASSERT_TRUE(out->open(tif, spec));
    std::vector<std::uint8_t> row(std::size_t(w) * 3);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < 3; ++c) row[std::size_t(3 * x + c)] = std::uint8_t((x * (c + 1) + y) / 7);
      ASSERT_TRUE(out->write_scanline(y, 0, OIIO::TypeDesc::UINT8, row.data()));
    }
    ASSERT_TRUE(out->close());
  }
  PyramidOptions po;
  po.cache_mb = 16;
  po.max_texture_size = 512;
  const std::uint64_t before = terralod::test::current_resident();
  terralod::test::reset_peak();
  double last = 0.0;
  ImagePyramid::convert(tif, tx, po, [&](double f) {
    EXPECT_GE(f, last);
    last = f;
  });
  const std::uint64_t grown = terralod::test::peak_resident() - before;
  EXPECT_EQ(last, 1.0);
  EXPECT_LT(grown, 48u << 20) << "the peak resident set grew by " << (grown >> 20) << " MB";
  const ImagePyramid pyr(tx, po);
  ASSERT_EQ(pyr.levels(), 5);  // 6000 x 4000 .. 375 x 250
  const RgbaImage r = pyr.read({0, 4000, 3000, 3, 2});
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 3; ++x)
      for (int c = 0; c < 3; ++c)
        EXPECT_EQ(r.get(x, y)[std::size_t(c)], std::uint8_t(((4000 + x) * (c + 1) + 3000 + y) / 7));
}

TEST(ImagePyramid, PixelsOutsideTheImageReadAsTransparentBlack) {
  const RgbaImage src = blocky(40, 20);
  const std::string path = tmp_path("outside.tx");
  ImagePyramid::convert(src, path);
  const ImagePyramid pyr(path);
  ASSERT_EQ(pyr.levels(), 1);
  // 16 x 8 window at (32, 16): 8 x 4 inside, the rest outside.
  const RgbaImage r = pyr.read({0, 32, 16, 16, 8});
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 16; ++x) {
      const bool inside = x < 8 && y < 4;
      const std::array<std::uint8_t, 4> zero{0, 0, 0, 0};
      EXPECT_EQ(r.get(x, y), inside ? src.get(32 + x, 16 + y) : zero) << x << "," << y;
    }
}

TEST(ImagePyramid, GreyFileFromDiskBecomesOpaqueRgba) {
  // A 300 x 200 grey PNG (value = (x + y) % 256), converted through the file path version.
  const std::string png = tmp_path("grey.png"), tx = tmp_path("grey.tx");
  std::vector<std::uint8_t> px(300 * 200);
  for (int y = 0; y < 200; ++y)
    for (int x = 0; x < 300; ++x) px[std::size_t(y) * 300 + x] = std::uint8_t((x + y) % 256);
  {
    auto out = OIIO::ImageOutput::create(png);
    ASSERT_TRUE(out);
    ASSERT_TRUE(out->open(png, OIIO::ImageSpec(300, 200, 1, OIIO::TypeDesc::UINT8)));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, px.data()));
    out->close();
  }
  PyramidOptions po;
  po.max_texture_size = 128;
  ImagePyramid::convert(png, tx, po);
  const ImagePyramid pyr(tx, po);
  ASSERT_EQ(pyr.levels(), 3);    // 300x200, 150x100, 75x50
  EXPECT_EQ(pyr.channels(), 4);  // convert writes RGBA
  EXPECT_EQ(ImagePyramid(png).channels(), 1);
  const RgbaImage r = pyr.read({0, 290, 190, 10, 10});
  for (int y = 0; y < 10; ++y)
    for (int x = 0; x < 10; ++x) {
      const std::uint8_t g = std::uint8_t((290 + x + 190 + y) % 256);
      EXPECT_EQ(r.get(x, y), (std::array<std::uint8_t, 4>{g, g, g, 255}));
    }
}

TEST(ImagePyramid, SixteenBitImagesAreStretchedToTheirValues) {
  // A 200 x 100 16-bit RGB TIFF of 12-bit values: R = 1000 + x (1000..1199), G = 3000 - 10 y,
  // B = 500 everywhere; the last row transparent (alpha 0) and 60000 in R, which no
  // histogram may count. Shown as it is, 1199 would be 1199 / 65535 * 255 = 5: black.
  const std::string tif = tmp_path("deep16.tif"), tx = tmp_path("deep16.tx");
  const int w = 200, h = 100;
  std::vector<std::uint16_t> px(std::size_t(w) * h * 4);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      std::uint16_t* p = &px[(std::size_t(y) * w + x) * 4];
      const bool last = y == h - 1;
      p[0] = std::uint16_t(last ? 60000 : 1000 + x), p[1] = std::uint16_t(3000 - 10 * y), p[2] = 500;
      p[3] = last ? 0 : 65535;
    }
  {
    auto out = OIIO::ImageOutput::create(tif);
    ASSERT_TRUE(out);
    OIIO::ImageSpec spec(w, h, 4, OIIO::TypeDesc::UINT16);
    spec.alpha_channel = 3;
    ASSERT_TRUE(out->open(tif, spec));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT16, px.data()));
    out->close();
  }
  using terralod::blocks::StretchOptions;
  // Auto: each band's 2 % cut. R: 99 rows of 1000..1199, so its 2 % point is 1003 and its
  // 98 % point 1195 (the 396th and 19404th of 19800 values, each value 99 times); G: rows
  // 0..98, 3000 - 10 y, 200 values a row: the 396th lies in row 97 (2030), the 19404th in
  // row 1 (2990).
  const std::vector<terralod::blocks::BandRange> r = ImagePyramid::convert(tif, tx);
  ASSERT_EQ(r.size(), 3u);
  EXPECT_EQ(r[0].lo, 1003.0);
  EXPECT_EQ(r[0].hi, 1195.0);
  EXPECT_EQ(r[1].lo, 2030.0);
  EXPECT_EQ(r[1].hi, 2990.0);
  EXPECT_EQ(r[2].lo, 500.0);
  const ImagePyramid pyr(tx);
  const RgbaImage l0 = pyr.read({0, 0, 0, w, h});
  for (int x : {0, 3, 100, 195, 199}) {
    const auto p = l0.get(x, 10);
    EXPECT_EQ(p[0], r[0].to_byte(1000 + x)) << x;
    EXPECT_EQ(p[3], 255);
  }
  EXPECT_EQ(l0.get(0, 10)[0], 0);
  EXPECT_EQ(l0.get(199, 10)[0], 255);
  EXPECT_EQ(l0.get(50, 0)[1], 255);  // 3000 >= 2990
  EXPECT_EQ(l0.get(50, h - 1)[3], 0);
  // Values: the same range in every band, exactly as given.
  const std::vector<terralod::blocks::BandRange> v =
      ImagePyramid::convert(tif, tx, {}, {}, terralod::blocks::parse_stretch("1000,1255"));
  ASSERT_EQ(v.size(), 3u);
  EXPECT_EQ(ImagePyramid(tx).read({0, 17, 5, 1, 1}).get(0, 0)[0], 17);
  // None: the type's whole range, as OpenImageIO converts it: dark.
  const std::vector<terralod::blocks::BandRange> n =
      ImagePyramid::convert(tif, tx, {}, {}, terralod::blocks::parse_stretch("none"));
  ASSERT_EQ(n.size(), 3u);
  EXPECT_EQ(n[0].hi, 65535.0);
  EXPECT_EQ(ImagePyramid(tx).read({0, 199, 5, 1, 1}).get(0, 0)[0], 5);
  // An 8-bit image is taken as it is unless asked.
  const std::string png = tmp_path("eight.png");
  write_layer_image(blocky(8, 8), png);
  EXPECT_TRUE(ImagePyramid::convert(png, tmp_path("eight.tx")).empty());
  EXPECT_EQ(
      ImagePyramid::convert(png, tmp_path("eight.tx"), {}, {}, StretchOptions{StretchOptions::Mode::Cut})
          .size(),
      3u);
}

TEST(ImagePyramid, StraightAlphaSurvivesAPngSource) {
  // PNG stores straight alpha; a reader that premultiplied would turn (200,100,50,128) into
  // (100,50,25,128) and (255,255,255,0) into black.
  RgbaImage img(4, 1);
  img.set(0, 0, {200, 100, 50, 128});
  img.set(1, 0, {10, 20, 30, 255});
  img.set(2, 0, {255, 255, 255, 0});
  img.set(3, 0, {80, 80, 80, 64});
  const std::string png = tmp_path("alpha.png"), tx = tmp_path("alpha.tx");
  write_layer_image(img, png);
  ImagePyramid::convert(png, tx);
  EXPECT_EQ(ImagePyramid(tx).read({0, 0, 0, 4, 1}), img);
  EXPECT_EQ(ImagePyramid(png).read({0, 0, 0, 4, 1}), img);
}

// A 6 x 4 TIFF whose channel c of pixel (x, y) is 10 * c + x + 6 y, the channels named
// `names`, channel `alpha` marked as alpha (-1: none).
std::string write_bands(const std::string& name, const std::vector<std::string>& names, int alpha) {
  const std::string path = tmp_path(name);
  const int n = int(names.size());
  OIIO::ImageSpec spec(6, 4, n, OIIO::TypeDesc::UINT8);
  spec.channelnames = names;
  spec.alpha_channel = alpha;
  std::vector<std::uint8_t> px(std::size_t(6 * 4 * n));
  for (int p = 0; p < 24; ++p)
    for (int c = 0; c < n; ++c) px[std::size_t(p * n + c)] = std::uint8_t(10 * c + p);
  auto out = OIIO::ImageOutput::create(path);
  EXPECT_TRUE(out && out->open(path, spec) && out->write_image(OIIO::TypeDesc::UINT8, px.data()) &&
              out->close());
  return path;
}

TEST(ImagePyramid, OnlyAChannelMarkedAlphaIsAlpha) {
  // Aerial imagery is often RGB + near infrared: its fourth band is no alpha, and a texture that
  // took it for one was drawn translucent. The rule of image_channels.hpp, through the converted
  // pyramid (as 'terralod texture add' reads a plain image) and through read_image.
  struct Case {
    std::string name;
    std::vector<std::string> names;
    int alpha;
    std::array<int, 4> rgba;  // the file's channel read as R, G, B, A; -1: opaque
  };
  const std::vector<Case> cases = {
      {"rgbn.tif", {"R", "G", "B", "N"}, -1, {0, 1, 2, -1}},
      {"rgban.tif", {"R", "G", "B", "A", "N"}, 3, {0, 1, 2, 3}},
      {"six.tif", {"b1", "b2", "b3", "b4", "b5", "b6"}, -1, {0, 1, 2, -1}},
      {"grey_alpha.tif", {"Y", "A"}, 1, {0, 0, 0, 1}},
      {"grey_other.tif", {"Y", "Q"}, -1, {0, 0, 0, -1}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const std::string tif = write_bands(c.name, c.names, c.alpha), tx = tmp_path(c.name + ".tx");
    ImagePyramid::convert(tif, tx);
    EXPECT_EQ(ImagePyramid(tif).channels(), int(c.names.size()));
    EXPECT_EQ(ImagePyramid(tx).channels(), 4);  // convert writes RGBA
    const Image rgb = read_image(tif);
    for (const std::string& file : {tif, tx}) {  // read from the image itself and from its pyramid
      const RgbaImage r = ImagePyramid(file).read({0, 0, 0, 6, 4});
      for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 6; ++x) {
          const auto band = [&](int k) {
            return k < 0 ? std::uint8_t(255) : std::uint8_t(10 * k + x + 6 * y);
          };
          EXPECT_EQ(r.get(x, y), (std::array<std::uint8_t, 4>{band(c.rgba[0]), band(c.rgba[1]),
                                                              band(c.rgba[2]), band(c.rgba[3])}))
              << file << " " << x << "," << y;
          for (int k = 0; k < 3; ++k)
            EXPECT_EQ(rgb.rgb[std::size_t(3 * (6 * y + x) + k)], band(c.rgba[std::size_t(k)]))
                << x << "," << y;
        }
    }
  }
  // Alpha alone is no image: refused, naming the file (an OpenEXR channel "A"; a TIFF of one
  // channel reads as grey).
  const std::string alpha_only = write_bands("alpha_only.exr", {"A"}, 0);
  try {
    ImagePyramid pyr(alpha_only);
    FAIL() << "an image of alpha alone was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(alpha_only), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("alpha"), std::string::npos) << e.what();
  }
}

TEST(ImagePyramid, BadFilesThrowNamingTheFile) {
  const std::string missing = tmp_path("does_not_exist.png");
  try {
    ImagePyramid::convert(missing, tmp_path("x.tx"));
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(missing), std::string::npos) << e.what();
  }
  EXPECT_THROW(ImagePyramid pyr(missing), std::runtime_error);
  // A flat (single-level) image bigger than the limit is not a pyramid.
  const std::string flat = tmp_path("flat.png");
  {
    auto out = OIIO::ImageOutput::create(flat);
    ASSERT_TRUE(out->open(flat, OIIO::ImageSpec(64, 64, 3, OIIO::TypeDesc::UINT8)));
    std::vector<std::uint8_t> px(64 * 64 * 3, 9);
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, px.data()));
    out->close();
  }
  PyramidOptions po;
  po.max_texture_size = 16;
  try {
    ImagePyramid pyr(flat, po);
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("MIP level"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(flat), std::string::npos) << e.what();
  }
  po.max_texture_size = 64;  // fits: a one-level pyramid
  EXPECT_EQ(ImagePyramid(flat, po).levels(), 1);
}

// Level k of a test pyramid: every byte depends on x, y and k, alpha included (0, partial and
// opaque), so a level read back from the wrong MIP level, premultiplied or filtered differs.
RgbaImage level_pattern(int w, int h, int k) {
  RgbaImage img(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      img.set(x, y,
              {std::uint8_t(x * 5 + k * 40), std::uint8_t(y * 11 + k), std::uint8_t((x * y + 3 * k) & 255),
               std::uint8_t((x + 2 * y + 17 * k) * 7 & 255)});
  return img;
}

std::vector<RgbaImage> given_levels(int w, int h, int max_texture_size) {
  std::vector<RgbaImage> out;
  int k = 0;
  for (const LevelSize& s : pyramid_levels(w, h, max_texture_size))
    out.push_back(level_pattern(s.width, s.height, k++));
  return out;
}

TEST(ImagePyramid, WrittenLevelsReadBackExactly) {
  // 100 x 60 with max 16: 100x60, 50x30, 25x15, 12x7 (floor halving), each given, none filtered.
  PyramidOptions po;
  po.max_texture_size = 16;
  const std::vector<RgbaImage> levels = given_levels(100, 60, 16);
  ASSERT_EQ(levels.size(), 4u);
  const std::string path = tmp_path("written.tx");
  ImagePyramid::write_levels(levels, path, po);
  EXPECT_FALSE(fs::exists(path + ".tmp"));
  const ImagePyramid pyr(path, po);
  ASSERT_EQ(pyr.levels(), 4);
  EXPECT_EQ(pyr.level_sizes(), pyramid_levels(100, 60, 16));
  EXPECT_EQ(pyr.channels(), 4);
  for (int k = 0; k < 4; ++k)
    EXPECT_EQ(pyr.read({k, 0, 0, levels[k].width, levels[k].height}), levels[std::size_t(k)])
        << "level " << k;
  // The same kind of file convert writes: tiled tile_size x tile_size, zip, one MIP level each.
  auto in = OIIO::ImageInput::open(path);
  ASSERT_TRUE(in);
  EXPECT_EQ(in->format_name(), std::string("tiff"));
  EXPECT_EQ(in->spec().tile_width, 64);
  EXPECT_EQ(in->spec().tile_height, 64);
  EXPECT_EQ(in->spec().get_string_attribute("compression"), "zip");
  int mips = 0;
  while (in->seek_subimage(0, mips)) ++mips;
  EXPECT_EQ(mips, 4);
  // A single level (fits already) is a one-level file.
  PyramidOptions big;
  big.max_texture_size = 128;
  ImagePyramid::write_levels({levels[0]}, tmp_path("one.tx"), big);
  EXPECT_EQ(ImagePyramid(tmp_path("one.tx"), big).read({0, 0, 0, 100, 60}), levels[0]);
}

TEST(ImagePyramid, WrongLevelsAreRefusedBeforeAnythingIsWritten) {
  PyramidOptions po;
  po.max_texture_size = 16;
  const std::string path = tmp_path("refused.tx");
  fs::remove(path);  // from an earlier run
  const auto refused = [&](const std::vector<RgbaImage>& levels, const std::vector<std::string>& words) {
    try {
      ImagePyramid::write_levels(levels, path, po);
      ADD_FAILURE() << "no exception";
    } catch (const std::invalid_argument& e) {
      for (const std::string& w : words)
        EXPECT_NE(std::string(e.what()).find(w), std::string::npos) << e.what();
    }
    EXPECT_FALSE(fs::exists(path + ".tmp"));
  };
  std::vector<RgbaImage> levels = given_levels(100, 60, 16);
  levels[2] = level_pattern(26, 15, 2);  // ceil instead of floor: 25 x 15 wanted
  refused(levels, {path, "level 2", "26 x 15", "25 x 15"});
  EXPECT_FALSE(fs::exists(path));
  levels = given_levels(100, 60, 16);
  levels.pop_back();
  refused(levels, {"got 3 levels", "level 3 is missing"});
  levels = given_levels(100, 60, 16);
  levels.push_back(level_pattern(6, 3, 4));
  refused(levels, {"got 5 levels", "level 4 is one too many"});
  refused({}, {"level 0"});
  EXPECT_FALSE(fs::exists(path));
  // A file already there stays as it was.
  ImagePyramid::write_levels(given_levels(100, 60, 16), path, po);
  const auto before = fs::file_size(path);
  levels = given_levels(100, 60, 16);
  levels[1] = level_pattern(50, 31, 1);
  refused(levels, {"level 1", "50 x 31", "50 x 30"});
  ASSERT_TRUE(fs::exists(path));
  EXPECT_EQ(fs::file_size(path), before);
  EXPECT_EQ(ImagePyramid(path, po).read({3, 0, 0, 12, 7}), level_pattern(12, 7, 3));
  // A write failure (no such folder) names the file and leaves nothing.
  const std::string nowhere = tmp_path("no_such_folder/x.tx");
  try {
    ImagePyramid::write_levels(given_levels(100, 60, 16), nowhere, po);
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(nowhere), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(nowhere + ".tmp"));
}

}  // namespace
