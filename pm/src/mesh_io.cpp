// Triangle mesh files: binary PLY and OBJ writers (sample or world units), binary PLY reader.
#include "terralod/pm/mesh_io.hpp"

#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace terralod::pm {

namespace {

enum class Format { Ply, Obj };

Format format_of(const std::string& path) {
  const std::size_t dot = path.find_last_of('.');
  const std::size_t slash = path.find_last_of('/');
  std::string ext =
      dot == std::string::npos || (slash != std::string::npos && dot < slash) ? "" : path.substr(dot + 1);
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char ch) { return char(std::tolower(ch)); });
  if (ext == "ply") return Format::Ply;
  if (ext == "obj") return Format::Obj;
  throw std::runtime_error(path + ": unknown mesh format (the name must end in .ply or .obj)");
}

/// Writes `bytes` to path + ".tmp", syncs it, and renames it onto `path`.
void write_file_atomically(const std::string& path, const std::string& bytes) {
  const std::string tmp = path + ".tmp";
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (!f) throw std::runtime_error(path + ": cannot write " + tmp + ": " + std::strerror(errno));
  bool ok = std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
  ok = std::fflush(f) == 0 && ok;
  ok = ::fsync(::fileno(f)) == 0 && ok;
  const int err = errno;
  ok = std::fclose(f) == 0 && ok;
  if (!ok) {
    std::remove(tmp.c_str());
    throw std::runtime_error(path + ": cannot write " + tmp + ": " + std::strerror(err ? err : errno));
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const int e = errno;
    std::remove(tmp.c_str());
    throw std::runtime_error(path + ": cannot rename " + tmp + " onto it: " + std::strerror(e));
  }
}

template <class T>
void append_le(std::string& out, T v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));  // the host is little-endian (checked below)
  out.append(b, sizeof(T));
}
static_assert(std::endian::native == std::endian::little, "mesh_io writes little-endian PLY by memcpy");

std::string encode_ply(const TriangleMeshData& m, const std::vector<std::string>& comments) {
  std::string out = "ply\nformat binary_little_endian 1.0\n";
  for (const std::string& c : comments) out += "comment " + c + "\n";
  out += "element vertex " + std::to_string(m.positions.size()) +
         "\nproperty double x\nproperty double y\nproperty double z\n"
         "element face " +
         std::to_string(m.triangles.size()) + "\nproperty list uchar int vertex_indices\nend_header\n";
  out.reserve(out.size() + 24 * m.positions.size() + 13 * m.triangles.size());
  for (const auto& p : m.positions)
    for (double v : p) append_le(out, v);
  for (const auto& t : m.triangles) {
    out.push_back(char(3));
    for (std::uint32_t v : t) append_le(out, std::int32_t(v));
  }
  return out;
}

void append_double(std::string& out, double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);  // shortest exact round trip
  out.append(buf, r.ptr);
}

