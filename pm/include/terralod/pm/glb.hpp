// The GLB container of glTF 2.0 (binary glTF): what every .glb terralod writes is wrapped in.
//
// Usage:
//   std::string file = terralod::pm::glb_container(json_text, buffer_bytes, "tile.glb");
//
// Contract: a 12-byte header (magic "glTF", version 2, total length), the JSON chunk padded with
// spaces to 4 bytes, and, when `bin` is not empty, the BIN chunk padded with zeros to 4 bytes
// (the JSON's buffers[0].byteLength must be bin.size(), the caller's concern). std::runtime_error
// naming `path` when the file would pass the format's uint32 length.
#pragma once

#include <string>
#include <string_view>

namespace terralod::pm {

std::string glb_container(std::string json, std::string_view bin, const std::string& path);

}  // namespace terralod::pm
