// glTF 2.0 encoding of a triangle mesh (.glb and .gltf); the layout is in gltf_writer.hpp.
#include "gltf_writer.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string_view>

#include "shortest_decimal.hpp"
#include "terralod/pm/byte_io.hpp"
#include "terralod/pm/glb.hpp"
#include "terralod/pm/json.hpp"

namespace terralod::pm::detail {

namespace {

constexpr std::uint32_t kGlbMagic = 0x46546C67u;   // "glTF"
constexpr std::uint32_t kChunkJson = 0x4E4F534Au;  // "JSON"
constexpr std::uint32_t kChunkBin = 0x004E4942u;   // "BIN\0"
constexpr int kFloat = 5126, kUnsignedShort = 5123, kUnsignedInt = 5125;
constexpr int kArrayBuffer = 34962, kElementArrayBuffer = 34963;
constexpr std::size_t kMaxShortVertices = 65535;  // index 65535 is reserved (primitive restart)

using Vec3 = std::array<double, 3>;

/// Our frame (x east, y north, z up) to glTF's (x, z, -y): a rotation, determinant +1.
Vec3 to_gltf(const Vec3& p) { return {p[0], p[2], -p[1]}; }

/// JSON text built by appending: strings as they are (already JSON), integers in decimal,
/// doubles as the shortest decimal that reads back to the same double (encode_gltf refuses
/// positions that are not finite first: JSON has no NaN or infinity).
struct Json {
  std::string text;
  Json& operator<<(std::string_view s) {
    text.append(s);
    return *this;
  }
  Json& operator<<(std::uint64_t v) {
    text += std::to_string(v);
    return *this;
  }
  Json& operator<<(int v) {
    text += std::to_string(v);
    return *this;
  }
  Json& operator<<(double v) {
    append_shortest(text, v);
    return *this;
  }
  Json& operator<<(const std::array<double, 3>& v) {
    return *this << "[" << v[0] << "," << v[1] << "," << v[2] << "]";
  }
};

std::string base64(std::span<const std::uint8_t> bytes) {
  static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    const std::size_t n = std::min<std::size_t>(3, bytes.size() - i);
    std::uint32_t v = 0;
    for (std::size_t k = 0; k < 3; ++k) v = (v << 8) | (k < n ? bytes[i + k] : 0u);
    for (std::size_t k = 0; k < 4; ++k) out += k <= n ? kAlphabet[(v >> (18 - 6 * k)) & 63u] : '=';
  }
  return out;
}

}  // namespace

