// The colour ramps of 'terralod texture thematic' (--ramp, the defaults) and its --rules file:
// level-of-detail design rules read from JSON into a render::LodDesignRule. No algorithm lives
// here: choosing a look per texel size and generalising blocks is render/thematic_texture.hpp.
//
// The rules file (every key optional except "rules"; unknown keys are errors):
//   {"generalise": "mean",                      nearest | majority | mean (default: mean for
//                                                slope and elevation, nearest for aspect)
//    "rules": [                                  at least one, near to far
//      {"max_texel_m": 60,                       texels up to this size (metres, > 0, strictly
//       "ramp": "0:ffffff,45:a00000",            increasing from rule to rule) get this look;
//       "bands": true},                          ramp as --ramp (default: the attribute's
//      {"ramp": "0:ffffff,45:606060"}]}          default ramp), bands as --bands (default false)
// The last rule has no max_texel_m: it draws every coarser texel. Mean is refused for aspect
// (it would average 359 and 1 degrees to 180).
#pragma once

#include <cstddef>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cli_common.hpp"
#include "terralod/render/thematic_texture.hpp"

namespace terralod::cli {

/// "RRGGBB" or "RRGGBBAA" (hex digits, either case; alpha 255 when absent), else nullopt.
std::optional<render::Rgba> parse_hex_color(const std::string& hex);

/// "V:RRGGBB[AA],V:RRGGBB[AA],...": the stops of a colour ramp, values strictly increasing.
/// UsageError "<what>: <why> in '<text>' (expected V:RRGGBB[AA],...)"; `what` names the
/// option or the place in a rules file.
std::vector<render::ColorRamp::Stop> parse_ramp(const std::string& text, const std::string& what);

/// The default ramps: slope white (flat) to dark red (45 degrees and steeper); aspect around
/// the compass; elevation green through brown to white over the terrain's own height range,
/// lo..hi (its lowest and highest valid sample).
std::vector<render::ColorRamp::Stop> default_ramp(render::TerrainAttribute attribute, double lo, double hi);

/// The stops as JSON array items "[value, r, g, b, a], ..." (the layer record's parameters).
std::string stops_json(const render::ColorRamp& ramp);

/// One look of a rules file.
struct ThematicLook {
  double max_texel_m = std::numeric_limits<double>::infinity();  ///< infinity: the last (far) look
  std::vector<render::ColorRamp::Stop> stops;                    ///< empty: the default ramp
  bool bands = false;
};

/// A checked rules file.
struct ThematicRules {
  std::string path;
  std::string generalise = "mean";  ///< nearest, majority or mean
  std::vector<ThematicLook> looks;  ///< at least one; max_texel_m strictly increasing, last infinite
};

/// Reads and checks the file of --rules for `attribute`. Throws
/// UsageError "option '--rules': <path>: <what is wrong, where>" for an unreadable file,
/// malformed JSON, unknown keys or values out of range.
ThematicRules read_thematic_rules(const std::string& path, render::TerrainAttribute attribute);

/// The design rule of `rules` (default ramps resolved against the terrain's height range lo..hi)
/// and its ramps, in order.
struct BuiltRule {
  render::LodDesignRule rule;
  std::vector<std::shared_ptr<const render::ColorRamp>> ramps;
  /// Index of the look `rule` uses for texels of this size (render::LodDesignRule::mapper_for).
  std::size_t look_for(double texel_size_m) const;
};
BuiltRule build_rule(const ThematicRules& rules, render::TerrainAttribute attribute, double lo, double hi);

/// The rules as the layer record's parameters: {"attribute", "rules_file", "generalise",
/// "sample_size_m", "rules": [{"max_texel_m"?, "mode", "stops"}], "level_rules": [look per level]}.
std::string rules_parameters(const ThematicRules& rules, const BuiltRule& built,
                             const std::string& attribute_name, double sample_size_m,
                             const std::vector<std::size_t>& level_rules);

}  // namespace terralod::cli
