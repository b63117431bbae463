// The shortest decimal text of a double, shared by the text mesh writers (OBJ in mesh_io.cpp,
// the glTF JSON in gltf_writer.cpp); their binary parts go through byte_io.hpp.
//
// Contract:
//   append_shortest(out, v)  appends the shortest decimal that reads back to the same double
//                            (std::to_chars); "nan" / "inf" for values that are not finite,
//                            which JSON writers must refuse before calling it.
#pragma once

#include <charconv>
#include <string>

namespace terralod::pm::detail {

inline void append_shortest(std::string& out, double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}

}  // namespace terralod::pm::detail
