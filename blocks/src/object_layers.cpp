// Object layers: GIS vector features read through OGR, moved into the terrain's world frame and
// stored in the block database with a block index (contract and on-disk format in
// terralod/blocks/object_layers.hpp).
//
// Memory: the layer being added is held whole (its points as doubles and its attributes' text),
// then written in one transaction; reads allocate the features they return.
#include "terralod/blocks/object_layers.hpp"

#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>
#include <sqlite3.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <memory>
#include <span>
#include <stdexcept>

#include "block_database_connection.hpp"
#include "block_database_schema.hpp"
#include "gdal_support.hpp"
#include "terralod/blocks/flight_track.hpp"
#include "terralod/blocks/geo_grid.hpp"
#include "terralod/blocks/object_rules.hpp"
#include "terralod/blocks/partition.hpp"
#include "terralod/pm/byte_io.hpp"
#include "terralod/pm/json.hpp"
#include "terralod/pm/timing.hpp"
#include "world_placement.hpp"

namespace terralod::blocks {

namespace {

namespace fs = std::filesystem;
using detail::BlockDatabaseImpl;
using detail::crs_name;
using detail::gdal_message;
using detail::OneOff;
using detail::QuietGdal;

constexpr std::uint8_t kFeatureVersion = 1;
// Points on the terrain's edge may come back from PROJ a rounding error outside it.
constexpr double kEdgeTolerance = 1e-6;  // samples

std::string shortest(double v) {
  std::array<char, 32> buf{};
  const auto r = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return std::string(buf.data(), r.ptr);
}

/// A date, time or date-time field in ISO 8601 (2024-05-01, 13:05:09, 2024-05-01T13:05:09.250Z,
/// ...+02:00), as GeoJSON and GeoPackage write them; OGR's own string is 2024/05/01.
std::string iso8601(OGRFeature& f, int field, AttributeType type) {
  int y = 0, mo = 0, d = 0, h = 0, mi = 0, tz = 0;
  float sec = 0.0f;
  if (!f.GetFieldAsDateTime(field, &y, &mo, &d, &h, &mi, &sec, &tz)) return f.GetFieldAsString(field);
  std::string out;
  char buf[64];
  if (type != AttributeType::Time) {
    std::snprintf(buf, sizeof buf, "%04d-%02d-%02d", y, mo, d);
    out = buf;
  }
  if (type == AttributeType::Date) return out;
  if (type == AttributeType::DateTime) out += 'T';
  const int whole = int(sec), ms = int(std::lround((double(sec) - whole) * 1000.0));
  if (ms > 0 && ms < 1000)
    std::snprintf(buf, sizeof buf, "%02d:%02d:%02d.%03d", h, mi, whole, ms);
  else
    std::snprintf(buf, sizeof buf, "%02d:%02d:%02d", h, mi, int(std::lround(sec)));
  out += buf;
  if (tz == 100) {  // OGR's time zone flag: 100 is UTC, 100 + k is k quarter hours east of it
    out += 'Z';
  } else if (tz > 1) {
    const int q = std::abs(tz - 100);
    std::snprintf(buf, sizeof buf, "%c%02d:%02d", tz > 100 ? '+' : '-', q / 4, q % 4 * 15);
    out += buf;
  }
  return out;
}

AttributeType attribute_type(OGRFieldType t) {
  switch (t) {
    case OFTInteger:
    case OFTInteger64:
      return AttributeType::Integer;
    case OFTReal:
      return AttributeType::Real;
    case OFTString:
      return AttributeType::String;
    case OFTDate:
      return AttributeType::Date;
    case OFTTime:
      return AttributeType::Time;
    case OFTDateTime:
      return AttributeType::DateTime;
    default:
      return AttributeType::Other;
  }
}

// One part in the input CRS: its rings (a point is one ring of one point).
struct RawPart {
  GeometryType geometry;
  std::vector<std::vector<WorldPoint>> rings;
};

std::vector<WorldPoint> curve_points(const OGRSimpleCurve& c) {
  std::vector<WorldPoint> pts(std::size_t(c.getNumPoints()));
  for (int i = 0; i < c.getNumPoints(); ++i) pts[std::size_t(i)] = {c.getX(i), c.getY(i)};
  return pts;
}

// Splits `g` into parts; false (with `type` = its OGR name) for a geometry type we do not place.
bool split(const OGRGeometry& g, std::vector<RawPart>& parts, std::string& type) {
  if (g.IsEmpty()) return true;
  const OGRwkbGeometryType t = wkbFlatten(g.getGeometryType());
  switch (t) {
    case wkbPoint: {
      const auto& p = *g.toPoint();
      parts.push_back({GeometryType::Point, {{{p.getX(), p.getY()}}}});
      return true;
    }
    case wkbLineString:
    case wkbLinearRing:
      parts.push_back({GeometryType::Line, {curve_points(*g.toSimpleCurve())}});
      return true;
    case wkbPolygon: {
      RawPart part{GeometryType::Polygon, {}};
      for (const OGRLinearRing* ring : *g.toPolygon()) part.rings.push_back(curve_points(*ring));
      parts.push_back(std::move(part));
      return true;
    }
    case wkbMultiPoint:
    case wkbMultiLineString:
    case wkbMultiPolygon:
    case wkbGeometryCollection:
      for (const OGRGeometry* sub : *g.toGeometryCollection())
        if (!split(*sub, parts, type)) return false;
      return true;
    case wkbCircularString:
    case wkbCompoundCurve:
    case wkbCurvePolygon:
    case wkbMultiCurve:
    case wkbMultiSurface: {
      const std::unique_ptr<OGRGeometry> linear(g.getLinearGeometry());
      return linear && split(*linear, parts, type);
    }
    default:
      type = OGRGeometryTypeToName(t);
      return false;
  }
}

// Source CRS -> database CRS -> sample (col, row) -> world (world_placement.hpp); see the
// header's "frame". A problem with the CRS is the input's: an ObjectLayerError.
class Placement {
 public:
  Placement(const BlockDatabase& db, const OGRSpatialReference& source, const std::string& input)
      : placement_(make(db, source, input)) {}

