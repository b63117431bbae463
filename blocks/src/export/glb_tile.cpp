// One tile as a quantized glTF binary (see glb_tile.hpp).
#include "glb_tile.hpp"

#include <meshoptimizer.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <vector>

#include "terralod/pm/byte_io.hpp"
#include "terralod/pm/glb.hpp"

namespace terralod::blocks::detail {
namespace {

constexpr int kQ = 32767;

std::string num(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

}  // namespace

GlbTile encode_tile_glb(const QuantizedMeshTile& t, const GeoRect& rect,
                        const std::function<pm::Ecef(std::size_t)>& normal, double s, double skirt,
                        bool meshopt, const std::string& path) {
  const std::size_t n = t.u.size();
  GlbTile out;
  // The translation: the rectangle's centre on the ellipsoid, in glTF axes, on the level's lattice.
  const double q = s / kQ;
  const pm::Ecef c =
      pm::ecef_from_geodetic({0.5 * (rect.west + rect.east), 0.5 * (rect.south + rect.north), 0.0});
  const pm::Ecef T{std::round(c[0] / q) * q, std::round(c[2] / q) * q, std::round(-c[1] / q) * q};
  // Decoded vertices, ECEF, relative to T, in glTF axes; then the skirt: a copy of every edge
  // vertex `skirt` metres lower (source[i] = the vertex it copies).
  std::vector<pm::Geodetic> geo(n);
  std::vector<std::uint32_t> source(n);
  for (std::size_t i = 0; i < n; ++i) {
    geo[i] = {rect.west + (rect.east - rect.west) * t.u[i] / kQ,
              rect.south + (rect.north - rect.south) * t.v[i] / kQ,
              double(t.min_height) + double(t.h[i]) / kQ * (double(t.max_height) - double(t.min_height))};
    source[i] = std::uint32_t(i);
  }
  std::vector<std::array<std::uint32_t, 3>> triangles = t.triangles;
  for (const auto& edge : t.edges) {
    for (std::size_t k = 0; k < edge.size(); ++k) {
      geo.push_back({geo[edge[k]].lon_deg, geo[edge[k]].lat_deg, geo[edge[k]].height - skirt});
      source.push_back(edge[k]);
      if (k == 0) continue;
      const std::uint32_t a = edge[k - 1], b = edge[k], a2 = std::uint32_t(geo.size() - 2),
                          b2 = std::uint32_t(geo.size() - 1);
      // Both faces: whichever side a client looks through a crack from, it sees the skirt.
      triangles.push_back({a, b, b2}), triangles.push_back({a, b2, a2});
      triangles.push_back({a, b2, b}), triangles.push_back({a, a2, b2});
    }
  }
  std::vector<pm::Ecef> ecef(geo.size());
  for (std::size_t i = 0; i < geo.size(); ++i) ecef[i] = pm::ecef_from_geodetic(geo[i]);
  for (const auto& tri : t.triangles)  // the surface's own triangles
    for (int k = 0; k < 3; ++k) {
      const pm::Ecef& a = ecef[tri[std::size_t(k)]];
      const pm::Ecef& b = ecef[tri[std::size_t((k + 1) % 3)]];
      out.longest_edge = std::max(out.longest_edge, std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]));
    }
  // Triangles in vertex-cache order and vertices in first-use order: what a GPU draws fastest, and
  // what EXT_meshopt_compression's codecs compress best. A vertex no triangle uses is dropped.
  std::vector<std::uint32_t> index(3 * triangles.size());
  for (std::size_t ti = 0; ti < triangles.size(); ++ti)
    for (int k = 0; k < 3; ++k) index[3 * ti + std::size_t(k)] = triangles[ti][std::size_t(k)];
  meshopt_optimizeVertexCache(index.data(), index.data(), index.size(), geo.size());
  std::vector<std::uint32_t> remap(geo.size());
  const std::size_t all =
      meshopt_optimizeVertexFetchRemap(remap.data(), index.data(), index.size(), geo.size());
  meshopt_remapIndexBuffer(index.data(), index.data(), index.size(), remap.data());
  std::vector<pm::Ecef> g(all);
  std::vector<std::uint32_t> from(all);
  for (std::size_t i = 0; i < geo.size(); ++i) {
    if (remap[i] == ~0u) continue;
    g[remap[i]] = {ecef[i][0] - T[0], ecef[i][2] - T[1], -ecef[i][1] - T[2]};
    from[remap[i]] = source[i];
  }

  pm::ByteWriter bin;
  std::array<int, 3> qmin{kQ, kQ, kQ}, qmax{-kQ, -kQ, -kQ};
  for (std::size_t i = 0; i < all; ++i) {
    double err2 = 0;
    for (int k = 0; k < 3; ++k) {
      const int qi = int(std::clamp<long>(std::lround(g[i][std::size_t(k)] / q), -kQ, kQ));
      qmin[std::size_t(k)] = std::min(qmin[std::size_t(k)], qi);
      qmax[std::size_t(k)] = std::max(qmax[std::size_t(k)], qi);
      bin.i16(std::int16_t(qi));
      const double e = double(qi) * q - g[i][std::size_t(k)];
      err2 += e * e;
    }
    bin.i16(0);  // stride 8
    out.displacement = std::max(out.displacement, std::sqrt(err2));
  }
  const std::size_t normals_at = bin.bytes.size();
  for (std::size_t i = 0; i < all; ++i) {
    const pm::Ecef e = normal(from[i]);
    const pm::Ecef gl{e[0], e[2], -e[1]};
    for (double c : gl) bin.i8(std::int8_t(std::lround(std::clamp(c, -1.0, 1.0) * 127.0)));
    bin.i8(0);  // stride 4
  }
  const std::size_t indices_at = bin.bytes.size();
  const bool wide = all > 65535;
  for (std::uint32_t i : index) {
    if (wide)
      bin.u32(i);
    else
      bin.u16(std::uint16_t(i));
  }
  const std::size_t index_bytes = bin.bytes.size() - indices_at;
  bin.pad_to(4);

