// `kestrel vocab`: train the place-recognition vocabulary (loop/vocabulary.hpp) from image
// files and/or frames rendered by the simulator, and write it as a .kvoc file.
#include <glob.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "apps/commands.hpp"
#include "core/error.hpp"
#include "io/image_io.hpp"
#include "loop/vocabulary.hpp"
#include "sim/simulator.hpp"
#include "tracking/feature_extractor.hpp"

namespace {

namespace fs = std::filesystem;
using kestrel::tracking::OrbDescriptor;

struct VocabOptions {
  std::string out;
  std::vector<std::string> images;
  std::vector<std::string> scenarios;
  int k = 10;
  int levels = 4;
  int every = 15;          // simulator frames: one in `every`
  double duration = -1.0;  // simulator seconds per scenario (default: the scenario's)
  int features = 1000;
  long long seed = 42;
};

bool is_image(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".bmp";
}

// A folder (its images, sorted), a glob pattern, or one file.
std::vector<std::string> expand_images(const std::string& arg) {
  std::vector<std::string> files;
  if (fs::is_directory(arg)) {
    for (const auto& e : fs::directory_iterator(arg))
      if (e.is_regular_file() && is_image(e.path())) files.push_back(e.path().string());
  } else if (fs::is_regular_file(arg)) {
    files.push_back(arg);
  } else {
    glob_t g{};
    if (::glob(arg.c_str(), 0, nullptr, &g) == 0)
      for (std::size_t i = 0; i < g.gl_pathc; ++i)
        if (is_image(g.gl_pathv[i])) files.emplace_back(g.gl_pathv[i]);
    globfree(&g);
  }
  if (files.empty()) throw kestrel::Error::at(arg, 0, "--images", "no image files found");
  std::sort(files.begin(), files.end());
  return files;
}

kestrel::PinholeCamera camera_for(const kestrel::Image& image) {
  kestrel::PinholeCamera c;
  c.width = image.width;
  c.height = image.height;
  c.fx = c.fy = 0.8 * image.width;  // only pixel geometry matters for ORB on one image
  c.cx = image.width / 2.0;
  c.cy = image.height / 2.0;
  return c;
}

void run_vocab(const VocabOptions& opt) {
  if (opt.images.empty() && opt.scenarios.empty())
    throw kestrel::Error("kestrel vocab: give --images and/or --scenario");
  kestrel::tracking::FeatureExtractorOptions fo;
  fo.target_features = opt.features;
  std::vector<std::vector<OrbDescriptor>> training;
  std::size_t descriptors = 0;
  for (const auto& arg : opt.images) {
    for (const auto& file : expand_images(arg)) {
      const kestrel::Image image = kestrel::io::load_image(file, kestrel::io::ImageKind::kColor);
      const kestrel::tracking::FeatureExtractor extractor(camera_for(image), fo);
      training.push_back(extractor.extract(image).descriptors);
      descriptors += training.back().size();
    }
    std::printf("images %s: %zu images so far, %zu descriptors\n", arg.c_str(), training.size(),
                descriptors);
  }
  for (const auto& name : opt.scenarios) {
    kestrel::sim::ScenarioOverrides ov;
    ov.duration = opt.duration;
    kestrel::sim::Simulator sim(kestrel::sim::load_scenario(name, ov));
    const kestrel::tracking::FeatureExtractor extractor(sim.calibration().camera, fo);
    int frames = 0;
    for (int k = 0; k < sim.frame_count(); k += std::max(1, opt.every)) {
      training.push_back(extractor.extract(sim.render(k).color).descriptors);
      descriptors += training.back().size();
      ++frames;
    }
    std::printf("scenario %s: %d frames, %zu descriptors so far\n", name.c_str(), frames,
                descriptors);
  }
  const auto start = std::chrono::steady_clock::now();
  kestrel::loop::VocabularyOptions vo;
  vo.k = opt.k;
  vo.levels = opt.levels;
  vo.seed = static_cast<std::uint64_t>(opt.seed);
  const auto voc = kestrel::loop::Vocabulary::train(training, vo);
  const double secs =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  voc.save(opt.out);
  std::printf(
      "vocabulary k=%d levels=%d: %zu words, %zu nodes from %zu images in %.1f s -> %s "
      "(%ju bytes)\n",
      voc.k(), voc.levels(), voc.num_words(), voc.num_nodes(), training.size(), secs,
      opt.out.c_str(), static_cast<std::uintmax_t>(fs::file_size(opt.out)));
}

void setup_vocab(CLI::App& app) {
  auto opt = std::make_shared<VocabOptions>();
  auto* cmd = app.add_subcommand(
      "vocab", "Train the bag-of-words vocabulary for place recognition (loop closing)");
  cmd->add_option("--out", opt->out, "vocabulary file to write (.kvoc)")->required();
  cmd->add_option("--images", opt->images, "image folder, glob pattern or file (repeatable)");
  cmd->add_option("--scenario", opt->scenarios,
                  "simulator scenario (name or YAML) to render frames from (repeatable)");
  cmd->add_option("--k", opt->k, "branching factor")->check(CLI::Range(2, 64));
  cmd->add_option("--levels", opt->levels, "tree depth")->check(CLI::Range(1, 8));
  cmd->add_option("--every", opt->every, "use one simulator frame in EVERY")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--duration", opt->duration, "simulated seconds per scenario (default: its own)");
  cmd->add_option("--features", opt->features, "ORB features per image")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--seed", opt->seed, "k-means++ seed");
  cmd->callback([opt] {
    try {
      run_vocab(*opt);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "kestrel vocab: %s\n", e.what());
      kestrel::apps::exit_code() = 1;
    }
  });
}

}  // namespace

KESTREL_COMMAND(90, setup_vocab);
