// Triangle mesh files: the writers (binary PLY, OBJ; glTF through gltf_writer.cpp) in sample or
// world units, chosen by extension, each written atomically. The readers are in mesh_reader.cpp.
#include "terralod/pm/mesh_io.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <sstream>
#include <stdexcept>

#include "gltf_writer.hpp"
#include "shortest_decimal.hpp"
#include "terralod/pm/atomic_file.hpp"
#include "terralod/pm/byte_io.hpp"

namespace terralod::pm {

namespace {

/// The format write_mesh writes to `path`; std::runtime_error naming it for any other extension.
MeshFormat write_format_of(const std::string& path) {
  if (const std::optional<MeshFormat> f = mesh_format_of(path)) return *f;
  throw std::runtime_error(path + ": unknown mesh format (the name must end in " +
                           std::string(kMeshWriteExtensions) + ")");
}

std::vector<std::uint8_t> encode_ply(const TriangleMeshData& m, const std::vector<std::string>& comments) {
  std::string header = "ply\nformat binary_little_endian 1.0\n";
  for (const std::string& c : comments) header += "comment " + c + "\n";
  header += "element vertex " + std::to_string(m.positions.size()) +
            "\nproperty double x\nproperty double y\nproperty double z\n"
            "element face " +
            std::to_string(m.triangles.size()) + "\nproperty list uchar int vertex_indices\nend_header\n";
  ByteWriter out;
  out.bytes.reserve(header.size() + 24 * m.positions.size() + 13 * m.triangles.size());
  out.raw(header.data(), header.size());
  for (const auto& p : m.positions)
    for (double v : p) out.f64(v);
  for (const auto& t : m.triangles) {
    out.u8(3);
    for (std::uint32_t v : t) out.i32(std::int32_t(v));
  }
  return std::move(out.bytes);
}

std::string encode_obj(const TriangleMeshData& m, const std::vector<std::string>& comments) {
  std::string out;
  for (const std::string& c : comments) out += "# " + c + "\n";
  out.reserve(out.size() + 40 * m.positions.size() + 24 * m.triangles.size());
  for (const auto& p : m.positions) {
    out += "v ";
    detail::append_shortest(out, p[0]);
    out += ' ';
    detail::append_shortest(out, p[1]);
    out += ' ';
    detail::append_shortest(out, p[2]);
    out += '\n';
  }
  for (const auto& t : m.triangles) {
    out += "f " + std::to_string(std::uint64_t(t[0]) + 1) + ' ' + std::to_string(std::uint64_t(t[1]) + 1) +
           ' ' + std::to_string(std::uint64_t(t[2]) + 1) + '\n';
  }
  return out;
}

void write_data(const TriangleMeshData& m, const std::string& path,
                const std::vector<std::string>& comments) {
  const MeshFormat fmt = write_format_of(path);
  for (std::size_t i = 0; i < m.triangles.size(); ++i)
    for (std::uint32_t v : m.triangles[i])
      if (v >= m.positions.size() || v > 0x7fffffffu)
        throw std::invalid_argument(path + ": triangle " + std::to_string(i) + " refers to vertex " +
                                    std::to_string(v) + " of " + std::to_string(m.positions.size()));
  switch (fmt) {
    case MeshFormat::Ply:
      return write_file_atomically(path, encode_ply(m, comments));
    case MeshFormat::Obj:
      return write_file_atomically(path, encode_obj(m, comments));
    case MeshFormat::Glb:
    case MeshFormat::Gltf:
      return write_file_atomically(path,
                                   detail::encode_gltf(m, /*binary=*/fmt == MeshFormat::Glb, comments, path));
  }
}

}  // namespace

std::optional<MeshFormat> mesh_format_of(const std::string& path) {
  const std::size_t dot = path.find_last_of('.');
  const std::size_t slash = path.find_last_of('/');
  std::string ext =
      dot == std::string::npos || (slash != std::string::npos && dot < slash) ? "" : path.substr(dot + 1);
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char ch) { return char(std::tolower(ch)); });
  if (ext == "ply") return MeshFormat::Ply;
  if (ext == "obj") return MeshFormat::Obj;
  if (ext == "glb") return MeshFormat::Glb;
  if (ext == "gltf") return MeshFormat::Gltf;
  return std::nullopt;
}

TriangleMeshData mesh_positions(const TriangleMesh& mesh, const Heightfield& hf, Units units) {
  TriangleMeshData out;
  const auto W = std::uint32_t(hf.width());
  out.positions.reserve(mesh.vertices.size());
  for (std::uint32_t s : mesh.vertices) {
    const double col = double(s % W), row = double(s / W);
    if (units == Units::World) {
      const auto [x, y] = hf.transform.to_world(col, row);
      out.positions.push_back({x, y, hf[s]});
    } else {
      out.positions.push_back({col, row, hf[s]});
    }
  }
  out.triangles = mesh.triangles;
  if (units == Units::World && hf.transform.determinant() < 0)
    for (auto& t : out.triangles) std::swap(t[1], t[2]);
  return out;
}

void write_mesh(const TriangleMesh& mesh, const Heightfield& hf, const std::string& path, Units units) {
  write_format_of(path);  // fail before doing any work
  for (std::uint32_t s : mesh.vertices)
    if (s >= hf.size())
      throw std::invalid_argument(path + ": mesh vertex " + std::to_string(s) +
                                  " is not a sample of the heightfield");
  std::ostringstream bound;
  bound.precision(17);
  bound << mesh.error_bound;
  write_data(
      mesh_positions(mesh, hf, units), path,
      {"terralod mesh",
       std::string("units ") + (units == Units::World ? "world (metres)" : "samples (col, row, metres)"),
       "error_bound " + bound.str()});
}

void write_mesh(const TriangleMeshData& mesh, const std::string& path) {
  write_data(mesh, path, {"terralod mesh"});
}

}  // namespace terralod::pm
