#pragma once
// A small line-plot writer for the run report: axes with "nice" ticks, polylines, point
// markers and a legend, as inline SVG text (the report must open without network access, so
// no plotting library from a CDN).
#include <string>
#include <vector>

namespace kestrel::report {

struct PlotSeries {
  std::string name;
  std::string color;  // any SVG colour, e.g. "#1f77b4"
  std::vector<double> x, y;
  bool dashed = false;
  bool markers = false;  // draw points instead of a line (e.g. objects on a map)
};

class SvgPlot {
 public:
  SvgPlot(std::string title, std::string x_label, std::string y_label, int width = 560,
          int height = 360);
  void add(PlotSeries series);
  // Same metres per pixel on both axes (top views).
  void set_equal_aspect(bool on) { equal_aspect_ = on; }
  std::string svg() const;

 private:
  std::string title_, x_label_, y_label_;
  int width_, height_;
  bool equal_aspect_ = false;
  std::vector<PlotSeries> series_;
};

// Tick positions covering [lo, hi] at 1, 2 or 5 times a power of ten, about `target` of them.
std::vector<double> nice_ticks(double lo, double hi, int target = 6);

// Text made safe for HTML/SVG element content and attribute values.
std::string xml_escape(const std::string& text);

}  // namespace kestrel::report
