// Esri ASCII grids (see dem_raster.hpp): the header, then the values read from the top in bands of
// rows (AsciiGridRows), through a buffer of the file rather than the whole text. read_ascii_grid
// joins the bands into one Raster; the windowed source (dem_windows.cpp) writes them to a temporary
// file once and reads its windows from there, since a text cannot be read from the middle.
#include <ogr_spatialref.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "dem_raster.hpp"
#include "gdal_support.hpp"

namespace terralod::blocks::detail {

namespace fs = std::filesystem;

namespace {

std::optional<double> parse_double(std::string_view t) {
  if (!t.empty() && t.front() == '+') t.remove_prefix(1);
  double v = 0.0;
  const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
  if (ec != std::errc() || end != t.data() + t.size() || t.empty()) return std::nullopt;
  return v;
}

std::string line_prefix(std::size_t line) { return "line " + std::to_string(line) + ": "; }

}  // namespace

/// Whitespace-separated tokens of a file, each with its 1-based line number, read through a
/// buffer of kChunk bytes (grown for a longer token).
class AsciiGridRows::Tokens {
 public:
  Tokens(const std::string& path, std::istream& in) : path_(path), in_(in), buf_(kChunk, '\0') {}
  /// The next token, valid until the next call, or an empty view at the end; line() is then its
  /// line (or the last line).
  std::string_view next() {
    if (pending_) {
      pending_ = false;
      line_ = pending_line_;
      return peeked_;
    }
    while (true) {
      while (pos_ < end_ && std::isspace((unsigned char)buf_[pos_])) {
        if (buf_[pos_] == '\n') ++line_;
        ++pos_;
      }
      if (pos_ < end_ || !fill(pos_)) break;
    }
    std::size_t start = pos_;
    while (true) {
      while (pos_ < end_ && !std::isspace((unsigned char)buf_[pos_])) ++pos_;
      if (pos_ < end_) break;
      const bool more = fill(start);  // moves the token's start to 0
      start = 0;
      if (!more) break;
    }
    return std::string_view(buf_.data() + start, pos_ - start);
  }
  /// The next token, without consuming it; line() stays where it was.
  std::string_view peek() {
    if (!pending_) {
      const std::size_t line = line_;
      peeked_ = std::string(next());
      pending_line_ = line_;
      line_ = line;
      pending_ = true;
    }
    return peeked_;
  }
  std::size_t line() const { return line_; }

