// Byte and text encoding shared by the mesh writers (mesh_io.cpp, gltf_writer.cpp).
//
// Contract:
//   append_le(out, v)        appends the sizeof(T) bytes of the arithmetic value v, little-endian
//                            (the host is little-endian: checked at compile time).
//   append_shortest(out, v)  appends the shortest decimal that reads back to the same double
//                            (std::to_chars); "nan" / "inf" for values that are not finite,
//                            which JSON writers must refuse before calling it.
#pragma once

#include <bit>
#include <charconv>
#include <cstring>
#include <string>
#include <type_traits>

namespace terralod::pm::detail {

static_assert(std::endian::native == std::endian::little, "the mesh writers store little-endian by memcpy");

template <class T>
void append_le(std::string& out, T v) {
  static_assert(std::is_arithmetic_v<T>);
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  out.append(b, sizeof(T));
}

inline void append_shortest(std::string& out, double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}

}  // namespace terralod::pm::detail
