// Object layers: point, line and polygon features of a GIS vector file (any source OGR reads:
// GeoJSON, GeoPackage, Shapefile, GPX, ...; and an IGC flight log, read by flight_track.hpp as one
// line named after the file, layer "track") moved into the terrain's world frame and stored in the
// block database with their attributes, indexed by block (issue 19, part 1; the paper's 3D map
// objects, seeds/dynamic-3d-maps-texture-layers.txt section 5.2).
//
// Usage:
//   namespace tb = terralod::blocks;
//   auto db = tb::BlockDatabase::open("terrain.db", tb::BlockDatabase::Mode::ReadWrite);
//   tb::ObjectLayerOptions o;
//   o.name = "peaks"; o.input = "peaks.geojson"; o.label_field = "name";
//   const tb::ObjectLayerReport r = tb::add_object_layer(db, o);     // one transaction
//   for (const tb::ObjectLayerInfo& l : tb::object_layers(db)) ...   // sorted by name
//   for (const tb::ObjectFeature& f : tb::object_features(db, "peaks")) f.parts[0][0].x ...
//   for (const tb::ObjectFeature& f : tb::block_object_features(db, "peaks", {1, 0})) ...
//
// Contract:
//   input      any OGR vector source with exactly one layer (a GeoPackage with several layers
//              is refused: export the one wanted). Its CRS must be known (GeoJSON is WGS 84,
//              longitude first; a Shapefile needs its .prj); coordinates are read in the
//              traditional GIS order (x = easting or longitude) whatever the CRS's axis order.
//              Z and M values are dropped: objects take the height of the drawn terrain later.
//   geometry   Point, LineString and Polygon, their Multi* forms and collections of them;
//              curves are linearised by OGR. Each part of a multi-geometry becomes its own
//              ObjectFeature (same source_fid, part = 0, 1, ...). A feature without geometry
//              (or with an empty one) is skipped and counted (ObjectLayerReport::skipped_empty).
//              All parts of a layer must have one geometry type (points, lines or polygons):
//              a mixed layer (an OpenStreetMap extract's GeoJSON, say) is an error unless
//              `geometry` takes one of them; the parts of the other types are then left out
//              and counted (ObjectLayerReport::other_geometry), and a file with no part of that
//              type is an error.
//   frame      coordinates are the database's world frame (x east, y north, metres; the frame
//              of the blocks' vertices): source CRS -> the database CRS (DatabaseInfo::crs_wkt,
//              by OGR/PROJ) -> sample (col, row) by the inverse of Georeference::crs_transform
//              -> world by DatabaseInfo::transform. Both maps are affine, so this is exact for
//              the local equirectangular frame of geographic DEMs and for projected ones alike.
//              A database without a CRS or without a georeference cannot take object layers.
//   extent     a part whose bounding box (in samples) does not meet the terrain's grid rectangle
//              [0, W-1] x [0, H-1] (edges included, within 1e-6 samples) is an error naming the
//              file and the feature id, and nothing is stored: a layer that does not fit the
//              terrain is almost always a wrong CRS, which counting would hide. Parts that
//              overlap the edge are kept whole.
//   index      each part is listed under every block its bounding box (in samples) touches,
//              closed intervals against the blocks' shared borders (partition.hpp), clamped to
//              the block grid; a database with block_size 0 has the single block (0, 0).
//   attributes every field of the feature, in the layer's field order, as text with the type
//              OGR gives it (AttributeType): OGR's text of the value, except reals, written as
//              the shortest decimal that reads back as the same double; unset or null fields
//              have type Null and value "".
//   kind       default from the geometry: points -> Icon, lines -> Line, polygons -> Shape.
//              Icon and Label need points, Line lines, Shape polygons; otherwise an error.
//   fields     label_field and height_field, when given, must name fields of the layer;
//              height_field must be an Integer, Integer64 or Real field.
//   rules      rules_json, when given, is the layer's design rules by level of detail: which
//              representation (icon, label, shape, line, symbol, none) each distance or screen
//              size gets, and the attribute that ranks labels. It is checked by
//              parse_object_rules (object_rules.hpp, the file format) before the input is read
//              and stored as given; a layer without rules draws every object as its kind.
//              The rules must fit the layer: "shape" needs polygons, "line" lines or polygons,
//              and priority_field must name a field of the layer (ObjectLayerError "<rules_source>
//              ..." naming the input, Cause Option).
//              A bad rules text is an ObjectLayerError "<rules_source>: line L, column C: ...".
//   errors     ObjectLayerError "<input>: <problem>" for the vector file (missing, unreadable,
//              no or unknown CRS, no transformation, outside the terrain, mixed geometry; Cause
//              Input) and for options that do not fit it (kind, fields, rules, empty name; Cause
//              Option); DatabaseError "<db>: object layer 'x' already exists" and for the
//              database itself. On any error the database is unchanged: the
//              file is read and checked completely before one transaction writes everything.
//   progress   called with the fraction of features read (0..1), at most every 1 % of them.
//   memory     the whole layer is held in memory while it is added (about 16 bytes per point
//              plus the attributes' text); reads allocate the features they return.
//
// On-disk format (part of database format version 1: these tables are created, all three
// together, by the first add_object_layer in the same transaction; a database without them
// simply has no object layers, and older terralods ignore them):
//   object_layers    name TEXT PRIMARY KEY, kind TEXT ('icon'|'label'|'shape'|'line'),
//                    geometry TEXT ('point'|'line'|'polygon'), source TEXT (the input path),
//                    crs_wkt TEXT (the input's CRS as WKT), feature_count INTEGER (stored
//                    parts), skipped INTEGER (features without geometry), label_field TEXT,
//                    height_field TEXT ('' when not given), rules TEXT (NULL when not given)
//   object_features  layer TEXT, id INTEGER (0..feature_count-1), source_fid INTEGER,
//                    part INTEGER, min_x, min_y, max_x, max_y REAL (world bounding box),
//                    size INTEGER, crc32 INTEGER, data BLOB; PRIMARY KEY (layer, id)
//   object_blocks    layer TEXT, col INTEGER, row INTEGER, feature INTEGER;
//                    PRIMARY KEY (layer, col, row, feature), WITHOUT ROWID
// data (pm/byte_io.hpp, little-endian), checked by size and CRC-32 on every read and by
// BlockDatabase::check_integrity() (which also checks each layer's feature_count against its
// stored features and that every index entry names a stored feature):
//   u8 version (1), u8 geometry (1 point, 2 line, 3 polygon),
//   varint rings; per ring: varint points, then per point f64 x, f64 y (world metres)
//     (a point has 1 ring of 1 point, a line 1 ring, a polygon its exterior ring then holes),
//   varint attributes; per attribute: varint n + n bytes name (UTF-8), u8 AttributeType,
//     varint m + m bytes value (UTF-8 text as OGR formats it).
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "terralod/blocks/block_database.hpp"

