// libFuzzer target for the strict JSON reader (pm/json.hpp): parse_json on arbitrary bytes must
// either throw JsonError "fuzz.json: line L, column C: ..." with L and C inside the text, or
// return a value whose byte ranges lie inside the text, whose write_json text parses back to a
// json_equal value, and whose strings survive json_quote.
//
// Bounded work: inputs over 64 KiB are skipped (returning -1 keeps them out of the corpus).
#include <cstdint>
#include <string>
#include <string_view>

#include "fuzz_support.hpp"
#include "terralod/pm/json.hpp"

namespace {

namespace pm = terralod::pm;

[[noreturn]] void finding(const std::string& what) { terralod::fuzz::finding("fuzz_json", what); }
#define REQUIRE(cond)                                 \
  do {                                                \
    if (!(cond)) finding("invariant broken: " #cond); \
  } while (0)

// Byte ranges nest inside the parent's; strings round-trip through json_quote.
void check(const pm::JsonValue& v, std::string_view text, std::size_t lo, std::size_t hi) {
  REQUIRE(lo <= v.begin && v.begin < v.end && v.end <= hi);
  const std::string_view raw = v.raw(text);
  switch (v.kind) {
    case pm::JsonValue::Kind::String:
      REQUIRE(raw.front() == '"' && raw.back() == '"');
      REQUIRE(pm::parse_json(pm::json_quote(v.string), "quote").string == v.string);
      break;
    case pm::JsonValue::Kind::Array:
      REQUIRE(raw.front() == '[' && raw.back() == ']');
      for (const pm::JsonValue& item : v.items) check(item, text, v.begin + 1, v.end - 1);
      break;
    case pm::JsonValue::Kind::Object:
      REQUIRE(raw.front() == '{' && raw.back() == '}');
      for (const auto& [key, member] : v.members) {
        REQUIRE(pm::parse_json(pm::json_quote(key), "key").string == key);
        check(member, text, v.begin + 1, v.end - 1);
      }
      break;
    default:
      break;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > 65536) return -1;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  pm::JsonValue v;
  try {
    v = pm::parse_json(text, "fuzz.json");
  } catch (const pm::JsonError& e) {
    REQUIRE(std::string_view(e.what()).substr(0, 16) == "fuzz.json: line ");
    REQUIRE(e.line() >= 1 && e.column() >= 1 && e.line() + e.column() <= size + 2);
    return 0;
  }
  check(v, text, 0, size);
  const std::string again = pm::write_json(v);
  const pm::JsonValue back = pm::parse_json(again, "again.json");
  REQUIRE(pm::json_equal(v, back));
  REQUIRE(pm::write_json(back) == again);
  return 0;
}
