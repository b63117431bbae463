// Design rules by level of detail of an object layer (object_rules.hpp): the strict reader of
// the rules file (pm/json.hpp, errors by line and column) and the choice of a representation
// by binary search over the ranges.
#include "terralod/blocks/object_rules.hpp"

#include <algorithm>
#include <cassert>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>

#include "terralod/pm/json.hpp"

namespace terralod::blocks {
namespace {

using pm::JsonValue;

constexpr std::pair<Representation, const char*> kNames[] = {
    {Representation::None, "none"},   {Representation::Icon, "icon"}, {Representation::Label, "label"},
    {Representation::Shape, "shape"}, {Representation::Line, "line"}, {Representation::Symbol, "symbol"},
};

std::string number_text(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// Errors at byte `at` of the rules: "<source>: line L, column C: <what>".
struct Fail {
  std::string_view text;
  const std::string& source;
  [[noreturn]] void operator()(std::size_t at, const std::string& what) const {
    throw pm::JsonError(text, at, source, what);
  }
  void need(const JsonValue& v, JsonValue::Kind k, const std::string& name) const {
    if (v.kind != k)
      (*this)(v.begin, name + " must be " + pm::json_kind_name(k) + ", not " + pm::json_kind_name(v.kind));
  }
  double positive(const JsonValue& v, const std::string& name, const char* unit) const {
    need(v, JsonValue::Kind::Number, name);
    if (!(v.number > 0.0)) (*this)(v.begin, name + " must be > 0 " + unit + ", not " + number_text(v.number));
    return v.number;
  }
};

}  // namespace

std::string representation_name(Representation r) {
  for (const auto& [rep, name] : kNames)
    if (rep == r) return name;
  return "none";
}

std::optional<Representation> parse_representation(std::string_view s) {
  for (const auto& [rep, name] : kNames)
    if (s == name) return rep;
  return std::nullopt;
}

ObjectRules ObjectRules::everything_as(Representation r) {
  ObjectRules out;
  out.ranges_ = {{std::numeric_limits<double>::infinity(), r}};
  return out;
}

Representation ObjectRules::choose(double distance_m, double screen_size_px) const {
  assert(!std::isnan(distance_m) && !std::isnan(screen_size_px));
  assert(!ranges_.empty());
  // The first range holding the value; the last range always does (limit +inf or 0).
  const auto it = measure_ == Measure::Distance
                      ? std::partition_point(ranges_.begin(), ranges_.end() - 1,
                                             [&](const RuleRange& r) { return r.limit < distance_m; })
                      : std::partition_point(ranges_.begin(), ranges_.end() - 1,
                                             [&](const RuleRange& r) { return r.limit > screen_size_px; });
  return it->draw;
}

double priority_value(std::string_view text) {
  double v = 0.0;
  const char* end = text.data() + text.size();
  const auto [p, ec] = std::from_chars(text.data(), end, v);
  return ec == std::errc() && p == end && std::isfinite(v) ? v : 0.0;
}

ObjectRules parse_object_rules(std::string_view json, const std::string& source) {
  const JsonValue doc = pm::parse_json(json, source);
  const Fail fail{json, source};
  fail.need(doc, JsonValue::Kind::Object, "the rules");
  ObjectRules out;
  const JsonValue* ranges = nullptr;
  for (const auto& [key, v] : doc.members) {
    if (key == "ranges") {
      ranges = &v;
    } else if (key == "priority_field") {
      fail.need(v, JsonValue::Kind::String, "\"priority_field\"");
      if (v.string.empty()) fail(v.begin, "\"priority_field\" is empty (leave it out for no priority)");
      out.priority_field_ = v.string;
    } else if (key == "label_size_px") {
      out.label_size_px_ = fail.positive(v, "\"label_size_px\"", "pixels");
    } else if (key == "icon_size_m") {
      out.icon_size_m_ = fail.positive(v, "\"icon_size_m\"", "metres");
    } else {
      fail(v.begin,
           "unknown key '" + key + "' (the keys are ranges, priority_field, label_size_px and icon_size_m)");
    }
  }
  if (!ranges)
    fail(doc.begin, "no \"ranges\" (an array of {\"max_distance_m\" or \"min_screen_px\", \"draw\"})");
  fail.need(*ranges, JsonValue::Kind::Array, "\"ranges\"");
  if (ranges->items.empty()) fail(ranges->begin, "\"ranges\" is empty; it needs at least one range");
  std::optional<ObjectRules::Measure> measure;  // from the first limit
  for (std::size_t k = 0; k < ranges->items.size(); ++k) {
    const JsonValue& r = ranges->items[k];
    const std::string name = "ranges[" + std::to_string(k) + "]";
    fail.need(r, JsonValue::Kind::Object, name);
    const bool last = k + 1 == ranges->items.size();
    RuleRange range;
    const JsonValue *limit = nullptr, *draw = nullptr;
    for (const auto& [key, v] : r.members) {
      if (key == "max_distance_m" || key == "min_screen_px") {
        const auto m =
            key == "max_distance_m" ? ObjectRules::Measure::Distance : ObjectRules::Measure::ScreenSize;
        if (limit) fail(v.begin, name + " has both max_distance_m and min_screen_px (one limit per range)");
        if (measure && *measure != m)
          fail(v.begin, name + "." + key + ": all ranges take the same limit, and " +
                            (m == ObjectRules::Measure::Distance ? "min_screen_px" : "max_distance_m") +
                            " came first");
        measure = m;
        limit = &v;
        const bool distance = m == ObjectRules::Measure::Distance;
        range.limit = fail.positive(v, name + "." + key, distance ? "metres" : "pixels");
        if (last)
          fail(v.begin, name + " is the last range: it holds every " + (distance ? "farther" : "smaller") +
                            " object, so it takes no " + key +
                            " (add {\"draw\": \"none\"} to draw nothing there)");
        if (!out.ranges_.empty()) {
          const double before = out.ranges_.back().limit;
          if (distance ? !(range.limit > before) : !(range.limit < before))
            fail(v.begin,
                 name + "." + key + " must be " + (distance ? "larger" : "smaller") +
                     " than the range before's " + number_text(before) +
                     (distance ? " (ranges go from near to far)" : " (ranges go from large to small)"));
        }
      } else if (key == "draw") {
        fail.need(v, JsonValue::Kind::String, name + ".draw");
        const auto rep = parse_representation(v.string);
        if (!rep)
          fail(v.begin, name + ".draw: unknown representation '" + v.string +
                            "' (icon, label, shape, line, symbol or none)");
        range.draw = *rep;
        draw = &v;
      } else {
        fail(v.begin,
             name + ": unknown key '" + key + "' (the keys are max_distance_m or min_screen_px, and draw)");
      }
    }
    if (!draw) fail(r.begin, name + " needs \"draw\" (icon, label, shape, line, symbol or none)");
    if (!last && !limit)
      fail(r.begin,
           name + " needs \"max_distance_m\" or \"min_screen_px\" (only the last range goes without)");
    out.ranges_.push_back(range);
  }
  out.measure_ = measure.value_or(ObjectRules::Measure::Distance);
  out.ranges_.back().limit =
      out.measure_ == ObjectRules::Measure::Distance ? std::numeric_limits<double>::infinity() : 0.0;
  return out;
}

}  // namespace terralod::blocks
