#pragma once
// The agent's object telemetry (a pipeline::Observer): the semantic database, as the mapping
// thread updates it, goes out as ObjectsMsg deltas -- the objects that changed by more than a
// few centimetres (or changed label, size, yaw or observation count) and the ids that
// disappeared (merged into another object, or removed as moving). AgentLink keeps the table
// the deltas add up to and re-publishes it as a retained full snapshot for late joiners.
#include <cstdint>
#include <map>
#include <mutex>
#include <vector>

#include "comm/agent_link.hpp"
#include "pipeline/system.hpp"

namespace kestrel::comm {

struct ObjectDeltaOptions {
  double min_move_m = 0.02;  // centre or size change that is worth a message
  double min_yaw_rad = 0.02;
};

ObjectInfo to_object_info(const semantic::SemanticObject& o);

// What turns `sent` into `now`: changed or new objects and removed ids (t and full unset).
// Empty objects and removed: nothing worth sending.
ObjectsMsg object_delta(const std::map<std::uint32_t, ObjectInfo>& sent,
                        const std::vector<ObjectInfo>& now, const ObjectDeltaOptions& options = {});

class ObjectTelemetry : public pipeline::Observer {
 public:
  explicit ObjectTelemetry(AgentLink& link, ObjectDeltaOptions options = {});

  void on_frame(const pipeline::FrameReport&) override {}
  void on_objects(const pipeline::ObjectsReport& report) override;

  std::uint64_t messages() const;
  std::size_t objects() const;  // in the table the agent has published

 private:
  AgentLink& link_;
  ObjectDeltaOptions options_;
  mutable std::mutex mutex_;
  std::map<std::uint32_t, ObjectInfo> sent_;
  std::uint64_t messages_ = 0;
};

}  // namespace kestrel::comm
