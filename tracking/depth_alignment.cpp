#include "tracking/depth_alignment.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>
#include <vector>

#include "core/so3.hpp"

namespace kestrel::tracking {
namespace {

// One depth reading's sigma at range z.
double reading_sigma(const DepthAlignmentOptions& o, double z) {
  return o.depth_sigma_floor + o.depth_sigma_z2 * z * z;
}

struct Cell {
  Vec3 p = Vec3::Zero();  // mean back-projected point
  Vec3 n = Vec3::Zero();  // unit normal towards the camera; zero when none
  double sigma = 0.0;     // of the mean's depth
  bool valid = false;
};

// Mean points of cell_px x cell_px cells, and (for the reference) normals from the neighbouring
// cells, none across a depth edge (the two sides of an outline are different surfaces).
class CellGrid {
 public:
  CellGrid(const Image& im, double scale, const PinholeCamera& cam, const DepthAlignmentOptions& o,
           bool normals)
      : size_(std::max(1, o.cell_px)),
        cols_(im.width / size_),
        rows_(im.height / size_),
        cells_(static_cast<std::size_t>(cols_) * rows_) {
    const double inv_scale = 1.0 / scale;
    const int need = static_cast<int>(std::ceil(o.min_cell_fill * size_ * size_));
    for (int cy = 0; cy < rows_; ++cy) {
      for (int cx = 0; cx < cols_; ++cx) {
        Vec3 sum = Vec3::Zero();
        double z_min = 1e9, z_max = 0.0;
        int count = 0;
        for (int v = cy * size_; v < (cy + 1) * size_; ++v) {
          const auto* row = im.row<std::uint16_t>(v);
          for (int u = cx * size_; u < (cx + 1) * size_; ++u) {
            const double z = row[u] * inv_scale;
            if (!(z >= o.min_depth_m && z <= o.max_depth_m)) continue;
            sum += Vec3((u - cam.cx) / cam.fx * z, (v - cam.cy) / cam.fy * z, z);
            z_min = std::min(z_min, z);
            z_max = std::max(z_max, z);
            ++count;
          }
        }
        if (count < need) continue;
        Cell& c = at(cx, cy);
        c.p = sum / count;
        const double one = reading_sigma(o, c.p.z());
        // A cell straddling an edge has no single surface.
        if (z_max - z_min > 6.0 * one + 0.02 * c.p.z()) continue;
        c.sigma = one / std::sqrt(static_cast<double>(count));
        c.valid = true;
      }
    }
    if (!normals) return;
    // The normal of the plane fitted to the cell means around each cell (radius normal_cells):
    // neighbouring means alone are a few centimetres apart at a few metres, where their noise
    // tilts a normal by a tenth of a radian, and a tilted normal invents constraints along the
    // surface that depth does not give.
    const int k = std::max(1, o.normal_cells);
    for (int cy = k; cy + k < rows_; ++cy) {
      for (int cx = k; cx + k < cols_; ++cx) {
        Cell& c = at(cx, cy);
        if (!c.valid) continue;
        Vec3 mean = Vec3::Zero();
        Mat3 scatter = Mat3::Zero();
        int m = 0;
        for (int dy = -k; dy <= k; ++dy) {
          for (int dx = -k; dx <= k; ++dx) {
            const Cell& q = at(cx + dx, cy + dy);
            if (!q.valid) continue;
            mean += q.p;
            scatter += q.p * q.p.transpose();
            ++m;
          }
        }
        if (m < (2 * k + 1) * (2 * k + 1) * 2 / 3) continue;
        mean /= m;
        scatter = scatter / m - mean * mean.transpose();
        const Eigen::SelfAdjointEigenSolver<Mat3> eig(scatter);
        // Off the plane by more than the noise (an edge, a crease, a corner): no single surface.
        const double one = reading_sigma(o, c.p.z());
        const double off_plane = std::sqrt(std::max(0.0, eig.eigenvalues()(0)));
        if (off_plane > 3.0 * one / std::sqrt(o.min_cell_fill * size_ * size_) + 0.002) continue;
        const Vec3 n = eig.eigenvectors().col(0);
        c.n = n.dot(c.p) > 0.0 ? Vec3(-n) : n;
      }
    }
  }