std::string encode_obj(const TriangleMeshData& m, const std::vector<std::string>& comments) {
  std::string out;
  for (const std::string& c : comments) out += "# " + c + "\n";
  out.reserve(out.size() + 40 * m.positions.size() + 24 * m.triangles.size());
  for (const auto& p : m.positions) {
    out += "v ";
    append_double(out, p[0]);
    out += ' ';
    append_double(out, p[1]);
    out += ' ';
    append_double(out, p[2]);
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
  const Format fmt = format_of(path);
  for (std::size_t i = 0; i < m.triangles.size(); ++i)
    for (std::uint32_t v : m.triangles[i])
      if (v >= m.positions.size() || v > 0x7fffffffu)
        throw std::invalid_argument(path + ": triangle " + std::to_string(i) + " refers to vertex " +
                                    std::to_string(v) + " of " + std::to_string(m.positions.size()));
  write_file_atomically(path, fmt == Format::Ply ? encode_ply(m, comments) : encode_obj(m, comments));
}

// ------------------------------------------------------------------------------ PLY reading

enum class Scalar { I8, U8, I16, U16, I32, U32, F32, F64 };

bool scalar_of(const std::string& s, Scalar& out) {
  static const std::pair<const char*, Scalar> names[] = {
      {"char", Scalar::I8},   {"int8", Scalar::I8},     {"uchar", Scalar::U8},   {"uint8", Scalar::U8},
      {"short", Scalar::I16}, {"int16", Scalar::I16},   {"ushort", Scalar::U16}, {"uint16", Scalar::U16},
      {"int", Scalar::I32},   {"int32", Scalar::I32},   {"uint", Scalar::U32},   {"uint32", Scalar::U32},
      {"float", Scalar::F32}, {"float32", Scalar::F32}, {"double", Scalar::F64}, {"float64", Scalar::F64}};
  for (const auto& [name, type] : names)
    if (s == name) return out = type, true;
  return false;
}

std::size_t size_of(Scalar s) {
  switch (s) {
    case Scalar::I8:
    case Scalar::U8:
      return 1;
    case Scalar::I16:
    case Scalar::U16:
      return 2;
    case Scalar::I32:
    case Scalar::U32:
    case Scalar::F32:
      return 4;
    case Scalar::F64:
      return 8;
  }
  return 0;
}

double read_scalar(const unsigned char* p, Scalar s) {
  auto get = [p]<class T>(T) {
    T v;
    std::memcpy(&v, p, sizeof(T));
    return double(v);
  };
  switch (s) {
    case Scalar::I8:
      return get(std::int8_t{});
    case Scalar::U8:
      return get(std::uint8_t{});
    case Scalar::I16:
      return get(std::int16_t{});
    case Scalar::U16:
      return get(std::uint16_t{});
    case Scalar::I32:
      return get(std::int32_t{});
    case Scalar::U32:
      return get(std::uint32_t{});
    case Scalar::F32:
      return get(float{});
    case Scalar::F64:
      return get(double{});
  }
  return 0.0;
}

struct Property {
  std::string name;
  bool list = false;
  Scalar type = Scalar::F64;  // scalar type, or the list's item type
  Scalar count = Scalar::U8;  // list count type
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> props;
};

}  // namespace

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
  format_of(path);  // fail before doing any work
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