  // Moves `rings` to the world frame in place and returns their bounding box in samples
  // (cmin, rmin, cmax, rmax); false if a point cannot be transformed.
  bool place(std::vector<std::vector<WorldPoint>>& rings, std::array<double, 4>& samples) {
    samples = detail::empty_sample_box();
    for (std::vector<WorldPoint>& ring : rings) {
      xs_.resize(ring.size());
      ys_.resize(ring.size());
      for (std::size_t i = 0; i < ring.size(); ++i) xs_[i] = ring[i].x, ys_[i] = ring[i].y;
      if (!placement_.place(xs_, ys_, samples)) return false;
      for (std::size_t i = 0; i < ring.size(); ++i) ring[i] = {xs_[i], ys_[i]};
    }
    return true;
  }

 private:
  static detail::WorldPlacement make(const BlockDatabase& db, const OGRSpatialReference& source,
                                     const std::string& input) {
    try {
      return detail::WorldPlacement(db, source, input);
    } catch (const GeoError& e) {
      throw ObjectLayerError(e.what());
    }
  }
  detail::WorldPlacement placement_;
  std::vector<double> xs_, ys_;
};

// A part ready to store.
struct StoredPart {
  ObjectFeature feature;
  std::array<double, 4> samples;  // bounding box in samples: cmin, rmin, cmax, rmax
};

std::vector<std::uint8_t> encode_feature(const ObjectFeature& f) {
  pm::ByteWriter w;
  w.u8(kFeatureVersion);
  w.u8(std::uint8_t(f.geometry));
  w.varint(f.rings.size());
  for (const auto& ring : f.rings) {
    w.varint(ring.size());
    for (const WorldPoint& p : ring) w.f64(p.x), w.f64(p.y);
  }
  w.varint(f.attributes.size());
  for (const ObjectAttribute& a : f.attributes) {
    w.varint(a.name.size());
    w.raw(a.name.data(), a.name.size());
    w.u8(std::uint8_t(a.type));
    w.varint(a.value.size());
    w.raw(a.value.data(), a.value.size());
  }
  return std::move(w.bytes);
}

void decode_feature(std::span<const std::uint8_t> bytes, ObjectFeature& f, const BlockDatabaseImpl& d,
                    const std::string& item) {
  pm::ByteReader r(bytes, [&](const pm::ByteReadFailure& e) {
    d.fail(item + ": truncated " + e.what + " at byte " + std::to_string(e.position));
  });
  if (r.u8("version") != kFeatureVersion) d.fail(item + ": unknown record version");
  const std::uint8_t g = r.u8("geometry");
  if (g < 1 || g > 3) d.fail(item + ": unknown geometry type " + std::to_string(g));
  f.geometry = GeometryType(g);
  const std::uint64_t rings = r.varint("rings");
  if (rings > r.left()) d.fail(item + ": corrupt ring count");
  f.rings.resize(std::size_t(rings));
  f.min = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity()};
  f.max = {-f.min.x, -f.min.y};
  for (auto& ring : f.rings) {
    const std::uint64_t n = r.varint("points");
    if (n > r.left() / 16) d.fail(item + ": corrupt point count");
    ring.resize(std::size_t(n));
    for (WorldPoint& p : ring) {
      p.x = r.f64("point");
      p.y = r.f64("point");
      f.min = {std::min(f.min.x, p.x), std::min(f.min.y, p.y)};
      f.max = {std::max(f.max.x, p.x), std::max(f.max.y, p.y)};
    }
  }
  const std::uint64_t attrs = r.varint("attributes");
  if (attrs > r.left()) d.fail(item + ": corrupt attribute count");
  f.attributes.resize(std::size_t(attrs));
  for (ObjectAttribute& a : f.attributes) {
    const auto name = r.raw(r.varint("attribute name"), "attribute name");
    a.name.assign(name.begin(), name.end());
    const std::uint8_t t = r.u8("attribute type");
    if (t > std::uint8_t(AttributeType::Other))
      d.fail(item + ": unknown attribute type " + std::to_string(t));
    a.type = AttributeType(t);
    const auto value = r.raw(r.varint("attribute value"), "attribute value");
    a.value.assign(value.begin(), value.end());
  }
  if (r.left() != 0) d.fail(item + ": bytes left over");
}

std::string feature_item(const std::string& layer, std::int64_t id) {
  return "object layer '" + layer + "': feature " + std::to_string(id);
}

// Reads the features of statement `st`, whose columns are (id, source_fid, part, size, crc32, data).
std::vector<ObjectFeature> read_features(BlockDatabaseImpl& d, sqlite3_stmt* st, const std::string& layer) {
  std::vector<ObjectFeature> out;
  std::vector<std::uint8_t> bytes;
  for (int rc; (rc = sqlite3_step(st)) != SQLITE_DONE;) {
    if (rc != SQLITE_ROW) d.check(rc, "object layer '" + layer + "': cannot read the features");
    ObjectFeature f;
    f.id = sqlite3_column_int64(st, 0);
    const std::string item = feature_item(layer, f.id);
    f.source_fid = d.integer(st, 1, item);
    f.part = int(d.integer(st, 2, item));
    const std::string problem = d.verify(st, 3, &bytes);
    if (!problem.empty()) d.fail(item + ": " + problem);
    decode_feature(bytes, f, d, item);
    out.push_back(std::move(f));
  }
  return out;
}

/// The layer of `ds` (the file `in`) to read: the one named `name`, else its only layer, else its
/// only layer with features. ObjectLayerError listing the layers otherwise (Cause Option for a
/// name it does not hold).
// An IGC flight log as a vector dataset of one line (its ground track, named after the file),
// in WGS 84: GDAL reads GPX tracks but not IGC logs. Errors of the log are the input's.
GDALDatasetUniquePtr open_igc(const std::string& in) {
  FlightTrack track;
  try {
    track = read_flight_track(in);
  } catch (const std::runtime_error& e) {
    throw ObjectLayerError(e.what());
  }
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("Memory");
  GDALDatasetUniquePtr ds(mem != nullptr ? mem->Create("", 0, 0, 0, GDT_Unknown, nullptr) : nullptr);
  if (!ds) throw ObjectLayerError(in + ": GDAL's Memory driver is missing (" + gdal_message("none") + ")");
  OGRSpatialReference wgs84;
  wgs84.SetWellKnownGeogCS("WGS84");
  wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  OGRLayer* layer = ds->CreateLayer("track", &wgs84, wkbLineString, nullptr);
  OGRFieldDefn name("name", OFTString);
  if (layer == nullptr || layer->CreateField(&name) != OGRERR_NONE)
    throw ObjectLayerError(in + ": cannot make its track a layer (" + gdal_message("GDAL refused") + ")");
  OGRLineString line;
  for (const TrackPoint& p : track.points) line.addPoint(p.lon, p.lat);
  const OGRFeatureUniquePtr f(OGRFeature::CreateFeature(layer->GetLayerDefn()));
  f->SetField("name", fs::path(in).stem().string().c_str());
  f->SetGeometry(&line);
  if (layer->CreateFeature(f.get()) != OGRERR_NONE)
    throw ObjectLayerError(in + ": cannot make its track a layer (" + gdal_message("GDAL refused") + ")");
  return ds;
}

OGRLayer& source_layer(GDALDataset& ds, const std::string& in, const std::string& name) {
  // GDAL's GPX driver gives every point of the tracks and routes again as layers of points:
  // those are not a choice of their own.
  const bool gpx = ds.GetDriver() != nullptr && EQUAL(ds.GetDriver()->GetDescription(), "GPX");
  const auto counts = [&](OGRLayer* l) {
    return !(gpx && (EQUAL(l->GetName(), "track_points") || EQUAL(l->GetName(), "route_points")));
  };
  const auto listing = [&](bool with_features_only) {
    std::string list;
    for (OGRLayer* l : ds.GetLayers()) {
      const GIntBig n = l->GetFeatureCount(TRUE);
      if (with_features_only && (n == 0 || !counts(l))) continue;
      list += (list.empty() ? "" : ", ") + std::string(l->GetName()) + " (" + std::to_string(n) + " " +
              OGRGeometryTypeToName(l->GetGeomType()) + ")";
    }
    return list;
  };
  if (!name.empty()) {
    if (OGRLayer* l = ds.GetLayerByName(name.c_str())) return *l;
    throw ObjectLayerError(in + ": has no layer '" + name + "'; its layers: " + listing(false),
                           ObjectLayerError::Cause::Option);
  }
  if (ds.GetLayerCount() == 0) throw ObjectLayerError(in + ": has no layer");
  if (ds.GetLayerCount() == 1) return *ds.GetLayer(0);
  OGRLayer* only = nullptr;
  int with_features = 0;
  for (OGRLayer* l : ds.GetLayers())
    if (counts(l) && l->GetFeatureCount(TRUE) > 0) ++with_features, only = l;
  if (with_features == 1) return *only;
  throw ObjectLayerError(in + ": has " + std::to_string(ds.GetLayerCount()) + " layers, " +
                             (with_features == 0 ? std::string("none with features: ") + listing(false)
                                                 : std::to_string(with_features) + " with features: " +
                                                       listing(true) + "; name one with --source-layer"),
                         ObjectLayerError::Cause::Input);
}

void require_layer(BlockDatabaseImpl& d, const BlockDatabase& db, const std::string& layer) {
  const std::vector<ObjectLayerInfo> layers = object_layers(db);
  if (std::none_of(layers.begin(), layers.end(), [&](const ObjectLayerInfo& l) { return l.name == layer; }))
    d.fail("object layer '" + layer + "': not in the database");
}

}  // namespace

