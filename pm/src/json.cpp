// The strict RFC 8259 reader, the string escaper and the compact writer of json.hpp.
#include "terralod/pm/json.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <system_error>
#include <unordered_set>

#include "shortest_decimal.hpp"
#include "terralod/pm/text.hpp"

namespace terralod::pm {
namespace {

constexpr int kMaxNesting = 64;

std::pair<std::size_t, std::size_t> line_column(std::string_view text, std::size_t offset) {
  std::size_t line = 1, column = 1;
  for (std::size_t k = 0; k < offset && k < text.size(); ++k) {
    if (text[k] == '\n')
      ++line, column = 1;
    else
      ++column;
  }
  return {line, column};
}

bool digit(char c) { return c >= '0' && c <= '9'; }

void append_utf8(std::string& o, unsigned cp) {
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

// Recursive descent over the text; the recursion is bounded by kMaxNesting.
class Parser {
 public:
  // A byte order mark before the value is skipped (RFC 8259 section 8.1 allows it); offsets
  // and columns still count in `text`.
  Parser(std::string_view text, const std::string& where)
      : s_(text), where_(where), i_(text.size() - without_utf8_bom(text).size()) {}

  JsonValue document() {
    JsonValue v = value(0);
    ws();
    if (i_ < s_.size()) fail(i_, "unexpected text after the JSON value");
    return v;
  }

 private:
  [[noreturn]] void fail(std::size_t at, const std::string& what) const {
    throw JsonError(s_, at, where_, what);
  }

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

  // `depth`: the arrays and objects around this value.
  JsonValue value(int depth) {
    ws();
    JsonValue v;
    v.begin = i_;
    if (i_ >= s_.size()) fail(i_, "unexpected end of the file, expected a value");
    const char c = s_[i_];
    if ((c == '{' || c == '[') && depth >= kMaxNesting) fail(i_, "nested more than 64 deep");
    if (c == '{') {
      v.kind = JsonValue::Kind::Object;
      ++i_;
      if (!eat('}')) {
        object_members(v, depth);
        expect('}', "or ',' in an object");
      }
    } else if (c == '[') {
      v.kind = JsonValue::Kind::Array;
      ++i_;
      if (!eat(']')) {
        do v.items.push_back(value(depth + 1));
        while (eat(','));
        expect(']', "or ',' in an array");
      }
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
    } else if (c == '-' || digit(c)) {
      v.kind = JsonValue::Kind::Number;
      v.number = number();
    } else {
      fail(i_, std::string("unexpected character '") + c + "', expected a value");
    }
    v.end = i_;
    return v;
  }

  // Duplicate keys: a linear scan for small objects, a hash set of the keys beyond that (a
  // hostile object of n keys costs O(n), not O(n^2)).
  void object_members(JsonValue& v, int depth) {
    constexpr std::size_t kScan = 16;
    std::unordered_set<std::string> seen;
    do {
      ws();
      const std::size_t key_at = i_;
      if (i_ >= s_.size() || s_[i_] != '"') fail(i_, "expected a key in double quotes");
      std::string key = string();
      bool twice = false;
      if (v.members.size() < kScan) {
        twice = std::any_of(v.members.begin(), v.members.end(),
                            [&](const JsonMember& m) { return m.key == key; });
      } else {
        if (seen.empty())
          for (const JsonMember& m : v.members) seen.insert(m.key);
        twice = !seen.insert(key).second;
      }
      if (twice) fail(key_at, "key '" + key + "' given twice");
      expect(':', "after a key");
      v.members.push_back({std::move(key), value(depth + 1)});
    } while (eat(','));
  }

  bool literal(std::string_view word) {
    if (s_.substr(i_, word.size()) != word) return false;
    i_ += word.size();
    return true;
  }

  // -?(0|[1-9][0-9]*)(.[0-9]+)?([eE][+-]?[0-9]+)?
  double number() {
    const std::size_t start = i_;
    const auto digits = [&] {
      if (i_ >= s_.size() || !digit(s_[i_])) fail(i_, "malformed number");
      while (i_ < s_.size() && digit(s_[i_])) ++i_;
    };
    const bool negative = s_[i_] == '-';
    if (negative) ++i_;
    const std::size_t int_at = i_;
    if (i_ < s_.size() && s_[i_] == '0')
      ++i_;
    else
      digits();
    const std::size_t int_end = i_;
    if (i_ < s_.size() && s_[i_] == '.') ++i_, digits();
    const std::size_t mantissa_end = i_;
    if (i_ < s_.size() && (s_[i_] == 'e' || s_[i_] == 'E')) {
      ++i_;
      if (i_ < s_.size() && (s_[i_] == '+' || s_[i_] == '-')) ++i_;
      digits();
    }
    double d = 0.0;
    const auto r = std::from_chars(s_.data() + start, s_.data() + i_, d);
    if (r.ec == std::errc() && r.ptr == s_.data() + i_ && std::isfinite(d)) return d;
    if (r.ec != std::errc::result_out_of_range) fail(start, "malformed number");
    // Out of range: too large (refused) or too small (zero). The decimal magnitude decides:
    // the position of the first non-zero digit relative to the point, plus the exponent.
    long long magnitude = 0;
    const std::size_t first = s_.find_first_not_of("0.", int_at);
    if (first >= mantissa_end) return negative ? -0.0 : 0.0;  // all zero digits
    magnitude = first < int_end ? (long long)(int_end - first) : -(long long)(first - int_end - 1);
    if (mantissa_end < i_) {
      long long e = 0;
      std::size_t k = mantissa_end + 1;
      const bool e_negative = s_[k] == '-';
      if (s_[k] == '+' || s_[k] == '-') ++k;
      for (; k < i_; ++k) e = std::min(e * 10 + (s_[k] - '0'), 100000LL);
      magnitude += e_negative ? -e : e;
    }
    if (magnitude > 0) fail(start, "number out of range");
    return negative ? -0.0 : 0.0;
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
          if (cp >= 0xD800 && cp < 0xDC00 && s_.substr(i_, 2) == "\\u") {
            i_ += 2;
            const unsigned lo = hex4();
            if (lo < 0xDC00 || lo >= 0xE000) fail(i_ - 6, "unpaired surrogate in a \\u escape");
            cp = 0x10000 + ((cp - 0xD800) << 10) + (lo - 0xDC00);
          } else if (cp >= 0xD800 && cp < 0xE000) {
            fail(i_ - 6, "unpaired surrogate in a \\u escape");
          }
          append_utf8(o, cp);
          break;
        }
        default:
          fail(i_ - 2, std::string("unknown escape '\\") + e + "' in a string");
      }
    }
  }

