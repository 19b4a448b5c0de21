#include "sim/photo_cutouts.hpp"

#include <algorithm>
#include <filesystem>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/error.hpp"

namespace kestrel::sim {
namespace {

struct Box {
  int x, y, w, h;  // pixels of the photo
};

// The table. The rectangles were read off the photos (and agree with YOLO-Fastest's boxes on
// them); hints fix what grabCut gets wrong from the rectangle alone: sure_fg marks subject it
// would drop (boots the colour of the grass), sure_bg background it would keep (leaves above
// the pickup's bonnet).
struct Entry {
  const char* name;
  const char* file;  // under images/
  Box rect;          // grabCut's initial rectangle: the subject lies inside
  std::vector<Box> sure_fg, sure_bg;
  int tex_w, tex_h;  // texture size, powers of two near the subject's aspect
  bool front_left;   // vehicles: the front points to the left of the photo
};

const std::vector<Entry>& table() {
  static const std::vector<Entry> t = {
      // A walker in a blue jacket, seen from behind (darknet's person.jpg).
      {"person-blue-jacket",
       "person.jpg",
       {186, 82, 94, 296},
       {{214, 330, 36, 38}},
       {},
       128,
       256,
       true},
      // A red estate car, side view, front to the left (PASCAL VOC 000004).
      {"car-red-wagon", "000004.jpg", {350, 326, 150, 62}, {}, {}, 256, 128, true},
      // A white pickup, side view, front to the right (darknet's dog.jpg, behind the bicycle).
      {"car-white-pickup", "dog.jpg", {462, 72, 225, 98}, {}, {{635, 72, 55, 45}}, 256, 128, false},
  };
  return t;
}

cv::Rect to_cv(const Box& b) { return {b.x, b.y, b.w, b.h}; }

}  // namespace

const std::vector<std::string>& cutout_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const Entry& e : table()) n.emplace_back(e.name);
    return n;
  }();
  return names;
}

