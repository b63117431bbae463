// PNG line plots through OpenImageIO's ImageBufAlgo drawing primitives (see plot.hpp).
#include "plot.hpp"

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <stdexcept>

namespace terralod::bench {
namespace {

namespace OIIO = OIIO_NAMESPACE;

constexpr std::array<std::array<float, 3>, 8> kPalette = {{{0.84f, 0.15f, 0.16f},
                                                           {0.12f, 0.47f, 0.71f},
                                                           {0.17f, 0.63f, 0.17f},
                                                           {1.00f, 0.50f, 0.05f},
                                                           {0.58f, 0.40f, 0.74f},
                                                           {0.55f, 0.34f, 0.29f},
                                                           {0.89f, 0.47f, 0.76f},
                                                           {0.50f, 0.50f, 0.50f}}};

std::string font() {
  const char* dejavu = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";
  return std::filesystem::exists(dejavu) ? dejavu : "";
}

/// One axis: maps a data value to a pixel coordinate.
struct Axis {
  bool log = true;
  double lo = 1, hi = 10;  // in data units
  int p0 = 0, p1 = 1;      // pixels of lo and hi
  double t(double v) const { return log ? std::log10(v) : v; }
  int pixel(double v) const {
    const double f = (t(v) - t(lo)) / (t(hi) - t(lo));
    return int(std::lround(p0 + f * (p1 - p0)));
  }
  bool usable(double v) const { return std::isfinite(v) && (!log || v > 0); }
  void fit(const std::vector<double>& values) {
    double mn = std::numeric_limits<double>::infinity(), mx = -mn;
    for (double v : values)
      if (usable(v)) mn = std::min(mn, v), mx = std::max(mx, v);
    if (!(mn <= mx)) {
      lo = log ? 1 : 0, hi = 10;
      return;
    }
    if (log) {
      lo = std::pow(10.0, std::floor(std::log10(mn)));
      hi = std::pow(10.0, std::ceil(std::log10(mx)));
      if (hi <= lo) hi = lo * 10;
    } else {
      const double pad = mx > mn ? 0.05 * (mx - mn) : std::max(1.0, std::abs(mx) * 0.1);
      lo = mn - pad, hi = mx + pad;
      if (mn >= 0 && lo < 0) lo = 0;
    }
  }
  std::vector<double> ticks() const {
    std::vector<double> out;
    if (log) {
      for (double d = lo; d <= hi * 1.0001; d *= 10)
        for (double m : {1.0, 2.0, 5.0})
          if (m * d <= hi * 1.0001) out.push_back(m * d);
    } else {
      const double raw = (hi - lo) / 6, mag = std::pow(10.0, std::floor(std::log10(raw)));
      const double step = raw / mag < 2 ? 2 * mag : raw / mag < 5 ? 5 * mag : 10 * mag;
      for (double v = std::ceil(lo / step) * step; v <= hi; v += step) out.push_back(v);
    }
    return out;
  }
};

std::string tick_label(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

}  // namespace

void write_line_plot(const std::vector<PlotSeries>& series, const PlotOptions& options,
                     const std::string& path) {
  assert(options.width_px >= 320 && options.height_px >= 240);
  const int W = options.width_px, H = options.height_px;
  const int left = 80, right = W - 200, top = 50, bottom = H - 60;
  OIIO::ImageBuf img(OIIO::ImageSpec(W, H, 3, OIIO::TypeDesc::FLOAT));
  const float white[3] = {1, 1, 1}, black[3] = {0, 0, 0}, grid[3] = {0.88f, 0.88f, 0.88f};
  OIIO::ImageBufAlgo::fill(img, white);
  const std::string f = font();

  Axis ax{options.log_x}, ay{options.log_y};
  std::vector<double> xs, ys;
  for (const PlotSeries& s : series) {
    assert(s.x.size() == s.y.size());
    for (std::size_t i = 0; i < s.x.size(); ++i)
      if (ax.usable(s.x[i]) && ay.usable(s.y[i])) xs.push_back(s.x[i]), ys.push_back(s.y[i]);
  }
  ax.fit(xs);
  ay.fit(ys);
  ax.p0 = left, ax.p1 = right;
  ay.p0 = bottom, ay.p1 = top;

  for (double v : ax.ticks()) {
    const int p = ax.pixel(v);
    OIIO::ImageBufAlgo::render_line(img, p, top, p, bottom, grid);
    OIIO::ImageBufAlgo::render_text(img, p, bottom + 18, tick_label(v), 13, f, black,
                                    OIIO::ImageBufAlgo::TextAlignX::Center);
  }
  for (double v : ay.ticks()) {
    const int p = ay.pixel(v);
    OIIO::ImageBufAlgo::render_line(img, left, p, right, p, grid);
    OIIO::ImageBufAlgo::render_text(img, left - 6, p + 5, tick_label(v), 13, f, black,
                                    OIIO::ImageBufAlgo::TextAlignX::Right);
  }
  OIIO::ImageBufAlgo::render_box(img, left, top, right, bottom, black);
  OIIO::ImageBufAlgo::render_text(img, (left + right) / 2, 22, options.title, 18, f, black,
                                  OIIO::ImageBufAlgo::TextAlignX::Center);
  OIIO::ImageBufAlgo::render_text(img, (left + right) / 2, H - 15, options.x_label, 15, f, black,
                                  OIIO::ImageBufAlgo::TextAlignX::Center);
  OIIO::ImageBufAlgo::render_text(img, 8, top - 6, options.y_label, 15, f, black);
  if (xs.empty())
    OIIO::ImageBufAlgo::render_text(img, (left + right) / 2, (top + bottom) / 2, "no data", 20, f, black,
                                    OIIO::ImageBufAlgo::TextAlignX::Center);

  for (std::size_t k = 0; k < series.size(); ++k) {
    const auto& c = kPalette[k % kPalette.size()];
    const float col[3] = {c[0], c[1], c[2]};
    const PlotSeries& s = series[k];
    bool have_prev = false;
    int px = 0, py = 0;
    for (std::size_t i = 0; i < s.x.size(); ++i) {
      if (!ax.usable(s.x[i]) || !ay.usable(s.y[i])) continue;
      const int x = ax.pixel(s.x[i]), y = ay.pixel(s.y[i]);
      if (have_prev)
        for (int d = -1; d <= 1; ++d) OIIO::ImageBufAlgo::render_line(img, px, py + d, x, y + d, col);
      OIIO::ImageBufAlgo::render_box(img, x - 4, y - 4, x + 4, y + 4, col, /*fill=*/true);
      px = x, py = y, have_prev = true;
    }
    const int ly = top + 10 + int(k) * 24;
    OIIO::ImageBufAlgo::render_box(img, right + 15, ly - 4, right + 45, ly + 4, col, /*fill=*/true);
    OIIO::ImageBufAlgo::render_text(img, right + 52, ly + 5, s.label, 14, f, black);
  }
  // 8-bit output: convert on write.
  img.set_write_format(OIIO::TypeDesc::UINT8);
  const std::string tmp = path + ".tmp.png";
  if (!img.write(tmp, OIIO::TypeDesc::UINT8, "png")) {
    std::filesystem::remove(tmp);
    throw std::runtime_error(path + ": cannot write the plot: " + img.geterror());
  }
  std::filesystem::rename(tmp, path);
}

}  // namespace terralod::bench