std::string kind_name(ObjectKind k) {
  switch (k) {
    case ObjectKind::Icon:
      return "icon";
    case ObjectKind::Label:
      return "label";
    case ObjectKind::Shape:
      return "shape";
    case ObjectKind::Line:
      return "line";
  }
  return "?";
}

std::optional<ObjectKind> parse_kind(const std::string& s) {
  for (ObjectKind k : {ObjectKind::Icon, ObjectKind::Label, ObjectKind::Shape, ObjectKind::Line})
    if (kind_name(k) == s) return k;
  return std::nullopt;
}

std::string geometry_name(GeometryType g) {
  return g == GeometryType::Point ? "point" : g == GeometryType::Line ? "line" : "polygon";
}

GeometryType parse_geometry(const std::string& name) {
  for (const GeometryType g : {GeometryType::Point, GeometryType::Line, GeometryType::Polygon})
    if (geometry_name(g) == name) return g;
  throw std::invalid_argument("unknown geometry '" + name + "' (point, line or polygon)");
}

std::string attribute_type_name(AttributeType t) {
  static const char* const names[] = {"null", "integer", "real",     "string",
                                      "date", "time",    "datetime", "other"};
  return names[std::size_t(t)];
}

const ObjectAttribute* ObjectFeature::attribute(const std::string& name) const {
  for (const ObjectAttribute& a : attributes)
    if (a.name == name) return &a;
  return nullptr;
}

