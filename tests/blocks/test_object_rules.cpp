// Design rules by level of detail (object_rules.hpp): hand-computed representations at, just
// below and just above every limit, by distance and by screen size; the default rule; the
// priority attribute; every malformed file refused with the file name, line and column.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <string>

#include "terralod/blocks/object_layers.hpp"
#include "terralod/blocks/object_rules.hpp"
#include "terralod/pm/json.hpp"

namespace {

namespace tb = terralod::blocks;
using R = tb::Representation;

// The file of the header's example:
//   0 ---- 2000 ---- 8000 ---- 30000 ---- inf   (metres, upper limits included)
//    shape       icon      label       none
const char* kDistance = R"({"ranges": [{"max_distance_m": 2000, "draw": "shape"},
  {"max_distance_m": 8000, "draw": "icon"}, {"max_distance_m": 30000, "draw": "label"},
  {"draw": "none"}], "priority_field": "population", "label_size_px": 16, "icon_size_m": 25})";

TEST(ObjectRules, DistanceRangesSwitchAtTheirLimits) {
  const tb::ObjectRules r = tb::parse_object_rules(kDistance, "d.json");
  EXPECT_EQ(r.measure(), tb::ObjectRules::Measure::Distance);
  ASSERT_EQ(r.ranges().size(), 4u);
  EXPECT_EQ(r.priority_field(), "population");
  EXPECT_EQ(r.label_size_px(), 16.0);
  EXPECT_EQ(r.icon_size_m(), 25.0);
  const double screen = 123.0;  // ignored by distance rules
  struct Case {
    double d;
    R want;
  };
  const Case cases[] = {
      {0.0, R::Shape},
      {1.0, R::Shape},
      {1999.999, R::Shape},
      {2000.0, R::Shape},
      {std::nextafter(2000.0, 1e9), R::Icon},
      {2000.001, R::Icon},
      {7999.999, R::Icon},
      {8000.0, R::Icon},
      {8000.001, R::Label},
      {29999.999, R::Label},
      {30000.0, R::Label},
      {std::nextafter(30000.0, 1e9), R::None},
      {30000.001, R::None},
      {1e12, R::None},
      {std::numeric_limits<double>::infinity(), R::None},
  };
  for (const Case& c : cases) {
    EXPECT_EQ(r.choose(c.d, screen), c.want) << "distance " << c.d;
    EXPECT_EQ(r.choose(c.d, 0.0), c.want) << "distance " << c.d;
  }
}

// Largest first:  inf ---- 200 ---- 8 ---- 0 px   (lower limits included)
//                   shape       symbol   none
TEST(ObjectRules, ScreenSizeRangesSwitchAtTheirLimits) {
  const tb::ObjectRules r = tb::parse_object_rules(
      R"({"ranges": [{"min_screen_px": 200, "draw": "shape"}, {"min_screen_px": 8, "draw": "symbol"},
          {"draw": "none"}]})",
      "s.json");
  EXPECT_EQ(r.measure(), tb::ObjectRules::Measure::ScreenSize);
  EXPECT_EQ(r.priority_field(), "");
  EXPECT_EQ(r.label_size_px(), 14.0);  // defaults
  EXPECT_EQ(r.icon_size_m(), 20.0);
  struct Case {
    double px;
    R want;
  };
  const Case cases[] = {
      {1e6, R::Shape},    {200.001, R::Shape}, {200.0, R::Shape}, {std::nextafter(200.0, 0.0), R::Symbol},
      {199.9, R::Symbol}, {8.001, R::Symbol},  {8.0, R::Symbol},  {std::nextafter(8.0, 0.0), R::None},
      {7.999, R::None},   {0.0, R::None},      {-1.0, R::None},
  };
  for (const Case& c : cases) {
    EXPECT_EQ(r.choose(50000.0, c.px), c.want) << "screen " << c.px;  // distance ignored
    EXPECT_EQ(r.choose(1.0, c.px), c.want) << "screen " << c.px;
  }
}

TEST(ObjectRules, OneRangeAndTheDefaultRuleDrawEverythingOneWay) {
  const tb::ObjectRules one = tb::parse_object_rules(R"({"ranges": [{"draw": "label"}]})", "one.json");
  for (double d : {0.0, 1.0, 1e9}) EXPECT_EQ(one.choose(d, d), R::Label);
  // The default rule of a layer of each kind: the kind's name is a representation's.
  for (tb::ObjectKind k :
       {tb::ObjectKind::Icon, tb::ObjectKind::Label, tb::ObjectKind::Shape, tb::ObjectKind::Line}) {
    ASSERT_TRUE(tb::parse_representation(tb::kind_name(k))) << tb::kind_name(k);
    const tb::ObjectRules def = tb::ObjectRules::everything_as(*tb::parse_representation(tb::kind_name(k)));
    ASSERT_EQ(def.ranges().size(), 1u);
    EXPECT_EQ(tb::representation_name(def.choose(0.0, 0.0)), tb::kind_name(k));
    EXPECT_EQ(tb::representation_name(def.choose(1e9, 1e9)), tb::kind_name(k));
    EXPECT_EQ(def.label_size_px(), 14.0);
    EXPECT_EQ(def.icon_size_m(), 20.0);
  }
  for (R rep : {R::None, R::Icon, R::Label, R::Shape, R::Line, R::Symbol})
    EXPECT_EQ(tb::parse_representation(tb::representation_name(rep)), rep);
  EXPECT_EQ(tb::parse_representation("Icon"), std::nullopt);
}