  // The three buffer views: (offset, length, stride) in `bin`; with meshopt, `bin` becomes the
  // fallback (buffer 1, no data) and each view also points at its compressed bytes in buffer 0.
  struct View {
    std::size_t at, length, stride, count;
    const char* mode;
    int target;
  };
  const View views[3] = {{0, normals_at, 8, all, "ATTRIBUTES", 34962},
                         {normals_at, indices_at - normals_at, 4, all, "ATTRIBUTES", 34962},
                         {indices_at, index_bytes, wide ? 4u : 2u, index.size(), "TRIANGLES", 34963}};
  std::string packed;
  std::size_t packed_at[3] = {0, 0, 0}, packed_length[3] = {0, 0, 0};
  if (meshopt) {
    for (int k = 0; k < 3; ++k) {
      const View& v = views[k];
      std::vector<unsigned char> code;
      if (v.target == 34962) {
        code.resize(meshopt_encodeVertexBufferBound(v.count, v.stride));
        code.resize(
            meshopt_encodeVertexBuffer(code.data(), code.size(), bin.bytes.data() + v.at, v.count, v.stride));
      } else {
        code.resize(meshopt_encodeIndexBufferBound(index.size(), all));
        code.resize(meshopt_encodeIndexBuffer(code.data(), code.size(), index.data(), index.size()));
      }
      if (code.empty()) throw std::runtime_error(path + ": meshopt could not encode a buffer view");
      packed_at[k] = packed.size(), packed_length[k] = code.size();
      packed.append(reinterpret_cast<const char*>(code.data()), code.size());
      packed.append((4 - packed.size() % 4) % 4, '\0');
    }
  }

  const std::string extensions =
      meshopt ? R"(["KHR_mesh_quantization","EXT_meshopt_compression"])" : R"(["KHR_mesh_quantization"])";
  std::string j = R"({"asset":{"version":"2.0","generator":"terralod export"},"extensionsUsed":)" +
                  extensions + R"(,"extensionsRequired":)" + extensions +
                  R"(,"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0,"translation":[)";
  j += num(T[0]) + "," + num(T[1]) + "," + num(T[2]) + "],\"scale\":[" + num(s) + "," + num(s) + "," +
       num(s) + "]}],";
  j += R"("meshes":[{"primitives":[{"attributes":{"POSITION":0,"NORMAL":1},"indices":2,"mode":4}]}],)";
  auto arr = [](const std::array<int, 3>& q) {
    // The stored integers (the validator wants an integer accessor's own values), appended piece
    // by piece: GCC 12 warns falsely on "[" + std::string.
    std::string a = "[";
    for (int k = 0; k < 3; ++k) {
      a += std::to_string(q[std::size_t(k)]);
      a += k < 2 ? "," : "]";
    }
    return a;
  };
  j += R"("accessors":[{"bufferView":0,"componentType":5122,"normalized":true,"count":)" +
       std::to_string(all) + R"(,"type":"VEC3","min":)" + arr(qmin) + R"(,"max":)" + arr(qmax) + "},";
  j += R"({"bufferView":1,"componentType":5120,"normalized":true,"count":)" + std::to_string(all) +
       R"(,"type":"VEC3"},)";
  j += R"({"bufferView":2,"componentType":)" + std::string(wide ? "5125" : "5123") + R"(,"count":)" +
       std::to_string(index.size()) + R"(,"type":"SCALAR"}],"bufferViews":[)";
  for (int k = 0; k < 3; ++k) {
    const View& v = views[k];
    j += std::string(k ? "," : "") + R"({"buffer":)" + (meshopt ? "1" : "0") + R"(,"byteOffset":)" +
         std::to_string(v.at) + R"(,"byteLength":)" + std::to_string(v.length);
    if (v.target == 34962) j += R"(,"byteStride":)" + std::to_string(v.stride);
    j += R"(,"target":)" + std::to_string(v.target);
    if (meshopt)
      j += R"(,"extensions":{"EXT_meshopt_compression":{"buffer":0,"byteOffset":)" +
           std::to_string(packed_at[k]) + R"(,"byteLength":)" + std::to_string(packed_length[k]) +
           R"(,"byteStride":)" + std::to_string(v.stride) + R"(,"count":)" + std::to_string(v.count) +
           R"(,"mode":")" + v.mode + "\"}}";
    j += "}";
  }
  if (meshopt)
    j += R"(],"buffers":[{"byteLength":)" + std::to_string(packed.size()) + R"(},{"byteLength":)" +
         std::to_string(bin.bytes.size()) +
         R"(,"extensions":{"EXT_meshopt_compression":{"fallback":true}}}]})";
  else
    j += R"(],"buffers":[{"byteLength":)" + std::to_string(bin.bytes.size()) + "}]}";
  out.bytes = pm::glb_container(std::move(j), meshopt ? std::string_view(packed) : bin.chars(), path);
  return out;
}

}  // namespace terralod::blocks::detail
