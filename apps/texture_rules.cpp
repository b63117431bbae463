// The colour ramps and the --rules file of 'terralod texture thematic' (texture_rules.hpp),
// read with the strict JSON reader of terralod/pm/json.hpp (errors by line and column).
#include "texture_rules.hpp"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <utility>

#include "terrain_input.hpp"
#include "terralod/pm/json.hpp"

namespace terralod::cli {
namespace {

namespace tr = terralod::render;
using pm::JsonValue;

// An error in a rules file at byte `at`: "<where>: line L, column C: <what>", as UsageError
// (exit code 2).
struct RulesError {
  std::string_view text;
  const std::string& where;
  [[noreturn]] void operator()(std::size_t at, const std::string& what) const {
    throw UsageError(pm::JsonError(text, at, where, what).what());
  }
};

std::string read_text(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw UsageError("option '--rules': cannot read " + path + ": " + std::strerror(errno));
  std::ostringstream ss;
  ss << f.rdbuf();
  if (f.bad()) throw UsageError("option '--rules': cannot read " + path + ": " + std::strerror(errno));
  return ss.str();
}

}  // namespace

std::optional<tr::Rgba> parse_hex_color(const std::string& hex) {
  if ((hex.size() != 6 && hex.size() != 8) ||
      hex.find_first_not_of("0123456789abcdefABCDEF") != std::string::npos)
    return std::nullopt;
  tr::Rgba c{0, 0, 0, 255};
  for (std::size_t k = 0; k < hex.size() / 2; ++k)
    c[k] = std::uint8_t(std::stoul(hex.substr(2 * k, 2), nullptr, 16));
  return c;
}

std::vector<tr::ColorRamp::Stop> parse_ramp(const std::string& text, const std::string& what) {
  const auto bad = [&](const std::string& why) {
    return UsageError(what + ": " + why + " in '" + text + "' (expected V:RRGGBB[AA],V:RRGGBB[AA],...)");
  };
  std::vector<tr::ColorRamp::Stop> stops;
  std::stringstream ss(text);
  for (std::string item; std::getline(ss, item, ',');) {
    const std::size_t colon = item.find(':');
    if (colon == std::string::npos) throw bad("a stop without ':'");
    const std::string v = item.substr(0, colon), hex = item.substr(colon + 1);
    char* end = nullptr;
    const double value = std::strtod(v.c_str(), &end);
    if (v.empty() || *end != '\0' || !std::isfinite(value) || !std::isfinite(float(value)))
      throw bad("'" + v + "' is not a number (a finite 32-bit float)");
    const std::optional<tr::Rgba> c = parse_hex_color(hex);
    if (!c) throw bad("'" + hex + "' is not a colour RRGGBB or RRGGBBAA");
    if (!stops.empty() && !(float(value) > stops.back().value)) throw bad("values not strictly increasing");
    stops.push_back({float(value), *c});
  }
  if (stops.empty()) throw bad("no stops");
  return stops;
}

std::vector<tr::ColorRamp::Stop> default_ramp(tr::TerrainAttribute attribute, double lo, double hi) {
  switch (attribute) {
    case tr::TerrainAttribute::SlopeDegrees:
      return {{0.0f, {255, 255, 255, 255}}, {45.0f, {160, 0, 0, 255}}};
    case tr::TerrainAttribute::AspectDegrees:
      return {{0.0f, {220, 40, 40, 255}},
              {90.0f, {230, 210, 40, 255}},
              {180.0f, {40, 170, 60, 255}},
              {270.0f, {50, 80, 220, 255}},
              {360.0f, {220, 40, 40, 255}}};
    case tr::TerrainAttribute::Elevation: {
      const float a = float(lo), b = float(hi) > a ? float(hi) : a + 1.0f;  // a flat terrain: one colour
      return {{a, {40, 120, 50, 255}}, {a + 0.5f * (b - a), {150, 110, 60, 255}}, {b, {250, 250, 250, 255}}};
    }
  }
  return {};
}

std::string stops_json(const tr::ColorRamp& ramp) {
  std::string out;
  for (const tr::ColorRamp::Stop& st : ramp.stops())
    out += strf("%s[%.9g, %d, %d, %d, %d]", out.empty() ? "" : ", ", double(st.value), st.color[0],
                st.color[1], st.color[2], st.color[3]);
  return out;
}

ThematicRules read_thematic_rules(const std::string& path, tr::TerrainAttribute attribute) {
  const std::string text = read_text(path);
  const std::string where = "option '--rules': " + path;
  const RulesError fail{text, where};
  JsonValue doc;
  try {
    doc = pm::parse_json(text, where);
  } catch (const pm::JsonError& e) {
    throw UsageError(e.what());
  }
  const auto need = [&](const JsonValue& v, JsonValue::Kind k, const std::string& name) {
    if (v.kind != k)
      fail(v.begin, name + " must be " + pm::json_kind_name(k) + ", not " + pm::json_kind_name(v.kind));
  };
  need(doc, JsonValue::Kind::Object, "the file");
  ThematicRules out;
  out.path = path;
  out.generalise = attribute == tr::TerrainAttribute::AspectDegrees ? "nearest" : "mean";
  const JsonValue* rules = nullptr;
  for (const auto& [key, v] : doc.members) {
    if (key == "generalise") {
      need(v, JsonValue::Kind::String, "\"generalise\"");
      if (v.string != "nearest" && v.string != "majority" && v.string != "mean")
        fail(v.begin, "\"generalise\" must be nearest, majority or mean, not '" + v.string + "'");
      if (v.string == "mean" && attribute == tr::TerrainAttribute::AspectDegrees)
        fail(v.begin,
             "\"generalise\": \"mean\" averages aspect degrees across north (359 and 1 give 180); use "
             "nearest or majority");
      out.generalise = v.string;
    } else if (key == "rules") {
      rules = &v;
    } else {
      fail(v.begin, "unknown key '" + key + "' (the keys are generalise and rules)");
    }
  }
  if (!rules) fail(0, "no \"rules\" (an array of {\"max_texel_m\", \"ramp\", \"bands\"})");
  need(*rules, JsonValue::Kind::Array, "\"rules\"");
  if (rules->items.empty()) fail(rules->begin, "\"rules\" is empty; it needs at least one rule");
  for (std::size_t k = 0; k < rules->items.size(); ++k) {
    const JsonValue& r = rules->items[k];
    const std::string name = "rules[" + std::to_string(k) + "]";
    need(r, JsonValue::Kind::Object, name);
    const bool last = k + 1 == rules->items.size();
    ThematicLook look;
    bool has_max = false;
    for (const auto& [key, v] : r.members) {
      if (key == "max_texel_m") {
        need(v, JsonValue::Kind::Number, name + ".max_texel_m");
        if (last)
          fail(v.begin, name + " is the last rule: it draws every coarser texel, so it takes no max_texel_m");
        if (!(v.number > 0.0)) fail(v.begin, name + ".max_texel_m must be > 0 metres");
        if (!out.looks.empty() && !(v.number > out.looks.back().max_texel_m))
          fail(v.begin, name + ".max_texel_m must be larger than the rule before's " +
                            strf("%.9g", out.looks.back().max_texel_m) + " (rules go from near to far)");
        look.max_texel_m = v.number;
        has_max = true;
      } else if (key == "ramp") {
        need(v, JsonValue::Kind::String, name + ".ramp");
        look.stops = parse_ramp(v.string, "option '--rules': " + path + ": " + name + ".ramp");
      } else if (key == "bands") {
        need(v, JsonValue::Kind::Bool, name + ".bands");
        look.bands = v.boolean;
      } else {
        fail(v.begin, name + ": unknown key '" + key + "' (the keys are max_texel_m, ramp and bands)");
      }
    }
    if (!last && !has_max)
      fail(r.begin, name + " needs \"max_texel_m\" (only the last rule, the far one, goes without)");
    out.looks.push_back(std::move(look));
  }
  return out;
}

std::size_t BuiltRule::look_for(double texel_size_m) const {
  const tr::ColorMapper* m = &rule.mapper_for(texel_size_m);
  for (std::size_t k = 0; k < ramps.size(); ++k)
    if (ramps[k].get() == m) return k;
  return ramps.size();
}

BuiltRule build_rule(const ThematicRules& rules, tr::TerrainAttribute attribute, double lo, double hi) {
  const tr::Reduction g = rules.generalise == "nearest"    ? tr::Reduction::Nearest
                          : rules.generalise == "majority" ? tr::Reduction::Majority
                                                           : tr::Reduction::Mean;
  BuiltRule out{tr::LodDesignRule(g), {}};
  for (const ThematicLook& look : rules.looks) {
    auto ramp = std::make_shared<const tr::ColorRamp>(
        look.stops.empty() ? default_ramp(attribute, lo, hi) : look.stops,
        look.bands ? tr::ColorRamp::Mode::Step : tr::ColorRamp::Mode::Linear);
    out.rule.add(look.max_texel_m, ramp);
    out.ramps.push_back(std::move(ramp));
  }
  return out;
}

std::string rules_parameters(const ThematicRules& rules, const BuiltRule& built,
                             const std::string& attribute_name, double sample_size_m,
                             const std::vector<std::size_t>& level_rules) {
  std::string looks, levels;
  for (std::size_t k = 0; k < rules.looks.size(); ++k) {
    const ThematicLook& l = rules.looks[k];
    looks += strf("%s{%s\"mode\": \"%s\", \"stops\": [%s]}", k ? ", " : "",
                  std::isfinite(l.max_texel_m) ? strf("\"max_texel_m\": %.17g, ", l.max_texel_m).c_str() : "",
                  l.bands ? "bands" : "linear", stops_json(*built.ramps[k]).c_str());
  }
  for (std::size_t k = 0; k < level_rules.size(); ++k) levels += strf("%s%zu", k ? ", " : "", level_rules[k]);
  return strf(
      "{\"attribute\": \"%s\", \"rules_file\": %s, \"generalise\": \"%s\", \"sample_size_m\": %.17g, "
      "\"rules\": "
      "[%s], \"level_rules\": [%s]}",
      attribute_name.c_str(), pm::json_quote(rules.path).c_str(), rules.generalise.c_str(), sample_size_m,
      looks.c_str(), levels.c_str());
}

}  // namespace terralod::cli
