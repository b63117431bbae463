// The text of terralod-fly's heads-up display: the lines about a frame's level of detail (in the
// window, and with --hud in the headless frames) and their drawing into an image.
#pragma once

#include <string>
#include <vector>

#include "fly_source.hpp"
#include "terralod/render/hud.hpp"
#include "terralod/render/image.hpp"

namespace terralod::fly {

// The lines about the level of detail of frame `r` under the live options `now`; without timings
// the text is the same on every run.
std::vector<std::string> lod_lines(const FrameRecord& r, const pm::RefinementOptions& now, bool timings);

// Draws text over an image at its top-left corner, `margin` pixels in (alpha-blended, the HUD's look).
void overlay_text(render::Image& img, const render::TextImage& t, int margin);

}  // namespace terralod::fly
