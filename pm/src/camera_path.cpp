// Reader and writer of camera-path CSV files (see camera_path.hpp for the format).
#include "terralod/pm/camera_path.hpp"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "terralod/pm/atomic_file.hpp"
#include "terralod/pm/text.hpp"

namespace terralod::pm {

namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

[[noreturn]] void fail(const std::string& name, std::size_t line, const std::string& what) {
  throw std::runtime_error(name + ": line " + std::to_string(line) + ": " + what);
}

std::vector<std::string_view> split(std::string_view s) {
  std::vector<std::string_view> out;
  std::size_t start = 0;
  for (std::size_t i = 0; i <= s.size(); ++i)
    if (i == s.size() || s[i] == ',') {
      out.push_back(trim(s.substr(start, i - start)));
      start = i + 1;
    }
  return out;
}

std::string printable(std::string_view s) {
  std::string out;
  for (char c : s.substr(0, 40)) out += (c >= 32 && c < 127) ? c : '?';
  if (s.size() > 40) out += "...";
  return out;
}

}  // namespace

std::vector<Camera> parse_camera_path(std::string_view text, const std::string& name,
                                      const CameraPathOptions& o) {
  if (o.width_px < 1 || o.height_px < 1 || !(o.near_m > 0) || !(o.far_m > o.near_m))
    throw std::invalid_argument("camera path: bad viewport or clip options");
  static const char* const kNames[6] = {"x", "y", "z", "yaw", "pitch", "fovy"};
  std::vector<Camera> path;
  bool header = false;
  std::size_t line_no = 0, pos = text.size() - without_utf8_bom(text).size();
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view line = trim(text.substr(pos, end - pos));
    pos = end + 1;
    ++line_no;
    if (line.empty() || line.front() == '#') continue;
    const std::vector<std::string_view> f = split(line);
    if (!header) {
      bool ok = f.size() == 6;
      for (std::size_t i = 0; ok && i < 6; ++i) ok = f[i] == kNames[i];
      if (!ok)
        fail(name, line_no, "expected the header 'x,y,z,yaw,pitch,fovy', found '" + printable(line) + "'");
      header = true;
      continue;
    }
    if (f.size() != 6)
      fail(name, line_no,
           "expected 6 comma-separated numbers, found " + std::to_string(f.size()) + " fields");
    if (path.size() >= o.max_rows) fail(name, line_no, "more than " + std::to_string(o.max_rows) + " rows");
    double v[6];
    for (int i = 0; i < 6; ++i) {
      const std::string_view s = f[std::size_t(i)];
      const char* b = s.data();
      const char* e = s.data() + s.size();
      if (!s.empty() && *b == '+') ++b;
      const auto r = std::from_chars(b, e, v[i]);
      if (s.empty() || r.ec != std::errc() || r.ptr != e || !std::isfinite(v[i]))
        fail(name, line_no, std::string(kNames[i]) + " is not a finite number: '" + printable(s) + "'");
    }
    if (v[4] < -90.0 || v[4] > 90.0) fail(name, line_no, "pitch must be in [-90, 90] degrees");
    if (!(v[5] > 0.0 && v[5] < 180.0)) fail(name, line_no, "fovy must be in (0, 180) degrees");
    Camera c;
    c.x = v[0], c.y = v[1], c.z = v[2], c.yaw_deg = v[3], c.pitch_deg = v[4], c.fovy_deg = v[5];
    c.width_px = o.width_px, c.height_px = o.height_px, c.near_m = o.near_m, c.far_m = o.far_m;
    path.push_back(c);
  }
  if (!header) fail(name, line_no, "no header line 'x,y,z,yaw,pitch,fovy' (empty file?)");
  if (path.empty()) fail(name, line_no, "no camera rows after the header");
  return path;
}

std::vector<Camera> read_camera_path(const std::string& path, const CameraPathOptions& options) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw std::runtime_error(path + ": " +
                             (std::filesystem::exists(path, ec) ? "not a regular file" : "no such file"));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path + ": cannot open for reading");
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw std::runtime_error(path + ": read error");
  return parse_camera_path(ss.str(), path, options);
}

void write_camera_path(const std::vector<Camera>& path, const std::string& file) {
  std::string text = "x,y,z,yaw,pitch,fovy\n";
  char buf[64];
  for (const Camera& c : path) {
    const double v[6] = {c.x, c.y, c.z, c.yaw_deg, c.pitch_deg, c.fovy_deg};
    for (int i = 0; i < 6; ++i) {
      const auto r = std::to_chars(buf, buf + sizeof buf, v[i]);
      text.append(buf, r.ptr);
      text += i == 5 ? '\n' : ',';
    }
  }
  write_file_atomically(file, text);
}

}  // namespace terralod::pm
