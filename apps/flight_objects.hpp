// The map objects of the flight tools (`terralod fly --objects`, `terralod-fly --objects`): the
// option's help, the placer over the named layers of a block database, the per-frame CSV of
// what is placed, and the text of a pick for a heads-up display. The placing itself is
// blocks::ObjectPlacer (object_placement.hpp).
//
// Usage:
//   std::optional<blocks::ObjectPlacer> objects = object_placer(a, db_path);   // --objects NAME...
//   objects->place(runtime, view);
//   write_objects_csv(objects->placed(), runtime, "out/objects_00000.csv");
//
// objects_NNNNN.csv: the header name,kind,x,y,z,ground_z and one row per object placed that
// frame, in placement order: name (the layer's label field, else the attribute "name", else
// the feature id; quoted as CSV when it holds a comma, quote or line break), kind (what the
// layer's rules draw it as this frame: icon, label, shape, line or symbol), the anchor x, y, z as drawn
// (world frame, metres, %.17g) and ground_z, the drawn terrain's height under the anchor
// (TerrainRuntime::drawn_height): equal to z as long as anchors stand on the ground.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "cli_common.hpp"
#include "terralod/blocks/object_placement.hpp"
#include "terralod/blocks/terrain_runtime.hpp"

namespace terralod::cli {

/// --objects NAME (repeatable): one line of help.
OptionSpec objects_option_spec();

/// The placer of --objects over the database `db_path` (nullopt without --objects).
/// DatabaseError "<db_path>: object layer 'x': not in the database" for a missing layer;
/// UsageError for a layer named twice.
std::optional<blocks::ObjectPlacer> object_placer(const Args& a, const std::string& db_path);

/// Writes `placed` as objects_NNNNN.csv (see above) to `path`; std::runtime_error naming it.
void write_objects_csv(const std::vector<blocks::PlacedObject>& placed, const blocks::TerrainRuntime& rt,
                       const std::string& path);

/// One HUD line: the objects placed this frame and the layers, hidden ones marked "(off)"; with
/// `timings`, the placement's time (headless frames leave it out, as lod_lines does).
std::string objects_line(const blocks::ObjectPlacer& placer, bool timings);

/// HUD lines for a pick: the object's name, kind, layer and attributes (name=value, wrapped at
/// about `width` characters), or the ground point, or "nothing" for nullopt.
std::vector<std::string> pick_lines(const std::optional<blocks::PickResult>& pick,
                                    const blocks::ObjectPlacer& placer, std::size_t width = 100);

}  // namespace terralod::cli
