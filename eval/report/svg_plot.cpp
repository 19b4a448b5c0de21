#include "eval/report/svg_plot.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <limits>

namespace kestrel::report {
namespace {

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f", v);
  return buf;
}

std::string tick_label(double v, double step) {
  char buf[32];
  const int decimals = step >= 1.0 ? 0 : static_cast<int>(std::ceil(-std::log10(step) - 1e-9));
  std::snprintf(buf, sizeof buf, "%.*f", std::min(decimals, 6),
                std::abs(v) < step * 1e-6 ? 0.0 : v);
  return buf;
}

}  // namespace

std::string xml_escape(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::vector<double> nice_ticks(double lo, double hi, int target) {
  if (!(hi > lo) || !std::isfinite(lo) || !std::isfinite(hi)) return {lo};
  const double raw = (hi - lo) / std::max(target, 1);
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  double step = mag;
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    step = m * mag;
    if (step >= raw) break;
  }
  std::vector<double> ticks;
  for (double t = std::ceil(lo / step - 1e-9) * step; t <= hi + step * 1e-9; t += step) {
    ticks.push_back(t);
  }
  return ticks;
}

SvgPlot::SvgPlot(std::string title, std::string x_label, std::string y_label, int width, int height)
    : title_(std::move(title)),
      x_label_(std::move(x_label)),
      y_label_(std::move(y_label)),
      width_(width),
      height_(height) {}

void SvgPlot::add(PlotSeries series) { series_.push_back(std::move(series)); }

