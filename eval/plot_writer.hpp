#pragma once
// `--plot FILE`: a PNG with the trajectories seen from above and the error along the path,
// drawn by gnuplot run as an external process (nothing to link, and the figure is optional).
#include <string>

#include "eval/trajectory_evaluation.hpp"

namespace kestrel::eval {

// Throws kestrel::Error when gnuplot is missing, fails, or the PNG cannot be written.
void write_evaluation_plot(const std::string& png_path, const Evaluation& evaluation,
                           const std::string& error_label);

}  // namespace kestrel::eval
