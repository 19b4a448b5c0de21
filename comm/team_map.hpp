#pragma once
// The team's one semantic map (mapd, issue 7): every agent's object table, in the agent's own
// gravity-aligned world frame, is brought into the team frame and merged.
//
// Frames: each agent's start pose T_team_agent (x, y, z, yaw: the frames share gravity) is a
// prior from the operator; it is refined by matching the agent's objects to the team map built
// so far -- same-label centres, every hypothesis from one correspondence (a shift) or two far
// enough apart (shift + yaw) scored by its inliers (hypothesize and verify over all
// correspondences, which are few), then least squares over the winner's inliers. Corrections
// larger than the bounds are refused: a wrong match must not throw an agent across the map.
// Merging: same label, centres closer than merge_factor x the larger object's largest side, at
// most one object per agent in a team object (an agent's own database already decided that
// two of its objects are distinct), nearest pairs first. No threads, no network.
#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "comm/schema.hpp"

namespace kestrel::comm {

// A gravity-aligned rigid transform: p_team = Rz(yaw) p_agent + t.
struct Pose4 {
  std::array<double, 3> t{};
  double yaw = 0.0;  // radians
  std::array<double, 3> apply(const std::array<double, 3>& p) const;
  Pose4 then(const Pose4& correction) const;  // correction applied after this
};

// "NAME:x,y,z,yaw_degrees" (mapd's --start); throws kestrel::Error naming `flag`.
std::pair<std::string, Pose4> parse_start_pose(const std::string& text, const std::string& flag);

struct TeamMapOptions {
  double merge_factor = 0.75;
  double match_gate_m = 1.5;   // a correspondence candidate lies this close under the prior
  double inlier_m = 0.4;       // a hypothesis' inlier lies this close after it
  double min_spread_m = 1.0;   // two correspondences this far apart fix the yaw
  double max_shift_m = 2.0;    // bounds of a correction to the prior
  double max_turn_rad = 0.35;  // 20 degrees
};

struct AgentFrame {
  Pose4 prior;         // configured start (identity when none)
  Pose4 T_team_agent;  // prior refined by the objects
  int matched = 0;     // inlier correspondences behind the refinement (0: the prior alone)
  bool reference = false;
};

struct TeamMapResult {
  std::vector<ObjectInfo> objects;  // team frame, stable ids, `agents` filled
  std::map<std::string, AgentFrame> frames;
  int merged = 0;  // agent objects that joined another agent's object
};

class TeamMap {
 public:
  explicit TeamMap(TeamMapOptions options = {});

  // Configured order: the first agent is the reference frame when it has objects.
  void set_start(const std::string& agent, const Pose4& T_team_agent);
  // An agent's objects message (a full snapshot replaces its table). False, and nothing
  // changes, when it is older than the last one applied from that agent (see ObjectsMsg::seq).
  bool apply(const std::string& agent, const ObjectsMsg& m);
  std::size_t agent_objects(const std::string& agent) const;

  // Aligns and merges from scratch (the tables are small); team ids stay stable across calls.
  TeamMapResult build();

 private:
  struct Member {
    std::string agent;
    ObjectInfo local;
    std::array<double, 3> c{};  // team frame
    double yaw = 0.0;
  };
  AgentFrame align(const std::string& agent, const std::vector<Member>& team) const;

  TeamMapOptions options_;
  std::vector<std::string> order_;
  std::map<std::string, Pose4> starts_;
  std::map<std::string, std::map<std::uint32_t, ObjectInfo>> tables_;
  std::map<std::string, std::uint64_t> seqs_;  // last applied ObjectsMsg::seq per agent
  std::map<std::pair<std::string, std::uint32_t>, std::uint32_t> team_ids_;
  std::uint32_t next_id_ = 1;
};

}  // namespace kestrel::comm
