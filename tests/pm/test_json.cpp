// Tests of terralod/pm/json.hpp: every kind of value, every escape (surrogate pairs included),
// every error with its line and column worked out by hand, the byte ranges of values, and
// json_quote / write_json round trips through parse_json.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "terralod/pm/json.hpp"

namespace pm = terralod::pm;
using Kind = pm::JsonValue::Kind;

namespace {

/// The message of parse_json's JsonError on `text` ("" when it parses), and its line/column.
struct Failure {
  std::string what;
  std::size_t line = 0, column = 0;
};
Failure failure(const std::string& text) {
  try {
    (void)pm::parse_json(text, "t.json");
  } catch (const pm::JsonError& e) {
    return {e.what(), e.line(), e.column()};
  }
  return {};
}

std::string decoded(const std::string& json_string_literal) {
  const pm::JsonValue v = pm::parse_json(json_string_literal, "s");
  EXPECT_EQ(v.kind, Kind::String);
  return v.string;
}

}  // namespace

TEST(Json, EveryKindOfValue) {
  // One document with each kind, members in file order.
  const std::string text = R"( {"n": null, "t": true, "f": false, "i": -12, "x": 0.5e2, "s": "a\"b",
  "a": [1, [], {}], "o": {"k": "v"}} )";
  const pm::JsonValue doc = pm::parse_json(text, "doc");
  ASSERT_EQ(doc.kind, Kind::Object);
  ASSERT_EQ(doc.members.size(), 8u);
  const char* keys[] = {"n", "t", "f", "i", "x", "s", "a", "o"};
  for (std::size_t k = 0; k < 8; ++k) EXPECT_EQ(doc.members[k].key, keys[k]);
  EXPECT_EQ(doc.find("n")->kind, Kind::Null);
  EXPECT_EQ(doc.find("t")->kind, Kind::Bool);
  EXPECT_TRUE(doc.find("t")->boolean);
  EXPECT_FALSE(doc.find("f")->boolean);
  EXPECT_EQ(doc.find("i")->number, -12.0);
  EXPECT_EQ(doc.find("x")->number, 50.0);
  EXPECT_EQ(doc.find("s")->string, "a\"b");
  const pm::JsonValue& a = *doc.find("a");
  ASSERT_EQ(a.kind, Kind::Array);
  ASSERT_EQ(a.items.size(), 3u);
  EXPECT_EQ(a.items[0].number, 1.0);
  EXPECT_EQ(a.items[1].kind, Kind::Array);
  EXPECT_TRUE(a.items[1].items.empty());
  EXPECT_EQ(a.items[2].kind, Kind::Object);
  EXPECT_EQ(doc.find("o")->find("k")->string, "v");
  EXPECT_EQ(doc.find("missing"), nullptr);
  EXPECT_EQ(a.find("x"), nullptr);  // not an object
  // Scalars alone are documents too.
  EXPECT_EQ(pm::parse_json("null", "n").kind, Kind::Null);
  EXPECT_EQ(pm::parse_json("\t\r\n 7 \n", "n").number, 7.0);
  EXPECT_EQ(pm::parse_json("\"\"", "n").string, "");
  EXPECT_STREQ(pm::json_kind_name(Kind::Array), "an array");
  EXPECT_STREQ(pm::json_kind_name(Kind::Bool), "a boolean");
}