ObjectLayerReport add_object_layer(BlockDatabase& db, const ObjectLayerOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  BlockDatabaseImpl& d = detail::ImplAccess::of(db);
  d.require_writable();
  const std::string& in = o.input;
  if (o.name.empty())
    throw ObjectLayerError(in + ": the object layer needs a name", ObjectLayerError::Cause::Option);
  for (const ObjectLayerInfo& l : object_layers(db))
    if (l.name == o.name) d.fail("object layer '" + o.name + "' already exists");
  const std::string rules_source = o.rules_source.empty() ? in + ": the rules" : o.rules_source;
  std::optional<ObjectRules> rules;
  if (o.rules_json) {
    try {
      rules = parse_object_rules(*o.rules_json, rules_source);  // "<source>: line L, column C: <what>"
    } catch (const pm::JsonError& e) {
      throw ObjectLayerError(e.what(), ObjectLayerError::Cause::Option);
    }
  }

  detail::register_gdal();
  const QuietGdal quiet;
  std::error_code ec;
  if (!fs::exists(in, ec)) throw ObjectLayerError(in + ": no such file");
  const GDALDatasetUniquePtr ds(
      detail::lower(fs::path(in).extension().string()) == ".igc"
          ? open_igc(in)
          : GDALDatasetUniquePtr(GDALDataset::Open(in.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY)));
  if (!ds)
    throw ObjectLayerError(in + ": not a readable vector file (" + gdal_message("no driver reads it") + ")");
  OGRLayer& layer = source_layer(*ds, in, o.source_layer);
  const OGRSpatialReference* srs = layer.GetSpatialRef();
  if (srs == nullptr || srs->IsEmpty())
    throw ObjectLayerError(
        in + ": unknown CRS (the file states none that GDAL reads; a Shapefile needs its .prj)");
  Placement placement(db, *srs, in);

  ObjectLayerReport report;
  ObjectLayerInfo& info = report.layer;
  info.name = o.name;
  info.source = ds->GetLayerCount() > 1 ? in + " (layer " + layer.GetName() + ")" : in;
  {
    char* wkt = nullptr;
    if (srs->exportToWkt(&wkt) == OGRERR_NONE && wkt != nullptr) info.crs_wkt = wkt;
    CPLFree(wkt);
  }
  report.source_crs_name = crs_name(*srs);
  OGRFeatureDefn& defn = *layer.GetLayerDefn();
  const auto field_index = [&](const std::string& f, const char* option) {
    const int i = defn.GetFieldIndex(f.c_str());
    if (i < 0) {
      std::string names;
      for (int k = 0; k < defn.GetFieldCount(); ++k)
        names += (k ? ", " : "") + std::string(defn.GetFieldDefn(k)->GetNameRef());
      throw ObjectLayerError(in + ": " + option + " '" + f + "' is not a field of the layer (fields: " +
                                 (names.empty() ? "none" : names) + ")",
                             ObjectLayerError::Cause::Option);
    }
    return i;
  };
  if (!o.label_field.empty()) field_index(o.label_field, "label field");
  if (!o.height_field.empty()) {
    const OGRFieldType t = defn.GetFieldDefn(field_index(o.height_field, "height field"))->GetType();
    if (t != OFTInteger && t != OFTInteger64 && t != OFTReal)
      throw ObjectLayerError(in + ": height field '" + o.height_field + "' is not numeric (it is " +
                                 OGRFieldDefn::GetFieldTypeName(t) + ")",
                             ObjectLayerError::Cause::Option);
  }
  if (rules && !rules->priority_field().empty())
    field_index(rules->priority_field(), (rules_source + ": priority_field").c_str());
  info.label_field = o.label_field;
  info.height_field = o.height_field;
  info.rules_json = o.rules_json;

  const DatabaseInfo& dbi = db.info();
  const double w = dbi.grid_width - 1.0, h = dbi.grid_height - 1.0;
  const GIntBig total = layer.GetFeatureCount(TRUE);
  const std::int64_t step = std::max<std::int64_t>(1, std::int64_t(total) / 100);
  std::vector<StoredPart> parts;
  std::vector<RawPart> raw;
  std::optional<GeometryType> geometry;
  layer.ResetReading();
  for (OGRFeatureUniquePtr feat(layer.GetNextFeature()); feat; feat.reset(layer.GetNextFeature())) {
    ++report.source_features;
    if (o.progress && report.source_features % step == 0 && total > 0)
      o.progress(std::min(1.0, double(report.source_features) / double(total)));
    const std::int64_t fid = feat->GetFID();
    const std::string where = in + ": feature " + std::to_string(fid);
    raw.clear();
    std::string type;
    const OGRGeometry* g = feat->GetGeometryRef();
    if (g != nullptr && !split(*g, raw, type))
      throw ObjectLayerError(where + ": unsupported geometry type " + type);
    if (raw.empty()) {
      ++info.skipped;
      continue;
    }
    std::vector<ObjectAttribute> attrs(std::size_t(feat->GetFieldCount()));
    for (int i = 0; i < feat->GetFieldCount(); ++i) {
      ObjectAttribute& a = attrs[std::size_t(i)];
      const OGRFieldDefn& fd = *feat->GetFieldDefnRef(i);
      a.name = fd.GetNameRef();
      if (!feat->IsFieldSetAndNotNull(i)) continue;
      a.type = attribute_type(fd.GetType());
      if (a.type == AttributeType::Real)
        a.value = shortest(feat->GetFieldAsDouble(i));
      else if (a.type == AttributeType::Date || a.type == AttributeType::Time ||
               a.type == AttributeType::DateTime)
        a.value = iso8601(*feat, i, a.type);
      else
        a.value = feat->GetFieldAsString(i);
    }
    for (std::size_t k = 0; k < raw.size(); ++k) {
      if (o.geometry && raw[k].geometry != *o.geometry) {
        ++report.other_geometry;
        continue;
      }
      if (geometry && *geometry != raw[k].geometry)
        throw ObjectLayerError(where + ": a " + geometry_name(raw[k].geometry) + " in a layer of " +
                               geometry_name(*geometry) +
                               "s (an object layer holds one geometry type: take one with --geometry "
                               "point|line|polygon, and add the file again for another)");
      geometry = raw[k].geometry;
      StoredPart p;
      p.feature.id = std::int64_t(parts.size());
      p.feature.source_fid = fid;
      p.feature.part = int(k);
      p.feature.geometry = raw[k].geometry;
      p.feature.rings = std::move(raw[k].rings);
      if (!placement.place(p.feature.rings, p.samples))
        throw ObjectLayerError(where + ": cannot be transformed to the terrain's CRS (" +
                               gdal_message("outside the transformation's domain") + ")");
      const auto& s = p.samples;
      if (s[2] < -kEdgeTolerance || s[3] < -kEdgeTolerance || s[0] > w + kEdgeTolerance ||
          s[1] > h + kEdgeTolerance)
        throw ObjectLayerError(where + ": lies wholly outside the terrain of " + db.path() +
                               " (is the file's CRS right?)");
      ObjectFeature& f = p.feature;
      f.min = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity()};
      f.max = {-f.min.x, -f.min.y};
      for (const auto& ring : f.rings)
        for (const WorldPoint& q : ring) {
          f.min = {std::min(f.min.x, q.x), std::min(f.min.y, q.y)};
          f.max = {std::max(f.max.x, q.x), std::max(f.max.y, q.y)};
          ++report.points;
        }
      f.attributes = attrs;
      parts.push_back(std::move(p));
    }
  }
  if (!geometry)
    throw ObjectLayerError(o.geometry ? in + ": has no " + geometry_name(*o.geometry) + " (" +
                                            std::to_string(report.other_geometry) + " parts of other types)"
                                      : in + ": has no feature with a geometry");
  info.geometry = *geometry;
  const ObjectKind natural = info.geometry == GeometryType::Point  ? ObjectKind::Icon
                             : info.geometry == GeometryType::Line ? ObjectKind::Line
                                                                   : ObjectKind::Shape;
  info.kind = o.kind.value_or(natural);
  const bool fits = info.kind == natural || (info.kind == ObjectKind::Label && natural == ObjectKind::Icon);
  if (!fits)
    throw ObjectLayerError(in + ": kind " + kind_name(info.kind) + " does not fit its " +
                               geometry_name(info.geometry) +
                               "s (icon and label need points, line lines, shape polygons)",
                           ObjectLayerError::Cause::Option);
  // A rule drawing a shape needs polygons, a line lines or polygons (their outlines); icons,
  // labels and symbols stand at any feature's anchor.
  if (rules)
    for (const RuleRange& r : rules->ranges()) {
      const bool bad = (r.draw == Representation::Shape && info.geometry != GeometryType::Polygon) ||
                       (r.draw == Representation::Line && info.geometry == GeometryType::Point);
      if (bad)
        throw ObjectLayerError(rules_source + ": draws \"" + representation_name(r.draw) + "\", which " +
                                   geometry_name(info.geometry) + "s of " + in +
                                   " cannot be (shape needs polygons, line lines or polygons)",
                               ObjectLayerError::Cause::Option);
    }
  info.feature_count = std::int64_t(parts.size());
  if (o.progress) o.progress(1.0);
  report.read_ms = pm::ms_since(t0);

  // Everything checked: one transaction writes the layer, its features and their index.
  const auto t1 = std::chrono::steady_clock::now();
  const int n = dbi.block_size > 0 ? dbi.block_size - 1 : 0;
  const BlockLayout layout =
      n > 0 ? partition(dbi.grid_width, dbi.grid_height, dbi.block_size) : BlockLayout{};
  const int bx = n > 0 ? layout.blocks_x : 1, by = n > 0 ? layout.blocks_y : 1;
  BlockDatabase::Transaction t(db);
  detail::create_object_tables(d);
  const std::string item = "object layer '" + o.name + "'";
  {
    OneOff st(d,
              "INSERT INTO object_layers(name, kind, geometry, source, crs_wkt, feature_count, skipped, "
              "label_field, height_field, rules) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10)",
              item);
    d.bind_text(st, 1, info.name, item);
    const std::string kind = kind_name(info.kind),
                      geometry_text = geometry_name(info.geometry);  // bound, not copied
    d.bind_text(st, 2, kind, item);
    d.bind_text(st, 3, geometry_text, item);
    d.bind_text(st, 4, info.source, item);
    d.bind_text(st, 5, info.crs_wkt, item);
    sqlite3_bind_int64(st, 6, info.feature_count);
    sqlite3_bind_int64(st, 7, info.skipped);
    d.bind_text(st, 8, info.label_field, item);
    d.bind_text(st, 9, info.height_field, item);
    if (info.rules_json) d.bind_text(st, 10, *info.rules_json, item);
    d.step_write(st, item);
  }
  OneOff put(
      d,
      "INSERT INTO object_features(layer, id, source_fid, part, min_x, min_y, max_x, max_y, size, crc32, "
      "data) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)",
      item);
  OneOff index(d, "INSERT INTO object_blocks(layer, col, row, feature) VALUES (?1, ?2, ?3, ?4)", item);
  d.bind_text(put, 1, o.name, item);
  d.bind_text(index, 1, o.name, item);
  for (const StoredPart& p : parts) {
    const ObjectFeature& f = p.feature;
    const std::string fi = feature_item(o.name, f.id);
    const std::vector<std::uint8_t> bytes = encode_feature(f);
    sqlite3_bind_int64(put, 2, f.id);
    sqlite3_bind_int64(put, 3, f.source_fid);
    sqlite3_bind_int(put, 4, f.part);
    sqlite3_bind_double(put, 5, f.min.x);
    sqlite3_bind_double(put, 6, f.min.y);
    sqlite3_bind_double(put, 7, f.max.x);
    sqlite3_bind_double(put, 8, f.max.y);
    d.bind_blob(put, 9, bytes, fi);
    d.step_write(put, fi);
    sqlite3_reset(put);
    // Blocks whose closed sample interval [c n, (c+1) n] meets the box, clamped to the grid.
    const auto range = [&](double lo, double hi, int count) {
      if (n == 0) return std::pair{0, 0};
      const int a = std::clamp(int(std::ceil(lo / n - 1.0)), 0, count - 1);
      const int b = std::clamp(int(std::floor(hi / n)), 0, count - 1);
      return std::pair{a, b};
    };
    const auto [c0, c1] = range(p.samples[0], p.samples[2], bx);
    const auto [r0, r1] = range(p.samples[1], p.samples[3], by);
    for (int c = c0; c <= c1; ++c)
      for (int r = r0; r <= r1; ++r) {
        sqlite3_bind_int(index, 2, c);
        sqlite3_bind_int(index, 3, r);
        sqlite3_bind_int64(index, 4, f.id);
        d.step_write(index, fi);
        sqlite3_reset(index);
        ++report.block_entries;
      }
  }
  t.commit();
  report.write_ms = pm::ms_since(t1);
  return report;
}

