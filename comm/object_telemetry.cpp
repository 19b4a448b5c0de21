#include "comm/object_telemetry.hpp"

#include <cmath>
#include <set>

namespace kestrel::comm {
namespace {

bool moved(const std::array<double, 3>& a, const std::array<double, 3>& b, double tol) {
  double d2 = 0.0;
  for (int i = 0; i < 3; ++i) d2 += (a[i] - b[i]) * (a[i] - b[i]);
  return d2 > tol * tol;
}

}  // namespace

ObjectInfo to_object_info(const semantic::SemanticObject& o) {
  ObjectInfo info;
  info.id = static_cast<std::uint32_t>(o.id);
  info.label = o.label;
  info.center = {o.box.center.x(), o.box.center.y(), o.box.center.z()};
  info.size = {o.box.size.x(), o.box.size.y(), o.box.size.z()};
  info.yaw = o.box.yaw;
  info.observations = static_cast<std::uint32_t>(std::max(0, o.observations));
  return info;
}

ObjectsMsg object_delta(const std::map<std::uint32_t, ObjectInfo>& sent,
                        const std::vector<ObjectInfo>& now, const ObjectDeltaOptions& options) {
  ObjectsMsg m;
  std::set<std::uint32_t> present;
  for (const ObjectInfo& o : now) {
    present.insert(o.id);
    const auto it = sent.find(o.id);
    if (it == sent.end()) {
      m.objects.push_back(o);
      continue;
    }
    const ObjectInfo& s = it->second;
    if (s.label != o.label || s.observations != o.observations ||
        moved(s.center, o.center, options.min_move_m) ||
        moved(s.size, o.size, options.min_move_m) ||
        std::fabs(std::remainder(s.yaw - o.yaw, M_PI)) > options.min_yaw_rad) {
      m.objects.push_back(o);
    }
  }
  for (const auto& [id, o] : sent)
    if (!present.count(id)) m.removed.push_back(id);
  return m;
}

ObjectTelemetry::ObjectTelemetry(AgentLink& link, ObjectDeltaOptions options)
    : link_(link), options_(options) {}

void ObjectTelemetry::on_objects(const pipeline::ObjectsReport& report) {
  std::vector<ObjectInfo> now;
  now.reserve(report.objects.size());
  for (const auto& o : report.objects) now.push_back(to_object_info(o));
  ObjectsMsg delta;
  {
    std::lock_guard lock(mutex_);
    delta = object_delta(sent_, now, options_);
    if (delta.objects.empty() && delta.removed.empty()) return;
    for (const auto& o : delta.objects) sent_[o.id] = o;
    for (auto id : delta.removed) sent_.erase(id);
    ++messages_;
  }
  delta.t = wall_clock_ns();
  link_.publish(delta);
}

std::uint64_t ObjectTelemetry::messages() const {
  std::lock_guard lock(mutex_);
  return messages_;
}

std::size_t ObjectTelemetry::objects() const {
  std::lock_guard lock(mutex_);
  return sent_.size();
}

}  // namespace kestrel::comm