TriangleMeshData read_ply(const std::string& path) {
  auto fail = [&](const std::string& what) -> std::runtime_error {
    return std::runtime_error(path + ": " + what);
  };
  // Only regular files: opening a FIFO would block, a device may never end, and a folder makes
  // the stream throw a message without the path.
  std::error_code ec;
  const std::filesystem::file_status st = std::filesystem::status(path, ec);
  if (std::filesystem::exists(st) && !std::filesystem::is_regular_file(st))
    throw fail("cannot read: not a regular file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw fail(std::string("cannot open: ") + std::strerror(errno));
  const std::string file((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw fail("cannot read");

  // Header: text lines up to "end_header".
  std::size_t end = file.find("\nend_header");
  if (end != std::string::npos) ++end;
  if (file.compare(0, 4, "ply\n") != 0 && file.compare(0, 5, "ply\r\n") != 0)
    throw fail("not a PLY file (no 'ply' line)");
  if (end == std::string::npos) throw fail("truncated PLY header (no end_header)");
  std::size_t body = file.find('\n', end);
  if (body == std::string::npos) throw fail("truncated PLY header (no end_header line end)");
  ++body;
  std::istringstream header(file.substr(0, end));
  std::string line;
  std::vector<Element> elements;
  bool format_ok = false;
  while (std::getline(header, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream ls(line);
    std::string word;
    ls >> word;
    if (word.empty() || word == "ply" || word == "comment" || word == "obj_info") continue;
    if (word == "format") {
      std::string fmt, ver;
      ls >> fmt >> ver;
      if (fmt != "binary_little_endian")
        throw fail("PLY format '" + fmt + "' is not supported (only binary_little_endian)");
      format_ok = true;
    } else if (word == "element") {
      Element e;
      long long count = -1;
      ls >> e.name >> count;
      if (!ls || count < 0) throw fail("bad PLY element line '" + line + "'");
      e.count = std::uint64_t(count);
      elements.push_back(std::move(e));
    } else if (word == "property") {
      if (elements.empty()) throw fail("PLY property before any element");
      Property p;
      std::string type;
      ls >> type;
      if (type == "list") {
        std::string ct, it;
        ls >> ct >> it >> p.name;
        p.list = true;
        if (!scalar_of(ct, p.count) || !scalar_of(it, p.type))
          throw fail("bad PLY property line '" + line + "'");
      } else {
        ls >> p.name;
        if (!scalar_of(type, p.type)) throw fail("bad PLY property line '" + line + "'");
      }
      if (!ls) throw fail("bad PLY property line '" + line + "'");
      elements.back().props.push_back(std::move(p));
    } else {
      throw fail("unknown PLY header line '" + line + "'");
    }
  }
  if (!format_ok) throw fail("PLY header has no format line");

  TriangleMeshData out;
  const auto* data = reinterpret_cast<const unsigned char*>(file.data());
  std::size_t pos = body;
  bool have_vertices = false;
  for (const Element& e : elements) {
    const std::size_t left = file.size() - pos;
    std::size_t fixed = 0;  // bytes per record outside lists; lists add at least their count
    for (const Property& p : e.props) fixed += size_of(p.list ? p.count : p.type);
    if (fixed == 0 ? e.count != 0 : e.count > left / fixed)
      throw fail("truncated: element " + e.name + " needs at least " + std::to_string(e.count) + " x " +
                 std::to_string(fixed) + " bytes, found " + std::to_string(left));
    if (e.name == "vertex") {
      int ix = -1, iy = -1, iz = -1;
      for (std::size_t i = 0; i < e.props.size(); ++i) {
        if (e.props[i].list) throw fail("list property in the vertex element is not supported");
        if (e.props[i].name == "x") ix = int(i);
        if (e.props[i].name == "y") iy = int(i);
        if (e.props[i].name == "z") iz = int(i);
      }
      if (ix < 0 || iy < 0 || iz < 0) throw fail("vertex element lacks x, y or z");
      out.positions.resize(e.count);
      for (auto& p : out.positions) {
        for (std::size_t i = 0; i < e.props.size(); ++i) {
          const double v = read_scalar(data + pos, e.props[i].type);
          if (int(i) == ix) p[0] = v;
          if (int(i) == iy) p[1] = v;
          if (int(i) == iz) p[2] = v;
          pos += size_of(e.props[i].type);
        }
      }
      have_vertices = true;
    } else if (e.name == "face") {
      out.triangles.resize(e.count);
      for (std::uint64_t f = 0; f < e.count; ++f) {
        bool got = false;
        for (const Property& p : e.props) {
          if (!p.list) {
            if (file.size() - pos < size_of(p.type)) throw fail("truncated face data");
            pos += size_of(p.type);
            continue;
          }
          if (file.size() - pos < size_of(p.count)) throw fail("truncated face data");
          const double k = read_scalar(data + pos, p.count);
          pos += size_of(p.count);
          if (p.name != "vertex_indices" && p.name != "vertex_index") {
            if (k < 0 || (file.size() - pos) / size_of(p.type) < k) throw fail("truncated face data");
            pos += std::size_t(k) * size_of(p.type);
            continue;
          }
          if (k != 3)
            throw fail("face " + std::to_string(f) + " has " + std::to_string(k) +
                       " vertices (only triangles are supported)");
          if (file.size() - pos < 3 * size_of(p.type)) throw fail("truncated face data");
          if (p.type != Scalar::I32 && p.type != Scalar::U32) throw fail("face indices must be int or uint");
          for (int c = 0; c < 3; ++c) {
            const double v = read_scalar(data + pos, p.type);
            pos += size_of(p.type);
            if (v < 0) throw fail("face " + std::to_string(f) + " has a negative vertex index");
            out.triangles[f][std::size_t(c)] = std::uint32_t(v);
          }
          got = true;
        }
        if (!got) throw fail("face element has no vertex_indices list");
      }
    } else {
      for (const Property& p : e.props)
        if (p.list) throw fail("list property in element " + e.name + " is not supported");
      pos += std::size_t(e.count) * fixed;
    }
  }
  if (!have_vertices) throw fail("PLY file has no vertex element");
  if (pos != file.size())
    throw fail(std::to_string(file.size() - pos) + " unexpected bytes after the last element");
  for (std::size_t f = 0; f < out.triangles.size(); ++f)
    for (std::uint32_t v : out.triangles[f])
      if (v >= out.positions.size())
        throw fail("face " + std::to_string(f) + " refers to vertex " + std::to_string(v) + " of " +
                   std::to_string(out.positions.size()));
  return out;
}

}  // namespace terralod::pm