TEST(ObjectRules, PriorityIsTheAttributeTextAsANumberOrZero) {
  EXPECT_EQ(tb::priority_value("1200"), 1200.0);  // OGR's text of an Integer
  EXPECT_EQ(tb::priority_value("-2.5"), -2.5);    // and of a Real
  EXPECT_EQ(tb::priority_value("1e3"), 1000.0);
  for (const char* no : {"", "Hut", "12 people", " 12", "1e999", "nan", "inf"})
    EXPECT_EQ(tb::priority_value(no), 0.0) << "'" << no << "'";
}

// Each bad file: the message names the file, the line and column of the offending value, and
// what is wrong.
TEST(ObjectRules, MalformedFilesAreRefusedWithFileLineAndColumn) {
  struct Case {
    const char* what;
    std::string json;
    std::size_t line, column;
    const char* expect;
  };
  const Case cases[] = {
      {"not JSON", "{\"ranges\": [", 1, 13, "bad.json: line 1, column 13"},
      {"not an object", "[1]", 1, 1, "the rules must be an object, not an array"},
      {"unknown key", "{\"ranges\": [{\"draw\": \"icon\"}],\n \"colour\": 3}", 2, 12, "unknown key 'colour'"},
      {"no ranges", "{}", 1, 1, "no \"ranges\""},
      {"ranges not array", "{\"ranges\": 4}", 1, 12, "\"ranges\" must be an array, not a number"},
      {"empty ranges", "{\"ranges\": []}", 1, 12, "\"ranges\" is empty"},
      {"range not object", "{\"ranges\": [3]}", 1, 13, "ranges[0] must be an object"},
      {"unknown range key", "{\"ranges\": [{\"draw\": \"icon\", \"max_m\": 3}]}", 1, 39,
       "ranges[0]: unknown key 'max_m'"},
      {"unknown representation", "{\"ranges\": [\n  {\"draw\": \"sprite\"}]}", 2, 12,
       "ranges[0].draw: unknown representation 'sprite' (icon, label, shape, line, symbol or none)"},
      {"draw not string", "{\"ranges\": [{\"draw\": 1}]}", 1, 22, "ranges[0].draw must be a string"},
      {"no draw", "{\"ranges\": [{\"max_distance_m\": 5}, {\"draw\": \"none\"}]}", 1, 13,
       "ranges[0] needs \"draw\""},
      {"negative distance",
       "{\"ranges\": [{\"max_distance_m\": -5, \"draw\": \"icon\"}, {\"draw\": \"none\"}]}", 1, 32,
       "ranges[0].max_distance_m must be > 0 metres, not -5"},
      {"zero distance", "{\"ranges\": [{\"max_distance_m\": 0, \"draw\": \"icon\"}, {\"draw\": \"none\"}]}",
       1, 32, "must be > 0 metres"},
      {"distance not number",
       "{\"ranges\": [{\"max_distance_m\": \"5\", \"draw\": \"icon\"}, {\"draw\": \"none\"}]}", 1, 32,
       "ranges[0].max_distance_m must be a number, not a string"},
      {"unordered distances",
       "{\"ranges\": [{\"max_distance_m\": 500, \"draw\": \"icon\"},\n {\"max_distance_m\": 100, \"draw\": "
       "\"label\"}, {\"draw\": \"none\"}]}",
       2, 21,
       "ranges[1].max_distance_m must be larger than the range before's 500 (ranges go from near to far)"},
      {"overlapping distances (equal)",
       "{\"ranges\": [{\"max_distance_m\": 500, \"draw\": \"icon\"}, {\"max_distance_m\": 500, \"draw\": "
       "\"label\"}, {\"draw\": \"none\"}]}",
       1, 73, "must be larger than the range before's 500"},
      {"unordered screen sizes",
       "{\"ranges\": [{\"min_screen_px\": 10, \"draw\": \"icon\"}, {\"min_screen_px\": 20, \"draw\": "
       "\"label\"}, {\"draw\": \"none\"}]}",
       1, 70,
       "ranges[1].min_screen_px must be smaller than the range before's 10 (ranges go from large to small)"},
      {"mixed limits",
       "{\"ranges\": [{\"max_distance_m\": 10, \"draw\": \"icon\"}, {\"min_screen_px\": 20, \"draw\": "
       "\"label\"}, {\"draw\": \"none\"}]}",
       1, 71, "all ranges take the same limit, and max_distance_m came first"},
      {"two limits",
       "{\"ranges\": [{\"max_distance_m\": 10, \"min_screen_px\": 2, \"draw\": \"icon\"}, {\"draw\": "
       "\"none\"}]}",
       1, 53, "ranges[0] has both max_distance_m and min_screen_px"},
      {"limit on the last range", "{\"ranges\": [{\"draw\": \"icon\", \"max_distance_m\": 100}]}", 1, 48,
       "ranges[0] is the last range: it holds every farther object, so it takes no max_distance_m"},
      {"no limit on a middle range", "{\"ranges\": [{\"draw\": \"icon\"}, {\"draw\": \"none\"}]}", 1, 13,
       "ranges[0] needs \"max_distance_m\" or \"min_screen_px\""},
      {"empty priority field", "{\"ranges\": [{\"draw\": \"icon\"}], \"priority_field\": \"\"}", 1, 50,
       "\"priority_field\" is empty"},
      {"bad label size", "{\"ranges\": [{\"draw\": \"icon\"}], \"label_size_px\": 0}", 1, 49,
       "\"label_size_px\" must be > 0 pixels, not 0"},
      {"bad icon size", "{\"ranges\": [{\"draw\": \"icon\"}], \"icon_size_m\": -1}", 1, 47,
       "\"icon_size_m\" must be > 0 metres, not -1"},
  };
  for (const Case& c : cases) {
    try {
      tb::parse_object_rules(c.json, "bad.json");
      ADD_FAILURE() << c.what << ": accepted";
    } catch (const terralod::pm::JsonError& e) {
      const std::string msg = e.what();
      EXPECT_EQ(msg.rfind("bad.json: line ", 0), 0u) << c.what << ": " << msg;
      EXPECT_EQ(e.line(), c.line) << c.what << ": " << msg;
      EXPECT_EQ(e.column(), c.column) << c.what << ": " << msg;
      EXPECT_NE(msg.find(c.expect), std::string::npos) << c.what << ": " << msg;
    }
  }
}

}  // namespace

