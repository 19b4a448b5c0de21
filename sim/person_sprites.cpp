#include "sim/person_sprites.hpp"

#include <algorithm>
#include <filesystem>
#include <numeric>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/error.hpp"
#include "sim/photo_cutouts.hpp"

namespace kestrel::sim {
namespace {

std::string find_one(const std::filesystem::path& dir, const std::string& prefix) {
  std::error_code ec;
  std::vector<std::string> hits;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
    const std::string n = e.path().filename().string();
    if (n.rfind(prefix, 0) == 0 && e.path().extension() == ".png")
      hits.push_back(e.path().string());
  }
  if (hits.empty())
    throw Error::at((dir / (prefix + "*.png")).string(), 0, "",
                    "person photo not found (set KESTREL_SHARED or the scenario's assets)");
  std::sort(hits.begin(), hits.end());
  return hits.front();
}

Sprite cut(const cv::Mat& rgb, const cv::Mat& member, cv::Rect box, bool mirror) {
  // Textures are powers of two; the cut-out is stretched into 128x256 and the quad restores
  // its aspect.
  constexpr int kW = 128, kH = 256;
  cv::Mat colour, alpha;
  cv::resize(rgb(box), colour, cv::Size(kW, kH), 0, 0, cv::INTER_AREA);
  cv::resize(member(box), alpha, cv::Size(kW, kH), 0, 0, cv::INTER_LINEAR);
  if (mirror) {
    cv::flip(colour, colour, 1);
    cv::flip(alpha, alpha, 1);
  }
  std::vector<std::uint8_t> bgra(static_cast<std::size_t>(kW) * kH * 4);
  for (int y = 0; y < kH; ++y) {
    for (int x = 0; x < kW; ++x) {
      const cv::Vec3b c = colour.at<cv::Vec3b>(y, x);
      std::uint8_t* q = &bgra[(static_cast<std::size_t>(y) * kW + x) * 4];
      q[0] = c[0];
      q[1] = c[1];
      q[2] = c[2];
      q[3] = alpha.at<std::uint8_t>(y, x) >= 128 ? 255 : 0;
    }
  }
  Sprite s;
  s.texture = Texture::from_bgra(kW, kH, std::move(bgra), true);
  s.aspect = static_cast<double>(box.width) / box.height;
  return s;
}

}  // namespace

std::vector<Sprite> load_person_sprites(const std::string& assets_dir) {
  const std::filesystem::path dir = std::filesystem::path(assets_dir) / "tum_fr3" / "frame";
  const std::string rgb_path = find_one(dir, "rgb_");
  const std::string mask_path = find_one(dir, "static_mask_");
  const cv::Mat rgb = cv::imread(rgb_path, cv::IMREAD_COLOR);
  const cv::Mat mask = cv::imread(mask_path, cv::IMREAD_GRAYSCALE);
  if (rgb.empty()) throw Error::at(rgb_path, 0, "", "cannot read the image");
  if (mask.empty() || mask.size() != rgb.size())
    throw Error::at(mask_path, 0, "", "cannot read the mask or its size differs from the image");
  // The mask is 0 on people. Each large connected region is one person.
  cv::Mat person = mask == 0;
  cv::morphologyEx(person, person, cv::MORPH_OPEN,
                   cv::getStructuringElement(cv::MORPH_ELLIPSE, {5, 5}));
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(person, labels, stats, centroids, 8, CV_32S);
  std::vector<int> order;
  for (int i = 1; i < n; ++i)
    if (stats.at<int>(i, cv::CC_STAT_AREA) > 2000) order.push_back(i);
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    return stats.at<int>(a, cv::CC_STAT_LEFT) < stats.at<int>(b, cv::CC_STAT_LEFT);
  });
  if (order.empty()) throw Error::at(mask_path, 0, "", "no person region in the mask");
  std::vector<Sprite> sprites;
  for (bool mirror : {false, true}) {
    for (int i : order) {
      const cv::Rect box(stats.at<int>(i, cv::CC_STAT_LEFT), stats.at<int>(i, cv::CC_STAT_TOP),
                         stats.at<int>(i, cv::CC_STAT_WIDTH), stats.at<int>(i, cv::CC_STAT_HEIGHT));
      sprites.push_back(cut(rgb, labels == i, box, mirror));
    }
  }
  // Then the people of the photos (no masks: grabCut cuts them), each also mirrored, so that
  // the walkers differ in clothes, pose and view and not only in the TUM pair.
  for (const std::string& name : cutout_names()) {
    if (name.rfind("person-", 0) != 0) continue;
    for (bool mirror : {false, true}) {
      Cutout c = load_cutout(assets_dir, name, mirror);
      sprites.push_back({std::move(c.texture), c.aspect});
    }
  }
  return sprites;
}

}  // namespace kestrel::sim
