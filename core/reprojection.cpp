#include "core/reprojection.hpp"

#include "core/so3.hpp"

namespace kestrel {

bool pose_residual(const PinholeCamera& camera, const SE3& T_c_w, const Vec3& p_w, const Vec2& uv,
                   Vec2* r, Mat26* J) {
  const Vec3 p_c = T_c_w * p_w;
  if (!(p_c.z() > 1e-6)) return false;
  const double iz = 1.0 / p_c.z();
  *r = Vec2(camera.fx * p_c.x() * iz + camera.cx - uv.x(),
            camera.fy * p_c.y() * iz + camera.cy - uv.y());
  if (J) {
    // d(exp(delta) p_c)/d(delta) = [I, -hat(p_c)]
    const Mat23 Jp = camera.project_jacobian(p_c);
    J->leftCols<3>() = Jp;
    J->rightCols<3>() = -Jp * SO3::hat(p_c);
  }
  return true;
}

}  // namespace kestrel
