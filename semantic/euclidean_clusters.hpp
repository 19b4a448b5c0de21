#pragma once
// Euclidean clustering on a voxel lattice: points whose voxels touch (26-neighbourhood) are one
// cluster, so two surfaces farther apart than about one voxel edge are separated. Linear in
// the number of points, no tree to build.
#include <vector>

#include <Eigen/Core>

namespace kestrel::semantic {

// Indices into `points`, one vector per cluster of at least min_points, largest first.
std::vector<std::vector<int>> euclidean_clusters(const std::vector<Eigen::Vector3f>& points,
                                                 float tolerance, int min_points);

}  // namespace kestrel::semantic