std::vector<ObjectLayerInfo> object_layers(const BlockDatabase& db) {
  BlockDatabaseImpl& d = detail::ImplAccess::of(db);
  std::vector<ObjectLayerInfo> out;
  if (!detail::object_tables_exist(d)) return out;
  OneOff st(
      d,
      "SELECT name, kind, geometry, source, crs_wkt, feature_count, skipped, label_field, height_field, "
      "rules FROM object_layers ORDER BY name",
      "cannot list the object layers");
  for (int rc; (rc = sqlite3_step(st)) != SQLITE_DONE;) {
    if (rc != SQLITE_ROW) d.check(rc, "cannot list the object layers");
    ObjectLayerInfo l;
    l.name = d.text(st, 0, "object_layers");
    const std::string item = "object layer '" + l.name + "'";
    const std::optional<ObjectKind> kind = parse_kind(d.text(st, 1, item));
    if (!kind) d.fail(item + ": corrupt record (unknown kind)");
    l.kind = *kind;
    const std::string g = d.text(st, 2, item);
    if (g == "point")
      l.geometry = GeometryType::Point;
    else if (g == "line")
      l.geometry = GeometryType::Line;
    else if (g == "polygon")
      l.geometry = GeometryType::Polygon;
    else
      d.fail(item + ": corrupt record (unknown geometry '" + g + "')");
    l.source = d.text(st, 3, item);
    l.crs_wkt = d.text(st, 4, item);
    l.feature_count = d.integer(st, 5, item);
    l.skipped = d.integer(st, 6, item);
    l.label_field = d.text(st, 7, item);
    l.height_field = d.text(st, 8, item);
    if (sqlite3_column_type(st, 9) != SQLITE_NULL) l.rules_json = d.text(st, 9, item);
    out.push_back(std::move(l));
  }
  return out;
}

