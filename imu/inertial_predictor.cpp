#include "imu/inertial_predictor.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <Eigen/Cholesky>

#include "imu/preintegration.hpp"

namespace kestrel::imu {

InertialPredictor::InertialPredictor(const InertialPredictorOptions& options)
    : options_(options),
      acc_bias_cov_(Mat3::Identity() * options.initial_acc_bias_sigma *
                    options.initial_acc_bias_sigma),
      gyro_bias_cov_(Mat3::Identity() * options.initial_gyro_bias_sigma *
                     options.initial_gyro_bias_sigma) {}

void InertialPredictor::add_samples(std::span<const ImuSample> samples) {
  for (const ImuSample& s : samples) {
    if (!imu_.empty() && s.t <= imu_.back().t) continue;
    if (!s.gyro.allFinite() || !s.acc.allFinite()) continue;
    if (att_R_ && !imu_.empty() && s.t > att_t_) {
      // Midpoint rule from the attitude's stamp (a fix may sit between two samples).
      const ImuSample& p = imu_.back();
      const double dt = to_seconds(s.t - std::max(p.t, att_t_));
      const Vec3 w = 0.5 * (p.gyro + s.gyro) - bias_.gyro;
      att_R_ = *att_R_ * SO3::exp(w * dt);
      att_t_ = s.t;
    }
    imu_.push_back(s);
  }
  if (imu_.empty()) return;
  const Timestamp keep_from = imu_.back().t - from_seconds(options_.buffer_s);
  // One sample before the horizon stays, for interpolation at it.
  while (imu_.size() > 2 && imu_[1].t < keep_from) imu_.pop_front();
}

std::vector<ImuSample> InertialPredictor::samples_between(Timestamp t0, Timestamp t1) const {
  std::vector<ImuSample> out;
  if (imu_.empty() || imu_.front().t > t0 || imu_.back().t < t1) return out;
  auto first = std::upper_bound(imu_.begin(), imu_.end(), t0,
                                [](Timestamp t, const ImuSample& s) { return t < s.t; });
  if (first != imu_.begin()) --first;
  auto last = std::lower_bound(imu_.begin(), imu_.end(), t1,
                               [](const ImuSample& s, Timestamp t) { return s.t < t; });
  if (last != imu_.end()) ++last;
  out.assign(first, last);
  return out;
}

void InertialPredictor::clear_fixes() {
  fixes_.clear();
  v_last_.reset();
  velocity_fitted_at_.reset();
  bias_updated_at_ = 0;
}

void InertialPredictor::reanchor(Timestamp t, const SE3& T_w_b, const Vec3& v_w) {
  const std::optional<Timestamp> fitted_at = velocity_fitted_at_;
  clear_fixes();
  velocity_fitted_at_ = fitted_at;  // the carried velocity is as old as its last fit
  if (!T_w_b.is_finite() || !v_w.allFinite()) return;
  fixes_.push_back({t, T_w_b});
  att_R_ = T_w_b.so3();
  att_t_ = t;
  att_fix_t_ = t;
  bias_updated_at_ = t;
  v_last_ = v_w;
  v_fix_ = fixes_.back();
}

void InertialPredictor::add_fix(Timestamp t, const SE3& T_w_b) {
  if (!T_w_b.is_finite()) return;
  if (!fixes_.empty() && t <= fixes_.back().t) return;
  fixes_.push_back({t, T_w_b});
  att_R_ = T_w_b.so3();
  att_t_ = t;
  att_fix_t_ = t;
  const Timestamp keep = from_seconds(std::max(options_.velocity_window_s, options_.bias_window_s));
  while (fixes_.size() > 2 && fixes_.back().t - fixes_[1].t >= keep) fixes_.pop_front();
  if (bias_updated_at_ == 0) bias_updated_at_ = fixes_.front().t;
  if (fixes_.back().t - bias_updated_at_ >= from_seconds(options_.bias_window_s) &&
      update_biases()) {
    bias_updated_at_ = fixes_.back().t;
  }
  update_velocity();
}

namespace {

// Kalman update of a bias estimate x (covariance P) with a measurement z (covariance C). A
// measurement beyond the 99.9% gate of chi-square with 3 dof (a window with a bad track in
// it: fix errors are not the white noise C assumes) is not fused.
bool fuse(Vec3& x, Mat3& P, const Vec3& z, const Mat3& C) {
  const Mat3 S_inv = (P + C).inverse();
  const Vec3 d = z - x;
  if (!S_inv.allFinite() || d.dot(S_inv * d) > 16.27) return false;
  const Mat3 K = P * S_inv;
  x += K * d;
  P = (Mat3::Identity() - K) * P;
  return true;
}

}  // namespace

std::vector<InertialPredictor::WindowTerm> InertialPredictor::window_terms(
    std::size_t first, const std::vector<ImuSample>& samples, Preintegration* pre_out) const {
  // One pre-integration pass from fix `first`, read at every later fix.
  const Fix& j = fixes_[first];
  const Mat3 R_j = j.T_w_b.rotation();
  const Vec3& g = options_.gravity;
  Preintegration pre(bias_, options_.noise);
  std::vector<WindowTerm> out;
  Timestamp t_prev = j.t;
  for (std::size_t m = first; m < fixes_.size(); ++m) {
    if (m > first) pre.integrate(samples, t_prev, fixes_[m].t);
    t_prev = fixes_[m].t;
    const double tau = pre.dt();
    out.push_back({tau,
                   fixes_[m].T_w_b.translation() - j.T_w_b.translation() - 0.5 * g * tau * tau -
                       R_j * pre.delta_p(),
                   pre.dp_dba()});
  }
  if (pre_out) *pre_out = pre;
  return out;
}

void InertialPredictor::set_gravity(const Vec3& g) {
  if (!g.allFinite()) throw std::invalid_argument("InertialPredictor::set_gravity: not finite");
  options_.gravity = g;
  // The accelerometer bias was fitted under the old gravity too: it starts again.
  bias_.acc.setZero();
  acc_bias_cov_ =
      Mat3::Identity() * options_.initial_acc_bias_sigma * options_.initial_acc_bias_sigma;
  v_last_.reset();
  velocity_fitted_at_.reset();
  if (!fixes_.empty()) update_velocity();
}

void InertialPredictor::set_gyro_bias(const Vec3& b, double sigma) {
  if (!b.allFinite() || !std::isfinite(sigma) || sigma <= 0.0) {
    throw std::invalid_argument("InertialPredictor::set_gyro_bias: a finite bias and sigma > 0");
  }
  bias_.gyro = b;
  gyro_bias_cov_ = Mat3::Identity() * sigma * sigma;
  gyro_bias_measured_ = true;
}

bool InertialPredictor::update_biases() {
  // The fixes of the window that just filled (they start at the previous update).
  std::size_t first = 0;
  while (first + 1 < fixes_.size() && fixes_[first].t < bias_updated_at_) ++first;
  const std::size_t n = fixes_.size() - first;
  if (n < 6) return false;
  const double window = to_seconds(fixes_.back().t - fixes_[first].t);
  // Random walk since the last update.
  const double h = window;
  acc_bias_cov_ += Mat3::Identity() * options_.noise.acc_walk * options_.noise.acc_walk * h;
  gyro_bias_cov_ += Mat3::Identity() * options_.noise.gyro_walk * options_.noise.gyro_walk * h;

  // Gyro bias: one Gauss-Newton step from the current estimate. Each fix is paired with the
  // one half a window later: long baselines, so fix noise weighs little against the bias, and
  // every fix used once, so the pairs are independent.
  {
    const double w = 1.0 / (2.0 * options_.fix_rotation_sigma * options_.fix_rotation_sigma);
    Mat3 H = Mat3::Zero();
    Vec3 g = Vec3::Zero();
    int used = 0;
    const std::size_t half = n / 2;
    for (std::size_t i = first; i + half < fixes_.size() && i < first + half; ++i) {
      const Fix& a = fixes_[i];
      const Fix& c = fixes_[i + half];
      const std::vector<ImuSample> s = samples_between(a.t, c.t);
      if (s.size() < 2) continue;
      Preintegration pre(bias_, options_.noise);
      pre.integrate(s, a.t, c.t);
      const SO3 R_visual = a.T_w_b.so3().inverse() * c.T_w_b.so3();
      const Vec3 r = (pre.delta_R().inverse() * R_visual).log();
      if (!r.allFinite() || r.norm() > options_.max_rotation_residual) continue;
      const Mat3& J = pre.dR_dbg();
      H += w * J.transpose() * J;
      g += w * J.transpose() * r;
      ++used;
    }
    if (used >= 3) {
      const Mat3 H_inv = H.inverse();
      const Vec3 z = bias_.gyro + H_inv * g;
      const double floor = options_.gyro_bias_window_floor;
      const Mat3 C = H_inv + Mat3::Identity() * floor * floor;
      if (C.allFinite() && z.allFinite() && fuse(bias_.gyro, gyro_bias_cov_, z, C)) {
        gyro_bias_measured_ = true;
      }
    }
  }

  // Accelerometer bias: fit x = [c, v_first, δb_a] to the window's positions; the offset c
  // takes the first fix's own noise, which would otherwise bias every term.
  const Fix& j = fixes_[first];
  const std::vector<ImuSample> s = samples_between(j.t, fixes_.back().t);
  if (s.size() < 2) return false;
  using Mat9 = Eigen::Matrix<double, 9, 9>;
  using Vec9 = Eigen::Matrix<double, 9, 1>;
  const double w_fix = 1.0 / (options_.fix_sigma * options_.fix_sigma);
  Mat9 H = Mat9::Zero();
  Vec9 b = Vec9::Zero();
  const Mat3 R_j = j.T_w_b.rotation();
  for (const WindowTerm& w : window_terms(first, s, nullptr)) {
    Eigen::Matrix<double, 3, 9> A;
    A.leftCols<3>() = Mat3::Identity();
    A.middleCols<3>(3) = w.tau * Mat3::Identity();
    A.rightCols<3>() = R_j * w.dp_dba;
    H += w_fix * A.transpose() * A;
    b += w_fix * A.transpose() * w.y;
  }
  const Eigen::LDLT<Mat9> ldlt(H);
  if (ldlt.info() != Eigen::Success) return false;
  const Vec9 x = ldlt.solve(b);
  const Mat9 cov = ldlt.solve(Mat9::Identity());
  if (!x.allFinite() || !cov.allFinite()) return false;
  const Mat3 C = cov.bottomRightCorner<3, 3>();
  fuse(bias_.acc, acc_bias_cov_, bias_.acc + x.tail<3>(), 0.5 * (C + C.transpose()));
  return true;
}

void InertialPredictor::update_velocity() {
  // A failure (the IMU not yet past this fix) keeps the last velocity with its own fix.
  const Fix& k = fixes_.back();
  std::size_t first = 0;
  const Timestamp window = from_seconds(options_.velocity_window_s);
  while (first + 2 < fixes_.size() && k.t - fixes_[first + 1].t >= window) ++first;
  const Fix& j = fixes_[first];
  if (k.t - j.t < from_seconds(options_.min_window_s)) return;
  const std::vector<ImuSample> s = samples_between(j.t, k.t);
  if (s.size() < 2) return;
  // v_j by a line fit with the biases held: y_m = c + v_j τ_m (c takes fix j's own noise).
  const Mat3 R_j = j.T_w_b.rotation();
  const Vec3& g = options_.gravity;
  Preintegration pre(bias_, options_.noise);
  double n = 0.0, sum_t = 0.0, sum_tt = 0.0;
  Vec3 sum_y = Vec3::Zero(), sum_ty = Vec3::Zero();
  for (const WindowTerm& w : window_terms(first, s, &pre)) {
    n += 1.0;
    sum_t += w.tau;
    sum_tt += w.tau * w.tau;
    sum_y += w.y;
    sum_ty += w.tau * w.y;
  }
  const double det = n * sum_tt - sum_t * sum_t;
  if (det <= 0.0) return;
  const Vec3 v_j = (n * sum_ty - sum_t * sum_y) / det;
  const Vec3 v_k = v_j + g * pre.dt() + R_j * pre.delta_v();
  if (v_k.allFinite()) {
    v_last_ = v_k;
    v_fix_ = k;
    velocity_fitted_at_ = k.t;
  }
}

std::optional<InertialPredictor::Attitude> InertialPredictor::attitude() const {
  if (!att_R_) return std::nullopt;
  return Attitude{*att_R_, att_t_, to_seconds(att_t_ - att_fix_t_)};
}

std::optional<InertialPrediction> InertialPredictor::predict(Timestamp t) const {
  if (!v_last_ || fixes_.empty()) return std::nullopt;
  const Fix& k = v_fix_;
  if (t < k.t || t - k.t > from_seconds(options_.max_gap_s)) return std::nullopt;
  InertialPrediction out;
  out.since_fix_s = to_seconds(t - k.t);
  if (t == k.t) {
    out.T_w_b = k.T_w_b;
    out.v_w = *v_last_;
    return out;
  }
  const std::vector<ImuSample> s = samples_between(k.t, t);
  if (s.size() < 2) return std::nullopt;
  Preintegration pre(bias_, options_.noise);
  pre.integrate(s, k.t, t);
  NavState x0;
  x0.R = k.T_w_b.so3();
  x0.p = k.T_w_b.translation();
  x0.v = *v_last_;
  const NavState x1 = pre.predict(x0, options_.gravity);
  out.T_w_b = SE3(x1.R, x1.p);
  out.v_w = x1.v;
  if (!out.T_w_b.is_finite() || !out.v_w.allFinite()) return std::nullopt;
  return out;
}

}  // namespace kestrel::imu
