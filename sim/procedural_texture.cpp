#include "sim/procedural_texture.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/error.hpp"

namespace kestrel::sim {

std::uint64_t hash64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

namespace {

double unit(std::uint64_t h) { return static_cast<double>(h >> 11) * (1.0 / 9007199254740992.0); }

// Periodic value noise: lattice of `cells` per side, wrapping, so the texture tiles seamlessly.
class ValueNoise {
 public:
  explicit ValueNoise(std::uint64_t seed) : seed_(seed) {}
  double at(double x, double y, int cells, int octave) const {
    const std::vector<double>& grid = lattice(cells, octave);
    const int ix = static_cast<int>(std::floor(x)), iy = static_cast<int>(std::floor(y));
    const double fx = x - ix, fy = y - iy;
    const double sx = fx * fx * (3 - 2 * fx), sy = fy * fy * (3 - 2 * fy);
    const int mask = cells - 1;  // cells is a power of two
    const auto value = [&](int a, int b) {
      return grid[static_cast<std::size_t>(b & mask) * cells + static_cast<std::size_t>(a & mask)];
    };
    const double v00 = value(ix, iy), v10 = value(ix + 1, iy);
    const double v01 = value(ix, iy + 1), v11 = value(ix + 1, iy + 1);
    return (v00 * (1 - sx) + v10 * sx) * (1 - sy) + (v01 * (1 - sx) + v11 * sx) * sy;
  }
  // Fractal noise in [0, 1] (octaves summed with gain 0.55) at every texel of an n x n texture,
  // octave by octave so that one lattice is in use at a time.
  std::vector<double> fbm_image(int n, int base_cells, int octaves) const {
    std::vector<double> out(static_cast<std::size_t>(n) * n, 0.0);
    double amp = 1, norm = 0;
    int cells = base_cells;
    for (int o = 0; o < octaves; ++o) {
      for (int y = 0; y < n; ++y) {
        for (int x = 0; x < n; ++x) {
          out[static_cast<std::size_t>(y) * n + x] +=
              amp *
              at(static_cast<double>(x) / n * cells, static_cast<double>(y) / n * cells, cells, o);
        }
      }
      norm += amp;
      amp *= 0.55;
      cells *= 2;
    }
    for (double& v : out) v /= norm;
    return out;
  }

 private:
  // Random lattice values of one octave, hashed once (per texel hashing made big textures slow).
  const std::vector<double>& lattice(int cells, int octave) const {
    const std::uint64_t key =
        (static_cast<std::uint64_t>(cells) << 8) | static_cast<std::uint64_t>(octave);
    auto it = grids_.find(key);
    if (it != grids_.end()) return it->second;
    std::vector<double> grid(static_cast<std::size_t>(cells) * cells);
    for (int b = 0; b < cells; ++b)
      for (int a = 0; a < cells; ++a)
        grid[static_cast<std::size_t>(b) * cells + a] = unit(hash_combine(
            hash_combine(seed_, static_cast<std::uint64_t>(octave)),
            static_cast<std::uint64_t>(a) * 73856093ULL ^ static_cast<std::uint64_t>(b)));
    return grids_.emplace(key, std::move(grid)).first->second;
  }

  std::uint64_t seed_;
  mutable std::map<std::uint64_t, std::vector<double>> grids_;
  mutable std::uint64_t last_key_ = 0;
  mutable const std::vector<double>* last_ = nullptr;
};

struct Canvas {
  int n;
  std::vector<double> rgb;  // 3 doubles per texel, 0..255
  explicit Canvas(int size) : n(size), rgb(static_cast<std::size_t>(size) * size * 3, 0.0) {}
  double* at(int x, int y) {
    x = ((x % n) + n) % n;
    y = ((y % n) + n) % n;
    return rgb.data() + (static_cast<std::size_t>(y) * n + x) * 3;
  }
  void blend(int x, int y, const double c[3], double a) {
    double* p = at(x, y);
    for (int k = 0; k < 3; ++k) p[k] = p[k] * (1 - a) + c[k] * a;
  }
  void rect(int x0, int y0, int w, int h, const double c[3], double a) {
    for (int y = y0; y < y0 + h; ++y)
      for (int x = x0; x < x0 + w; ++x) blend(x, y, c, a);
  }
  void disc(double cx, double cy, double r, const double c[3], double a) {
    for (int y = static_cast<int>(cy - r) - 1; y <= static_cast<int>(cy + r) + 1; ++y)
      for (int x = static_cast<int>(cx - r) - 1; x <= static_cast<int>(cx + r) + 1; ++x)
        if ((x - cx) * (x - cx) + (y - cy) * (y - cy) <= r * r) blend(x, y, c, a);
  }
};

class Rng {
 public:
  explicit Rng(std::uint64_t seed) : state_(seed) {}
  double uniform() { return unit(hash64(state_++)); }
  double uniform(double a, double b) { return a + (b - a) * uniform(); }
  int integer(int a, int b) { return a + static_cast<int>(uniform() * (b - a + 1) * 0.999999); }

