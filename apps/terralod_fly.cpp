// terralod-fly: the flight-simulation style navigation demo. A GLFW window with flight controls
// and a heads-up display, or, with --headless, the same frames rendered through OSMesa along a
// scripted camera path, written as PNG frames plus a per-frame statistics CSV.
//
// The terrain: a block database through blocks::TerrainRuntime (the approximation tree from its
// root, PM blocks streamed with prefetch, watertight seams, geomorphs, the bound of what is
// drawn), or a single progressive mesh run through pm::SelectiveRefinement: a DEM (built
// in memory, with a progress bar), a .pm file, or, given nothing, the built-in generated
// terrain of `terralod demo`. No terrain algorithm lives here: the app only maps input to a
// camera and library results to pixels and text.
//
// This file: the command line's entry; fly_cli.hpp (options, terrain), fly_source.hpp (the
// terrains), fly_pipeline.hpp (one frame), fly_hud.hpp (its text), fly_modes.hpp (window and
// headless runs).
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "cli_common.hpp"
#include "fly_cli.hpp"
#include "fly_modes.hpp"

int main(int argc, char** argv) {
  const terralod::cli::CommandSpec spec = terralod::fly::fly_spec();
  try {
    const terralod::cli::Args a(spec, std::vector<std::string>(argv + 1, argv + argc));
    if (a.help()) {
      std::fputs(spec.usage().c_str(), stdout);
      return 0;
    }
    return a.has("--headless") ? terralod::fly::run_headless(a) : terralod::fly::run_window(a);
  } catch (const terralod::cli::UsageError& e) {
    std::fprintf(stderr, "terralod-fly: %s (see 'terralod-fly --help')\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "terralod-fly: %s\n", e.what());
    return 1;
  }
}
