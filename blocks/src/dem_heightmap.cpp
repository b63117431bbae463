// Heightmap images through OpenImageIO (see dem_raster.hpp): 8- to 32-bit integer or
// floating-point grey images, with an optional alpha channel marking voids, read in bands of rows
// from the top (HeightmapRows). read_heightmap joins the bands into one Raster; the windowed
// source (dem_windows.cpp) writes them to a temporary file once and reads its windows from there,
// since PNG, the usual heightmap format, cannot be read from the middle: every read behind the
// last one would decode the image again from its first row.
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "dem_raster.hpp"

namespace terralod::blocks::detail {

HeightmapRows::HeightmapRows(const std::string& path, bool limit_size) : path_(path) {
  require_file(path);
  in_ = OIIO::ImageInput::open(path);
  if (!in_) {
    std::string msg = OIIO::geterror();
    throw DemError(path, "OpenImageIO cannot read it as an image: " + (msg.empty() ? "unknown format" : msg));
  }
  const OIIO::ImageSpec& spec = in_->spec();
  if (spec.deep) throw DemError(path, "is a deep image; a heightmap must be a plain single-channel image");
  // Grey and alpha (what image tools and GDAL's PNG writer give a heightmap with voids): the
  // heights are the grey channel, the samples where alpha is 0 are voids.
  alpha_ = spec.nchannels == 2 && spec.alpha_channel == 1;
  if (spec.nchannels != 1 && !alpha_) {
    throw DemError(path, "has " + std::to_string(spec.nchannels) +
                             " channels; a heightmap must have one (grey), or grey and alpha");
  }
  if (spec.depth > 1) throw DemError(path, "is a volume image; a heightmap must be 2-D");
  if (limit_size || spec.width < 2 || spec.height < 2) check_dimensions(path, spec.width, spec.height);
  using B = OIIO::TypeDesc::BASETYPE;
  switch (B(spec.format.basetype)) {
    // Integers are read in their own type: OpenImageIO would normalise them to [0,1] as floats.
    case B::UINT8:
    case B::INT8:
    case B::UINT16:
    case B::INT16:
      type_ = spec.format;
      exact_in_float_ = true;
      break;
    case B::UINT32:
    case B::INT32:
      type_ = spec.format;
      break;
    case B::HALF:
    case B::FLOAT:
      type_ = OIIO::TypeDesc::DOUBLE;
      exact_in_float_ = true;
      break;
    case B::DOUBLE:
      type_ = OIIO::TypeDesc::DOUBLE;
      break;
    default:
      throw DemError(path,
                     "pixel type " + std::string(spec.format.c_str()) + " is not supported for heightmaps");
  }
  // Tiled files are read a row of tiles at a time (read_tiles needs whole tiles but at the edges).
  band_rows_ = spec.tile_width > 0 ? std::max(1, spec.tile_height) : std::max(1, (1 << 20) / spec.width);
}

HeightmapRows::~HeightmapRows() = default;

int HeightmapRows::width() const { return in_->spec().width; }
int HeightmapRows::height() const { return in_->spec().height; }

int HeightmapRows::next(std::vector<double>& raw) {
  const OIIO::ImageSpec& spec = in_->spec();
  const int y0 = next_row_, y1 = std::min(spec.height, y0 + band_rows_);
  if (y0 >= y1) return 0;
  const int channels = alpha_ ? 2 : 1;
  const std::size_t n = std::size_t(spec.width) * std::size_t(y1 - y0);
  bytes_.resize(n * std::size_t(channels) * type_.size());
  const bool ok =
      spec.tile_width > 0
          ? in_->read_tiles(0, 0, spec.x, spec.x + spec.width, spec.y + y0, spec.y + y1, spec.z, spec.z + 1,
                            0, channels, type_, bytes_.data())
          : in_->read_scanlines(0, 0, spec.y + y0, spec.y + y1, spec.z, 0, channels, type_, bytes_.data());
  if (!ok) throw DemError(path_, "cannot read the pixels: " + in_->geterror());
  raw.resize(n);
  const auto convert = [&](auto zero) {
    using T = decltype(zero);
    const T* v = reinterpret_cast<const T*>(bytes_.data());
    for (std::size_t i = 0; i < n; ++i) {
      const bool transparent = alpha_ && v[2 * i + 1] == zero;
      raw[i] = transparent ? std::numeric_limits<double>::quiet_NaN() : double(v[alpha_ ? 2 * i : i]);
    }
  };
  using B = OIIO::TypeDesc::BASETYPE;
  switch (B(type_.basetype)) {
    case B::UINT8:
      convert(std::uint8_t(0));
      break;
    case B::INT8:
      convert(std::int8_t(0));
      break;
    case B::UINT16:
      convert(std::uint16_t(0));
      break;
    case B::INT16:
      convert(std::int16_t(0));
      break;
    case B::UINT32:
      convert(std::uint32_t(0));
      break;
    case B::INT32:
      convert(std::int32_t(0));
      break;
    default:
      convert(0.0);
      break;
  }
  next_row_ = y1;
  return y1 - y0;
}

double heightmap_metres(double raw, double scale, double offset) {
  const double v = raw * scale + offset;
  return is_height(v) ? v : std::numeric_limits<double>::quiet_NaN();
}

std::string heightmap_note(const DemOptions& options) {
  if (options.vertical_scale == 1.0 && options.vertical_offset == 0.0) return "";
  return "; heights = raw * " + format_number(options.vertical_scale) + " + " +
         format_number(options.vertical_offset) + " m";
}

Raster read_heightmap(const std::string& path, const DemOptions& options) {
  HeightmapRows rows(path, true);
  Raster r = read_all_rows(rows, [&](double raw) {
    return heightmap_metres(raw, options.vertical_scale, options.vertical_offset);
  });
  r.geo.kind = Georef::Kind::None;
  r.height_note = heightmap_note(options);
  return r;
}

}  // namespace terralod::blocks::detail