namespace terralod::blocks {

/// A bad vector file or bad options. what() = "<input>: <problem>".
class ObjectLayerError : public std::runtime_error {
 public:
  /// Input: the file (missing, unreadable, CRS, extent, geometry). Option: an option that does
  /// not fit the file (kind, label or height field, rules text, an empty name).
  enum class Cause { Input, Option };
  explicit ObjectLayerError(const std::string& what, Cause cause = Cause::Input)
      : std::runtime_error(what), cause_(cause) {}
  Cause cause() const { return cause_; }

 private:
  Cause cause_;
};

enum class ObjectKind { Icon, Label, Shape, Line };
enum class GeometryType : std::uint8_t { Point = 1, Line = 2, Polygon = 3 };
/// OGR's field types, grouped: Integer covers OFTInteger and OFTInteger64 (booleans too).
enum class AttributeType : std::uint8_t {
  Null = 0,
  Integer = 1,
  Real = 2,
  String = 3,
  Date = 4,
  Time = 5,
  DateTime = 6,
  Other = 7
};

/// "icon", "label", "shape", "line" and back (nullopt for anything else).
std::string kind_name(ObjectKind k);
std::optional<ObjectKind> parse_kind(const std::string& s);
std::string geometry_name(GeometryType g);  ///< "point", "line", "polygon"
/// "point", "line" or "polygon" (geometry_name's words); std::invalid_argument otherwise.
GeometryType parse_geometry(const std::string& name);
std::string attribute_type_name(AttributeType t);

struct WorldPoint {
  double x = 0.0, y = 0.0;  ///< world frame, metres
  bool operator==(const WorldPoint&) const = default;
};

struct ObjectAttribute {
  std::string name;
  AttributeType type = AttributeType::Null;
  std::string value;  ///< OGR's text of the value; "" for Null
  bool operator==(const ObjectAttribute&) const = default;
};

/// One stored part of a source feature.
struct ObjectFeature {
  std::int64_t id = 0;          ///< 0..feature_count-1 within its layer
  std::int64_t source_fid = 0;  ///< the feature's id in the input (OGR FID)
  int part = 0;                 ///< index of the part within a multi-geometry
  GeometryType geometry = GeometryType::Point;
  /// Point: one ring of one point; line: one ring; polygon: exterior ring, then holes.
  std::vector<std::vector<WorldPoint>> rings;
  WorldPoint min, max;  ///< world bounding box of the rings
  std::vector<ObjectAttribute> attributes;
  /// The attribute called `name`, or nullptr.
  const ObjectAttribute* attribute(const std::string& name) const;
};

struct ObjectLayerInfo {
  std::string name;
  ObjectKind kind = ObjectKind::Icon;
  GeometryType geometry = GeometryType::Point;
  std::string source;   ///< the input file, and "(layer L)" after it when it has several
  std::string crs_wkt;  ///< the input's CRS
  std::int64_t feature_count = 0;
  std::int64_t skipped = 0;               ///< source features without geometry
  std::string label_field, height_field;  ///< "" when not given
  std::optional<std::string> rules_json;  ///< as given to add_object_layer
};

struct ObjectLayerOptions {
  std::string name;   ///< non-empty, unique in the database
  std::string input;  ///< the vector file (any OGR source)
  /// The input's layer to read. "" = its only layer, or its only layer with features (a GPX
  /// file has five: waypoints, routes, tracks, route_points, track_points); a source with
  /// several of those is an error that lists them.
  std::string source_layer;
  std::optional<ObjectKind> kind;  ///< default: from the geometry
  /// Only the parts of this geometry type, the others left out (see the contract); nullopt:
  /// every part, which must then all have one type.
  std::optional<GeometryType> geometry;
  std::string label_field, height_field;  ///< "" = none
  std::optional<std::string> rules_json;  ///< object_rules.hpp text, stored as given
  std::string rules_source;  ///< names the rules in errors (their file); "" = "<input>: the rules"
  std::function<void(double)> progress;  ///< fraction of features read; may be empty
};

struct ObjectLayerReport {
  ObjectLayerInfo layer;             ///< as stored
  std::int64_t source_features = 0;  ///< features in the input
  std::int64_t points = 0;           ///< vertices stored, all parts together
  std::int64_t other_geometry = 0;   ///< parts of other types left out by options.geometry
  std::int64_t block_entries = 0;    ///< rows of the block index written
  std::string source_crs_name;       ///< e.g. "WGS 84"
  double read_ms = 0.0, write_ms = 0.0;
};

/// Reads `options.input`, checks it against the terrain of `db` (ReadWrite) and stores it as
/// one object layer in one transaction (see the contract above).
ObjectLayerReport add_object_layer(BlockDatabase& db, const ObjectLayerOptions& options);

/// Every object layer, sorted by name; empty for a database without object tables.
std::vector<ObjectLayerInfo> object_layers(const BlockDatabase& db);
/// The features of one layer, by id. DatabaseError if the layer does not exist or a record
/// is corrupt.
std::vector<ObjectFeature> object_features(const BlockDatabase& db, const std::string& layer);
/// The features of one layer listed under block `key`, by id (empty for a block with none).
std::vector<ObjectFeature> block_object_features(const BlockDatabase& db, const std::string& layer,
                                                 BlockKey key);

}  // namespace terralod::blocks