// Seeded random edits of a valid file (a fuzz-like sweep; no libFuzzer target yet): every
// result either parses into rules whose ranges keep their order, or throws JsonError naming the
// file with a line and column inside the text; never anything else.
TEST(ObjectRules, MutatedFilesParseIntoOrderedRulesOrFailWithAPosition) {
  const unsigned seed = 77;
  std::printf("seed %u\n", seed);
  std::mt19937 rng(seed);
  const std::string base = kDistance;
  const std::string alphabet = "{}[]\":,.-+0123456789e \nabcdefghijklmnopqrstuvwxyz_";
  int parsed = 0, refused = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    std::string s = base;
    const int edits = 1 + int(rng() % 4);
    for (int e = 0; e < edits && !s.empty(); ++e) {
      const std::size_t at = rng() % s.size();
      switch (rng() % 3) {
        case 0:
          s[at] = alphabet[rng() % alphabet.size()];
          break;
        case 1:
          s.erase(at, 1 + rng() % 8);
          break;
        default:
          s.insert(at, 1, alphabet[rng() % alphabet.size()]);
          break;
      }
    }
    try {
      const tb::ObjectRules r = tb::parse_object_rules(s, "m.json");
      ++parsed;
      ASSERT_FALSE(r.ranges().empty()) << s;
      for (std::size_t k = 1; k + 1 < r.ranges().size(); ++k)
        ASSERT_TRUE(r.measure() == tb::ObjectRules::Measure::Distance
                        ? r.ranges()[k].limit > r.ranges()[k - 1].limit
                        : r.ranges()[k].limit < r.ranges()[k - 1].limit)
            << s;
      for (std::size_t k = 0; k + 1 < r.ranges().size(); ++k) {  // each limit belongs to its range
        const double v = r.ranges()[k].limit;
        ASSERT_EQ(r.choose(v, v), r.ranges()[k].draw) << s;
      }
    } catch (const terralod::pm::JsonError& e) {
      ++refused;
      ASSERT_EQ(std::string(e.what()).rfind("m.json: line ", 0), 0u) << e.what();
      ASSERT_GE(e.line(), 1u);
      ASSERT_GE(e.column(), 1u);
      ASSERT_LE(e.line() + e.column(), s.size() + 2) << e.what();
    }
  }
  std::printf("%d mutated files parsed, %d refused\n", parsed, refused);
  EXPECT_GT(parsed, 100);
  EXPECT_GT(refused, 10000);
}
