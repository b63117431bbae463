// The two ways terralod-fly runs (main picks one by --headless): a GLFW window with flight
// controls and a heads-up display (fly_window.cpp), or frames rendered offscreen along a camera
// path into PNGs and frames.csv (fly_headless.cpp). Each returns the exit status.
#pragma once

#include "cli_common.hpp"

namespace terralod::fly {

int run_window(const cli::Args& a);
int run_headless(const cli::Args& a);

}  // namespace terralod::fly
