// The colour ramps and the --rules file of 'terralod texture thematic' (texture_rules.hpp),
// with the small strict JSON reader the rules file needs (RFC 8259 values, errors by line and
// column).
#include "texture_rules.hpp"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <utility>

#include "terrain_input.hpp"

namespace terralod::cli {
namespace {

namespace tr = terralod::render;

// A parsed JSON value; `at` is its first byte in the text (for messages).
struct JsonValue {
  enum class Kind { Null, Bool, Number, String, Array, Object } kind = Kind::Null;
  std::size_t at = 0;
  bool boolean = false;
  double number = 0.0;
  std::string string;
  std::vector<JsonValue> items;                            // Array
  std::vector<std::pair<std::string, JsonValue>> members;  // Object, in file order, keys unique
};

const char* kind_name(JsonValue::Kind k) {
  switch (k) {
    case JsonValue::Kind::Null:
      return "null";
    case JsonValue::Kind::Bool:
      return "a boolean";
    case JsonValue::Kind::Number:
      return "a number";
    case JsonValue::Kind::String:
      return "a string";
    case JsonValue::Kind::Array:
      return "an array";
    case JsonValue::Kind::Object:
      return "an object";
  }
  return "?";
}

// Strict recursive-descent JSON: no comments, no trailing commas, nesting at most 64 deep.
class JsonParser {
 public:
  JsonParser(const std::string& text, std::string where) : s_(text), where_(std::move(where)) {}

  JsonValue document() {
    JsonValue v = value(0);
    ws();
    if (i_ < s_.size()) fail(i_, "unexpected text after the JSON value");
    return v;
  }

  // "<where>: line L, column C: <what>".
  [[noreturn]] void fail(std::size_t at, const std::string& what) const {
    std::size_t line = 1, col = 1;
    for (std::size_t k = 0; k < at && k < s_.size(); ++k) {
      if (s_[k] == '\n')
        ++line, col = 1;
      else
        ++col;
    }
    throw UsageError(where_ + ": line " + std::to_string(line) + ", column " + std::to_string(col) + ": " +
                     what);
  }

 private:
  void ws() {
    while (i_ < s_.size() && (s_[i_] == ' ' || s_[i_] == '\t' || s_[i_] == '\n' || s_[i_] == '\r')) ++i_;
  }
  bool eat(char c) {
    ws();
    if (i_ < s_.size() && s_[i_] == c) return ++i_, true;
    return false;
  }
  void expect(char c, const char* context) {
    if (!eat(c)) fail(i_, std::string("expected '") + c + "' " + context);
  }

  JsonValue value(int depth) {
    if (depth > 64) fail(i_, "nested more than 64 deep");
    ws();
    JsonValue v;
    v.at = i_;
    if (i_ >= s_.size()) fail(i_, "unexpected end of the file, expected a value");
    const char c = s_[i_];
    if (c == '{') {
      v.kind = JsonValue::Kind::Object;
      ++i_;
      if (eat('}')) return v;
      do {
        ws();
        const std::size_t key_at = i_;
        if (i_ >= s_.size() || s_[i_] != '"') fail(i_, "expected a key in double quotes");
        std::string key = string();
        for (const auto& m : v.members)
          if (m.first == key) fail(key_at, "key '" + key + "' given twice");
        expect(':', "after a key");
        v.members.emplace_back(std::move(key), value(depth + 1));
      } while (eat(','));
      expect('}', "or ',' in an object");
    } else if (c == '[') {
      v.kind = JsonValue::Kind::Array;
      ++i_;
      if (eat(']')) return v;
      do v.items.push_back(value(depth + 1));
      while (eat(','));
      expect(']', "or ',' in an array");
    } else if (c == '"') {
      v.kind = JsonValue::Kind::String;
      v.string = string();
    } else if (literal("true")) {
      v.kind = JsonValue::Kind::Bool;
      v.boolean = true;
    } else if (literal("false")) {
      v.kind = JsonValue::Kind::Bool;
    } else if (literal("null")) {
      v.kind = JsonValue::Kind::Null;
    } else if (c == '-' || (c >= '0' && c <= '9')) {
      v.kind = JsonValue::Kind::Number;
      v.number = number();
    } else {
      fail(i_, std::string("unexpected character '") + c + "', expected a value");
    }
    return v;
  }

