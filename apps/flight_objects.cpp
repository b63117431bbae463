// The map objects of the flight tools (see flight_objects.hpp).
#include "flight_objects.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <set>
#include <stdexcept>

namespace terralod::cli {

namespace {

// A CSV field: as is, or quoted with doubled quotes when it holds a comma, quote or line break.
std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\r\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

}  // namespace

OptionSpec objects_option_spec() {
  return {"--objects", "NAME",
          "object layer of --db ('terralod objects add') placed on the drawn terrain (repeatable)", false,
          true};
}

std::optional<blocks::ObjectPlacer> object_placer(const Args& a, const std::string& db_path) {
  const std::vector<std::string> names = a.get_all("--objects");
  if (names.empty()) return std::nullopt;
  std::set<std::string> seen;
  for (const std::string& n : names)
    if (!seen.insert(n).second) throw UsageError("--objects " + n + " is given twice");
  return blocks::ObjectPlacer(blocks::BlockDatabase::open(db_path), names);
}

void write_objects_csv(const std::vector<blocks::PlacedObject>& placed, const blocks::TerrainRuntime& rt,
                       const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (!f) throw std::runtime_error(path + ": cannot write (" + std::strerror(errno) + ")");
  std::fprintf(f, "name,kind,x,y,z,ground_z\n");
  for (const blocks::PlacedObject& p : placed)
    std::fprintf(f, "%s,%s,%.17g,%.17g,%.17g,%.17g\n", csv_field(p.object->name).c_str(),
                 blocks::representation_name(p.draw).c_str(), p.anchor.x, p.anchor.y, p.anchor.z,
                 rt.drawn_height(p.anchor.x, p.anchor.y));
  if (std::fclose(f) != 0) throw std::runtime_error(path + ": cannot write (" + std::strerror(errno) + ")");
}

std::string objects_line(const blocks::ObjectPlacer& placer, bool timings) {
  std::string s = strf("objects %zu in view", placer.placed().size());
  if (timings) s += strf(" (%.2f ms)", placer.stats().place_ms);
  s += "   layers";
  for (const blocks::ObjectLayerInfo& l : placer.layers())
    s += strf("  %s%s", l.name.c_str(), placer.layer_visible(l.name) ? "" : "(off)");
  return s;
}

std::vector<std::string> pick_lines(const std::optional<blocks::PickResult>& pick,
                                    const blocks::ObjectPlacer& placer, std::size_t width) {
  if (!pick) return {"picked: nothing (the ray meets no object and no drawn terrain)"};
  const pm::Vec3& p = pick->point;
  if (!pick->object) return {strf("picked: ground at x %.1f  y %.1f  z %.2f m", p.x, p.y, p.z)};
  const blocks::MapObject& m = *pick->object;
  std::vector<std::string> lines = {strf("picked: %s (%s of layer %s, feature %lld) at z %.2f m",
                                         m.name.c_str(), blocks::kind_name(m.kind).c_str(),
                                         placer.layers()[m.layer].name.c_str(), (long long)m.feature.id,
                                         p.z)};
  std::string line;  // attributes, wrapped
  for (const blocks::ObjectAttribute& at : m.feature.attributes) {
    const std::string item = strf("  %s=%s", at.name.c_str(), at.value.c_str());
    if (!line.empty() && line.size() + item.size() > width) {
      lines.push_back(line);
      line.clear();
    }
    line += item;
  }
  if (!line.empty()) lines.push_back(line);
  return lines;
}

}  // namespace terralod::cli
