// Triangle mesh readers for TINs made by other tools: PLY (ascii, binary little- and big-endian)
// and Wavefront OBJ, with errors that name the file and the line or record that is wrong.
#include <algorithm>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string_view>

#include "terralod/pm/mesh_io.hpp"

namespace terralod::pm {

namespace {

/// The whole of a regular file. Only regular files: opening a FIFO would block, a device may
/// never end, and a folder makes the stream throw a message without the path.
std::string read_whole_file(const std::string& path) {
  std::error_code ec;
  const std::filesystem::file_status st = std::filesystem::status(path, ec);
  if (std::filesystem::exists(st) && !std::filesystem::is_regular_file(st))
    throw std::runtime_error(path + ": cannot read: not a regular file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path + ": cannot open: " + std::strerror(errno));
  std::string file((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw std::runtime_error(path + ": cannot read");
  return file;
}

/// Text split into lines with their 1-based numbers ('\n' or "\r\n" endings).
class Lines {
 public:
  Lines(std::string_view text, std::size_t first_line) : text_(text), next_number_(first_line) {}
  /// The next line without its ending; false at the end of the text.
  bool next(std::string_view& line, std::size_t& number) {
    if (pos_ >= text_.size()) return false;
    const std::size_t end = std::min(text_.find('\n', pos_), text_.size());
    line = text_.substr(pos_, end - pos_);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    number = next_number_++;
    pos_ = end + 1;
    return true;
  }
  /// The number the next line would have (one past the last line at the end).
  std::size_t next_number() const { return next_number_; }

 private:
  std::string_view text_;
  std::size_t pos_ = 0, next_number_;
};

/// The line's whitespace-separated words.
std::vector<std::string_view> words_of(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (true) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    if (i == line.size()) return out;
    const std::size_t start = i;
    while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    out.push_back(line.substr(start, i - start));
  }
}

bool parse_number(std::string_view s, double& out) {
  const auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

bool parse_integer(std::string_view s, long long& out) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  const auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

std::string quoted(std::string_view s) { return "'" + std::string(s.substr(0, 60)) + "'"; }

// ------------------------------------------------------------------------------ PLY

enum class Scalar { I8, U8, I16, U16, I32, U32, F32, F64 };
enum class Encoding { Ascii, BinaryLittle, BinaryBig };

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

bool is_integer(Scalar s) { return s != Scalar::F32 && s != Scalar::F64; }

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

/// The binary value at `p` of type `s`, stored in `encoding`'s byte order.
double read_scalar(const unsigned char* p, Scalar s, Encoding encoding) {
  unsigned char b[8];
  const std::size_t n = size_of(s);
  std::memcpy(b, p, n);
  if ((encoding == Encoding::BinaryBig) != (std::endian::native == std::endian::big)) std::reverse(b, b + n);
  auto get = [&b]<class T>(T) {
    T v;
    std::memcpy(&v, b, sizeof(T));
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

struct PlyHeader {
  Encoding encoding = Encoding::BinaryLittle;
  std::vector<Element> elements;
  std::size_t body = 0;       // byte offset of the first byte after end_header's line
  std::size_t body_line = 1;  // its line number (ascii)
};

bool is_face_indices(const Property& p) {
  return p.list && (p.name == "vertex_indices" || p.name == "vertex_index");
}

PlyHeader parse_ply_header(const std::string& file, const std::string& path) {
  auto fail = [&](const std::string& what) { return std::runtime_error(path + ": " + what); };
  if (file.compare(0, 4, "ply\n") != 0 && file.compare(0, 5, "ply\r\n") != 0)
    throw fail("not a PLY file (no 'ply' line)");
  std::size_t end = file.find("\nend_header");
  if (end == std::string::npos) throw fail("truncated PLY header (no end_header)");
  ++end;
  std::size_t body = file.find('\n', end);
  if (body == std::string::npos) throw fail("truncated PLY header (no end_header line end)");
  ++body;

  PlyHeader h;
  h.body = body;
  Lines lines(std::string_view(file).substr(0, end), 1);
  std::string_view view;
  std::size_t number = 0;
  bool format_ok = false;
  while (lines.next(view, number)) {
    const std::string line(view);
    auto bad = [&](const std::string& what) { return fail("line " + std::to_string(number) + ": " + what); };
    std::istringstream ls(line);
    std::string word;
    ls >> word;
    if (word.empty() || word == "ply" || word == "comment" || word == "obj_info") continue;
    if (word == "format") {
      std::string fmt, ver;
      ls >> fmt >> ver;
      if (fmt == "ascii")
        h.encoding = Encoding::Ascii;
      else if (fmt == "binary_little_endian")
        h.encoding = Encoding::BinaryLittle;
      else if (fmt == "binary_big_endian")
        h.encoding = Encoding::BinaryBig;
      else
        throw bad("PLY format '" + fmt +
                  "' is not supported (ascii, binary_little_endian or binary_big_endian)");
      if (ver != "1.0") throw bad("PLY version '" + ver + "' is not supported (only 1.0)");
      format_ok = true;
    } else if (word == "element") {
      Element e;
      long long count = -1;
      ls >> e.name >> count;
      if (!ls || count < 0) throw bad("bad PLY element line '" + line + "'");
      e.count = std::uint64_t(count);
      h.elements.push_back(std::move(e));
    } else if (word == "property") {
      if (h.elements.empty()) throw bad("PLY property before any element");
      Property p;
      std::string type;
      ls >> type;
      if (type == "list") {
        std::string ct, it;
        ls >> ct >> it >> p.name;
        p.list = true;
        if (!scalar_of(ct, p.count) || !scalar_of(it, p.type) || !is_integer(p.count))
          throw bad("bad PLY property line '" + line + "'");
      } else {
        ls >> p.name;
        if (!scalar_of(type, p.type)) throw bad("bad PLY property line '" + line + "'");
      }
      if (!ls) throw bad("bad PLY property line '" + line + "'");
      h.elements.back().props.push_back(std::move(p));
    } else {
      throw bad("unknown PLY header line '" + line + "'");
    }
  }
  if (!format_ok) throw fail("PLY header has no format line");
  h.body_line = lines.next_number() + 1;  // end_header's own line comes before the body

  bool have_vertices = false;
  for (const Element& e : h.elements) {
    if (e.name == "vertex") {
      have_vertices = true;
      bool x = false, y = false, z = false;
      for (const Property& p : e.props) {
        if (p.list) throw fail("list property " + p.name + " in the vertex element is not supported");
        x = x || p.name == "x";
        y = y || p.name == "y";
        z = z || p.name == "z";
      }
      if (!x || !y || !z) throw fail("vertex element lacks x, y or z");
    } else if (e.name == "face") {
      const auto lists = std::count_if(e.props.begin(), e.props.end(), is_face_indices);
      if (lists != 1)
        throw fail("face element needs one vertex_indices list, found " + std::to_string(lists));
      for (const Property& p : e.props)
        if (is_face_indices(p) && !is_integer(p.type)) throw fail("face indices must have an integer type");
    }
  }
  if (!have_vertices) throw fail("PLY file has no vertex element");
  return h;
}

/// Stores a face's three indices (any integer values; range-checked against the vertex count
/// at the end); `where` names the record for messages.
template <class Where>
void store_face(double k, const double* v, std::array<std::uint32_t, 3>& out, const Where& where,
                const std::string& path) {
  if (k != 3)
    throw std::runtime_error(path + ": " + where() + " has " + std::to_string(std::int64_t(k)) +
                             " vertices (only triangles are supported)");
  for (int c = 0; c < 3; ++c) {
    if (v[c] < 0 || v[c] > double(std::numeric_limits<std::uint32_t>::max()))
      throw std::runtime_error(path + ": " + where() + " has vertex index " +
                               std::to_string(std::int64_t(v[c])));
    out[std::size_t(c)] = std::uint32_t(v[c]);
  }
}

/// The body of a binary PLY (either byte order).
void read_ply_binary(const std::string& file, const PlyHeader& h, const std::string& path,
                     TriangleMeshData& out) {
  auto fail = [&](const std::string& what) { return std::runtime_error(path + ": " + what); };
  const auto* data = reinterpret_cast<const unsigned char*>(file.data());
  std::size_t pos = h.body;
  for (const Element& e : h.elements) {
    const std::size_t left = file.size() - pos;
    std::size_t fixed = 0;  // bytes per record outside lists; lists add at least their count
    for (const Property& p : e.props) fixed += size_of(p.list ? p.count : p.type);
    if (fixed == 0 ? e.count != 0 : e.count > left / fixed)
      throw fail("truncated: element " + e.name + " needs at least " + std::to_string(e.count) + " x " +
                 std::to_string(fixed) + " bytes, found " + std::to_string(left));
    if (e.name == "vertex") {
      out.positions.resize(e.count);
      for (auto& p : out.positions) {
        for (const Property& prop : e.props) {
          const double v = read_scalar(data + pos, prop.type, h.encoding);
          if (prop.name == "x") p[0] = v;
          if (prop.name == "y") p[1] = v;
          if (prop.name == "z") p[2] = v;
          pos += size_of(prop.type);
        }
      }
    } else if (e.name == "face") {
      out.triangles.resize(e.count);
      for (std::uint64_t f = 0; f < e.count; ++f) {
        auto where = [f] { return "element face record " + std::to_string(f); };
        for (const Property& p : e.props) {
          if (!p.list) {
            if (file.size() - pos < size_of(p.type)) throw fail("truncated: " + where());
            pos += size_of(p.type);
            continue;
          }
          if (file.size() - pos < size_of(p.count)) throw fail("truncated: " + where());
          const double k = read_scalar(data + pos, p.count, h.encoding);
          pos += size_of(p.count);
          if (k < 0 || double((file.size() - pos) / size_of(p.type)) < k) throw fail("truncated: " + where());
          if (!is_face_indices(p)) {
            pos += std::size_t(k) * size_of(p.type);
            continue;
          }
          double v[3] = {0, 0, 0};
          for (std::size_t c = 0; c < std::min<std::size_t>(3, std::size_t(k)); ++c)
            v[c] = read_scalar(data + pos + c * size_of(p.type), p.type, h.encoding);
          store_face(k, v, out.triangles[f], where, path);
          pos += 3 * size_of(p.type);
        }
      }
    } else {
      for (const Property& p : e.props)
        if (p.list) throw fail("list property " + p.name + " in element " + e.name + " is not supported");
      pos += std::size_t(e.count) * fixed;
    }
  }
  if (pos != file.size())
    throw fail(std::to_string(file.size() - pos) + " unexpected bytes after the last element");
}

/// The body of an ascii PLY: one record per line, values separated by spaces.
void read_ply_ascii(const std::string& file, const PlyHeader& h, const std::string& path,
                    TriangleMeshData& out) {
  auto fail = [&](const std::string& what) { return std::runtime_error(path + ": " + what); };
  const std::string_view body = std::string_view(file).substr(h.body);
  Lines lines(body, h.body_line);
  std::string_view line;
  std::size_t number = 0;
  for (const Element& e : h.elements) {
    // Every value takes at least one character and one separator (the last may lack it).
    const std::uint64_t values = std::max<std::size_t>(1, e.props.size());
    if (e.count > (body.size() + 1) / 2 / values)
      throw fail("truncated: element " + e.name + " declares " + std::to_string(e.count) + " records of " +
                 std::to_string(values) + " values, more than the " + std::to_string(body.size()) +
                 " bytes after the header hold");
    if (e.name == "vertex") out.positions.resize(e.count);
    if (e.name == "face") out.triangles.resize(e.count);
    for (std::uint64_t r = 0; r < e.count; ++r) {
      std::vector<std::string_view> words;
      while (words.empty()) {
        if (!lines.next(line, number))
          throw fail("truncated: the file ends at line " + std::to_string(lines.next_number() - 1) +
                     " before element " + e.name + " record " + std::to_string(r) + " of " +
                     std::to_string(e.count));
        words = words_of(line);
      }
      auto where = [&e, number, r] {
        return "line " + std::to_string(number) + " (element " + e.name + " record " + std::to_string(r) +
               ")";
      };
      std::size_t w = 0;
      auto value = [&](Scalar type, const std::string& what) {
        if (w == words.size()) throw fail(where() + ": too few values, " + what + " is missing");
        double v = 0;
        long long i = 0;
        const bool ok = is_integer(type) ? parse_integer(words[w], i) : parse_number(words[w], v);
        if (!ok) throw fail(where() + ": " + what + " " + quoted(words[w]) + " is not a number of its type");
        ++w;
        return is_integer(type) ? double(i) : v;
      };
      for (const Property& p : e.props) {
        if (!p.list) {
          const double v = value(p.type, p.name);
          if (e.name == "vertex") {
            if (p.name == "x") out.positions[r][0] = v;
            if (p.name == "y") out.positions[r][1] = v;
            if (p.name == "z") out.positions[r][2] = v;
          }
          continue;
        }
        const double k = value(p.count, p.name + "'s count");
        if (k < 0 || k > double(words.size() - w))
          throw fail(where() + ": " + p.name + " counts " + std::to_string(std::int64_t(k)) +
                     " values, the line has " + std::to_string(words.size() - w));
        double v[3] = {0, 0, 0};
        for (std::size_t c = 0; c < std::size_t(k); ++c) {
          const double x = value(p.type, p.name + " item");
          if (c < 3) v[c] = x;
        }
        if (e.name == "face" && is_face_indices(p)) store_face(k, v, out.triangles[r], where, path);
      }
      if (w != words.size())
        throw fail(where() + ": " + std::to_string(words.size() - w) + " values too many");
    }
  }
  while (lines.next(line, number))
    if (!words_of(line).empty())
      throw fail("line " + std::to_string(number) + ": data after the last element");
}

/// Range checks shared by the readers: finite coordinates, indices below the vertex count.
void check_mesh(const TriangleMeshData& m, const std::string& path) {
  for (std::size_t i = 0; i < m.positions.size(); ++i)
    for (const double c : m.positions[i])
      if (!std::isfinite(c))
        throw std::runtime_error(path + ": vertex " + std::to_string(i) +
                                 " has a coordinate that is not finite");
  for (std::size_t f = 0; f < m.triangles.size(); ++f)
    for (std::uint32_t v : m.triangles[f])
      if (v >= m.positions.size())
        throw std::runtime_error(path + ": face " + std::to_string(f) + " refers to vertex " +
                                 std::to_string(v) + " of " + std::to_string(m.positions.size()));
}

// ------------------------------------------------------------------------------ OBJ

/// A face corner "a", "a/b", "a/b/c" or "a//c": the 0-based vertex index of `a` (negative =
/// relative to the `defined` vertices so far); b and c must be integers or (c's b) empty.
std::uint32_t obj_corner(std::string_view corner, std::size_t defined, const std::string& path,
                         std::size_t line) {
  const auto where = [&] { return path + ": line " + std::to_string(line); };
  std::string_view parts[3];
  std::size_t n = 0, start = 0;
  while (true) {
    const std::size_t slash = corner.find('/', start);
    if (n == 3)
      throw std::runtime_error(where() + ": face corner " + quoted(corner) + " has more than 3 parts");
    parts[n++] =
        corner.substr(start, slash == std::string_view::npos ? std::string_view::npos : slash - start);
    if (slash == std::string_view::npos) break;
    start = slash + 1;
  }
  long long a = 0, other = 0;
  if (!parse_integer(parts[0], a))
    throw std::runtime_error(where() + ": face corner " + quoted(corner) +
                             " does not start with a vertex index");
  for (std::size_t i = 1; i < n; ++i)
    if ((i == 2 || !parts[i].empty() || n == 2) && !parse_integer(parts[i], other))
      throw std::runtime_error(where() + ": face corner " + quoted(corner) + " is not a, a/b, a/b/c or a//c");
  const long long count = static_cast<long long>(defined);
  const long long index = a > 0 ? a - 1 : count + a;  // a = -1: the last vertex so far
  if (a == 0 || index < 0 || index >= count)
    throw std::runtime_error(where() + ": face corner " + quoted(corner) + " refers to vertex " +
                             std::to_string(a) + ", but " + std::to_string(defined) +
                             " vertices are defined before it");
  return std::uint32_t(index);
}

}  // namespace

TriangleMeshData read_ply(const std::string& path) {
  const std::string file = read_whole_file(path);
  const PlyHeader h = parse_ply_header(file, path);
  TriangleMeshData out;
  if (h.encoding == Encoding::Ascii)
    read_ply_ascii(file, h, path, out);
  else
    read_ply_binary(file, h, path, out);
  check_mesh(out, path);
  return out;
}

TriangleMeshData read_obj(const std::string& path) {
  const std::string file = read_whole_file(path);
  TriangleMeshData out;
  Lines lines(file, 1);
  std::string_view line;
  std::size_t number = 0;
  std::vector<std::uint32_t> corners;
  while (lines.next(line, number)) {
    line = line.substr(0, line.find('#'));
    const std::vector<std::string_view> words = words_of(line);
    if (words.empty()) continue;
    const auto where = [&] { return path + ": line " + std::to_string(number); };
    if (words[0] == "v") {
      if (words.size() < 4 || words.size() > 8)
        throw std::runtime_error(where() + ": a 'v' line needs x y z (and at most w or r g b [a]), found " +
                                 std::to_string(words.size() - 1) + " values");
      std::array<double, 3> p{};
      for (std::size_t i = 1; i < words.size(); ++i) {
        double v = 0;
        if (!parse_number(words[i], v) || !std::isfinite(v))
          throw std::runtime_error(where() + ": " + quoted(words[i]) + " is not a finite number");
        if (i <= 3) p[i - 1] = v;
      }
      if (out.positions.size() == std::numeric_limits<std::uint32_t>::max())
        throw std::runtime_error(where() + ": more than 2^32 - 1 vertices");
      out.positions.push_back(p);
    } else if (words[0] == "f") {
      if (words.size() < 4)
        throw std::runtime_error(where() + ": a face needs at least 3 corners, found " +
                                 std::to_string(words.size() - 1));
      corners.clear();
      for (std::size_t i = 1; i < words.size(); ++i)
        corners.push_back(obj_corner(words[i], out.positions.size(), path, number));
      for (std::size_t i = 1; i + 1 < corners.size(); ++i)
        out.triangles.push_back({corners[0], corners[i], corners[i + 1]});
    }
  }
  if (out.positions.empty())
    throw std::runtime_error(path + ": no vertices ('v' lines): not a Wavefront OBJ mesh");
  return out;
}

TriangleMeshData read_mesh(const std::string& path) {
  const std::optional<MeshFormat> format = mesh_format_of(path);
  if (format == MeshFormat::Ply) return read_ply(path);
  if (format == MeshFormat::Obj) return read_obj(path);
  throw std::runtime_error(path + ": cannot read this mesh format (the name must end in " +
                           std::string(kMeshReadExtensions) + ")");
}

}  // namespace terralod::pm
