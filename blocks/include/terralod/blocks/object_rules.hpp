// Design rules by level of detail of an object layer (issue 19, point 3): a small JSON file,
// stored with the layer, that says for each camera-distance range (or each range of the
// object's size on screen) whether an object is drawn as a 3D icon, a label, a shape, a line, a
// 2D symbol in a thematic texture layer, or not at all (the paper's 3D map objects,
// seeds/dynamic-3d-maps-texture-layers.txt section 5.2).
//
// Usage:
//   namespace tb = terralod::blocks;
//   const tb::ObjectRules rules = l.rules_json ? tb::parse_object_rules(*l.rules_json, l.source)
//                                              : tb::ObjectRules::everything_as(
//                                                    *tb::parse_representation(tb::kind_name(l.kind)));
//   const tb::ObjectAttribute* a = feature.attribute(rules.priority_field());  // once per
//   const double p = a ? tb::priority_value(a->value) : 0.0;                  // feature, at load
//   switch (rules.choose(distance_m, screen_px)) { ... }       // per object per frame
//
// The rules file (one JSON object, read by pm::parse_json; unknown keys are errors):
//   {"ranges": [                                 at least one, near to far
//      {"max_distance_m": 2000, "draw": "shape"},   objects up to 2000 m from the camera
//      {"max_distance_m": 8000, "draw": "icon"},    (2000, 8000] m
//      {"max_distance_m": 30000, "draw": "label"},  (8000, 30000] m
//      {"draw": "none"}],                           farther than 30000 m: not drawn
//    "priority_field": "population",              optional: the numeric attribute that ranks
//                                                 labels when they overlap (higher wins)
//    "label_size_px": 14,                         optional, > 0: label text height (default 14)
//    "icon_size_m": 20}                           optional, > 0: icon size in metres (default 20)
//   Ranges keyed by the object's size on screen instead (largest first):
//   {"ranges": [{"min_screen_px": 200, "draw": "shape"},   objects >= 200 px on screen
//               {"min_screen_px": 8, "draw": "icon"},      [8, 200) px
//               {"draw": "none"}]}                         smaller than 8 px
//
//   ranges     every range but the last has exactly one limit, all ranges the same one:
//              "max_distance_m" (metres, > 0, strictly increasing: near to far; a range holds
//              the distances d with previous max < d <= max, the first one from 0), or
//              "min_screen_px" (pixels, > 0, strictly decreasing: large to small; a range holds
//              the sizes s with min <= s < previous min). The last range has no limit: it holds
//              everything farther (or smaller); write {"draw": "none"} to draw nothing there.
//              A single range without a limit draws every object one way.
//   draw       "icon" (a 3D icon at a point), "label" (text at a point), "shape" (the polygon
//              extruded or draped), "line" (the polyline on the terrain), "symbol" (a 2D symbol
//              drawn into a thematic texture layer) or "none" (not drawn). Which
//              representations a renderer can make of which geometry is the renderer's
//              business; the rules only name them.
//   priority   the value of the attribute named by "priority_field", read by priority_value:
//              the attribute's text as a finite number, else 0 (a feature without the field, a
//              null or a text that is no number: the field is data, not a promise). Without a
//              priority_field every label has priority 0.
//   Why "max_distance_m" and not "max_distance": every length key of terralod's rules files
//   carries its unit (the texture rules' max_texel_m); a last range without a limit (instead of
//   an implicit "none" past the last one) makes "what is drawn far away" explicit.
//
// The default rule (a layer stored without rules): everything_as(the representation of the
//   layer's kind: each ObjectKind's kind_name is also a representation name): one range, every
//   object drawn as the layer's kind at every distance and size, priority 0, label_size_px 14,
//   icon_size_m 20.
//
// Contract:
//   parse_object_rules(json, source): the rules, or pm::JsonError
//     "<source>: line L, column C: <what>" for malformed JSON and for every rule broken above
//     (unknown key, wrong type, missing or empty "ranges", a limit <= 0, out of order or on the
//     last range, missing on another one, both kinds of limit, an unknown "draw" name); the
//     position is that of the offending value. `source` names the rules in messages (their file).
//   choose(distance_m, screen_size_px): the representation of the one range holding the value of
//     the rules' measure (the other argument is ignored); O(log ranges), no allocation, no
//     hysteresis (a pure function: an object exactly at a limit is in the nearer/larger range).
//     Arguments must not be NaN (asserted).
//   memory     16 bytes per range plus the priority field's name.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace terralod::blocks {

/// How an object is drawn at a given level of detail.
enum class Representation : std::uint8_t { None, Icon, Label, Shape, Line, Symbol };

/// "none", "icon", "label", "shape", "line", "symbol" and back (nullopt for anything else).
/// The names of object_layers.hpp's kinds are among them.
std::string representation_name(Representation r);
std::optional<Representation> parse_representation(std::string_view s);

/// A priority attribute's text (ObjectAttribute::value) as a number: the whole text read as a
/// finite double (std::from_chars), else 0.
double priority_value(std::string_view text);

/// One range of a rules file: objects up to (Distance) or from (ScreenSize) `limit` are drawn
/// as `draw`. The last range's limit is +infinity (Distance) or 0 (ScreenSize).
struct RuleRange {
  double limit = 0.0;
  Representation draw = Representation::None;
  bool operator==(const RuleRange&) const = default;
};

/// Checked design rules of one layer (see the file format above).
class ObjectRules {
 public:
  enum class Measure : std::uint8_t { Distance, ScreenSize };

  /// The default rule: one range drawing every object as `r` (see above).
  static ObjectRules everything_as(Representation r);

  /// The representation for an object `distance_m` metres from the camera whose extent covers
  /// `screen_size_px` pixels on screen (only the rules' measure is read).
  Representation choose(double distance_m, double screen_size_px) const;

  Measure measure() const { return measure_; }
  /// Near to far (Distance: limits increasing, last +inf; ScreenSize: decreasing, last 0).
  const std::vector<RuleRange>& ranges() const { return ranges_; }
  const std::string& priority_field() const { return priority_field_; }  ///< "" = none
  double label_size_px() const { return label_size_px_; }
  double icon_size_m() const { return icon_size_m_; }

 private:
  friend ObjectRules parse_object_rules(std::string_view json, const std::string& source);
  Measure measure_ = Measure::Distance;
  std::vector<RuleRange> ranges_;
  std::string priority_field_;
  double label_size_px_ = 14.0, icon_size_m_ = 20.0;
};

/// Reads and checks a rules file; pm::JsonError "<source>: line L, column C: <what>".
ObjectRules parse_object_rules(std::string_view json, const std::string& source);

}  // namespace terralod::blocks