 private:
  static constexpr std::size_t kChunk = std::size_t(1) << 20;
  /// Moves buf_[keep, end_) to the front and reads more after it; false when nothing more came.
  bool fill(std::size_t keep) {
    std::memmove(buf_.data(), buf_.data() + keep, end_ - keep);
    end_ -= keep;
    pos_ -= keep;
    if (end_ == buf_.size()) buf_.resize(2 * buf_.size());
    in_.read(buf_.data() + end_, std::streamsize(buf_.size() - end_));
    const std::size_t got = std::size_t(in_.gcount());
    if (in_.bad()) throw DemError(path_, "cannot read the file");
    if (std::memchr(buf_.data() + end_, '\0', got) != nullptr)
      throw DemError(path_, "is a binary file, not an Esri ASCII grid");
    end_ += got;
    return got > 0;
  }
  std::string path_;
  std::istream& in_;
  std::string buf_;
  std::size_t pos_ = 0, end_ = 0, line_ = 1;
  std::string peeked_;
  bool pending_ = false;
  std::size_t pending_line_ = 1;
};

AsciiGridRows::AsciiGridRows(const std::string& path, bool limit_size) : path_(path) {
  require_file(path);
  in_.open(path, std::ios::binary);
  if (!in_) throw DemError(path, "cannot open the file for reading");
  std::error_code ec;
  const std::uintmax_t bytes = fs::file_size(path, ec);
  tokens_ = std::make_unique<Tokens>(path, in_);

  // Header: "key value" pairs, keys case-insensitive, until the first token that is a number.
  static constexpr std::array<std::string_view, 10> kKeys = {
      "ncols",     "nrows",    "xllcorner", "xllcenter", "yllcorner",
      "yllcenter", "cellsize", "dx",        "dy",        "nodata_value"};
  std::array<std::optional<double>, kKeys.size()> value;
  Tokens& tokens = *tokens_;
  while (true) {
    const std::string_view t = tokens.peek();
    if (t.empty() || parse_double(t)) break;
    const std::string token(tokens.next());
    const std::size_t line = tokens.line();
    const std::string key = detail::lower(token);
    const auto it = std::find(kKeys.begin(), kKeys.end(), key);
    if (it == kKeys.end()) {
      throw DemError(path, line_prefix(line) + "'" + token +
                               "' is not an Esri ASCII grid header key (ncols, nrows, xllcorner, ...)");
    }
    auto& slot = value[std::size_t(it - kKeys.begin())];
    if (slot) throw DemError(path, line_prefix(line) + "header key '" + key + "' appears twice");
    const std::string_view v = tokens.next();
    if (v.empty() || tokens.line() != line) {
      throw DemError(path, line_prefix(line) + "header key '" + key + "' has no value");
    }
    slot = parse_double(v);
    // GDAL writes a float raster whose nodata is NaN with "NODATA_value nan": NaN values are
    // voids anyway.
    const bool nan_nodata = slot && std::isnan(*slot) && key == "nodata_value";
    if (!slot || (!std::isfinite(*slot) && !nan_nodata)) {
      throw DemError(
          path, line_prefix(line) + "value '" + std::string(v) + "' of '" + key + "' is not a finite number");
    }
  }
  auto get = [&](std::string_view key) -> std::optional<double>& {
    return value[std::size_t(std::find(kKeys.begin(), kKeys.end(), key) - kKeys.begin())];
  };
  auto count = [&](std::string_view key) {
    const auto& v = get(key);
    if (!v) throw DemError(path, "header lacks '" + std::string(key) + "' (not an Esri ASCII grid?)");
    if (*v != std::floor(*v) || *v < 1 || *v > double(std::numeric_limits<int>::max())) {
      throw DemError(path, "header value " + std::string(key) + " = " + format_number(*v) +
                               " is not a positive whole number");
    }
    return (long long)*v;
  };
  const long long ncols = count("ncols"), nrows = count("nrows");
  auto one_of = [&](std::string_view corner, std::string_view centre) {
    const auto &a = get(corner), &b = get(centre);
    if (a && b) {
      throw DemError(path, "header has both '" + std::string(corner) + "' and '" + std::string(centre) + "'");
    }
    if (!a && !b) {
      throw DemError(path, "header lacks '" + std::string(corner) + "' or '" + std::string(centre) + "'");
    }
    return std::pair{a ? *a : *b, a.has_value()};
  };
  const auto [xll, x_is_corner] = one_of("xllcorner", "xllcenter");
  const auto [yll, y_is_corner] = one_of("yllcorner", "yllcenter");
  double dx = 0, dy = 0;
  if (get("cellsize")) {
    if (get("dx") || get("dy")) throw DemError(path, "header has both 'cellsize' and 'dx'/'dy'");
    dx = dy = *get("cellsize");
  } else if (get("dx") && get("dy")) {
    dx = *get("dx");
    dy = *get("dy");
  } else {
    throw DemError(path, "header lacks 'cellsize' (or 'dx' and 'dy')");
  }
  if (!(dx > 0) || !(dy > 0)) throw DemError(path, "cell size must be positive");
  if (limit_size || ncols < 2 || nrows < 2) check_dimensions(path, ncols, nrows);
  width_ = int(ncols), height_ = int(nrows);

  // Every value takes at least one byte: refuse a header that promises more than the file can
  // hold before allocating for the promise (a 60-byte file could otherwise claim 8 GiB).
  const std::uintmax_t total = std::uintmax_t(ncols) * std::uintmax_t(nrows);
  if (!ec && total > bytes) {
    throw DemError(path, "header declares " + std::to_string(ncols) + " x " + std::to_string(nrows) + " = " +
                             std::to_string(total) + " values, but the file has only " +
                             std::to_string(bytes) + " bytes (truncated?)");
  }
  nodata_ = get("nodata_value");

  // Corner (lower-left of the lower-left cell) or centre of the lower-left cell; row 0 is north.
  const double x0 = x_is_corner ? xll + 0.5 * dx : xll;
  const double y_south = y_is_corner ? yll + 0.5 * dy : yll;
  const double gt[6] = {x0 - 0.5 * dx, dx, 0.0, y_south + (double(nrows) - 0.5) * dy, 0.0, -dy};

  // Optional sidecar .prj with the CRS.
  std::optional<OGRSpatialReference> srs;
  for (const char* ext : {".prj", ".PRJ"}) {
    const fs::path prj = fs::path(path).replace_extension(ext);
    if (!fs::is_regular_file(prj, ec)) continue;
    std::ifstream pin(prj, std::ios::binary);
    const std::string wkt((std::istreambuf_iterator<char>(pin)), std::istreambuf_iterator<char>());
    register_gdal();
    QuietGdal quiet;
    srs.emplace();
    srs->SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    if (srs->SetFromUserInput(wkt.c_str()) != OGRERR_NONE) {
      throw DemError(path, "sidecar " + prj.string() +
                               " holds no CRS GDAL understands: " + gdal_message("unparsable WKT"));
    }
    geo_.crs_wkt = wkt_of(*srs);
    break;
  }
  georeference(geo_, gt, srs ? &*srs : nullptr);
  if (!srs) geo_.description = "Esri ASCII grid coordinates without a .prj, taken as metres";
  band_rows_ = std::max(1, (1 << 20) / width_);
}

AsciiGridRows::~AsciiGridRows() = default;

int AsciiGridRows::next(std::vector<double>& z) {
  const int rows = std::min(band_rows_, height_ - next_row_);
  if (rows <= 0) return 0;
  const std::size_t n = std::size_t(width_) * std::size_t(rows);
  const std::size_t done = std::size_t(width_) * std::size_t(next_row_);
  const std::size_t total = std::size_t(width_) * std::size_t(height_);
  z.resize(n);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  Tokens& tokens = *tokens_;
  for (std::size_t i = 0; i < n; ++i) {
    const std::string_view t = tokens.next();
    if (t.empty()) {
      throw DemError(path_, line_prefix(tokens.line()) + "data ends after " + std::to_string(done + i) +
                                " of " + std::to_string(width_) + " x " + std::to_string(height_) + " = " +
                                std::to_string(total) + " values");
    }
    const std::optional<double> v = parse_double(t);
    if (!v) throw DemError(path_, line_prefix(tokens.line()) + "'" + std::string(t) + "' is not a number");
    z[i] = (nodata_ && *v == *nodata_) || !is_height(*v) ? nan : *v;
  }
  next_row_ += rows;
  if (next_row_ == height_) {
    if (const std::string_view extra = tokens.next(); !extra.empty()) {
      throw DemError(path_, line_prefix(tokens.line()) + "more values than ncols x nrows = " +
                                std::to_string(total) + " (first extra: '" + std::string(extra) + "')");
    }
  }
  return rows;
}

Raster read_ascii_grid(const std::string& path) {
  AsciiGridRows rows(path, true);
  Raster r = read_all_rows(rows, [](double v) { return v; });
  r.geo = rows.georef();
  return r;
}

}  // namespace terralod::blocks::detail
