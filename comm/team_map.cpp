#include "comm/team_map.hpp"

#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>

#include "comm/topics.hpp"
#include "core/error.hpp"

namespace kestrel::comm {
namespace {

using P3 = std::array<double, 3>;

double dist(const P3& a, const P3& b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                   (a[2] - b[2]) * (a[2] - b[2]));
}
double dist_xy(const P3& a, const P3& b) { return std::hypot(a[0] - b[0], a[1] - b[1]); }
double largest_side(const ObjectInfo& o) { return std::max({o.size[0], o.size[1], o.size[2]}); }
// Box yaws are axis directions, defined modulo pi (semantic::UprightBox: (-pi/2, pi/2]).
double wrap_axis(double yaw) {
  double y = std::remainder(yaw, M_PI);
  if (y <= -M_PI / 2) y += M_PI;
  return y;
}

// Least-squares shift + yaw taking a[i] onto b[i] (2D Procrustes in x, y; z shifts only).
Pose4 fit_pose4(const std::vector<P3>& a, const std::vector<P3>& b, bool with_yaw) {
  const double n = static_cast<double>(a.size());
  P3 ma{}, mb{};
  for (std::size_t i = 0; i < a.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      ma[k] += a[i][k] / n;
      mb[k] += b[i][k] / n;
    }
  Pose4 p;
  if (with_yaw) {
    double s = 0.0, c = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) {
      const double ax = a[i][0] - ma[0], ay = a[i][1] - ma[1];
      const double bx = b[i][0] - mb[0], by = b[i][1] - mb[1];
      s += ax * by - ay * bx;
      c += ax * bx + ay * by;
    }
    p.yaw = std::atan2(s, c);
  }
  const P3 ra = Pose4{{0, 0, 0}, p.yaw}.apply(ma);
  for (int k = 0; k < 3; ++k) p.t[k] = mb[k] - ra[k];
  return p;
}

}  // namespace

P3 Pose4::apply(const P3& p) const {
  const double c = std::cos(yaw), s = std::sin(yaw);
  return {c * p[0] - s * p[1] + t[0], s * p[0] + c * p[1] + t[1], p[2] + t[2]};
}

Pose4 Pose4::then(const Pose4& correction) const {
  Pose4 out;
  out.yaw = std::remainder(yaw + correction.yaw, 2 * M_PI);
  out.t = correction.apply(t);
  return out;
}

std::pair<std::string, Pose4> parse_start_pose(const std::string& text, const std::string& flag) {
  const auto colon = text.find(':');
  const std::string name = text.substr(0, colon);
  auto fail = [&](const std::string& why) {
    throw Error::at("command line", 0, flag, "'" + text + "': " + why);
  };
  if (colon == std::string::npos || !valid_agent_id(name)) fail("expected NAME:x,y,z,yaw");
  std::vector<double> v;
  std::stringstream in(text.substr(colon + 1));
  for (std::string item; std::getline(in, item, ',');) {
    try {
      std::size_t used = 0;
      v.push_back(std::stod(item, &used));
      if (used != item.size()) fail("'" + item + "' is not a number");
    } catch (const std::logic_error&) {
      fail("'" + item + "' is not a number");
    }
    if (!std::isfinite(v.back())) fail("not finite");
  }
  if (v.size() != 4) fail("expected four numbers x,y,z (m) and yaw (degrees)");
  Pose4 p;
  p.t = {v[0], v[1], v[2]};
  p.yaw = v[3] * M_PI / 180.0;
  return {name, p};
}

TeamMap::TeamMap(TeamMapOptions options) : options_(options) {}

void TeamMap::set_start(const std::string& agent, const Pose4& T_team_agent) {
  if (!starts_.count(agent)) order_.push_back(agent);
  starts_[agent] = T_team_agent;
}

bool TeamMap::apply(const std::string& agent, const ObjectsMsg& m) {
  std::uint64_t& seq = seqs_[agent];
  if (!objects_message_is_new(seq, m.seq)) return false;
  if (m.seq != 0) seq = m.seq;
  auto& table = tables_[agent];
  if (m.full) table.clear();
  for (const ObjectInfo& o : m.objects) {
    ObjectInfo local = o;
    local.agents.clear();  // an agent speaks for itself only
    table[o.id] = std::move(local);
  }
  for (auto id : m.removed) table.erase(id);
  return true;
}

std::size_t TeamMap::agent_objects(const std::string& agent) const {
  const auto it = tables_.find(agent);
  return it == tables_.end() ? 0 : it->second.size();
}

