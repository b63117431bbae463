// libFuzzer target for the object layers' design rules (blocks/object_rules.hpp): on arbitrary
// bytes parse_object_rules either throws JsonError "fuzz.json: line L, column C: ..." with L and
// C inside the text, or returns rules that keep their contract: at least one range; limits
// strictly increasing and the last +inf (distance) or strictly decreasing and the last 0
// (screen size); sizes > 0; choose() equal to a linear scan of the ranges at probes around
// every limit; max_drawn_distance the edge of what choose() draws.
//
// Bounded work: inputs over 64 KiB are skipped (returning -1 keeps them out of the corpus).
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>

#include "fuzz_support.hpp"
#include "terralod/blocks/object_rules.hpp"
#include "terralod/pm/json.hpp"

namespace {

namespace tb = terralod::blocks;

[[noreturn]] void finding(const std::string& what) { terralod::fuzz::finding("fuzz_object_rules", what); }
#define REQUIRE(cond)                                 \
  do {                                                \
    if (!(cond)) finding("invariant broken: " #cond); \
  } while (0)

// The range a value falls in, by a linear scan of the contract (object_rules.hpp).
tb::Representation scan(const tb::ObjectRules& r, double v) {
  const bool distance = r.measure() == tb::ObjectRules::Measure::Distance;
  for (const tb::RuleRange& g : r.ranges())
    if (distance ? v <= g.limit : v >= g.limit) return g.draw;
  return r.ranges().back().draw;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > 65536) return -1;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  tb::ObjectRules r;
  try {
    r = tb::parse_object_rules(text, "fuzz.json");
  } catch (const terralod::pm::JsonError& e) {
    REQUIRE(std::string_view(e.what()).substr(0, 16) == "fuzz.json: line ");
    REQUIRE(e.line() >= 1 && e.column() >= 1 && e.line() + e.column() <= size + 2);
    return 0;
  }
  const auto& g = r.ranges();
  REQUIRE(!g.empty());
  const bool distance = r.measure() == tb::ObjectRules::Measure::Distance;
  const double inf = std::numeric_limits<double>::infinity();
  REQUIRE(g.back().limit == (distance ? inf : 0.0));
  for (std::size_t k = 0; k + 1 < g.size(); ++k) {
    REQUIRE(g[k].limit > 0 && std::isfinite(g[k].limit));
    REQUIRE(distance ? g[k].limit < g[k + 1].limit : g[k].limit > g[k + 1].limit);
  }
  REQUIRE(r.label_size_px() > 0 && r.icon_size_m() > 0 && r.line_width_m() > 0);
  REQUIRE(r.icon_quads() >= 1 && r.icon_quads() <= 3);
  for (const tb::RuleRange& range : g)
    for (double v :
         {range.limit, std::nextafter(range.limit, -inf), std::nextafter(range.limit, inf), 0.0, inf})
      if (!std::isnan(v)) REQUIRE(r.choose(v, v) == scan(r, v));
  const double extent = 30.0, focal = 623.5;
  const double reach = r.max_drawn_distance(extent, focal);
  if (std::isfinite(reach)) {  // just beyond it nothing is drawn; at it something is
    const double beyond = std::nextafter(reach, inf) * (1 + 1e-12);
    REQUIRE(r.choose(beyond, extent * focal / beyond) == tb::Representation::None);
    REQUIRE(reach > 0);
  }
  return 0;
}
