// Heightmap images through OpenImageIO (detail::read_heightmap, see dem_raster.hpp): 8- to
// 32-bit integer or floating-point grey images, with an optional alpha channel marking voids.
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "dem_raster.hpp"

namespace terralod::blocks::detail {
namespace {

template <typename T>
void read_integers(const std::string& path, OIIO::ImageInput& in, OIIO::TypeDesc type, Raster& r) {
  std::vector<T> raw(r.z.size());
  if (!in.read_image(0, 0, 0, 1, type, raw.data())) {
    throw DemError(path, "cannot read the pixels: " + in.geterror());
  }
  std::transform(raw.begin(), raw.end(), r.z.begin(), [](T v) { return double(v); });
}

}  // namespace

Raster read_heightmap(const std::string& path, const DemOptions& options) {
  require_file(path);
  auto in = OIIO::ImageInput::open(path);
  if (!in) {
    std::string msg = OIIO::geterror();
    throw DemError(path, "OpenImageIO cannot read it as an image: " + (msg.empty() ? "unknown format" : msg));
  }
  const OIIO::ImageSpec& spec = in->spec();
  if (spec.deep) throw DemError(path, "is a deep image; a heightmap must be a plain single-channel image");
  // Grey and alpha (what image tools and GDAL's PNG writer give a heightmap with voids): the
  // heights are the grey channel, the samples where alpha is 0 are voids.
  const bool alpha = spec.nchannels == 2 && spec.alpha_channel == 1;
  if (spec.nchannels != 1 && !alpha) {
    throw DemError(path, "has " + std::to_string(spec.nchannels) +
                             " channels; a heightmap must have one (grey), or grey and alpha");
  }
  if (spec.depth > 1) throw DemError(path, "is a volume image; a heightmap must be 2-D");
  check_dimensions(path, spec.width, spec.height);

  Raster r;
  r.width = spec.width;
  r.height = spec.height;
  r.z.resize(std::size_t(r.width) * r.height);
  using B = OIIO::TypeDesc::BASETYPE;
  // Integers are read in their own type: OpenImageIO would normalise them to [0,1] as floats.
  switch (B(spec.format.basetype)) {
    case B::UINT8:
      read_integers<std::uint8_t>(path, *in, OIIO::TypeDesc::UINT8, r);
      break;
    case B::INT8:
      read_integers<std::int8_t>(path, *in, OIIO::TypeDesc::INT8, r);
      break;
    case B::UINT16:
      read_integers<std::uint16_t>(path, *in, OIIO::TypeDesc::UINT16, r);
      break;
    case B::INT16:
      read_integers<std::int16_t>(path, *in, OIIO::TypeDesc::INT16, r);
      break;
    case B::UINT32:
      read_integers<std::uint32_t>(path, *in, OIIO::TypeDesc::UINT32, r);
      break;
    case B::INT32:
      read_integers<std::int32_t>(path, *in, OIIO::TypeDesc::INT32, r);
      break;
    case B::HALF:
    case B::FLOAT:
    case B::DOUBLE:
      if (!in->read_image(0, 0, 0, 1, OIIO::TypeDesc::DOUBLE, r.z.data())) {
        throw DemError(path, "cannot read the pixels: " + in->geterror());
      }
      break;
    default:
      throw DemError(path,
                     "pixel type " + std::string(spec.format.c_str()) + " is not supported for heightmaps");
  }
  std::vector<float> opacity;
  if (alpha) {
    opacity.resize(r.z.size());
    if (!in->read_image(0, 0, 1, 2, OIIO::TypeDesc::FLOAT, opacity.data()))
      throw DemError(path, "cannot read the alpha channel: " + in->geterror());
  }
  in->close();
  for (std::size_t i = 0; i < r.z.size(); ++i) {
    double& v = r.z[i];
    v = v * options.vertical_scale + options.vertical_offset;
    if (!is_height(v) || (alpha && opacity[i] == 0.0f)) v = std::numeric_limits<double>::quiet_NaN();
  }
  r.geo.kind = Georef::Kind::None;
  if (options.vertical_scale != 1.0 || options.vertical_offset != 0.0) {
    r.height_note = "; heights = raw * " + format_number(options.vertical_scale) + " + " +
                    format_number(options.vertical_offset) + " m";
  }
  return r;
}

}  // namespace terralod::blocks::detail