  int size() const { return size_; }
  int cols() const { return cols_; }
  int rows() const { return rows_; }
  const Cell& at(int cx, int cy) const { return cells_[static_cast<std::size_t>(cy) * cols_ + cx]; }

 private:
  Cell& at(int cx, int cy) { return cells_[static_cast<std::size_t>(cy) * cols_ + cx]; }

  int size_, cols_, rows_;
  std::vector<Cell> cells_;
};

bool usable(const Image& im, double scale, const PinholeCamera& cam) {
  return !im.empty() && im.type == PixelType::kU16 && im.channels == 1 && scale > 0.0 &&
         im.width == cam.width && im.height == cam.height;
}

// The pixel where the current camera (T = T_ref_cur) sees a reference point, with its
// Jacobian for a left update [rotation, translation] of T; false behind the camera.
bool track_residual(const CornerTrack& t, const PinholeCamera& camera, const SE3& T, Vec2& r,
                    Eigen::Matrix<double, 2, 6>* J) {
  const Mat3 Rt = T.so3().matrix().transpose();
  const Vec3 x = Rt * (t.p_ref - T.translation());
  if (!(x.z() > 1e-6)) return false;
  r = Vec2(camera.fx * x.x() / x.z() + camera.cx, camera.fy * x.y() / x.z() + camera.cy) - t.uv_cur;
  if (J) {
    // x(exp(d) T) = R^T dR^T (p - dR t - dt): dx/dphi = R^T [p]x, dx/dt = -R^T.
    Eigen::Matrix<double, 3, 6> dx;
    dx.leftCols<3>() = Rt * SO3::hat(t.p_ref);
    dx.rightCols<3>() = -Rt;
    *J = camera.project_jacobian(x) * dx;
  }
  return true;
}

void add_tracks(const std::vector<CornerTrack>& tracks, const PinholeCamera& camera, const SE3& T,
                const DepthAlignmentOptions& o, Mat6& H, Vec6& g) {
  const double inv_s2 = 1.0 / (o.track_pixel_sigma * o.track_pixel_sigma);
  const double k = 2.0 * o.track_pixel_sigma;
  for (const CornerTrack& t : tracks) {
    Vec2 r;
    Eigen::Matrix<double, 2, 6> J;
    if (!track_residual(t, camera, T, r, &J)) continue;
    const double e = r.norm();
    if (!(e <= o.track_max_px)) continue;
    const double w = (e <= k ? 1.0 : k / e) * inv_s2;
    H.noalias() += w * J.transpose() * J;
    g.noalias() += w * J.transpose() * r;
  }
}

// The prior's translation can be off by more than the tracks' gate: a centimetre is 5 px at a
// wall 1.1 m away (corridor-dark, seed 6, 18.7 s), and there the tracks LK slid 7-15 px
// happened to lie within the gate of the prior while the true ones did not, and took the step
// 16 mm off. The gyro's rotation is good to a fraction of a pixel, so each track alone
// proposes the translation that puts it where it was found (the least change that does); the
// proposal most tracks agree with (within track_max_px) is where the alignment starts.
std::optional<Vec3> consensus_shift(const std::vector<CornerTrack>& tracks,
                                    const PinholeCamera& camera, const SE3& T,
                                    const DepthAlignmentOptions& o) {
  struct Linear {
    Vec2 r;
    Eigen::Matrix<double, 2, 3> Jt;
  };
  std::vector<Linear> lin;
  lin.reserve(tracks.size());
  for (const CornerTrack& t : tracks) {
    Linear l;
    Eigen::Matrix<double, 2, 6> J;
    if (!track_residual(t, camera, T, l.r, &J)) continue;
    l.Jt = J.rightCols<3>();
    lin.push_back(l);
  }
  const double gate2 = o.track_max_px * o.track_max_px;
  int best = 0;
  Vec3 best_shift = Vec3::Zero();
  for (const Linear& a : lin) {
    const Mat2 JJt = a.Jt * a.Jt.transpose();
    if (std::abs(JJt.determinant()) < 1e-12) continue;
    const Vec3 shift = -a.Jt.transpose() * JJt.inverse() * a.r;
    int agree = 0;
    for (const Linear& b : lin) agree += (b.r + b.Jt * shift).squaredNorm() <= gate2;
    if (agree > best) {
      best = agree;
      best_shift = shift;
    }
  }
  int at_prior = 0;
  for (const Linear& b : lin) at_prior += b.r.squaredNorm() <= gate2;
  if (best <= at_prior) return std::nullopt;
  return best_shift;
}

int track_inliers(const std::vector<CornerTrack>& tracks, const PinholeCamera& camera, const SE3& T,
                  double inlier_px) {
  int n = 0;
  for (const CornerTrack& t : tracks) {
    Vec2 r;
    if (track_residual(t, camera, T, r, nullptr) && r.norm() <= inlier_px) ++n;
  }
  return n;
}

}  // namespace

DepthAlignmentResult align_depth(const Image& ref_depth, double ref_scale, const Image& cur_depth,
                                 double cur_scale, const PinholeCamera& camera,
                                 const DepthAlignmentPrior& prior,
                                 const DepthAlignmentOptions& options,
                                 const std::vector<PixelBox>& exclude,
                                 const std::vector<CornerTrack>& tracks) {
  DepthAlignmentResult result;
  result.T_ref_cur = prior.T_ref_cur;
  if (!usable(ref_depth, ref_scale, camera) || !usable(cur_depth, cur_scale, camera) ||
      !prior.T_ref_cur.is_finite() || !(prior.rotation_sigma > 0.0) ||
      !(prior.translation_sigma > 0.0)) {
    return result;
  }
  const CellGrid cur(cur_depth, cur_scale, camera, options, false);
  std::vector<const Cell*> points;
  int valid = 0;
  for (int cy = 0; cy < cur.rows(); ++cy) {
    for (int cx = 0; cx < cur.cols(); ++cx) {
      if (!cur.at(cx, cy).valid) continue;
      ++valid;
      const double u = (cx + 0.5) * cur.size(), v = (cy + 0.5) * cur.size();
      const auto inside = [&](const PixelBox& b) { return b.contains(u, v); };
      if (std::none_of(exclude.begin(), exclude.end(), inside)) points.push_back(&cur.at(cx, cy));
    }
  }
  if (static_cast<int>(points.size()) < options.min_points ||
      static_cast<double>(valid - static_cast<int>(points.size())) >
          options.max_excluded_share * valid) {
    return result;
  }
  // Only now the reference's normals, the costly part: most refusals are movers' boxes.
  const CellGrid ref(ref_depth, ref_scale, camera, options, true);

  const double w_rot = 1.0 / (prior.rotation_sigma * prior.rotation_sigma);
  const double w_trans = 1.0 / (prior.translation_sigma * prior.translation_sigma);
  SE3 T = prior.T_ref_cur;
  if (const auto shift = consensus_shift(tracks, camera, T, options)) {
    T = SE3(T.so3(), T.translation() + *shift);
  }
  Mat3 data_tt = Mat3::Zero();
  Mat6 data = Mat6::Zero();
  for (int it = 0; it < options.iterations; ++it) {
    Mat6 H = Mat6::Zero();  // [rotation, translation] of a left update of T
    Vec6 g = Vec6::Zero();
    Mat3 Htt = Mat3::Zero();
    double sum_sq = 0.0;
    int n = 0;
    for (const Cell* c : points) {
      const Vec3 x = T * c->p;
      if (x.z() <= 0.0) continue;
      const double u = camera.fx * x.x() / x.z() + camera.cx;
      const double v = camera.fy * x.y() / x.z() + camera.cy;
      if (!(u >= 0.0 && v >= 0.0)) continue;
      const int cx = static_cast<int>(u) / ref.size(), cy = static_cast<int>(v) / ref.size();
      if (cx >= ref.cols() || cy >= ref.rows()) continue;
      const Cell& q = ref.at(cx, cy);
      if (!q.valid || q.n.isZero()) continue;
      const double r = q.n.dot(x - q.p);
      if (std::abs(r) > options.max_distance_m) continue;
      const double sigma = std::hypot(q.sigma, c->sigma);
      const double e = r / sigma;
      const double huber =
          std::abs(e) <= options.huber_sigmas ? 1.0 : options.huber_sigmas / std::abs(e);
      const double w = huber / (sigma * sigma);
      Vec6 J;
      J << x.cross(q.n), q.n;
      H.noalias() += w * J * J.transpose();
      g.noalias() += w * J * r;
      Htt.noalias() += w * q.n * q.n.transpose();
      sum_sq += e * e;
      ++n;
    }
    result.points = n;
    if (n < options.min_points) return result;
    result.rms_sigmas = std::sqrt(sum_sq / n);
    data_tt = Htt;
    // Directions the data knows worse than min_information are left to the prior (Zhang,
    // Kaess and Singh, ICRA 2016, "On degeneracy of optimization-based state estimation
    // problems"): along a bare wall the data's only say comes from the noise of its normals.
    {
      const Eigen::SelfAdjointEigenSolver<Mat6> eig(H);
      Mat6 P = Mat6::Zero();
      for (int i = 0; i < 6; ++i) {
        if (eig.eigenvalues()(i) >= options.min_information) {
          P += eig.eigenvectors().col(i) * eig.eigenvectors().col(i).transpose();
        }
      }
      H = P * H * P;
      g = P * g;
    }
    add_tracks(tracks, camera, T, options, H, g);
    data = H;
    // The prior on T's deviation from the prediction, linearized at the current T.
    const Vec3 phi = (T.so3() * prior.T_ref_cur.so3().inverse()).log();
    const Vec3 dt = T.translation() - prior.T_ref_cur.translation();
    const Mat3 Jt_rot = -SO3::hat(T.translation());
    H.topLeftCorner<3, 3>() += w_rot * Mat3::Identity() + w_trans * Jt_rot.transpose() * Jt_rot;
    H.topRightCorner<3, 3>() += w_trans * Jt_rot.transpose();
    H.bottomLeftCorner<3, 3>() += w_trans * Jt_rot;
    H.bottomRightCorner<3, 3>() += w_trans * Mat3::Identity();
    g.head<3>() += w_rot * phi + w_trans * Jt_rot.transpose() * dt;
    g.tail<3>() += w_trans * dt;
    const Vec6 delta = -H.ldlt().solve(g);
    if (!delta.allFinite()) return result;
    const SO3 dR = SO3::exp(delta.head<3>());
    T = SE3(dR * T.so3(), dR * T.translation() + delta.tail<3>());
    if (delta.head<3>().norm() < 1e-6 && delta.tail<3>().norm() < 1e-5) break;
  }
  if (!T.is_finite() || result.rms_sigmas > options.max_rms_sigmas) return result;
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(data_tt);
  result.weakest_translation_information = eig.eigenvalues()(0);
  result.track_inliers = track_inliers(tracks, camera, T, options.track_inlier_px);
  result.weakest_information = Eigen::SelfAdjointEigenSolver<Mat6>(data).eigenvalues()(0);
  result.T_ref_cur = T;
  result.ok = true;
  return result;
}

}  // namespace kestrel::tracking
