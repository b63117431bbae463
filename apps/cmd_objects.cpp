// terralod objects add|list: object layers of a block database (GIS vector features placed in
// the terrain's world frame, blocks/object_layers.hpp). Parsing and printing only.
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <optional>
#include <sstream>
#include <string>

#include "commands.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/object_layers.hpp"

namespace terralod::cli {
namespace {

namespace tb = terralod::blocks;
using Clock = std::chrono::steady_clock;

std::string read_rules(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::ostringstream text;
  if (f) text << f.rdbuf();
  if (!f || f.bad()) throw UsageError("option '--rules': " + path + ": cannot be read");
  return text.str();
}

int objects_add(const Args& a, const std::string& path) {
  if (!a.has("--layer")) throw UsageError("'objects add' needs --layer NAME");
  if (!a.has("--input")) throw UsageError("'objects add' needs --input FILE");
  tb::ObjectLayerOptions o;
  o.name = a.get("--layer");
  o.input = a.get("--input");
  if (a.has("--kind"))
    o.kind = tb::parse_kind(a.get_choice("--kind", {"icon", "label", "shape", "line"}, "icon"));
  if (a.has("--geometry"))
    o.geometry = tb::parse_geometry(a.get_choice("--geometry", {"point", "line", "polygon"}, "point"));
  o.source_layer = a.get("--source-layer");
  o.label_field = a.get("--label-field");
  o.height_field = a.get("--height-field");
  if (a.has("--rules")) {
    o.rules_source = a.get("--rules");
    o.rules_json = read_rules(o.rules_source);  // before the database is opened
  }
  auto db = tb::BlockDatabase::open(path, tb::BlockDatabase::Mode::ReadWrite);
  tb::ObjectLayerReport r;
  try {
    ProgressBar bar("read " + o.input);
    o.progress = [&](double f) { bar.update(f); };
    r = tb::add_object_layer(db, o);
  } catch (const tb::ObjectLayerError& e) {
    if (e.cause() == tb::ObjectLayerError::Cause::Option) throw UsageError(e.what());
    throw;
  }
  const tb::ObjectLayerInfo& l = r.layer;
  const std::string others =
      o.geometry ? strf(", %lld parts of other types left out", static_cast<long long>(r.other_geometry))
                 : "";
  print_line(strf(
      "read %s: %lld features (%lld without geometry, skipped%s) in %s -> %lld %s parts, %lld points, %s",
      l.source.c_str(), static_cast<long long>(r.source_features), static_cast<long long>(l.skipped),
      others.c_str(), r.source_crs_name.c_str(), static_cast<long long>(l.feature_count),
      tb::geometry_name(l.geometry).c_str(), static_cast<long long>(r.points),
      format_duration(r.read_ms).c_str()));
  print_line(strf("store object layer '%s' (%s): %lld features, %lld block index entries -> %s, %s",
                  l.name.c_str(), tb::kind_name(l.kind).c_str(), static_cast<long long>(l.feature_count),
                  static_cast<long long>(r.block_entries), path.c_str(),
                  format_duration(r.write_ms).c_str()));
  return 0;
}

int objects_list(const std::string& path) {
  const auto db = tb::BlockDatabase::open(path);
  const auto layers = tb::object_layers(db);
  if (layers.empty()) {
    print_line(path + ": no object layers");
    return 0;
  }
  for (const tb::ObjectLayerInfo& l : layers) {
    std::string crs = "unknown";
    if (const auto p = l.crs_wkt.find('"'); p != std::string::npos) {  // the WKT's own name
      const auto q = l.crs_wkt.find('"', p + 1);
      if (q != std::string::npos) crs = l.crs_wkt.substr(p + 1, q - p - 1);
    }
    print_line(strf("%s\tkind %s\t%lld features (%ss)\tsource %s\tCRS %s", l.name.c_str(),
                    tb::kind_name(l.kind).c_str(), static_cast<long long>(l.feature_count),
                    tb::geometry_name(l.geometry).c_str(), l.source.c_str(), crs.c_str()));
  }
  return 0;
}

}  // namespace

CommandSpec objects_spec() {
  CommandSpec s;
  s.name = "objects";
  s.positionals = "add|list DB";
  s.min_positionals = s.max_positionals = 2;
  s.summary = "Add or list object layers (GIS points, lines, polygons) of a block database.";
  s.description =
      "An object layer holds the features of one vector file (GeoJSON, GeoPackage, Shapefile or any\n"
      "other source GDAL/OGR reads, with a known CRS; GeoJSON and GPX are WGS 84): one layer of it\n"
      "(--source-layer, or the file's only layer, or its only layer with features: a GPX file's\n"
      "tracks when it has no waypoints or routes; an IGC flight log gives its ground track as one line\n"
      "named after the file), moved into the terrain's world frame, with their\n"
      "attributes, indexed by block. The database must come from a georeferenced DEM.\n"
      "Multi-geometries are split into parts; features without geometry are skipped and counted; a\n"
      "layer holds one geometry type: a file that mixes them (an OpenStreetMap extract) is an error\n"
      "unless --geometry point|line|polygon takes one (the parts of the others are counted and left\n"
      "out; add the file again for another); a feature wholly outside the terrain is an error.\n"
      "Each add is one transaction: on any error the database is unchanged.\n"
      "  add   --layer NAME --input FILE [--source-layer L] [--geometry G]\n"
      "        [--kind icon|label|shape|line] [--label-field F] [--height-field F]\n"
      "        [--rules RULES.json]: kind defaults from the geometry (points icon, lines line,\n"
      "        polygons shape; label also takes points).\n"
      "        --label-field and --height-field name fields of the file (the height one\n"
      "        numeric). --rules is the layer's design rules by level of detail, checked and\n"
      "        stored with it: for each camera-distance range (or screen-size range) draw icon,\n"
      "        label, shape, line, symbol or none, e.g.\n"
      "        {\"ranges\": [{\"max_distance_m\": 2000, \"draw\": \"icon\"},\n"
      "        {\"max_distance_m\": 30000, \"draw\": \"label\"}, {\"draw\": \"none\"}],\n"
      "        \"priority_field\": \"population\"} (format: blocks/object_rules.hpp). Without\n"
      "        --rules every object is drawn as the layer's kind at every distance.\n"
      "  list  one line per layer: name, kind, features, source file, CRS.";
  s.options = {
      {"--layer", "NAME", "add: object layer name (unique in the database)"},
      {"--input", "FILE", "add: the vector file"},
      {"--source-layer", "L",
       "add: the file's layer to read (default: its only one, or its only one with features)"},
      {"--geometry", "G", "add: only the file's point, line or polygon parts (default: all, of one type)"},
      {"--kind", "K", "add: icon, label, shape or line (default: from the geometry)"},
      {"--label-field", "F",
       "add: the attribute that labels a feature (default name; a feature without one gets no label)"},
      {"--height-field", "F", "add: the numeric attribute that gives a shape's height"},
      {"--rules", "FILE", "add: design rules by level of detail (JSON; errors name the file, line, column)"},
  };
  return s;
}

int cmd_objects(const Args& a) {
  const std::string verb = a.positionals()[0], path = a.positionals()[1];
  if (verb == "add") return objects_add(a, path);
  if (verb == "list") {
    for (const char* o : {"--layer", "--input", "--source-layer", "--geometry", "--kind", "--label-field",
                          "--height-field", "--rules"})
      if (a.has(o)) throw UsageError(std::string("option '") + o + "' is for 'objects add'");
    return objects_list(path);
  }
  throw UsageError("unknown action '" + verb + "' (add or list)");
}

}  // namespace terralod::cli