  bool literal(const char* word) {
    const std::size_t n = std::strlen(word);
    if (s_.compare(i_, n, word) != 0) return false;
    i_ += n;
    return true;
  }

  static bool digit(char c) { return c >= '0' && c <= '9'; }

  // -?(0|[1-9][0-9]*)(.[0-9]+)?([eE][+-]?[0-9]+)?
  double number() {
    const std::size_t start = i_;
    const auto digits = [&] {
      if (i_ >= s_.size() || !digit(s_[i_])) fail(i_, "malformed number");
      while (i_ < s_.size() && digit(s_[i_])) ++i_;
    };
    if (s_[i_] == '-') ++i_;
    if (i_ < s_.size() && s_[i_] == '0')
      ++i_;
    else
      digits();
    if (i_ < s_.size() && s_[i_] == '.') ++i_, digits();
    if (i_ < s_.size() && (s_[i_] == 'e' || s_[i_] == 'E')) {
      ++i_;
      if (i_ < s_.size() && (s_[i_] == '+' || s_[i_] == '-')) ++i_;
      digits();
    }
    const double d = std::strtod(s_.substr(start, i_ - start).c_str(), nullptr);
    if (!std::isfinite(d)) fail(start, "number out of range");
    return d;
  }

  void utf8(std::string& o, unsigned cp) {
    if (cp < 0x80) {
      o += char(cp);
    } else if (cp < 0x800) {
      o += char(0xC0 | (cp >> 6)), o += char(0x80 | (cp & 0x3F));
    } else if (cp < 0x10000) {
      o += char(0xE0 | (cp >> 12)), o += char(0x80 | ((cp >> 6) & 0x3F)), o += char(0x80 | (cp & 0x3F));
    } else {
      o += char(0xF0 | (cp >> 18)), o += char(0x80 | ((cp >> 12) & 0x3F));
      o += char(0x80 | ((cp >> 6) & 0x3F)), o += char(0x80 | (cp & 0x3F));
    }
  }

  unsigned hex4() {
    if (i_ + 4 > s_.size()) fail(i_, "truncated \\u escape");
    unsigned v = 0;
    for (int k = 0; k < 4; ++k, ++i_) {
      const char c = s_[i_];
      const int d = digit(c)                 ? c - '0'
                    : (c >= 'a' && c <= 'f') ? c - 'a' + 10
                    : (c >= 'A' && c <= 'F') ? c - 'A' + 10
                                             : -1;
      if (d < 0) fail(i_, "bad hex digit in a \\u escape");
      v = v * 16 + unsigned(d);
    }
    return v;
  }

  std::string string() {
    const std::size_t start = i_;
    ++i_;  // the opening quote
    std::string o;
    for (;;) {
      if (i_ >= s_.size()) fail(start, "string without its closing quote");
      const char c = s_[i_++];
      if (c == '"') return o;
      if (static_cast<unsigned char>(c) < 0x20) fail(i_ - 1, "control character in a string");
      if (c != '\\') {
        o += c;
        continue;
      }
      if (i_ >= s_.size()) fail(start, "string without its closing quote");
      const char e = s_[i_++];
      switch (e) {
        case '"':
        case '\\':
        case '/':
          o += e;
          break;
        case 'b':
          o += '\b';
          break;
        case 'f':
          o += '\f';
          break;
        case 'n':
          o += '\n';
          break;
        case 'r':
          o += '\r';
          break;
        case 't':
          o += '\t';
          break;
        case 'u': {
          unsigned cp = hex4();
          if (cp >= 0xD800 && cp < 0xDC00 && s_.compare(i_, 2, "\\u") == 0) {
            i_ += 2;
            const unsigned lo = hex4();
            if (lo < 0xDC00 || lo >= 0xE000) fail(i_ - 6, "unpaired surrogate in a \\u escape");
            cp = 0x10000 + ((cp - 0xD800) << 10) + (lo - 0xDC00);
          } else if (cp >= 0xD800 && cp < 0xE000) {
            fail(i_ - 6, "unpaired surrogate in a \\u escape");
          }
          utf8(o, cp);
          break;
        }
        default:
          fail(i_ - 2, std::string("unknown escape '\\") + e + "' in a string");
      }
    }
  }

