// Independent quantized-mesh-1.0 reader (see quantized_mesh_reader.hpp).
#include "quantized_mesh_reader.hpp"

#include <zlib.h>

#include <cmath>
#include <cstring>
#include <stdexcept>

namespace terralod::test {
namespace {

std::vector<std::uint8_t> gunzip(std::span<const std::uint8_t> in) {
  z_stream zs{};
  if (inflateInit2(&zs, 15 + 32) != Z_OK) throw std::runtime_error("inflateInit2 failed");
  std::vector<std::uint8_t> out;
  std::uint8_t buf[65536];
  zs.next_in = const_cast<Bytef*>(in.data());
  zs.avail_in = uInt(in.size());
  int rc = Z_OK;
  while (rc != Z_STREAM_END) {
    zs.next_out = buf;
    zs.avail_out = sizeof buf;
    rc = inflate(&zs, Z_NO_FLUSH);
    if (rc != Z_OK && rc != Z_STREAM_END) {
      inflateEnd(&zs);
      throw std::runtime_error("gzip data is corrupt");
    }
    out.insert(out.end(), buf, buf + (sizeof buf - zs.avail_out));
  }
  inflateEnd(&zs);
  return out;
}

struct Cursor {
  std::span<const std::uint8_t> b;
  std::size_t at = 0;
  template <class T>
  T get(const char* what) {
    if (at + sizeof(T) > b.size()) throw std::runtime_error(std::string("tile ends inside ") + what);
    T v;
    std::memcpy(&v, b.data() + at, sizeof(T));
    at += sizeof(T);
    return v;
  }
};

}  // namespace

DecodedTile decode_quantized_mesh_tile(std::span<const std::uint8_t> raw) {
  std::vector<std::uint8_t> owned;
  if (raw.size() >= 2 && raw[0] == 0x1f && raw[1] == 0x8b) {
    owned = gunzip(raw);
    raw = owned;
  }
  Cursor c{raw};
  DecodedTile t;
  for (double& x : t.center) x = c.get<double>("the header");
  t.min_height = c.get<float>("the header");
  t.max_height = c.get<float>("the header");
  for (double& x : t.sphere) x = c.get<double>("the header");
  for (double& x : t.horizon) x = c.get<double>("the header");
  if (c.at != 88) throw std::runtime_error("header is not 88 bytes");
  const std::uint32_t n = c.get<std::uint32_t>("the vertex count");
  if (std::size_t(n) * 6 > raw.size() - c.at) throw std::runtime_error("vertex count larger than the tile");
  for (auto* a : {&t.u, &t.v, &t.h}) {
    int value = 0;
    for (std::uint32_t i = 0; i < n; ++i) {
      const std::uint16_t z = c.get<std::uint16_t>("the vertex data");
      value += (z >> 1) ^ (-(z & 1));
      if (value < 0 || value > 32767) throw std::runtime_error("vertex value outside 0..32767");
      a->push_back(value);
    }
  }
  t.wide_indices = n > 65536;
  const std::size_t align = t.wide_indices ? 4 : 2;
  while (c.at % align != 0) c.get<std::uint8_t>("the padding");
  auto index = [&](const char* what) -> std::uint32_t {
    return t.wide_indices ? c.get<std::uint32_t>(what) : c.get<std::uint16_t>(what);
  };
  const std::uint32_t nt = c.get<std::uint32_t>("the triangle count");
  if (std::size_t(nt) * 3 * (t.wide_indices ? 4 : 2) > raw.size() - c.at)
    throw std::runtime_error("triangle count larger than the tile");
  std::uint32_t highest = 0;
  for (std::uint32_t i = 0; i < nt; ++i) {
    std::array<std::uint32_t, 3> tri{};
    for (auto& x : tri) {
      const std::uint32_t code = index("the indices");
      if (code > highest) throw std::runtime_error("index code above the high-water mark");
      x = highest - code;
      if (code == 0) ++highest;
      if (x >= n) throw std::runtime_error("index past the vertices");
    }
    t.triangles.push_back(tri);
  }
  for (auto& e : t.edges) {
    const std::uint32_t m = c.get<std::uint32_t>("an edge count");
    if (m > n) throw std::runtime_error("edge list longer than the vertices");
    for (std::uint32_t i = 0; i < m; ++i) {
      e.push_back(index("an edge list"));
      if (e.back() >= n) throw std::runtime_error("edge index past the vertices");
    }
  }
  while (c.at < raw.size()) {
    const std::uint8_t id = c.get<std::uint8_t>("an extension header");
    const std::uint32_t len = c.get<std::uint32_t>("an extension header");
    if (len > raw.size() - c.at) throw std::runtime_error("extension longer than the tile");
    const std::size_t end = c.at + len;
    if (id == 1) {
      if (len != 2 * n) throw std::runtime_error("normals extension of the wrong length");
      for (std::uint32_t i = 0; i < n; ++i) {
        const std::uint8_t x = c.get<std::uint8_t>("normals");
        t.normals.push_back({x, c.get<std::uint8_t>("normals")});
      }
    } else if (id == 4) {
      const std::uint32_t jl = c.get<std::uint32_t>("metadata");
      if (jl + 4 != len) throw std::runtime_error("metadata length disagrees with its extension's");
      t.metadata.assign(reinterpret_cast<const char*>(raw.data() + c.at), jl);
    }
    c.at = end;
  }
  return t;
}

std::array<double, 3> oct_decode(std::uint8_t xb, std::uint8_t yb) {
  double x = xb / 255.0 * 2.0 - 1.0, y = yb / 255.0 * 2.0 - 1.0;
  const double z = 1.0 - (std::abs(x) + std::abs(y));
  if (z < 0) {
    const double ox = x;
    x = (1.0 - std::abs(y)) * (ox < 0 ? -1.0 : 1.0);
    y = (1.0 - std::abs(ox)) * (y < 0 ? -1.0 : 1.0);
  }
  const double l = std::sqrt(x * x + y * y + z * z);
  return {x / l, y / l, z / l};
}

}  // namespace terralod::test