 private:
  std::uint64_t state_;
};

void mix(const std::array<int, 3>& a, const std::array<int, 3>& b, double t, double out[3]) {
  for (int k = 0; k < 3; ++k)
    out[k] = a[static_cast<std::size_t>(k)] * (1 - t) + b[static_cast<std::size_t>(k)] * t;
}

// Scattered marks (speckles, strokes, blobs): the corners that trackers lock on to.
void scatter_marks(Canvas& cv, Rng& rng, int count, double contrast) {
  for (int i = 0; i < count; ++i) {
    const double shade = rng.uniform() < 0.5 ? rng.uniform(0, 60) : rng.uniform(190, 255);
    const double c[3] = {shade * rng.uniform(0.7, 1.0), shade * rng.uniform(0.7, 1.0),
                         shade * rng.uniform(0.7, 1.0)};
    const double a = 0.35 * contrast + 0.4 * contrast * rng.uniform();
    const int kind = rng.integer(0, 2);
    const double x = rng.uniform(0, cv.n), y = rng.uniform(0, cv.n);
    if (kind == 0) {
      cv.disc(x, y, rng.uniform(1.0, cv.n / 40.0), c, a);
    } else if (kind == 1) {
      cv.rect(static_cast<int>(x), static_cast<int>(y), rng.integer(2, cv.n / 24),
              rng.integer(1, 4), c, a);
    } else {
      cv.rect(static_cast<int>(x), static_cast<int>(y), rng.integer(1, 4),
              rng.integer(2, cv.n / 24), c, a);
    }
  }
}

void base_noise(Canvas& cv, const ValueNoise& noise, const TextureSpec& s, int cells,
                double contrast) {
  const std::vector<double> f = noise.fbm_image(cv.n, cells, 6);
  for (int y = 0; y < cv.n; ++y) {
    for (int x = 0; x < cv.n; ++x) {
      const double t = std::clamp(
          0.5 + (f[static_cast<std::size_t>(y) * cv.n + x] - 0.5) * 2.2 * contrast, 0.0, 1.0);
      double c[3];
      mix(s.color_a, s.color_b, t, c);
      double* p = cv.at(x, y);
      for (int k = 0; k < 3; ++k) p[k] = c[k];
    }
  }
}

Texture load_photo(const TextureSpec& spec) {
  cv::Mat img = cv::imread(spec.photo, cv::IMREAD_COLOR);
  if (img.empty()) throw Error::at(spec.photo, 0, "photo", "cannot read the image");
  cv::Mat sized;
  cv::resize(img, sized, cv::Size(spec.size, spec.size), 0, 0, cv::INTER_AREA);
  std::vector<std::uint8_t> bgra(static_cast<std::size_t>(spec.size) * spec.size * 4);
  for (int y = 0; y < spec.size; ++y) {
    for (int x = 0; x < spec.size; ++x) {
      const cv::Vec3b p = sized.at<cv::Vec3b>(y, x);
      std::uint8_t* q = &bgra[(static_cast<std::size_t>(y) * spec.size + x) * 4];
      q[0] = p[0];
      q[1] = p[1];
      q[2] = p[2];
      q[3] = 255;
    }
  }
  return Texture::from_bgra(spec.size, spec.size, std::move(bgra), false);
}

}  // namespace

Texture make_texture(const TextureSpec& spec, std::uint64_t seed) {
  if (!is_power_of_two(spec.size) || spec.size < 16 || spec.size > 4096) {
    throw Error("texture: size " + std::to_string(spec.size) +
                " must be a power of two in 16..4096");
  }
  if (spec.style == "photo") return load_photo(spec);
  const int n = spec.size;
  Canvas cv(n);
  ValueNoise noise(seed);
  Rng rng(hash_combine(seed, 12345));
  const double contrast = std::clamp(spec.contrast, 0.0, 1.0);
  if (spec.style == "noise") {
    base_noise(cv, noise, spec, 4, contrast);
    scatter_marks(cv, rng, static_cast<int>(n * n / 350 * contrast), contrast);
  } else if (spec.style == "bricks" || spec.style == "tiles") {
    base_noise(cv, noise, spec, 8, 0.5 * contrast);
    const bool bricks = spec.style == "bricks";
    const int rows = bricks ? 16 : 8, cols = bricks ? 8 : 8;
    const int bh = n / rows, bw = n / cols;
    for (int r = 0; r < rows; ++r) {
      const int off = bricks && (r % 2) ? bw / 2 : 0;
      for (int c = 0; c < cols; ++c) {
        const double g = rng.uniform(0.75, 1.2);
        for (int y = r * bh; y < (r + 1) * bh; ++y) {
          for (int x = c * bw + off; x < (c + 1) * bw + off; ++x) {
            double* p = cv.at(x, y);
            const bool mortar = (y - r * bh) < 2 || (x - c * bw - off) < 2;
            for (int k = 0; k < 3; ++k) p[k] = mortar ? 0.45 * p[k] : std::min(255.0, p[k] * g);
          }
        }
      }
    }
    scatter_marks(cv, rng, static_cast<int>(n * n / 900 * contrast), contrast);
  } else if (spec.style == "posters") {
    base_noise(cv, noise, spec, 4, 0.6 * contrast);
    for (int i = 0; i < 14; ++i) {
      const double c[3] = {rng.uniform(20, 255), rng.uniform(20, 255), rng.uniform(20, 255)};
      const int w = rng.integer(n / 10, n / 4), h = rng.integer(n / 10, n / 3);
      const int x = rng.integer(0, n - 1), y = rng.integer(0, n - 1);
      cv.rect(x, y, w, h, c, 0.9 * contrast);
      // Text-like lines of short dark strokes.
      const double ink[3] = {rng.uniform(0, 60), rng.uniform(0, 60), rng.uniform(0, 60)};
      for (int line = 0; line < h / 8; ++line) {
        int xx = x + 3;
        while (xx < x + w - 6) {
          const int len = rng.integer(2, 7);
          cv.rect(xx, y + 4 + line * 8, len, 3, ink, 0.85 * contrast);
          xx += len + rng.integer(1, 4);
        }
      }
    }
    scatter_marks(cv, rng, static_cast<int>(n * n / 1500 * contrast), contrast);
  } else if (spec.style == "wood") {
    const std::vector<double> warp = noise.fbm_image(n, 2, 4),
                              grain_noise = noise.fbm_image(n, 16, 3);
    for (int y = 0; y < n; ++y) {
      for (int x = 0; x < n; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * n + x;
        const double v = static_cast<double>(y) / n;
        const double grain = 0.5 + 0.5 * std::sin(2 * M_PI * (v * 7 + 2.0 * warp[i]));
        const double t = std::clamp(0.25 + 0.6 * grain * contrast + 0.2 * grain_noise[i], 0.0, 1.0);
        double c[3];
        mix(spec.color_a, spec.color_b, t, c);
        double* p = cv.at(x, y);
        for (int k = 0; k < 3; ++k) p[k] = c[k];
      }
    }
    scatter_marks(cv, rng, static_cast<int>(n * n / 2000 * contrast), contrast);
  } else if (spec.style == "car") {
    // Body paint with a band of dark windows on top and two wheels below: reads as a vehicle.
    base_noise(cv, noise, spec, 8, 0.25 * contrast);
    const double glass[3] = {40, 45, 55}, tyre[3] = {20, 20, 20}, rim[3] = {170, 170, 175};
    cv.rect(n / 10, n / 12, n * 8 / 10, n / 4, glass, 0.9);
    cv.rect(n / 2 - 2, n / 12, 4, n / 4, rim, 1.0);
    for (const double cx : {0.22 * n, 0.78 * n}) {
      cv.disc(cx, 0.8 * n, 0.14 * n, tyre, 1.0);
      cv.disc(cx, 0.8 * n, 0.07 * n, rim, 1.0);
    }
    const double light[3] = {240, 240, 200};
    cv.rect(n / 40, n / 2, n / 20, n / 12, light, 1.0);
    scatter_marks(cv, rng, static_cast<int>(n * n / 3000 * contrast), contrast);
  } else {
    throw Error("texture: unknown style '" + spec.style +
                "' (noise, bricks, tiles, posters, wood, car, photo)");
  }
  std::vector<std::uint8_t> bgra(static_cast<std::size_t>(n) * n * 4);
  for (std::size_t i = 0; i < static_cast<std::size_t>(n) * n; ++i) {
    // RGB canvas to BGRA texels.
    bgra[4 * i + 0] = static_cast<std::uint8_t>(std::clamp(cv.rgb[3 * i + 2], 0.0, 255.0));
    bgra[4 * i + 1] = static_cast<std::uint8_t>(std::clamp(cv.rgb[3 * i + 1], 0.0, 255.0));
    bgra[4 * i + 2] = static_cast<std::uint8_t>(std::clamp(cv.rgb[3 * i + 0], 0.0, 255.0));
    bgra[4 * i + 3] = 255;
  }
  return Texture::from_bgra(n, n, std::move(bgra), false);
}

}  // namespace kestrel::sim
