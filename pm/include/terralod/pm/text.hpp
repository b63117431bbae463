// Text files people edit: a UTF-8 byte order mark, which Windows editors and Excel's "CSV UTF-8"
// put at the start of a file, is not part of its first line or JSON value.
#pragma once

#include <string_view>

namespace terralod::pm {

/// `text` without a leading UTF-8 byte order mark (EF BB BF); unchanged when it has none.
constexpr std::string_view without_utf8_bom(std::string_view text) {
  return text.substr(0, 3) == "\xEF\xBB\xBF" ? text.substr(3) : text;
}

}  // namespace terralod::pm