Cutout load_cutout(const std::string& assets_dir, const std::string& name, bool mirror,
                   int columns) {
  const auto& t = table();
  const auto it = std::find_if(t.begin(), t.end(), [&](const Entry& e) { return name == e.name; });
  if (it == t.end()) {
    std::string known;
    for (const auto& n : cutout_names()) known += (known.empty() ? "" : ", ") + n;
    throw Error("photo cut-out '" + name + "' is not in the table (known: " + known + ")");
  }
  const Entry& e = *it;
  const std::string path = (std::filesystem::path(assets_dir) / "images" / e.file).string();
  if (!std::filesystem::exists(path))
    throw Error::at(path, 0, "", "photo not found (set KESTREL_SHARED or the scenario's assets)");
  const cv::Mat photo = cv::imread(path, cv::IMREAD_COLOR);
  if (photo.empty()) throw Error::at(path, 0, "", "cannot read the image");
  const cv::Rect image(0, 0, photo.cols, photo.rows);
  const cv::Rect rect = to_cv(e.rect) & image;
  if (rect.area() < 100) throw Error::at(path, 0, "", "cut-out '" + name + "' lies off the image");

  // grabCut from the rectangle, then once more with the hints. Its Gaussian mixtures start
  // from k-means on OpenCV's thread RNG: seeding it (and restoring it after) makes the mask,
  // and so every frame, the same on every run.
  cv::RNG& rng = cv::theRNG();
  const std::uint64_t saved = rng.state;
  rng.state = 0x5eed5eedULL;
  cv::Mat mask(photo.size(), CV_8U, cv::Scalar(cv::GC_BGD));
  mask(rect).setTo(cv::GC_PR_FGD);
  for (const Box& b : e.sure_fg) mask(to_cv(b) & rect).setTo(cv::GC_FGD);
  for (const Box& b : e.sure_bg) mask(to_cv(b) & image).setTo(cv::GC_BGD);
  cv::Mat bgd, fgd;
  cv::grabCut(photo, mask, rect, bgd, fgd, 6, cv::GC_INIT_WITH_MASK);
  rng.state = saved;
  cv::Mat subject = (mask == cv::GC_FGD) | (mask == cv::GC_PR_FGD);

  // Keep the largest region: grabCut leaves specks of look-alike background.
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(subject, labels, stats, centroids, 8, CV_32S);
  int best = 0;
  for (int i = 1; i < n; ++i)
    if (best == 0 || stats.at<int>(i, cv::CC_STAT_AREA) > stats.at<int>(best, cv::CC_STAT_AREA))
      best = i;
  if (best == 0) throw Error::at(path, 0, "", "grabCut found nothing in cut-out '" + name + "'");
  subject = labels == best;
  // Fill holes (a window pane grabCut took for sky) so the subject is solid: closing.
  cv::morphologyEx(subject, subject, cv::MORPH_CLOSE,
                   cv::getStructuringElement(cv::MORPH_ELLIPSE, {5, 5}));
  const cv::Rect box(stats.at<int>(best, cv::CC_STAT_LEFT), stats.at<int>(best, cv::CC_STAT_TOP),
                     stats.at<int>(best, cv::CC_STAT_WIDTH),
                     stats.at<int>(best, cv::CC_STAT_HEIGHT));

  cv::Mat colour, alpha;
  cv::resize(photo(box), colour, cv::Size(e.tex_w, e.tex_h), 0, 0, cv::INTER_AREA);
  cv::resize(subject(box), alpha, cv::Size(e.tex_w, e.tex_h), 0, 0, cv::INTER_LINEAR);
  if (mirror) {
    cv::flip(colour, colour, 1);
    cv::flip(alpha, alpha, 1);
  }
  std::vector<std::uint8_t> bgra(static_cast<std::size_t>(e.tex_w) * e.tex_h * 4);
  for (int y = 0; y < e.tex_h; ++y) {
    for (int x = 0; x < e.tex_w; ++x) {
      const cv::Vec3b c = colour.at<cv::Vec3b>(y, x);
      std::uint8_t* q = &bgra[(static_cast<std::size_t>(y) * e.tex_w + x) * 4];
      q[0] = c[0];
      q[1] = c[1];
      q[2] = c[2];
      q[3] = alpha.at<std::uint8_t>(y, x) >= 128 ? 255 : 0;
    }
  }
  Cutout out;
  out.texture = Texture::from_bgra(e.tex_w, e.tex_h, std::move(bgra), true);
  out.aspect = static_cast<double>(box.width) / box.height;
  out.front_left = e.front_left != mirror;
  // Paint for the parts the photo does not show (roof, bonnet, ends): the median colour of the
  // subject's middle band, below a car's windows and above its wheels.
  {
    std::vector<int> ch[3];
    for (int y = box.y + box.height * 2 / 5; y < box.y + box.height * 7 / 10; ++y)
      for (int x = box.x; x < box.x + box.width; ++x)
        if (subject.at<std::uint8_t>(y, x)) {
          const cv::Vec3b c = photo.at<cv::Vec3b>(y, x);
          for (int k = 0; k < 3; ++k) ch[k].push_back(c[k]);
        }
    for (int k = 0; k < 3; ++k) {
      if (ch[k].empty()) continue;
      std::nth_element(ch[k].begin(), ch[k].begin() + ch[k].size() / 2, ch[k].end());
      out.paint[static_cast<std::size_t>(2 - k)] = ch[k][ch[k].size() / 2];  // BGR to RGB
    }
  }

  // The silhouette per column bin: median top and bottom edge of the subject's columns.
  cv::Mat member = subject(box).clone();
  if (mirror) cv::flip(member, member, 1);
  for (int c = 0; c < columns; ++c) {
    const int x0 = c * member.cols / columns,
              x1 = std::max(x0 + 1, (c + 1) * member.cols / columns);
    std::vector<int> tops, bottoms;
    for (int x = x0; x < x1; ++x) {
      int top = -1, bottom = -1;
      for (int y = 0; y < member.rows; ++y) {
        if (member.at<std::uint8_t>(y, x) == 0) continue;
        if (top < 0) top = y;
        bottom = y + 1;
      }
      if (top >= 0) tops.push_back(top), bottoms.push_back(bottom);
    }
    if (tops.empty()) {
      out.top.push_back(1.0f);
      out.bottom.push_back(1.0f);
      continue;
    }
    std::nth_element(tops.begin(), tops.begin() + tops.size() / 2, tops.end());
    std::nth_element(bottoms.begin(), bottoms.begin() + bottoms.size() / 2, bottoms.end());
    out.top.push_back(static_cast<float>(tops[tops.size() / 2]) / member.rows);
    out.bottom.push_back(static_cast<float>(bottoms[bottoms.size() / 2]) / member.rows);
  }
  return out;
}

}  // namespace kestrel::sim
