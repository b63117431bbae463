// quantized-mesh-1.0 tiles (see quantized_mesh.hpp).
#include "terralod/blocks/quantized_mesh.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <tuple>
#include <utility>

#include "terralod/pm/byte_io.hpp"
#include "terralod/pm/deflate_codec.hpp"
#include "terralod/pm/json.hpp"

namespace terralod::blocks {
namespace {

constexpr int kMaxQ = 32767;

std::uint16_t quantize(double t) { return std::uint16_t(std::lround(std::clamp(t, 0.0, 1.0) * kMaxQ)); }

double snorm(double v) { return std::round((std::clamp(v, -1.0, 1.0) * 0.5 + 0.5) * 255.0); }

// The octahedral wrap between the lower half of the octahedron and the outer triangles of the
// unit square, the same map both ways: (x, y) -> ((1 - |y|) sign x, (1 - |x|) sign y), sign 0 = +.
std::pair<double, double> octahedral_wrap(double x, double y) {
  return {(1.0 - std::abs(y)) * (x < 0 ? -1.0 : 1.0), (1.0 - std::abs(x)) * (y < 0 ? -1.0 : 1.0)};
}

}  // namespace

GeoRect tile_rect(TileId id) {
  const double w = 180.0 / std::ldexp(1.0, id.z);
  return {-180.0 + id.x * w, -90.0 + id.y * w, -180.0 + (id.x + 1) * w, -90.0 + (id.y + 1) * w};
}

double level_max_geometric_error(int z) {
  return pm::kWgs84A * 2.0 * std::numbers::pi * 0.25 / (65.0 * 2.0) / std::ldexp(1.0, z);
}

std::array<std::uint8_t, 2> oct_encode(const pm::Ecef& n) {
  const double l1 = std::abs(n[0]) + std::abs(n[1]) + std::abs(n[2]);
  double x = n[0] / l1, y = n[1] / l1;
  if (n[2] < 0) std::tie(x, y) = octahedral_wrap(x, y);
  return {std::uint8_t(snorm(x)), std::uint8_t(snorm(y))};
}

pm::Ecef oct_decode(std::array<std::uint8_t, 2> b) {
  double x = b[0] / 255.0 * 2.0 - 1.0, y = b[1] / 255.0 * 2.0 - 1.0;
  const double z = 1.0 - (std::abs(x) + std::abs(y));
  if (z < 0) std::tie(x, y) = octahedral_wrap(x, y);
  const double l = std::sqrt(x * x + y * y + z * z);
  return {x / l, y / l, z / l};
}

std::vector<pm::Ecef> area_weighted_normals(std::span<const pm::Ecef> p,
                                            std::span<const std::array<std::uint32_t, 3>> triangles) {
  std::vector<pm::Ecef> n(p.size(), pm::Ecef{0, 0, 0});
  for (const auto& tri : triangles) {
    const pm::Ecef &a = p[tri[0]], &b = p[tri[1]], &c = p[tri[2]];
    const pm::Ecef e1{b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2{c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const pm::Ecef f{e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                     e1[0] * e2[1] - e1[1] * e2[0]};
    for (std::uint32_t v : tri)
      for (int k = 0; k < 3; ++k) n[v][std::size_t(k)] += f[std::size_t(k)];
  }
  for (std::size_t i = 0; i < n.size(); ++i) {
    const double len = std::sqrt(n[i][0] * n[i][0] + n[i][1] * n[i][1] + n[i][2] * n[i][2]);
    if (len > 0) {
      for (double& x : n[i]) x /= len;
    } else {  // an isolated vertex: the ellipsoid's normal
      const pm::Geodetic g = pm::geodetic_from_ecef(p[i]);
      n[i] = pm::geodetic_surface_normal(g.lon_deg, g.lat_deg);
    }
  }
  return n;
}

QuantizedMeshTile make_quantized_mesh(const GeoRect& rect, std::span<const pm::Geodetic> vertices,
                                      std::span<const std::array<std::uint32_t, 3>> triangles,
                                      const QuantizedMeshOptions& options) {
  assert(rect.east > rect.west && rect.north > rect.south);
  QuantizedMeshTile t;
  // Vertices in order of first use (the high-water-mark index coding needs it).
  std::vector<std::uint32_t> order, index(vertices.size(), UINT32_MAX);
  for (const auto& tri : triangles)
    for (std::uint32_t v : tri) {
      assert(v < vertices.size());
      if (index[v] == UINT32_MAX) {
        index[v] = std::uint32_t(order.size());
        order.push_back(v);
      }
    }
  t.triangles.reserve(triangles.size());
  for (const auto& tri : triangles) t.triangles.push_back({index[tri[0]], index[tri[1]], index[tri[2]]});
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (std::uint32_t v : order) {
    lo = std::min(lo, vertices[v].height);
    hi = std::max(hi, vertices[v].height);
  }
  if (order.empty()) lo = hi = 0;
  if (options.height_step > 0) {
    const double step = options.height_step;
    lo = std::floor(lo / step) * step;
    if (hi - lo > (kMaxQ - 1) * step)
      throw std::invalid_argument("quantized mesh: heights span " + std::to_string(hi - lo) +
                                  " m, more than 32766 height steps of " + std::to_string(step) + " m");
    hi = lo + kMaxQ * step;
  }
  t.min_height = float(lo);
  t.max_height = float(hi);
  // Quantize against the heights as stored (floats), so that decoding reproduces them.
  const double hlo = t.min_height, hhi = t.max_height;
  std::vector<pm::Ecef> ecef;
  ecef.reserve(order.size());
  for (std::uint32_t v : order) {
    const pm::Geodetic& g = vertices[v];
    t.u.push_back(quantize((g.lon_deg - rect.west) / (rect.east - rect.west)));
    t.v.push_back(quantize((g.lat_deg - rect.south) / (rect.north - rect.south)));
    if (options.height_step > 0)  // on the step's lattice: the same height, the same decoded value
      t.h.push_back(std::uint16_t(std::clamp<long>(
          std::lround(g.height / options.height_step) - std::lround(hlo / options.height_step), 0, kMaxQ)));
    else
      t.h.push_back(hhi > hlo ? quantize((g.height - hlo) / (hhi - hlo)) : 0);
    // The decoded position, so that the header bounds what a client draws.
    const double lon = rect.west + (rect.east - rect.west) * t.u.back() / kMaxQ;
    const double lat = rect.south + (rect.north - rect.south) * t.v.back() / kMaxQ;
    ecef.push_back(pm::ecef_from_geodetic({lon, lat, hlo + (hhi - hlo) * t.h.back() / kMaxQ}));
  }
  t.sphere = pm::bounding_sphere(ecef);
  t.center = t.sphere.center;
  t.horizon = pm::horizon_occlusion_point(ecef, t.sphere.center);
  // Edges, sorted along each edge (west and east by v, south and north by u).
  for (std::uint32_t i = 0; i < order.size(); ++i) {
    if (t.u[i] == 0) t.edges[0].push_back(i);
    if (t.v[i] == 0) t.edges[1].push_back(i);
    if (t.u[i] == kMaxQ) t.edges[2].push_back(i);
    if (t.v[i] == kMaxQ) t.edges[3].push_back(i);
  }
  for (int e = 0; e < 4; ++e) {
    const auto& key = e % 2 == 0 ? t.v : t.u;
    std::sort(t.edges[std::size_t(e)].begin(), t.edges[std::size_t(e)].end(),
              [&](std::uint32_t a, std::uint32_t b) { return key[a] < key[b]; });
  }
  if (options.normals && options.normal) {
    t.normals.reserve(order.size());
    for (std::uint32_t v : order) t.normals.push_back(oct_encode(options.normal(v)));
  } else if (options.normals) {
    const std::vector<pm::Ecef> n = area_weighted_normals(ecef, t.triangles);
    t.normals.reserve(order.size());
    for (const pm::Ecef& m : n) t.normals.push_back(oct_encode(m));
  }
  t.metadata = options.metadata;
  return t;
}

std::vector<std::uint8_t> encode_quantized_mesh(const QuantizedMeshTile& t) {
  const std::size_t n = t.u.size();
  assert(t.v.size() == n && t.h.size() == n && (t.normals.empty() || t.normals.size() == n));
  pm::ByteWriter w;
  for (double c : t.center) w.f64(c);
  w.f32(t.min_height);
  w.f32(t.max_height);
  for (double c : t.sphere.center) w.f64(c);
  w.f64(t.sphere.radius);
  for (double c : t.horizon) w.f64(c);
  w.u32(std::uint32_t(n));
  for (const auto* a : {&t.u, &t.v, &t.h}) {
    int prev = 0;
    for (std::uint16_t x : *a) {
      w.u16(std::uint16_t(pm::zigzag(int(x) - prev)));
      prev = x;
    }
  }
  const bool wide = n > 65536;
  auto put_index = [&](std::uint32_t i) {
    if (wide)
      w.u32(i);
    else
      w.u16(std::uint16_t(i));
  };
  w.pad_to(wide ? 4 : 2);
  w.u32(std::uint32_t(t.triangles.size()));
  std::uint32_t highest = 0;
  for (const auto& tri : t.triangles)
    for (std::uint32_t i : tri) {
      if (i > highest) throw std::invalid_argument("quantized mesh: vertices are not in order of first use");
      put_index(highest - i);
      if (i == highest) ++highest;
    }
  for (const auto& e : t.edges) {
    w.u32(std::uint32_t(e.size()));
    for (std::uint32_t i : e) put_index(i);
  }
  if (!t.normals.empty()) {
    w.u8(1);
    w.u32(std::uint32_t(2 * n));
    for (const auto& o : t.normals) {
      w.u8(o[0]);
      w.u8(o[1]);
    }
  }
  if (!t.metadata.empty()) {
    w.u8(4);
    w.u32(std::uint32_t(4 + t.metadata.size()));
    w.u32(std::uint32_t(t.metadata.size()));
    w.raw(t.metadata.data(), t.metadata.size());
  }
  return std::move(w.bytes);
}

std::vector<std::uint8_t> gzip(std::span<const std::uint8_t> bytes) {
  // Level 6: at zlib's level 9 the compression was 31 % of `terralod export`'s CPU time (17.8 %
  // at 6) for tiles 0.14 % smaller. libdeflate's level 6 (zlib's level 6 before): N44W072's tiles
  // 1 % smaller, its export in 0.91x the CPU.
  std::vector<std::uint8_t> out;
  if (pm::gzip_compress(bytes, 6, out) == 0)
    throw std::runtime_error("gzip: cannot allocate the deflate compressor");
  return out;
}

std::string layer_json(const std::string& name, const GeoRect& b,
                       const std::vector<std::vector<TileRange>>& available,
                       const std::vector<std::string>& extensions, const std::string& extra_members) {
  const auto quoted = [](const std::string& s) { return pm::json_quote(s); };
  char buf[256];
  std::string j =
      "{\n  \"tilejson\": \"2.1.0\",\n  \"name\": " + quoted(name) +
      ",\n  \"version\": \"1.0.0\",\n  \"format\": \"quantized-mesh-1.0\",\n  \"scheme\": \"tms\",\n"
      "  \"projection\": \"EPSG:4326\",\n  \"tiles\": [\"{z}/{x}/{y}.terrain?v={version}\"],\n";
  std::snprintf(buf, sizeof buf,
                "  \"bounds\": [%.17g, %.17g, %.17g, %.17g],\n  \"minzoom\": 0,\n  \"maxzoom\": %d,\n",
                b.west, b.south, b.east, b.north, int(available.size()) - 1);
  j += buf;
  j += "  \"extensions\": [";
  for (std::size_t i = 0; i < extensions.size(); ++i) j += (i ? ", " : "") + quoted(extensions[i]);
  j += "],\n  \"available\": [\n";
  for (std::size_t z = 0; z < available.size(); ++z) {
    j += "    [";
    for (std::size_t i = 0; i < available[z].size(); ++i) {
      const TileRange& r = available[z][i];
      std::snprintf(buf, sizeof buf, "%s{\"startX\": %d, \"startY\": %d, \"endX\": %d, \"endY\": %d}",
                    i ? ", " : "", r.start_x, r.start_y, r.end_x, r.end_y);
      j += buf;
    }
    j += z + 1 < available.size() ? "],\n" : "]\n";
  }
  j += "  ]";
  if (!extra_members.empty()) j += ",\n  " + extra_members;
  j += "\n}\n";
  return j;
}

}  // namespace terralod::blocks
