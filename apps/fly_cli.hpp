// terralod-fly's command line: its --help text and options, and what they ask for: the image
// size, the refinement options, the texture layers and the terrain (a LodSource).
#pragma once

#include <memory>
#include <optional>
#include <utility>

#include "cli_common.hpp"
#include "flight_objects.hpp"
#include "fly_source.hpp"
#include "layer_options.hpp"

namespace terralod::fly {

// What `terralod-fly --help` prints and the parser accepts.
cli::CommandSpec fly_spec();

// --objects NAME... of --db (flight_objects.hpp); nullopt without --objects. UsageError when
// there is no --db.
std::optional<blocks::ObjectPlacer> fly_objects(const cli::Args& a);

// --size WxH, each 1..16384 (default 1280x720).
std::pair<int, int> parse_size(const cli::Args& a);

// --tau (> 0, default 1) and --morph (>= 0, default 0.3), with a cull margin of 1.3.
pm::RefinementOptions refinement_options(const cli::Args& a);

// --texture-db (default --db) / --layer / --lens (layer_options.hpp); nullopt without layers.
// Usage errors come before anything is read.
std::optional<cli::LayerSetup> layer_setup(const cli::Args& a);

// The terrain of the command line: --db (with --memory, --theta), else --input or the built-in
// terrain of --terrain-size.
std::unique_ptr<LodSource> open_terrain(const cli::Args& a);

}  // namespace terralod::fly