TEST(Json, Numbers) {
  EXPECT_EQ(pm::parse_json("0", "n").number, 0.0);
  EXPECT_TRUE(std::signbit(pm::parse_json("-0", "n").number));
  EXPECT_EQ(pm::parse_json("1E+2", "n").number, 100.0);
  EXPECT_EQ(pm::parse_json("-2.5e-1", "n").number, -0.25);
  EXPECT_EQ(pm::parse_json("0.1", "n").number, 0.1);  // correctly rounded
  EXPECT_EQ(pm::parse_json("1.7976931348623157e308", "n").number, 1.7976931348623157e308);
  EXPECT_EQ(pm::parse_json("4.9406564584124654e-324", "n").number, 4.9406564584124654e-324);  // denormal
  // Too small for a double: zero with its sign; too large: refused.
  EXPECT_EQ(pm::parse_json("1e-400", "n").number, 0.0);
  EXPECT_TRUE(std::signbit(pm::parse_json("-0.0001e-397", "n").number));
  EXPECT_EQ(failure("1e400").what, "t.json: line 1, column 1: number out of range");
  EXPECT_EQ(failure("[0.5e309]").what, "t.json: line 1, column 2: number out of range");
  EXPECT_EQ(failure("123456789e99999999999999").what, "t.json: line 1, column 1: number out of range");
  for (const char* bad : {"01", "+1", ".5", "1.", "1e", "-", "1.e3", "0x10", "NaN", "Infinity", "-Infinity"})
    EXPECT_NE(failure(bad).what, "") << bad;
  EXPECT_EQ(failure("1.").what, "t.json: line 1, column 3: malformed number");
  EXPECT_EQ(failure("01").what, "t.json: line 1, column 2: unexpected text after the JSON value");
}

TEST(Json, Escapes) {
  EXPECT_EQ(decoded(R"("\" \\ \/ \b \f \n \r \t")"), "\" \\ / \b \f \n \r \t");
  EXPECT_EQ(decoded(R"("\u0041\u00e9\u20AC")"), "A\xC3\xA9\xE2\x82\xAC");  // A, e acute, euro: 1, 2, 3 bytes
  EXPECT_EQ(decoded(R"("\u0000")"), std::string(1, '\0'));
  EXPECT_EQ(decoded(R"("\u007f\u0080\u07ff\u0800\uffff")"),
            "\x7F\xC2\x80\xDF\xBF\xE0\xA0\x80\xEF\xBF\xBF");  // the UTF-8 length boundaries
  // Surrogate pairs: U+1F600 = D83D DE00 -> F0 9F 98 80; U+10000 and U+10FFFF at the ends.
  EXPECT_EQ(decoded(R"("\ud83d\ude00")"), "\xF0\x9F\x98\x80");
  EXPECT_EQ(decoded(R"("\uD800\uDC00")"), "\xF0\x90\x80\x80");
  EXPECT_EQ(decoded(R"("\uDBFF\uDFFF")"), "\xF4\x8F\xBF\xBF");
  // Raw UTF-8 (and other bytes >= 0x80) pass through as they are.
  EXPECT_EQ(decoded("\"\xC3\xA9\xFF\""), "\xC3\xA9\xFF");
}

TEST(Json, EveryErrorWithLineAndColumn) {
  struct Case {
    std::string text, what;
  };
  const Case cases[] = {
      // Trailing commas: the ']' / '}' where a value / key was due (line 3, column 1).
      {"{\"a\": [\n  1,\n]}", "line 3, column 1: unexpected character ']', expected a value"},
      {"{\"a\": 1,\n}", "line 2, column 1: expected a key in double quotes"},
      // A key twice: at the second one.
      {"{\"k\": 1,\n \"k\": 2}", "line 2, column 2: key 'k' given twice"},
      {"{\"k\": 1, \"\\u006b\": 2}", "line 1, column 10: key 'k' given twice"},  // same key once decoded
      // Bad escapes: at the backslash.
      {"\"ab\\x\"", "line 1, column 4: unknown escape '\\x' in a string"},
      {"\"\\u12G4\"", "line 1, column 6: bad hex digit in a \\u escape"},
      {"\"\\u12", "line 1, column 4: truncated \\u escape"},
      // Lone surrogates: at the backslash of the offending \u.
      {"\"x\\ud83d\"", "line 1, column 3: unpaired surrogate in a \\u escape"},
      {"\"\\ude00\"", "line 1, column 2: unpaired surrogate in a \\u escape"},
      {"\"\\ud83d\\u0041\"", "line 1, column 8: unpaired surrogate in a \\u escape"},
      {"\"\\ude00\\ud83d\"", "line 1, column 2: unpaired surrogate in a \\u escape"},  // reversed
      // Control character inside a string.
      {"\"a\tb\"", "line 1, column 3: control character in a string"},
      // Text after the value.
      {"{} {}", "line 1, column 4: unexpected text after the JSON value"},
      {"1 // comment", "line 1, column 3: unexpected text after the JSON value"},
      // Truncated input.
      {"", "line 1, column 1: unexpected end of the file, expected a value"},
      {"[1, 2", "line 1, column 6: expected ']' or ',' in an array"},
      {"{\"a\"", "line 1, column 5: expected ':' after a key"},
      {"{\"a\": ", "line 1, column 7: unexpected end of the file, expected a value"},
      {"\n  \"abc", "line 2, column 3: string without its closing quote"},
      {"\"abc\\", "line 1, column 1: string without its closing quote"},
      {"tru", "line 1, column 1: unexpected character 't', expected a value"},
      // Other syntax.
      {"{'a': 1}", "line 1, column 2: expected a key in double quotes"},
      {"{\"a\" 1}", "line 1, column 6: expected ':' after a key"},
      {"[1 2]", "line 1, column 4: expected ']' or ',' in an array"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.text);
    EXPECT_EQ(failure(c.text).what, "t.json: " + c.what);
  }
  const Failure f = failure("{\n\n   \"a\": x}");
  EXPECT_EQ(f.line, 3u);
  EXPECT_EQ(f.column, 9u);
}

