#include "semantic/euclidean_clusters.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>

namespace kestrel::semantic {
namespace {

std::uint64_t pack(int x, int y, int z) {
  auto q = [](int v) { return static_cast<std::uint64_t>(v + (1 << 20)) & 0x1FFFFF; };
  return q(x) | (q(y) << 21) | (q(z) << 42);
}

}  // namespace

std::vector<std::vector<int>> euclidean_clusters(const std::vector<Eigen::Vector3f>& points,
                                                 float tolerance, int min_points) {
  struct Voxel {
    std::vector<int> members;
    int label = -1;
  };
  std::unordered_map<std::uint64_t, Voxel> voxels;
  voxels.reserve(points.size());
  std::vector<Eigen::Vector3i> cell(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3f& p = points[i];
    cell[i] = Eigen::Vector3i(static_cast<int>(std::floor(p.x() / tolerance)),
                              static_cast<int>(std::floor(p.y() / tolerance)),
                              static_cast<int>(std::floor(p.z() / tolerance)));
    voxels[pack(cell[i].x(), cell[i].y(), cell[i].z())].members.push_back(static_cast<int>(i));
  }
  std::vector<std::vector<int>> clusters;
  std::vector<Voxel*> stack;
  std::vector<Eigen::Vector3i> stack_cell;
  int next_label = 0;
  for (auto& [key, seed] : voxels) {
    if (seed.label >= 0) continue;
    std::vector<int> members;
    seed.label = next_label;
    stack.assign(1, &seed);
    stack_cell.assign(1, cell[seed.members.front()]);
    while (!stack.empty()) {
      Voxel* v = stack.back();
      const Eigen::Vector3i c = stack_cell.back();
      stack.pop_back();
      stack_cell.pop_back();
      members.insert(members.end(), v->members.begin(), v->members.end());
      for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const auto it = voxels.find(pack(c.x() + dx, c.y() + dy, c.z() + dz));
            if (it == voxels.end() || it->second.label >= 0) continue;
            it->second.label = next_label;
            stack.push_back(&it->second);
            stack_cell.emplace_back(c.x() + dx, c.y() + dy, c.z() + dz);
          }
    }
    ++next_label;
    if (static_cast<int>(members.size()) >= min_points) clusters.push_back(std::move(members));
  }
  std::sort(clusters.begin(), clusters.end(),
            [](const auto& a, const auto& b) { return a.size() > b.size(); });
  return clusters;
}

}  // namespace kestrel::semantic
