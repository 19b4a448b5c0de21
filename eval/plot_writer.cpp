#include "eval/plot_writer.hpp"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>

#include "core/error.hpp"

extern char** environ;

namespace kestrel::eval {
namespace {

namespace fs = std::filesystem;

// gnuplot single-quoted strings escape a quote by doubling it.
std::string quoted(const std::string& s) {
  std::string out = "'";
  for (char c : s) {
    if (c == '\'') out += '\'';
    if (c == '\n') {
      out += ", ";
      continue;
    }
    out += c;
  }
  return out + "'";
}

// The top view shows the two axes along which the reference moves most (x-y for a robot on
// the ground with z up, x-z for KITTI's camera frame with y down).
std::array<int, 2> top_view_axes(const Evaluation& ev) {
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 hi = -lo;
  for (const Mat4& p : ev.ref) {
    lo = lo.cwiseMin(p.topRightCorner<3, 1>());
    hi = hi.cwiseMax(p.topRightCorner<3, 1>());
  }
  const Vec3 extent = hi - lo;
  int smallest = 0;
  for (int k = 1; k < 3; ++k) {
    if (extent(k) < extent(smallest)) smallest = k;
  }
  return smallest == 0 ? std::array<int, 2>{1, 2}
                       : (smallest == 1 ? std::array<int, 2>{0, 2} : std::array<int, 2>{0, 1});
}

void run_gnuplot(const fs::path& script) {
  const std::string program = "gnuplot";
  const std::string script_text = script.string();
  char* argv[] = {const_cast<char*>(program.c_str()), const_cast<char*>(script_text.c_str()),
                  nullptr};
  pid_t pid = 0;
  const int rc = posix_spawnp(&pid, program.c_str(), nullptr, nullptr, argv, environ);
  if (rc == ENOENT) {
    throw Error("--plot needs gnuplot, which is not on PATH (Debian: apt install gnuplot-nox)");
  }
  if (rc != 0) throw Error(std::string("cannot start gnuplot: ") + std::strerror(rc));
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) throw Error(std::string("waiting for gnuplot: ") + std::strerror(errno));
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    throw Error("gnuplot failed on " + script_text);
  }
}

}  // namespace

void write_evaluation_plot(const std::string& png_path, const Evaluation& ev,
                           const std::string& error_label) {
  static const char* kAxisNames[] = {"x", "y", "z"};
  const fs::path dir =
      fs::temp_directory_path() / ("kestrel-plot-" + std::to_string(::getpid()) + "-" +
                                   std::to_string(reinterpret_cast<std::uintptr_t>(&ev)));
  fs::create_directories(dir);
  const auto axes = top_view_axes(ev);
  {
    std::ofstream traj(dir / "trajectories.dat");
    for (std::size_t k = 0; k < ev.ref.size(); ++k) {
      traj << ev.ref[k](axes[0], 3) << ' ' << ev.ref[k](axes[1], 3) << ' ' << ev.est[k](axes[0], 3)
           << ' ' << ev.est[k](axes[1], 3) << '\n';
    }
    // Distance travelled along the reference, the x axis of the error plot.
    std::vector<double> travelled(ev.ref.size(), 0.0);
    for (std::size_t k = 1; k < ev.ref.size(); ++k) {
      travelled[k] =
          travelled[k - 1] +
          (ev.ref[k].topRightCorner<3, 1>() - ev.ref[k - 1].topRightCorner<3, 1>()).norm();
    }
    std::ofstream err(dir / "errors.dat");
    for (std::size_t k = 0; k < ev.errors.size(); ++k) {
      err << travelled[ev.error_pose[k]] << ' ' << ev.errors[k] << '\n';
    }
    if (!traj || !err) throw Error::at((dir / "trajectories.dat").string(), 0, "", "write error");
  }
  const fs::path script = dir / "plot.gp";
  {
    std::ofstream gp(script);
    gp << "set terminal pngcairo size 1400,650 font 'Sans,10'\n"
       << "set output " << quoted(png_path) << "\n"
       << "set multiplot layout 1,2 title " << quoted(ev.title) << "\n"
       << "set grid\n"
       << "set title 'trajectories (top view)'\n"
       << "set xlabel '" << kAxisNames[axes[0]] << " (m)'\n"
       << "set ylabel '" << kAxisNames[axes[1]] << " (m)'\n"
       << "set size ratio -1\n"
       << "plot " << quoted((dir / "trajectories.dat").string())
       << " using 1:2 with lines lw 2 lc rgb 'gray50' title 'reference', '' using 3:4 with lines "
          "lc rgb '#1f77b4' title 'estimate'\n"
       << "set size noratio\n"
       << "set title 'error along the path'\n"
       << "set xlabel 'distance along the reference (m)'\n"
       << "set ylabel " << quoted(error_label) << "\n"
       << "plot " << quoted((dir / "errors.dat").string())
       << " using 1:2 with lines lc rgb '#d62728' title " << quoted(error_label) << "\n"
       << "unset multiplot\n";
    if (!gp) throw Error::at(script.string(), 0, "", "write error");
  }
  try {
    run_gnuplot(script);
  } catch (...) {
    fs::remove_all(dir);
    throw;
  }
  fs::remove_all(dir);
  if (!fs::exists(png_path) || fs::file_size(png_path) == 0) {
    throw Error::at(png_path, 0, "", "gnuplot wrote no image");
  }
}

}  // namespace kestrel::eval