std::string SvgPlot::svg() const {
  constexpr double kLeft = 62, kRight = 16, kTop = 30, kBottom = 46;
  const double pw = width_ - kLeft - kRight, ph = height_ - kTop - kBottom;
  double x0 = std::numeric_limits<double>::infinity(), x1 = -x0, y0 = x0, y1 = -x0;
  for (const PlotSeries& s : series_) {
    for (std::size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      x0 = std::min(x0, s.x[i]), x1 = std::max(x1, s.x[i]);
      y0 = std::min(y0, s.y[i]), y1 = std::max(y1, s.y[i]);
    }
  }
  if (!std::isfinite(x0)) x0 = 0, x1 = 1, y0 = 0, y1 = 1;
  // Degenerate ranges (one point, a flat line) still get a readable axis.
  if (x1 - x0 < 1e-9) x0 -= 0.5, x1 += 0.5;
  if (y1 - y0 < 1e-9) y0 -= 0.5, y1 += 0.5;
  const double mx = 0.04 * (x1 - x0), my = 0.06 * (y1 - y0);
  x0 -= mx, x1 += mx, y0 -= my, y1 += my;
  if (equal_aspect_) {
    const double scale = std::max((x1 - x0) / pw, (y1 - y0) / ph);
    const double cx = 0.5 * (x0 + x1), cy = 0.5 * (y0 + y1);
    x0 = cx - 0.5 * pw * scale, x1 = cx + 0.5 * pw * scale;
    y0 = cy - 0.5 * ph * scale, y1 = cy + 0.5 * ph * scale;
  }
  auto px = [&](double x) { return kLeft + (x - x0) / (x1 - x0) * pw; };
  auto py = [&](double y) { return kTop + (1.0 - (y - y0) / (y1 - y0)) * ph; };

  std::string out = "<svg class=\"plot\" width=\"" + std::to_string(width_) + "\" height=\"" +
                    std::to_string(height_) + "\" viewBox=\"0 0 " + std::to_string(width_) + " " +
                    std::to_string(height_) + "\" font-family=\"sans-serif\" font-size=\"11\">\n";
  out += "<rect x=\"0\" y=\"0\" width=\"" + std::to_string(width_) + "\" height=\"" +
         std::to_string(height_) + "\" fill=\"white\"/>\n";
  out += "<text x=\"" + num(width_ / 2.0) + "\" y=\"18\" text-anchor=\"middle\" font-size=\"13\">" +
         xml_escape(title_) + "</text>\n";
  const auto xt = nice_ticks(x0, x1), yt = nice_ticks(y0, y1);
  const double xstep = xt.size() > 1 ? xt[1] - xt[0] : 1.0;
  const double ystep = yt.size() > 1 ? yt[1] - yt[0] : 1.0;
  for (double t : xt) {
    out += "<line x1=\"" + num(px(t)) + "\" y1=\"" + num(kTop) + "\" x2=\"" + num(px(t)) +
           "\" y2=\"" + num(kTop + ph) + "\" stroke=\"#e4e4e4\"/>";
    out += "<text x=\"" + num(px(t)) + "\" y=\"" + num(kTop + ph + 15) +
           "\" text-anchor=\"middle\">" + tick_label(t, xstep) + "</text>\n";
  }
  for (double t : yt) {
    out += "<line x1=\"" + num(kLeft) + "\" y1=\"" + num(py(t)) + "\" x2=\"" + num(kLeft + pw) +
           "\" y2=\"" + num(py(t)) + "\" stroke=\"#e4e4e4\"/>";
    out += "<text x=\"" + num(kLeft - 5) + "\" y=\"" + num(py(t) + 4) + "\" text-anchor=\"end\">" +
           tick_label(t, ystep) + "</text>\n";
  }
  out += "<rect x=\"" + num(kLeft) + "\" y=\"" + num(kTop) + "\" width=\"" + num(pw) +
         "\" height=\"" + num(ph) + "\" fill=\"none\" stroke=\"#444\"/>\n";
  out += "<text x=\"" + num(kLeft + pw / 2) + "\" y=\"" + num(height_ - 8.0) +
         "\" text-anchor=\"middle\">" + xml_escape(x_label_) + "</text>\n";
  out += "<text transform=\"translate(14 " + num(kTop + ph / 2) +
         ") rotate(-90)\" text-anchor=\"middle\">" + xml_escape(y_label_) + "</text>\n";

  // Lines are clipped to the plot area so an outlier cannot draw over the axes.
  static std::atomic<int> clip_counter{0};
  const std::string clip = "clip" + std::to_string(++clip_counter);
  out += "<clipPath id=\"" + clip + "\"><rect x=\"" + num(kLeft) + "\" y=\"" + num(kTop) +
         "\" width=\"" + num(pw) + "\" height=\"" + num(ph) + "\"/></clipPath>\n";
  out += "<g clip-path=\"url(#" + clip + ")\">\n";
  for (const PlotSeries& s : series_) {
    const std::size_t n = std::min(s.x.size(), s.y.size());
    if (s.markers) {
      for (std::size_t i = 0; i < n; ++i) {
        out += "<circle cx=\"" + num(px(s.x[i])) + "\" cy=\"" + num(py(s.y[i])) +
               "\" r=\"3.5\" fill=\"" + xml_escape(s.color) + "\"/>";
      }
      out += "\n";
      continue;
    }
    out += "<polyline fill=\"none\" stroke-width=\"1.6\" stroke=\"" + xml_escape(s.color) + "\"" +
           (s.dashed ? " stroke-dasharray=\"5 3\"" : "") + " points=\"";
    for (std::size_t i = 0; i < n; ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      out += num(px(s.x[i])) + "," + num(py(s.y[i])) + " ";
    }
    out += "\"/>\n";
  }
  out += "</g>\n";
  double ly = kTop + 8;
  for (const PlotSeries& s : series_) {
    const double lx = kLeft + pw - 150;
    out += "<rect x=\"" + num(lx - 4) + "\" y=\"" + num(ly - 9) +
           "\" width=\"150\" height=\"15\" fill=\"white\" fill-opacity=\"0.8\"/>";
    if (s.markers) {
      out += "<circle cx=\"" + num(lx + 9) + "\" cy=\"" + num(ly - 2) + "\" r=\"3.5\" fill=\"" +
             xml_escape(s.color) + "\"/>";
    } else {
      out += "<line x1=\"" + num(lx) + "\" y1=\"" + num(ly - 2) + "\" x2=\"" + num(lx + 18) +
             "\" y2=\"" + num(ly - 2) + "\" stroke-width=\"2\" stroke=\"" + xml_escape(s.color) +
             "\"" + (s.dashed ? " stroke-dasharray=\"5 3\"" : "") + "/>";
    }
    out += "<text x=\"" + num(lx + 24) + "\" y=\"" + num(ly + 2) + "\">" + xml_escape(s.name) +
           "</text>\n";
    ly += 16;
  }
  out += "</svg>\n";
  return out;
}

}  // namespace kestrel::report
