#pragma once
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace kestrel {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;
using Vec4 = Eigen::Vector4d;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat2 = Eigen::Matrix2d;
using Mat3 = Eigen::Matrix3d;
using Mat4 = Eigen::Matrix4d;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Mat23 = Eigen::Matrix<double, 2, 3>;
using Quat = Eigen::Quaterniond;

}  // namespace kestrel