  const std::string& s_;
  std::string where_;
  std::size_t i_ = 0;
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
    if (v.empty() || *end != '\0' || !std::isfinite(value)) throw bad("'" + v + "' is not a number");
    if ((hex.size() != 6 && hex.size() != 8) ||
        hex.find_first_not_of("0123456789abcdefABCDEF") != std::string::npos)
      throw bad("'" + hex + "' is not a colour RRGGBB or RRGGBBAA");
    tr::Rgba c{0, 0, 0, 255};
    for (std::size_t k = 0; k < hex.size() / 2; ++k)
      c[k] = std::uint8_t(std::stoul(hex.substr(2 * k, 2), nullptr, 16));
    if (!stops.empty() && !(float(value) > stops.back().value)) throw bad("values not strictly increasing");
    stops.push_back({float(value), c});
  }
  if (stops.empty()) throw bad("no stops");
  return stops;
}

std::vector<tr::ColorRamp::Stop> default_ramp(tr::TerrainAttribute attribute, const pm::Heightfield& hf) {
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
      const auto [lo, hi] = height_range(hf);
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
  JsonParser parser(text, "option '--rules': " + path);
  const JsonValue doc = parser.document();
  const auto need = [&](const JsonValue& v, JsonValue::Kind k, const std::string& name) {
    if (v.kind != k) parser.fail(v.at, name + " must be " + kind_name(k) + ", not " + kind_name(v.kind));
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
        parser.fail(v.at, "\"generalise\" must be nearest, majority or mean, not '" + v.string + "'");
      if (v.string == "mean" && attribute == tr::TerrainAttribute::AspectDegrees)
        parser.fail(v.at,
                    "\"generalise\": \"mean\" averages aspect degrees across north (359 and 1 give 180); use "
                    "nearest or majority");
      out.generalise = v.string;
    } else if (key == "rules") {
      rules = &v;
    } else {
      parser.fail(v.at, "unknown key '" + key + "' (the keys are generalise and rules)");
    }
  }
  if (!rules) parser.fail(0, "no \"rules\" (an array of {\"max_texel_m\", \"ramp\", \"bands\"})");
  need(*rules, JsonValue::Kind::Array, "\"rules\"");
  if (rules->items.empty()) parser.fail(rules->at, "\"rules\" is empty; it needs at least one rule");
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
          parser.fail(v.at,
                      name + " is the last rule: it draws every coarser texel, so it takes no max_texel_m");
        if (!(v.number > 0.0)) parser.fail(v.at, name + ".max_texel_m must be > 0 metres");
        if (!out.looks.empty() && !(v.number > out.looks.back().max_texel_m))
          parser.fail(v.at, name + ".max_texel_m must be larger than the rule before's " +
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
        parser.fail(v.at, name + ": unknown key '" + key + "' (the keys are max_texel_m, ramp and bands)");
      }
    }
    if (!last && !has_max)
      parser.fail(r.at, name + " needs \"max_texel_m\" (only the last rule, the far one, goes without)");
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

BuiltRule build_rule(const ThematicRules& rules, tr::TerrainAttribute attribute, const pm::Heightfield& hf) {
  const tr::Reduction g = rules.generalise == "nearest"    ? tr::Reduction::Nearest
                          : rules.generalise == "majority" ? tr::Reduction::Majority
                                                           : tr::Reduction::Mean;
  BuiltRule out{tr::LodDesignRule(g), {}};
  for (const ThematicLook& look : rules.looks) {
    auto ramp = std::make_shared<const tr::ColorRamp>(
        look.stops.empty() ? default_ramp(attribute, hf) : look.stops,
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
      attribute_name.c_str(), JsonWriter::quote(rules.path).c_str(), rules.generalise.c_str(), sample_size_m,
      looks.c_str(), levels.c_str());
}

}  // namespace terralod::cli