TEST(Json, NestingIsLimitedTo64) {
  const auto nested = [](int n) {
    return std::string(std::size_t(n), '[') + std::string(std::size_t(n), ']');
  };
  const pm::JsonValue v = pm::parse_json(nested(64), "deep");
  const pm::JsonValue* p = &v;
  int depth = 1;
  while (!p->items.empty()) p = &p->items[0], ++depth;
  EXPECT_EQ(depth, 64);
  // The 65th opening bracket (column 65) is refused, objects count as arrays do.
  EXPECT_EQ(failure(nested(65)).what, "t.json: line 1, column 65: nested more than 64 deep");
  std::string objects;
  for (int k = 0; k < 65; ++k) objects += "{\"a\":";
  EXPECT_EQ(failure(objects + "1" + std::string(65, '}')).what,
            "t.json: line 1, column 321: nested more than 64 deep");  // 64 x 5 characters before it
  // Hostile depth costs nothing: a million brackets fail at the 65th.
  EXPECT_EQ(failure(std::string(1000000, '[')).column, 65u);
}

TEST(Json, ByteRangesGiveTheRawText) {
  //                       0         1         2         3
  //                       0123456789012345678901234567890123456
  const std::string text = R"({"p": {"a": [1, 2.50]}, "s": "x\n"} )";
  const pm::JsonValue doc = pm::parse_json(text, "r");
  EXPECT_EQ(doc.begin, 0u);
  EXPECT_EQ(doc.end, 35u);  // after the closing brace, before the trailing space
  const pm::JsonValue& p = *doc.find("p");
  EXPECT_EQ(p.raw(text), R"({"a": [1, 2.50]})");
  EXPECT_EQ(p.find("a")->raw(text), "[1, 2.50]");
  EXPECT_EQ(p.find("a")->items[1].raw(text), "2.50");
  EXPECT_EQ(doc.find("s")->raw(text), R"("x\n")");  // with its quotes and escapes
  EXPECT_EQ(doc.find("s")->begin, 29u);
}

TEST(Json, AByteOrderMarkBeforeTheValueIsSkipped) {
  // A rules file saved by a Windows editor starts with EF BB BF (RFC 8259 8.1 lets a parser skip it).
  const std::string text = "\xEF\xBB\xBF{\"a\": 1}";
  const pm::JsonValue doc = pm::parse_json(text, "r");
  EXPECT_EQ(doc.find("a")->number, 1.0);
  EXPECT_EQ(doc.raw(text), "{\"a\": 1}");  // ranges still index the text as given
  try {                                    // columns count its bytes: the error is at the fourth byte
    pm::parse_json("\xEF\xBB\xBFx", "r");
    ADD_FAILURE() << "no error";
  } catch (const pm::JsonError& e) {
    EXPECT_NE(std::string(e.what()).find("line 1, column 4"), std::string::npos) << e.what();
  }
  EXPECT_THROW(pm::parse_json("1 \xEF\xBB\xBF", "r"), pm::JsonError);  // only at the start
}

