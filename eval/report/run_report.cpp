#include "eval/report/run_report.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <fstream>

#include "core/error.hpp"
#include "eval/report/image_embed.hpp"
#include "eval/report/svg_plot.hpp"
#include "eval/trajectory_evaluation.hpp"
#include "io/trajectory_io.hpp"

namespace kestrel::report {
namespace {

// Colours of the runs (matplotlib's tab10), ground truth in black.
const char* const kColors[] = {"#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b"};
const char* color_of(std::size_t i) { return kColors[i % (sizeof kColors / sizeof *kColors)]; }

std::string fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

struct Ape {
  bool ok = false;
  std::string why;  // when not ok
  eval::Evaluation e;
};

// The same settings as pipeline::run_sequence, so the report's RMSE is the printed one.
Ape compute_ape(const Trajectory& gt, const Trajectory& est) {
  Ape a;
  if (est.size() < 3) {
    a.why = "fewer than 3 tracked poses";
    return a;
  }
  eval::ApeOptions opt;
  opt.association.method = eval::AssociationMethod::kEvo;
  opt.association.max_diff = 0.01;
  opt.alignment = eval::Alignment::kSe3;
  try {
    a.e = eval::evaluate_ape(io::to_pose_series(gt), io::to_pose_series(est), opt);
    a.ok = true;
  } catch (const std::exception& ex) {
    a.why = ex.what();
  }
  return a;
}

std::string td(const std::string& s) { return "<td>" + s + "</td>"; }
std::string th(const std::string& s) { return "<th>" + s + "</th>"; }

std::string pct(std::size_t part, std::size_t total) {
  return total ? fmt("%.1f%%", 100.0 * part / total) : "-";
}

std::string summary_table(const ReportInput& in, const std::vector<Ape>& apes) {
  std::string h = "<table id=\"summary\"><tr>" + th("run") + th("frames") + th("tracked") +
                  th("lost") + th("APE RMSE (m)") + th("APE median (m)") + th("APE max (m)") +
                  th("tracking FPS") + th("detector FPS") + th("wall (s)") + "</tr>\n";
  for (std::size_t i = 0; i < in.runs.size(); ++i) {
    const RunRecord& r = in.runs[i];
    const Ape& a = apes[i];
    h += "<tr>" + td("<b>" + xml_escape(r.name) + "</b> " + xml_escape(r.description)) +
         td(std::to_string(r.frames)) + td(std::to_string(r.tracked)) + td(std::to_string(r.lost)) +
         td(a.ok ? fmt("%.4f", a.e.stats.rmse) : "-") +
         td(a.ok ? fmt("%.4f", a.e.stats.median) : "-") +
         td(a.ok ? fmt("%.4f", a.e.stats.max) : "-") +
         td(r.tracking_ms_median > 0 ? fmt("%.1f", 1000.0 / r.tracking_ms_median) : "-") +
         td(r.detector_ms_median > 0 ? fmt("%.1f", 1000.0 / r.detector_ms_median) : "-") +
         td(fmt("%.1f", r.wall_seconds)) + "</tr>\n";
  }
  return h + "</table>\n";
}

std::string removal_table(const ReportInput& in) {
  std::string h = "<table id=\"removal\"><tr>" + th("run") + th("dynamic features") +
                  th("removed") + th("removed %") + th("static features") + th("kept") +
                  th("kept %") + "</tr>\n";
  bool any = false;
  for (const RunRecord& r : in.runs) {
    if (!r.has_removal) continue;
    any = true;
    h += "<tr>" + td(xml_escape(r.name)) + td(std::to_string(r.dynamic_total)) +
         td(std::to_string(r.dynamic_removed)) + td(pct(r.dynamic_removed, r.dynamic_total)) +
         td(std::to_string(r.static_total)) + td(std::to_string(r.static_kept)) +
         td(pct(r.static_kept, r.static_total)) + "</tr>\n";
  }
  if (!any)
    return "<p>No ground-truth mover masks for this dataset: removal is not measured.</p>\n";
  return h + "</table>\n<p class=\"note\">A feature is truly dynamic when its pixel lies in the " +
         "simulator's mover mask; removed = labelled dynamic, kept = not labelled dynamic.</p>\n";
}

std::string timing_tables(const ReportInput& in) {
  std::string h;
  for (const RunRecord& r : in.runs) {
    if (r.stages.empty()) continue;
    h += "<h3>" + xml_escape(r.name) + "</h3>\n<table class=\"timing\"><tr>" + th("stage") +
         th("count") + th("median (ms)") + th("p90 (ms)") + th("max (ms)") + "</tr>\n";
    for (const StageTiming& s : r.stages) {
      h += "<tr>" + td(xml_escape(s.stage)) + td(std::to_string(s.count)) +
           td(fmt("%.2f", s.p50_ms)) + td(fmt("%.2f", s.p90_ms)) + td(fmt("%.2f", s.max_ms)) +
           "</tr>\n";
    }
    h += "</table>\n";
    if (!r.counters.empty()) {
      h += "<p class=\"note\">";
      for (const auto& [k, v] : r.counters) h += xml_escape(k) + " " + std::to_string(v) + " · ";
      h += "</p>\n";
    }
  }
  return h.empty() ? "<p>No stage timings recorded.</p>\n" : h;
}

std::string trajectory_plots(const ReportInput& in, const std::vector<Ape>& apes) {
  const bool has_gt = in.ground_truth && !in.ground_truth->empty();
  SvgPlot top(has_gt ? "Top view (aligned to ground truth)" : "Top view", "x (m)", "y (m)");
  top.set_equal_aspect(true);
  SvgPlot height("Height over time", "t (s)", "z (m)");
  SvgPlot ape("APE (translation) along time", "t (s)", "error (m)");
  double t0 = 0.0;
  PlotSeries gt_xy{"ground truth", "#000000", {}, {}, true, false};
  PlotSeries gt_z = gt_xy;
  if (in.ground_truth && !in.ground_truth->empty()) {
    const Trajectory& gt = *in.ground_truth;
    t0 = gt.stamps.front();
    for (std::size_t i = 0; i < gt.size(); ++i) {
      const Vec3 p = gt.poses[i].translation();
      gt_xy.x.push_back(p.x()), gt_xy.y.push_back(p.y());
      gt_z.x.push_back(gt.stamps[i] - t0), gt_z.y.push_back(p.z());
    }
  } else {
    for (const RunRecord& r : in.runs) {
      if (!r.estimate.empty()) {
        t0 = r.estimate.stamps.front();
        break;
      }
    }
  }
  bool any_ape = false;
  for (std::size_t i = 0; i < in.runs.size(); ++i) {
    const RunRecord& r = in.runs[i];
    PlotSeries xy{r.name, color_of(i), {}, {}, false, false};
    PlotSeries z = xy, err = xy;
    if (apes[i].ok) {
      // The aligned estimate, so the curves lie on the ground truth they are scored against.
      const eval::Evaluation& e = apes[i].e;
      for (std::size_t k = 0; k < e.est.size(); ++k) {
        xy.x.push_back(e.est[k](0, 3)), xy.y.push_back(e.est[k](1, 3));
        z.x.push_back(e.stamps[k] - t0), z.y.push_back(e.est[k](2, 3));
      }
      for (std::size_t k = 0; k < e.errors.size() && k < e.stamps.size(); ++k) {
        err.x.push_back(e.stamps[k] - t0), err.y.push_back(e.errors[k]);
      }
      any_ape = true;
      ape.add(err);
    } else {
      for (std::size_t k = 0; k < r.estimate.size(); ++k) {
        const Vec3 p = r.estimate.poses[k].translation();
        xy.x.push_back(p.x()), xy.y.push_back(p.y());
        z.x.push_back(r.estimate.stamps[k] - t0), z.y.push_back(p.z());
      }
    }
    top.add(xy);
    height.add(z);
  }
  // Ground truth last, dashed, so an estimate lying on it does not hide it.
  if (!gt_xy.x.empty()) {
    top.add(gt_xy);
    height.add(gt_z);
  }
  std::string h = "<div class=\"plots\">\n" + top.svg() + height.svg();
  if (any_ape) h += ape.svg();
  h += "</div>\n";
  for (std::size_t i = 0; i < in.runs.size(); ++i) {
    if (!apes[i].ok && in.ground_truth) {
      h += "<p class=\"note\">" + xml_escape(in.runs[i].name) + ": no APE (" +
           xml_escape(apes[i].why) + ").</p>\n";
    }
  }
  return h;
}

// What a long run's memory does: flat once the map stops growing, a slope where it leaks.
std::string memory_plot(const ReportInput& in) {
  SvgPlot plot("Resident memory along the run", "t (s)", "RSS (MiB)");
  bool any = false;
  for (std::size_t i = 0; i < in.runs.size(); ++i) {
    const RunRecord& r = in.runs[i];
    if (r.memory_mib.size() < 2) continue;
    PlotSeries s{r.name, color_of(i), {}, {}, false, false};
    for (const auto& [t, mib] : r.memory_mib) s.x.push_back(t), s.y.push_back(mib);
    plot.add(s);
    any = true;
  }
  return any ? "<div class=\"plots\">\n" + plot.svg() + "</div>\n" : "";
}

std::string frame_strip(const ReportInput& in) {
  if (in.frames.empty()) return "<p>No frames were passed to the report.</p>\n";
  std::string h = "<div class=\"strip\">\n";
  constexpr int kWidth = 400;
  for (const StripFrame& f : in.frames) {
    if (f.image.empty()) continue;
    const double s = f.image.width > kWidth ? static_cast<double>(kWidth) / f.image.width : 1.0;
    const int w = static_cast<int>(std::lround(f.image.width * s));
    const int hgt = static_cast<int>(std::lround(f.image.height * s));
    h += "<figure><svg width=\"" + std::to_string(w) + "\" height=\"" + std::to_string(hgt) +
         "\" viewBox=\"0 0 " + std::to_string(f.image.width) + " " +
         std::to_string(f.image.height) + "\">";
    h += "<image width=\"" + std::to_string(f.image.width) + "\" height=\"" +
         std::to_string(f.image.height) + "\" href=\"" + jpeg_data_uri(f.image, 0) + "\"/>";
    for (const FrameBox& b : f.boxes) {
      const char* c = b.moving ? "#ff3030" : "#30c0ff";
      h += "<rect x=\"" + fmt("%.1f", b.x0) + "\" y=\"" + fmt("%.1f", b.y0) + "\" width=\"" +
           fmt("%.1f", b.x1 - b.x0) + "\" height=\"" + fmt("%.1f", b.y1 - b.y0) +
           "\" fill=\"none\" stroke-width=\"2\" stroke=\"" + c + "\"/>";
      h += "<text x=\"" + fmt("%.1f", b.x0 + 2) + "\" y=\"" + fmt("%.1f", b.y0 + 14) +
           "\" font-size=\"14\" font-family=\"sans-serif\" fill=\"" + c + "\">" +
           xml_escape(b.label) + "</text>";
    }
    for (const FramePoint& p : f.points) {
      h += "<circle cx=\"" + fmt("%.1f", p.x) + "\" cy=\"" + fmt("%.1f", p.y) +
           "\" r=\"2.5\" fill=\"" + (p.dynamic ? "#ff3030" : "#30ff60") + "\"/>";
    }
    h += "</svg><figcaption>" + xml_escape(f.caption) + "</figcaption></figure>\n";
  }
  bool points = false;
  for (const StripFrame& f : in.frames) points = points || !f.points.empty();
  return h + "</div>\n<p class=\"note\">Boxes: red = moving, blue = static." +
         (points ? " Points: green = static feature, red = rejected as dynamic." : "") + "</p>\n";
}

std::string grid_section(const GridMap& g) {
  const Image& im = g.occupancy;
  if (im.empty()) return "";
  const double w = im.width * g.resolution, hh = im.height * g.resolution;
  // World (x, y) to the grid image's pixel frame: y grows up in the world, down in the image.
  auto gx = [&](double x) { return fmt("%.3f", (x - g.origin_x) / g.resolution); };
  auto gy = [&](double y) { return fmt("%.3f", im.height - (y - g.origin_y) / g.resolution); };
  const int view_w = 640;
  const int view_h = static_cast<int>(std::lround(view_w * hh / std::max(w, 1e-9)));
  std::string h = "<svg id=\"grid\" width=\"" + std::to_string(view_w) + "\" height=\"" +
                  std::to_string(view_h) + "\" viewBox=\"0 0 " + std::to_string(im.width) + " " +
                  std::to_string(im.height) + "\">";
  h += "<image width=\"" + std::to_string(im.width) + "\" height=\"" + std::to_string(im.height) +
       "\" style=\"image-rendering:pixelated\" href=\"" + png_data_uri(im) + "\"/>";
  for (std::size_t i = 0; i < g.paths.size(); ++i) {
    h += "<polyline fill=\"none\" stroke-width=\"" + fmt("%.2f", 0.004 * im.width + 1) +
         "\" stroke=\"" + color_of(i) + "\" points=\"";
    for (const auto& [x, y] : g.paths[i]) h += gx(x) + "," + gy(y) + " ";
    h += "\"/>";
  }
  for (const GridMap::Object& o : g.objects) {
    h += "<circle cx=\"" + gx(o.x) + "\" cy=\"" + gy(o.y) + "\" r=\"" +
         fmt("%.2f", 0.006 * im.width + 1.5) + "\" fill=\"#ff7f0e\"/><text x=\"" + gx(o.x) +
         "\" y=\"" + gy(o.y) + "\" dx=\"4\" font-size=\"" + fmt("%.1f", 0.02 * im.width + 4) +
         "\" font-family=\"sans-serif\">" + xml_escape(o.label) + "</text>";
  }
  h += "</svg>\n<p class=\"note\">" + fmt("%.2f", g.resolution) + " m cells, " +
       std::to_string(im.width) + " × " + std::to_string(im.height) + "; " +
       std::to_string(g.objects.size()) + " objects, " + std::to_string(g.paths.size()) +
       " paths.</p>\n";
  return h;
}

std::string utc_now() {
  const std::time_t t = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M:%S UTC", &tm);
  return buf;
}

const char* kStyle = R"(<style>
body{font-family:sans-serif;margin:24px;color:#222;max-width:1300px}
h1{margin-bottom:4px}h2{border-bottom:1px solid #ccc;padding-bottom:3px;margin-top:28px}
table{border-collapse:collapse;margin:8px 0}td,th{border:1px solid #bbb;padding:3px 8px;text-align:right}
th{background:#f0f0f0}td:first-child{text-align:left}
.plots svg{margin:4px;border:1px solid #ddd}.strip{display:flex;flex-wrap:wrap;gap:8px}
figure{margin:0;width:400px}figcaption{font-size:12px;color:#555}.note{font-size:12px;color:#555}
pre{background:#f6f6f6;padding:8px;overflow-x:auto;font-size:12px}
</style>
)";

}  // namespace

std::string render_report(const ReportInput& in) {
  std::vector<Ape> apes;
  for (const RunRecord& r : in.runs) {
    apes.push_back(in.ground_truth ? compute_ape(*in.ground_truth, r.estimate) : Ape{});
    if (!in.ground_truth) apes.back().why = "no ground truth";
  }
  std::string h = "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>" +
                  xml_escape(in.title) + "</title>\n" + kStyle + "</head>\n<body>\n";
  h += "<h1>" + xml_escape(in.title) + "</h1>\n<p class=\"note\">kestrel " +
       xml_escape(in.version) + " · " + utc_now() + " · " + xml_escape(in.dataset) + "</p>\n";
  for (const std::string& n : in.notes) h += "<p>" + xml_escape(n) + "</p>\n";
  h += "<h2>Summary</h2>\n" + summary_table(in, apes);
  h += "<h2>Trajectories</h2>\n" + trajectory_plots(in, apes);
  h += "<h2>Dynamic-feature removal</h2>\n" + removal_table(in);
  h += "<h2>Frames</h2>\n" + frame_strip(in);
  if (in.grid) h += "<h2>Occupancy grid</h2>\n" + grid_section(*in.grid);
  h += "<h2>Per-stage timing</h2>\n" + timing_tables(in) + memory_plot(in);
  h += "<h2>Provenance</h2>\n<p>Command:</p>\n<pre id=\"command\">" + xml_escape(in.command_line) +
       "</pre>\n<p>Version: kestrel " + xml_escape(in.version) +
       "</p>\n<p>Config:</p>\n<pre id=\"config\">" +
       xml_escape(in.config_text.empty() ? "(defaults)" : in.config_text) + "</pre>\n";
  h += "</body>\n</html>\n";
  return h;
}

void write_report(const ReportInput& input, const std::string& path) {
  const std::string text = render_report(input);
  std::ofstream out(path, std::ios::binary);
  out << text;
  if (!out) throw Error::at(path, 0, "report.html", "cannot write the report");
}

}  // namespace kestrel::report