std::vector<ObjectFeature> object_features(const BlockDatabase& db, const std::string& layer) {
  BlockDatabaseImpl& d = detail::ImplAccess::of(db);
  require_layer(d, db, layer);
  OneOff st(
      d, "SELECT id, source_fid, part, size, crc32, data FROM object_features WHERE layer = ?1 ORDER BY id",
      "object layer '" + layer + "': cannot read the features");
  d.bind_text(st, 1, layer, "object layer '" + layer + "'");
  return read_features(d, st, layer);
}

std::vector<ObjectFeature> block_object_features(const BlockDatabase& db, const std::string& layer,
                                                 BlockKey key) {
  BlockDatabaseImpl& d = detail::ImplAccess::of(db);
  require_layer(d, db, layer);
  OneOff st(d,
            "SELECT f.id, f.source_fid, f.part, f.size, f.crc32, f.data FROM object_blocks b JOIN "
            "object_features f "
            "ON f.layer = b.layer AND f.id = b.feature WHERE b.layer = ?1 AND b.col = ?2 AND b.row = ?3 "
            "ORDER BY f.id",
            "object layer '" + layer + "': cannot read the block index");
  d.bind_text(st, 1, layer, "object layer '" + layer + "'");
  sqlite3_bind_int(st, 2, key.col);
  sqlite3_bind_int(st, 3, key.row);
  return read_features(d, st, layer);
}

}  // namespace terralod::blocks