AgentFrame TeamMap::align(const std::string& agent, const std::vector<Member>& team) const {
  AgentFrame f;
  if (const auto it = starts_.find(agent); it != starts_.end()) f.prior = it->second;
  f.T_team_agent = f.prior;
  std::vector<const ObjectInfo*> objs;
  std::vector<P3> pri;
  for (const auto& [id, o] : tables_.at(agent)) {
    objs.push_back(&o);
    pri.push_back(f.prior.apply(o.center));
  }
  struct Corr {
    std::size_t i, j;
  };
  std::vector<Corr> cand;
  for (std::size_t i = 0; i < objs.size(); ++i)
    for (std::size_t j = 0; j < team.size(); ++j)
      if (team[j].local.label == objs[i]->label && dist(pri[i], team[j].c) < options_.match_gate_m)
        cand.push_back({i, j});
  if (cand.empty() || pri.empty()) return f;
  P3 centroid{};
  for (const P3& p : pri)
    for (int k = 0; k < 3; ++k) centroid[k] += p[k] / static_cast<double>(pri.size());

  // One-to-one inliers of a correction (nearest pairs first) and their summed residual.
  auto score = [&](const Pose4& corr, std::vector<Corr>* inliers) {
    struct Near {
      double d;
      std::size_t i, j;
    };
    std::vector<Near> near;
    for (const Corr& c : cand) {
      const double d = dist(corr.apply(pri[c.i]), team[c.j].c);
      if (d < options_.inlier_m) near.push_back({d, c.i, c.j});
    }
    std::sort(near.begin(), near.end(), [](const Near& a, const Near& b) { return a.d < b.d; });
    std::set<std::size_t> used_i, used_j;
    std::pair<int, double> s{0, 0.0};
    for (const Near& n : near) {
      if (used_i.count(n.i) || used_j.count(n.j)) continue;
      used_i.insert(n.i);
      used_j.insert(n.j);
      ++s.first;
      s.second += n.d;
      if (inliers) inliers->push_back({n.i, n.j});
    }
    return s;
  };
  auto within_bounds = [&](const Pose4& corr) {
    return std::fabs(corr.yaw) <= options_.max_turn_rad &&
           dist(corr.apply(centroid), centroid) <= options_.max_shift_m;
  };
  auto fit = [&](const std::vector<Corr>& cs) {
    std::vector<P3> a, b;
    double spread = 0.0;
    for (const Corr& c : cs) {
      a.push_back(pri[c.i]);
      b.push_back(team[c.j].c);
      for (const P3& q : a) spread = std::max(spread, dist_xy(q, a.back()));
    }
    return fit_pose4(a, b, spread >= options_.min_spread_m);
  };

  // Ranked by inliers, then by residual plus a little of the shift: between equally good
  // hypotheses (a lone correspondence always fits exactly) the one nearest the prior wins.
  auto cost = [&](const Pose4& h, double residual) {
    return residual + 0.05 * dist(h.apply(centroid), centroid);
  };
  Pose4 best;  // the prior as it is
  std::pair<int, double> best_score = score(best, nullptr);
  best_score.second = cost(best, best_score.second);
  auto consider = [&](const Pose4& h) {
    if (!within_bounds(h)) return;
    auto s = score(h, nullptr);
    s.second = cost(h, s.second);
    if (s.first > best_score.first ||
        (s.first == best_score.first && s.second < best_score.second - 1e-9)) {
      best = h;
      best_score = s;
    }
  };
  for (std::size_t x = 0; x < cand.size(); ++x) {
    consider(fit({cand[x]}));
    for (std::size_t y = x + 1; y < cand.size(); ++y) {
      if (cand[x].i == cand[y].i || cand[x].j == cand[y].j) continue;
      if (dist_xy(pri[cand[x].i], pri[cand[y].i]) < options_.min_spread_m) continue;
      consider(fit({cand[x], cand[y]}));
    }
  }
  std::vector<Corr> inliers;
  score(best, &inliers);
  if (inliers.empty()) return f;
  const Pose4 refined = fit(inliers);
  if (within_bounds(refined) && score(refined, nullptr).first >= best_score.first) best = refined;
  f.T_team_agent = f.prior.then(best);
  f.matched = static_cast<int>(inliers.size());
  return f;
}

