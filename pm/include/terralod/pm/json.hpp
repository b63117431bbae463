// JSON text (RFC 8259): the one strict reader and the one string escaper of terralod, used by
// the --rules files of `terralod texture thematic`, the texture layer records of the block
// database and the glTF writer.
//
// Usage:
//   const terralod::pm::JsonValue doc = terralod::pm::parse_json(text, "rules.json");
//   if (const terralod::pm::JsonValue* n = doc.find("name"); n && n->kind == JsonValue::Kind::String)
//     use(n->string);
//   std::string_view raw = doc.find("parameters")->raw(text);  // the value's text, verbatim
//   std::string out = "{\"name\": " + terralod::pm::json_quote(name) + "}";
//
// Contract:
//   - parse_json(text, where) reads exactly one JSON value, with whitespace (space, tab, CR, LF)
//     around it and a UTF-8 byte order mark before it (Windows editors write one), and returns
//     it. Strict: no comments, no trailing commas, no single quotes, no NaN or Infinity, no
//     leading zeros or '+', no control character (< 0x20) inside a string, no key twice in one
//     object, and nothing but whitespace after the value. Limits: at most
//     64 arrays and objects nested inside each other; a number must be finite as a double
//     (1e400 is refused; a number too small for a double, like 1e-400, reads as 0 with its
//     sign). Escapes: \" \\ \/ \b \f \n \r \t and \uXXXX (hex digits either case) decoded to
//     UTF-8, a high surrogate followed by a low one as one code point; a lone or reversed
//     surrogate is an error. Bytes >= 0x80 are kept as they are and not checked to be UTF-8
//     (records written by earlier versions may hold other bytes in their strings).
//   - Every failure throws JsonError "<where>: line L, column C: <what>"; L and C count from 1,
//     C in bytes, at the offending byte (a string without its closing quote: its opening one).
//     parse_json never crashes and never reads outside `text`, whatever the bytes.
//   - JsonValue holds the decoded value: `boolean`, `number`, `string`, `items` (arrays) or
//     `members` (objects: {key, value}, in file order, keys unique) by `kind`, and the byte range
//     [begin, end) of the value in the text (raw() returns it; strings include their quotes).
//   - json_quote(s) returns s as a JSON string literal: '"' and '\\' escaped by a backslash,
//     bytes below 0x20 as \u00xx (lower-case hex), every other byte unchanged. parse_json of
//     the result gives s back for any s (s need not be UTF-8; see above).
//   - write_json(v) returns compact JSON text of v (no spaces; strings by json_quote; numbers
//     as the shortest decimal that reads back to the same double) that parses back to a value
//     json_equal to v.
//   - Memory: the returned tree holds a decoded copy of every value, about 120 bytes per value
//     plus its string; the parser itself uses stack proportional to the nesting (<= 64).
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace terralod::pm {

/// Malformed JSON: "<where>: line L, column C: <what>".
class JsonError : public std::runtime_error {
 public:
  /// The error at byte `offset` of `text` (its line and column are counted here).
  JsonError(std::string_view text, std::size_t offset, const std::string& where, const std::string& what);
  std::size_t line() const { return line_; }
  std::size_t column() const { return column_; }

 private:
  JsonError(const std::string& where, std::pair<std::size_t, std::size_t> line_column,
            const std::string& what);
  std::size_t line_, column_;
};

struct JsonMember;

/// One parsed JSON value; children own their own values.
struct JsonValue {
  enum class Kind { Null, Bool, Number, String, Array, Object };
  Kind kind = Kind::Null;
  bool boolean = false;             ///< Bool
  double number = 0.0;              ///< Number (finite)
  std::string string;               ///< String, decoded
  std::vector<JsonValue> items;     ///< Array
  std::vector<JsonMember> members;  ///< Object, in file order, keys unique
  std::size_t begin = 0, end = 0;   ///< bytes [begin, end) of the text

  /// The member named `key`, or nullptr when there is none (or this is not an object).
  const JsonValue* find(std::string_view key) const;
  /// The value's own text: text.substr(begin, end - begin). `text` must be the parsed text.
  std::string_view raw(std::string_view text) const { return text.substr(begin, end - begin); }
};

/// One member of an object (a named struct, not std::pair: clang cannot instantiate
/// std::pair<std::string, JsonValue> inside JsonValue's own definition).
struct JsonMember {
  std::string key;
  JsonValue value;
};

/// "null", "a boolean", "a number", "a string", "an array", "an object" (for messages).
const char* json_kind_name(JsonValue::Kind kind);

/// Parses `text` as one JSON value; `where` starts every error message. Throws JsonError.
JsonValue parse_json(std::string_view text, const std::string& where);

/// `s` as a JSON string literal, quotes included (see the contract).
std::string json_quote(std::string_view s);

/// Compact JSON text of `v` (see the contract).
std::string write_json(const JsonValue& v);

/// The same value: same kinds, numbers (==), strings, items and members in order; the byte
/// ranges are ignored.
bool json_equal(const JsonValue& a, const JsonValue& b);

}  // namespace terralod::pm