std::string encode_gltf(const TriangleMeshData& mesh, bool binary, const std::vector<std::string>& comments,
                        const std::string& path) {
  const std::size_t n = mesh.positions.size(), t = mesh.triangles.size();
  const bool has_mesh = t > 0;
  for (std::size_t i = 0; i < n; ++i)
    for (const double c : mesh.positions[i])
      if (!std::isfinite(c))
        throw std::runtime_error(path + ": vertex " + std::to_string(i) +
                                 " is not finite (glTF's JSON cannot hold its bounds)");
  const std::uint64_t buffer_bytes =
      has_mesh ? 24 * std::uint64_t(n) + 3 * std::uint64_t(t) * (n <= kMaxShortVertices ? 2 : 4) : 0;
  if (buffer_bytes + 65536 > std::numeric_limits<std::uint32_t>::max())
    throw std::runtime_error(path + ": " + std::to_string(n) + " vertices and " + std::to_string(t) +
                             " triangles need " + std::to_string(buffer_bytes) +
                             " bytes, more than glTF's 4 GiB buffer (uint32 lengths)");

  // The bounding box's centre in glTF axes becomes the node's translation.
  Vec3 lo{0, 0, 0}, hi{0, 0, 0};
  if (has_mesh) {
    lo = hi = to_gltf(mesh.positions[0]);
    for (const Vec3& p : mesh.positions) {
      const Vec3 g = to_gltf(p);
      for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], g[k]), hi[k] = std::max(hi[k], g[k]);
    }
  }
  const Vec3 centre{0.5 * lo[0] + 0.5 * hi[0], 0.5 * lo[1] + 0.5 * hi[1], 0.5 * lo[2] + 0.5 * hi[2]};

  ByteWriter buffer;
  std::array<float, 3> fmin{}, fmax{};
  const bool short_indices = n <= kMaxShortVertices;
  if (has_mesh) {
    buffer.bytes.reserve(buffer_bytes);
    fmin.fill(std::numeric_limits<float>::infinity());
    fmax.fill(-std::numeric_limits<float>::infinity());
    for (const Vec3& p : mesh.positions) {
      const Vec3 g = to_gltf(p);
      for (int k = 0; k < 3; ++k) {
        const auto f = static_cast<float>(g[k] - centre[k]);
        fmin[k] = std::min(fmin[k], f);
        fmax[k] = std::max(fmax[k], f);
        buffer.f32(f);
      }
    }
    // Area-weighted normals: each triangle adds its cross product (twice its area times its
    // unit normal) to its three corners; from differences of the doubles, so that large world
    // coordinates lose nothing, in our frame, then rotated like the positions.
    std::vector<Vec3> normal(n, Vec3{0, 0, 0});
    for (const auto& tri : mesh.triangles) {
      const Vec3& a = mesh.positions[tri[0]];
      const Vec3& b = mesh.positions[tri[1]];
      const Vec3& c = mesh.positions[tri[2]];
      const Vec3 u{b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v{c[0] - a[0], c[1] - a[1], c[2] - a[2]};
      const Vec3 cr{u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
      for (const std::uint32_t i : tri)
        for (int k = 0; k < 3; ++k) normal[i][k] += cr[k];
    }
    for (const Vec3& nv : normal) {
      const Vec3 g = to_gltf(nv);
      const double len = std::sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
      const Vec3 unit =
          len > 0 && std::isfinite(len) ? Vec3{g[0] / len, g[1] / len, g[2] / len} : Vec3{0, 1, 0};
      for (int k = 0; k < 3; ++k) buffer.f32(static_cast<float>(unit[k]));
    }
    for (const auto& tri : mesh.triangles)
      for (const std::uint32_t i : tri) {
        if (short_indices)
          buffer.u16(static_cast<std::uint16_t>(i));
        else
          buffer.u32(i);
      }
  }

  Json j;
  j << R"({"asset":{"version":"2.0","generator":"terralod")";
  if (!comments.empty()) {
    j << R"(,"extras":{"comments":[)";
    for (std::size_t i = 0; i < comments.size(); ++i) j << (i ? "," : "") << json_quote(comments[i]);
    j << "]}";
  }
  j << R"(},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{)";
  if (!has_mesh) {
    j << "}]}";
  } else {
    const std::uint64_t vec3_bytes = 12 * std::uint64_t(n), index_bytes = buffer_bytes - 2 * vec3_bytes;
    const std::array<double, 3> min{fmin[0], fmin[1], fmin[2]}, max{fmax[0], fmax[1], fmax[2]};
    j << R"("mesh":0,"translation":)" << centre << "}]";
    j << R"(,"meshes":[{"primitives":[{"attributes":{"POSITION":0,"NORMAL":1},"indices":2,"mode":4}]}])";
    j << R"(,"accessors":[)";
    j << R"({"bufferView":0,"byteOffset":0,"componentType":)" << kFloat << R"(,"count":)" << std::uint64_t(n)
      << R"(,"type":"VEC3","min":)" << min << R"(,"max":)" << max << "},";
    j << R"({"bufferView":1,"byteOffset":0,"componentType":)" << kFloat << R"(,"count":)" << std::uint64_t(n)
      << R"(,"type":"VEC3"},)";
    j << R"({"bufferView":2,"byteOffset":0,"componentType":)"
      << (short_indices ? kUnsignedShort : kUnsignedInt) << R"(,"count":)" << 3 * std::uint64_t(t)
      << R"(,"type":"SCALAR"}])";
    j << R"(,"bufferViews":[)";
    j << R"({"buffer":0,"byteOffset":0,"byteLength":)" << vec3_bytes << R"(,"target":)" << kArrayBuffer
      << "},";
    j << R"({"buffer":0,"byteOffset":)" << vec3_bytes << R"(,"byteLength":)" << vec3_bytes << R"(,"target":)"
      << kArrayBuffer << "},";
    j << R"({"buffer":0,"byteOffset":)" << 2 * vec3_bytes << R"(,"byteLength":)" << index_bytes
      << R"(,"target":)" << kElementArrayBuffer << "}]";
    j << R"(,"buffers":[{"byteLength":)" << std::uint64_t(buffer.bytes.size());
    if (!binary) j << R"(,"uri":"data:application/octet-stream;base64,)" << base64(buffer.bytes) << "\"";
    j << "}]}";
  }
  std::string json = std::move(j.text);
  if (!binary) return json + "\n";

  return glb_container(std::move(json), has_mesh ? buffer.chars() : std::string_view(), path);
}

}  // namespace terralod::pm::detail

namespace terralod::pm {

std::string glb_container(std::string json, std::string_view bin, const std::string& path) {
  json.append((4 - json.size() % 4) % 4, ' ');
  const std::size_t bin_padded = (bin.size() + 3) / 4 * 4;
  const std::size_t total = 12 + 8 + json.size() + (bin.empty() ? 0 : 8 + bin_padded);
  if (total > std::numeric_limits<std::uint32_t>::max())
    throw std::runtime_error(path + ": " + std::to_string(total) +
                             " bytes, more than a GLB file's uint32 length can hold");
  ByteWriter head;  // the file header and the JSON chunk's
  head.u32(detail::kGlbMagic);
  head.u32(2);
  head.u32(static_cast<std::uint32_t>(total));
  head.u32(static_cast<std::uint32_t>(json.size()));
  head.u32(detail::kChunkJson);
  std::string out;
  out.reserve(total);
  out += head.chars();
  out += json;
  if (!bin.empty()) {
    ByteWriter chunk;  // the BIN chunk's header
    chunk.u32(static_cast<std::uint32_t>(bin_padded));
    chunk.u32(detail::kChunkBin);
    out += chunk.chars();
    out += bin;
    out.append(bin_padded - bin.size(), '\0');
  }
  return out;
}

}  // namespace terralod::pm
