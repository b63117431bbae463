// Tests of the contrast stretch (image_stretch.hpp): the option's forms and its errors, exact
// percentiles of integer bands, the range of a band of one value, the types' whole ranges, and
// the rounding of values to bytes.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "terralod/blocks/image_stretch.hpp"

namespace {

using namespace terralod::blocks;

TEST(ImageStretch, ParsesEveryFormAndRefusesTheRest) {
  EXPECT_EQ(parse_stretch("auto").mode, StretchOptions::Mode::Auto);
  EXPECT_EQ(parse_stretch("none").mode, StretchOptions::Mode::None);
  const StretchOptions cut = parse_stretch("0.5%");
  EXPECT_EQ(cut.mode, StretchOptions::Mode::Cut);
  EXPECT_DOUBLE_EQ(cut.cut_percent, 0.5);
  const StretchOptions v = parse_stretch("100,4000");
  EXPECT_EQ(v.mode, StretchOptions::Mode::Values);
  EXPECT_EQ(v.lo, 100.0);
  EXPECT_EQ(v.hi, 4000.0);
  EXPECT_EQ(describe(cut), "0.5 % cut");
  EXPECT_EQ(describe(v), "values 100..4000");
  for (const char* bad :
       {"", "Auto", "50%", "-1%", "2%x", "%", "4000,100", "5,5", "1,2,3", "1,inf", "nan,2", "x"})
    EXPECT_THROW(parse_stretch(bad), std::invalid_argument) << bad;
  try {
    parse_stretch("4000,100");
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--stretch '4000,100'"), std::string::npos) << e.what();
  }
}

TEST(ImageStretch, AnIntegerBandIsCutAtItsExactPercentiles) {
  // 16-bit values 1001..1100, once each: the 2 % point is the 2nd value, the 98 % the 98th.
  std::optional<BandHistogram> h = exact_histogram(16, false, false);
  ASSERT_TRUE(h);
  for (int v = 1001; v <= 1100; ++v) h->add(v);
  h->add(std::nan(""));  // not counted
  EXPECT_EQ(h->total(), 100u);
  const BandRange r = h->cut(2.0);
  EXPECT_EQ(r.lo, 1002.0);
  EXPECT_EQ(r.hi, 1098.0);
  const BandRange all = h->cut(0.0);
  EXPECT_EQ(all.lo, 1001.0);
  EXPECT_EQ(all.hi, 1100.0);
  // Signed 16-bit: bins from -32768.
  std::optional<BandHistogram> s = exact_histogram(16, true, false);
  ASSERT_TRUE(s);
  for (int v = -50; v < 50; ++v) s->add(v);
  EXPECT_EQ(s->cut(10.0).lo, -41.0);
  EXPECT_EQ(s->cut(10.0).hi, 39.0);
  // Wider types and floating point are measured first.
  EXPECT_FALSE(exact_histogram(32, false, false));
  EXPECT_FALSE(exact_histogram(32, false, true));
}

TEST(ImageStretch, ABandOfOneValueAndAnEmptyOneStillGiveARange) {
  BandHistogram one(7.0, 7.0, 65536);  // minimum = maximum
  for (int i = 0; i < 10; ++i) one.add(7.0);
  const BandRange r = one.cut(2.0);
  EXPECT_EQ(r.lo, 7.0);
  EXPECT_GT(r.hi, r.lo);
  EXPECT_EQ(r.to_byte(7.0), 0);
  const BandRange none = BandHistogram(0, 1, 16).cut(2.0);
  EXPECT_LT(none.lo, none.hi);
}

TEST(ImageStretch, FloatBandsAreCountedOnTheirOwnRange) {
  BandHistogram h(0.1, 0.5, 65536);
  for (int i = 0; i <= 1000; ++i) h.add(0.1 + 0.4 * i / 1000.0);
  const BandRange r = h.cut(5.0);
  EXPECT_NEAR(r.lo, 0.1 + 0.4 * 0.05, 1e-5);
  EXPECT_NEAR(r.hi, 0.1 + 0.4 * 0.95, 1e-5);
}

TEST(ImageStretch, EachOptionTakesOneStepForEightBitAndDeepImages) {
  using S = StretchStep;
  const auto step = [](const char* text, bool deep) { return stretch_step(parse_stretch(text), deep); };
  EXPECT_EQ(step("auto", false), S::AsIs);
  EXPECT_EQ(step("auto", true), S::Cut);
  EXPECT_EQ(step("none", false), S::AsIs);
  EXPECT_EQ(step("none", true), S::Fixed);
  EXPECT_EQ(step("5%", false), S::Cut);
  EXPECT_EQ(step("5%", true), S::Cut);
  EXPECT_EQ(step("10,20", false), S::Fixed);
  EXPECT_EQ(step("10,20", true), S::Fixed);
  EXPECT_EQ(fixed_range(parse_stretch("10,20"), type_range(16, false, false)).lo, 10.0);
  EXPECT_EQ(fixed_range(parse_stretch("10,20"), type_range(16, false, false)).hi, 20.0);
  EXPECT_EQ(fixed_range(parse_stretch("none"), type_range(16, false, false)).hi, 65535.0);
  EXPECT_EQ(fixed_range(parse_stretch("none"), type_range(32, true, true)).hi, 1.0);
}

TEST(ImageStretch, TypeRangesAndBytes) {
  EXPECT_EQ(type_range(8, false, false).hi, 255.0);
  EXPECT_EQ(type_range(16, false, false).hi, 65535.0);
  EXPECT_EQ(type_range(16, true, false).hi, 32767.0);
  EXPECT_EQ(type_range(16, true, false).lo, 0.0);
  EXPECT_EQ(type_range(32, false, true).hi, 1.0);
  const BandRange r{100, 355};
  EXPECT_EQ(r.to_byte(100), 0);
  EXPECT_EQ(r.to_byte(99), 0);
  EXPECT_EQ(r.to_byte(100.4), 0);
  EXPECT_EQ(r.to_byte(100.6), 1);
  EXPECT_EQ(r.to_byte(227.5), 128);  // halves round away from zero, as GDAL's -scale does
  EXPECT_EQ(r.to_byte(355), 255);
  EXPECT_EQ(r.to_byte(1e9), 255);
  EXPECT_EQ(r.to_byte(std::nan("")), 0);
}

}  // namespace
