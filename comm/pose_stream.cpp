#include "comm/pose_stream.hpp"

#include <algorithm>
#include <optional>

namespace kestrel::comm {
namespace {

constexpr std::size_t kKept = 64;
constexpr std::uint8_t kStateOk = 1, kStateRelocalized = 3;  // tracking::TrackingState

// T_a * exp(alpha * log(T_a^-1 T_b)): alpha 0 gives T_a, 1 gives T_b, beyond 1 extrapolates.
SE3 blend(const SE3& Ta, const SE3& Tb, double alpha) {
  return Ta * SE3::exp(alpha * (Ta.inverse() * Tb).log());
}

}  // namespace

PoseStream::PoseStream(Publish publish, PoseStreamOptions options)
    : publish_(std::move(publish)), options_(options) {}

void PoseStream::on_camera_frame(Timestamp t, std::int64_t now_ns) {
  std::lock_guard lock(mutex_);
  if (!pending_.empty() && t <= pending_.back().t) return;
  if (t <= last_published_t_) return;
  pending_.push_back({t, now_ns});
  drain(now_ns, false);
}

void PoseStream::on_tracked(Timestamp t, const SE3& T_w_body, std::uint8_t state,
                            std::int64_t now_ns) {
  std::lock_guard lock(mutex_);
  if (tracked_.empty() || t > tracked_.back().t) {
    tracked_.push_back({t, T_w_body, state});
    if (tracked_.size() > kKept) tracked_.pop_front();
    if (state == kStateOk || state == kStateRelocalized) {
      anchors_.push_back({t, T_w_body, state});
      if (anchors_.size() > kKept) anchors_.pop_front();
    }
  }
  drain(now_ns, false);
}

void PoseStream::poll(std::int64_t now_ns) {
  std::lock_guard lock(mutex_);
  drain(now_ns, false);
}

void PoseStream::flush() {
  std::lock_guard lock(mutex_);
  drain(0, true);
}

PoseStreamCounts PoseStream::counts() const {
  std::lock_guard lock(mutex_);
  return counts_;
}

bool PoseStream::emit(Timestamp t, const SE3& T, std::uint8_t state) {
  const Timestamp period = static_cast<Timestamp>(1e9 / options_.rate_hz);
  // 2% slack so that a 30 Hz camera is not decimated by stamp jitter.
  if (last_published_t_ >= 0 && t - last_published_t_ < period - period / 50) {
    ++counts_.decimated;
    return false;
  }
  last_published_t_ = t;
  PoseMsg m;
  m.t = t;
  const Vec3 p = T.translation();
  const Quat q = T.quaternion();
  m.p = {p.x(), p.y(), p.z()};
  m.q = {q.x(), q.y(), q.z(), q.w()};
  m.state = state;
  m.seq = ++seq_;
  ++counts_.published;
  if (state != kPosePredicted) ++counts_.tracked;  // predictions: counted by the caller
  publish_(m);
  return true;
}

void PoseStream::drain(std::int64_t now_ns, bool force) {
  while (!pending_.empty()) {
    const Pending f = pending_.front();
    const auto own = std::find_if(tracked_.begin(), tracked_.end(),
                                  [&](const Tracked& r) { return r.t == f.t; });
    if (own != tracked_.end()) {
      pending_.pop_front();
      emit(own->t, own->T, own->state);
      continue;
    }
    const bool passed = !tracked_.empty() && tracked_.back().t > f.t;
    if (!passed && !force && now_ns - f.arrived_ns < options_.max_wait_ns) return;
    pending_.pop_front();
    // The good poses around the frame's stamp.
    const auto after = std::upper_bound(anchors_.begin(), anchors_.end(), f.t,
                                        [](Timestamp t, const Tracked& a) { return t < a.t; });
    if (after == anchors_.begin()) {
      ++counts_.unsaid;  // nothing tracked before it
      continue;
    }
    const Tracked& a = *std::prev(after);
    if (after != anchors_.end() && after->t - a.t <= 2 * options_.max_extrapolation) {
      const double alpha = static_cast<double>(f.t - a.t) / static_cast<double>(after->t - a.t);
      if (emit(f.t, blend(a.T, after->T, alpha), kPosePredicted)) ++counts_.interpolated;
      continue;
    }
    if (f.t - a.t > options_.max_extrapolation) {
      ++counts_.unsaid;  // the last tracked pose is too old to say where the agent is
      continue;
    }
    // At the velocity between the last two good poses; held when there is only one.
    SE3 T = a.T;
    if (std::prev(after) != anchors_.begin()) {
      const Tracked& a0 = *std::prev(after, 2);
      if (a.t - a0.t > 0 && a.t - a0.t <= options_.max_extrapolation)
        T = blend(a0.T, a.T,
                  1.0 + static_cast<double>(f.t - a.t) / static_cast<double>(a.t - a0.t));
    }
    if (emit(f.t, T, kPosePredicted)) ++counts_.extrapolated;
  }
}

}  // namespace kestrel::comm
