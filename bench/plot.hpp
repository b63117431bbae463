// Line plots with logarithmic or linear axes written as PNG files (OpenImageIO), for the
// run-time-versus-error benchmark's figures.
//
// Usage:
//   terralod::bench::PlotSeries s{"PM blocks", {0.9, 1.4, 2.0}, {8, 2, 0.5}};
//   terralod::bench::PlotOptions o;
//   o.title = "error vs time"; o.x_label = "frame time, ms"; o.y_label = "tau, px";
//   terralod::bench::write_line_plot({s}, o, "error_vs_time.png");
//
// Contract:
//   - Each series has x.size() == y.size() (asserted) and is drawn as a polyline through its
//     points in the given order, with a marker at each point, in its own colour (a fixed
//     palette by series index), and labelled in a legend.
//   - Log axes ignore points whose coordinate is <= 0 or not finite (they cannot be placed);
//     linear axes ignore non-finite ones. If no point is left, the axes are drawn around
//     [1, 10] and the plot says "no data".
//   - Axis ranges cover every plotted point with a margin; log axes extend to whole decades
//     and are ticked at 1, 2, 5 x 10^k.
//   - Text uses DejaVuSans (/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf) when present,
//     OpenImageIO's default font otherwise.
//   - Errors (the PNG cannot be written) throw std::runtime_error naming the file.
// Memory: one RGB float image of width x height pixels (12 bytes per pixel).
#pragma once

#include <string>
#include <vector>

namespace terralod::bench {

struct PlotSeries {
  std::string label;
  std::vector<double> x, y;
};

struct PlotOptions {
  std::string title, x_label, y_label;
  bool log_x = true, log_y = true;
  int width_px = 960, height_px = 640;  ///< image size, >= 320 x 240
};

/// Draws the series and writes a PNG (8-bit RGB) to `path`.
void write_line_plot(const std::vector<PlotSeries>& series, const PlotOptions& options,
                     const std::string& path);

}  // namespace terralod::bench