TeamMapResult TeamMap::build() {
  TeamMapResult r;
  std::vector<std::string> pending;
  for (const auto& a : order_)
    if (agent_objects(a) > 0) pending.push_back(a);
  for (const auto& [a, table] : tables_)
    if (!table.empty() && !starts_.count(a)) pending.push_back(a);

  std::vector<Member> team;
  auto add = [&](const std::string& agent, const AgentFrame& f) {
    r.frames[agent] = f;
    for (const auto& [id, o] : tables_.at(agent)) {
      team.push_back(
          {agent, o, f.T_team_agent.apply(o.center), wrap_axis(o.yaw + f.T_team_agent.yaw)});
    }
  };
  if (!pending.empty()) {
    AgentFrame ref;
    if (const auto it = starts_.find(pending.front()); it != starts_.end()) ref.prior = it->second;
    ref.T_team_agent = ref.prior;
    ref.reference = true;
    add(pending.front(), ref);
    pending.erase(pending.begin());
  }
  // The agent that shares most with the map so far goes next: it is the best anchored.
  while (!pending.empty()) {
    std::size_t pick = 0;
    int most = -1;
    for (std::size_t k = 0; k < pending.size(); ++k) {
      const AgentFrame f = align(pending[k], team);
      if (f.matched > most) {
        most = f.matched;
        pick = k;
      }
    }
    add(pending[pick], align(pending[pick], team));
    pending.erase(pending.begin() + static_cast<std::ptrdiff_t>(pick));
  }

  // Merge: nearest same-label pairs of different agents first; a team object holds one object
  // per agent at most.
  const std::size_t n = team.size();
  std::vector<std::size_t> root(n);
  std::vector<std::set<std::string>> agents(n);
  for (std::size_t i = 0; i < n; ++i) {
    root[i] = i;
    agents[i] = {team[i].agent};
  }
  auto find = [&](std::size_t i) {
    while (root[i] != i) i = root[i] = root[root[i]];
    return i;
  };
  struct Pair {
    double d;
    std::size_t a, b;
  };
  std::vector<Pair> pairs;
  for (std::size_t a = 0; a < n; ++a)
    for (std::size_t b = a + 1; b < n; ++b) {
      if (team[a].agent == team[b].agent || team[a].local.label != team[b].local.label) continue;
      const double d = dist(team[a].c, team[b].c);
      const double gate = options_.merge_factor *
                          std::max(largest_side(team[a].local), largest_side(team[b].local));
      if (d < gate) pairs.push_back({d, a, b});
    }
  std::sort(pairs.begin(), pairs.end(), [](const Pair& x, const Pair& y) { return x.d < y.d; });
  for (const Pair& p : pairs) {
    const std::size_t ra = find(p.a), rb = find(p.b);
    if (ra == rb) continue;
    bool overlap = false;
    for (const auto& a : agents[rb]) overlap = overlap || agents[ra].count(a);
    if (overlap) continue;
    root[rb] = ra;
    agents[ra].insert(agents[rb].begin(), agents[rb].end());
    ++r.merged;
  }
  std::map<std::size_t, std::vector<std::size_t>> clusters;
  for (std::size_t i = 0; i < n; ++i) clusters[find(i)].push_back(i);

  std::set<std::uint32_t> taken;
  std::vector<std::pair<std::vector<std::size_t>, std::uint32_t>> assigned;
  // Ids: a cluster keeps the lowest team id any of its members had, so the page's objects keep
  // their identity while agents refine them.
  for (auto& [rt, members] : clusters) {
    std::uint32_t id = 0;
    for (std::size_t i : members) {
      const auto it = team_ids_.find({team[i].agent, team[i].local.id});
      if (it != team_ids_.end() && !taken.count(it->second) && (id == 0 || it->second < id)) {
        id = it->second;
      }
    }
    if (id != 0) taken.insert(id);
    assigned.emplace_back(members, id);
  }
  for (auto& [members, id] : assigned) {
    if (id == 0) {
      while (taken.count(next_id_)) ++next_id_;
      id = next_id_++;
      taken.insert(id);
    }
    ObjectInfo o;
    o.id = id;
    o.label = team[members.front()].local.label;
    double w_sum = 0.0;
    std::size_t heaviest = members.front();
    for (std::size_t i : members) {
      const double w = std::max(1.0, static_cast<double>(team[i].local.observations));
      w_sum += w;
      for (int k = 0; k < 3; ++k) {
        o.center[k] += w * team[i].c[k];
        o.size[k] += w * team[i].local.size[k];
      }
      o.observations += team[i].local.observations;
      if (team[i].local.observations > team[heaviest].local.observations) heaviest = i;
      o.agents.push_back(team[i].agent);
      team_ids_[{team[i].agent, team[i].local.id}] = id;
    }
    for (int k = 0; k < 3; ++k) {
      o.center[k] /= w_sum;
      o.size[k] /= w_sum;
    }
    o.yaw = team[heaviest].yaw;
    std::sort(o.agents.begin(), o.agents.end());
    r.objects.push_back(std::move(o));
  }
  std::sort(r.objects.begin(), r.objects.end(),
            [](const ObjectInfo& a, const ObjectInfo& b) { return a.id < b.id; });
  return r;
}

}  // namespace kestrel::comm