  std::string_view s_;
  const std::string& where_;
  std::size_t i_ = 0;
};

void write(std::string& out, const JsonValue& v) {
  switch (v.kind) {
    case JsonValue::Kind::Null:
      out += "null";
      break;
    case JsonValue::Kind::Bool:
      out += v.boolean ? "true" : "false";
      break;
    case JsonValue::Kind::Number:
      detail::append_shortest(out, v.number);
      break;
    case JsonValue::Kind::String:
      out += json_quote(v.string);
      break;
    case JsonValue::Kind::Array:
      out += '[';
      for (std::size_t k = 0; k < v.items.size(); ++k) {
        if (k) out += ',';
        write(out, v.items[k]);
      }
      out += ']';
      break;
    case JsonValue::Kind::Object:
      out += '{';
      for (std::size_t k = 0; k < v.members.size(); ++k) {
        if (k) out += ',';
        out += json_quote(v.members[k].key);
        out += ':';
        write(out, v.members[k].value);
      }
      out += '}';
      break;
  }
}

}  // namespace

JsonError::JsonError(std::string_view text, std::size_t offset, const std::string& where,
                     const std::string& what)
    : JsonError(where, line_column(text, offset), what) {}

JsonError::JsonError(const std::string& where, std::pair<std::size_t, std::size_t> lc,
                     const std::string& what)
    : std::runtime_error(where + ": line " + std::to_string(lc.first) + ", column " +
                         std::to_string(lc.second) + ": " + what),
      line_(lc.first),
      column_(lc.second) {}

const JsonValue* JsonValue::find(std::string_view key) const {
  for (const JsonMember& m : members)
    if (m.key == key) return &m.value;
  return nullptr;
}

const char* json_kind_name(JsonValue::Kind kind) {
  switch (kind) {
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

JsonValue parse_json(std::string_view text, const std::string& where) {
  return Parser(text, where).document();
}

std::string json_quote(std::string_view s) {
  std::string out;
  out.reserve(s.size() + 2);
  out += '"';
  for (const char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += ch;
    } else if (c < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", unsigned(c));
      out += buf;
    } else {
      out += ch;
    }
  }
  out += '"';
  return out;
}

std::string write_json(const JsonValue& v) {
  std::string out;
  write(out, v);
  return out;
}

bool json_equal(const JsonValue& a, const JsonValue& b) {
  if (a.kind != b.kind) return false;
  switch (a.kind) {
    case JsonValue::Kind::Null:
      return true;
    case JsonValue::Kind::Bool:
      return a.boolean == b.boolean;
    case JsonValue::Kind::Number:
      return a.number == b.number;
    case JsonValue::Kind::String:
      return a.string == b.string;
    case JsonValue::Kind::Array:
      return std::equal(a.items.begin(), a.items.end(), b.items.begin(), b.items.end(), json_equal);
    case JsonValue::Kind::Object:
      return std::equal(a.members.begin(), a.members.end(), b.members.begin(), b.members.end(),
                        [](const JsonMember& x, const JsonMember& y) {
                          return x.key == y.key && json_equal(x.value, y.value);
                        });
  }
  return false;
}

}  // namespace terralod::pm