TEST(Json, QuoteEscapesQuotesBackslashesAndControlCharacters) {
  EXPECT_EQ(pm::json_quote("plain é"), "\"plain é\"");
  EXPECT_EQ(pm::json_quote("a\"b\\c"), R"("a\"b\\c")");
  EXPECT_EQ(pm::json_quote(std::string("\n\t\x1f\0\x7f", 5)), "\"\\u000a\\u0009\\u001f\\u0000\x7f\"");
  EXPECT_EQ(pm::json_quote(""), "\"\"");
}

TEST(Json, QuoteRoundTripsEveryByteAndEveryCodePointBelow256) {
  std::string bytes, utf8;
  for (int b = 0; b < 256; ++b) {
    bytes += char(b);
    // Code point b as UTF-8 (one byte below 0x80, two from 0x80).
    if (b < 0x80)
      utf8 += char(b);
    else
      utf8 += char(0xC0 | (b >> 6)), utf8 += char(0x80 | (b & 0x3F));
    const std::string one(1, char(b));
    EXPECT_EQ(decoded(pm::json_quote(one)), one) << b;
  }
  EXPECT_EQ(decoded(pm::json_quote(utf8)), utf8);
  EXPECT_EQ(decoded(pm::json_quote(bytes)), bytes);
  // As keys too.
  std::string object = "{";  // (appended: GCC 12's -Wrestrict misfires on "{" + ...)
  object += pm::json_quote(utf8);
  object += ": 1}";
  const pm::JsonValue o = pm::parse_json(object, "k");
  EXPECT_EQ(o.members.at(0).key, utf8);
}

TEST(Json, WriteJsonParsesBackToTheSameValue) {
  const std::string text =
      R"({"n": null, "b": [true, false], "x": [0.1, -0, 1e-300, 1.7976931348623157e308, 123456789012345678],
          "s": "\u0001\"\\\ud83d\ude00", "o": {"": {}, "e": []}})";
  const pm::JsonValue v = pm::parse_json(text, "w");
  const std::string out = pm::write_json(v);
  EXPECT_EQ(out.find(' '), std::string::npos) << out;  // compact
  const pm::JsonValue back = pm::parse_json(out, "again");
  EXPECT_TRUE(pm::json_equal(v, back)) << out;
  EXPECT_EQ(pm::write_json(back), out);
  EXPECT_EQ(pm::write_json(pm::parse_json("[1.5,\"a\"]", "s")), "[1.5,\"a\"]");
  // json_equal looks at values: kinds, order and numbers matter.
  EXPECT_FALSE(pm::json_equal(pm::parse_json("[1,2]", "a"), pm::parse_json("[2,1]", "b")));
  EXPECT_FALSE(
      pm::json_equal(pm::parse_json("{\"a\":1,\"b\":2}", "a"), pm::parse_json("{\"b\":2,\"a\":1}", "b")));
  EXPECT_FALSE(pm::json_equal(pm::parse_json("0", "a"), pm::parse_json("false", "b")));
  EXPECT_TRUE(pm::json_equal(pm::parse_json(" [ 1 ,{} ] ", "a"), pm::parse_json("[1.0,{}]", "b")));
}

TEST(Json, ManyKeysAreCheckedForDuplicatesInLinearTime) {
  // 20000 distinct keys, then one repeated: past the linear-scan threshold, the hash set finds it.
  std::string text = "{";
  for (int k = 0; k < 20000; ++k) text += "\"k" + std::to_string(k) + "\": 0,";
  const pm::JsonValue ok = pm::parse_json(text.substr(0, text.size() - 1) + "}", "many");
  EXPECT_EQ(ok.members.size(), 20000u);
  EXPECT_EQ(ok.find("k19999")->number, 0.0);
  const Failure f = failure(text + "\"k7\": 1}");
  EXPECT_NE(f.what.find("key 'k7' given twice"), std::string::npos) << f.what;
  EXPECT_EQ(f.column, text.size() + 1);
}
