#include "sim/world.hpp"

#include <cmath>

#include <Eigen/Geometry>

#include "core/error.hpp"

namespace kestrel::sim {
namespace {

constexpr float kTile = 1.0f;  // metres: large faces are split so perspective stays accurate

Vec3f f3(const Vec3& v) { return v.cast<float>(); }

}  // namespace

void add_furniture(Mesh& mesh, const std::string& label, const Vec3f& base, const Vec3f& size,
                   float yaw, int texture, std::uint16_t instance) {
  const Eigen::Matrix3f R = Eigen::AngleAxisf(yaw, Vec3f::UnitZ()).toRotationMatrix();
  const auto part = [&](float x, float y, float z, float sx, float sy, float sz) {
    // (x y z) is the part's centre in the object's frame, z up from the floor.
    add_box(mesh, base + R * Vec3f(x, y, z), Vec3f(sx, sy, sz), yaw, texture, instance, 0.6f, kTile,
            BoxFaces{false, false, false});
  };
  const float sx = size.x(), sy = size.y(), sz = size.z();
  if (label == "chair") {
    const float seat = 0.48f * sz, leg = 0.04f;
    part(0, 0, seat, sx, sy, 0.06f);
    part(-0.5f * sx + 0.03f, 0, seat + 0.5f * (sz - seat), 0.06f, sy, sz - seat);
    for (float ix : {-1.f, 1.f})
      for (float iy : {-1.f, 1.f})
        part(ix * (0.5f * sx - leg), iy * (0.5f * sy - leg), 0.5f * (seat - 0.03f), leg, leg,
             seat - 0.03f);
  } else if (label == "dining table" || label == "table" || label == "desk") {
    const float top = 0.05f, leg = 0.06f;
    part(0, 0, sz - 0.5f * top, sx, sy, top);
    for (float ix : {-1.f, 1.f})
      for (float iy : {-1.f, 1.f})
        part(ix * (0.5f * sx - leg), iy * (0.5f * sy - leg), 0.5f * (sz - top), leg, leg, sz - top);
  } else {
    add_box(mesh, base + Vec3f(0, 0, 0.5f * sz), size, yaw, texture, instance, 0.6f, kTile,
            BoxFaces{false, true, false});
  }
}

int World::add_texture(Texture t) {
  textures_.push_back(std::move(t));
  return static_cast<int>(textures_.size()) - 1;
}

void World::apply_lights(Mesh& mesh, std::size_t from) const {
  if (lights_.empty()) return;
  for (std::size_t i = from; i < mesh.size(); ++i) {
    Triangle& tri = mesh[i];
    const Vec3 c = ((tri.v[0].p + tri.v[1].p + tri.v[2].p) / 3.0f).cast<double>();
    for (const LightZone& z : lights_) {
      if ((c.array() >= z.min.array()).all() && (c.array() <= z.max.array()).all()) {
        tri.shade = std::min(1.0f, tri.shade * static_cast<float>(z.gain));
      }
    }
  }
}

World::World(const Scenario& sc) : movers_(sc.movers), lights_(sc.lights) {
  if (sc.movers.size() > static_cast<std::size_t>(kMaxMovers)) {
    throw Error::at(sc.source, 0, "movers", "at most " + std::to_string(kMaxMovers) + " movers");
  }
  if (sc.objects.size() > kMaxInstances - kFirstObjectId) {
    throw Error::at(sc.source, 0, "world.objects", "too many objects");
  }
  std::uint64_t k = 0;
  const auto seed_for = [&](std::uint64_t salt) { return hash_combine(sc.seed, salt); };
  if (sc.has_ground) {
    const int tex = add_texture(make_texture(sc.ground_texture, seed_for(++k)));
    const Vec3f c = f3(sc.ground_center);
    const float hx = static_cast<float>(sc.ground_size[0]) / 2,
                hy = static_cast<float>(sc.ground_size[1]) / 2;
    add_quad(static_mesh_, c + Vec3f(-hx, -hy, 0), c + Vec3f(hx, -hy, 0), c + Vec3f(hx, hy, 0),
             c + Vec3f(-hx, hy, 0), Vec2f::Zero(), static_cast<float>(sc.ground_texture.scale), tex,
             0, kTile);
  }
  for (const StaticBoxSpec& b : sc.boxes) {
    const int tex = add_texture(make_texture(b.texture, seed_for(++k)));
    add_box(static_mesh_, f3(b.center), f3(b.size), static_cast<float>(b.yaw), tex, 0,
            static_cast<float>(b.texture.scale), kTile, BoxFaces{b.inward, true, false});
  }
  int j = 0;
  for (const ObjectSpec& o : sc.objects) {
    const int tex = add_texture(make_texture(o.texture, seed_for(++k)));
    const auto id = static_cast<std::uint16_t>(kFirstObjectId + j);
    const Vec3f base = f3(o.center) - Vec3f(0, 0, 0.5f * static_cast<float>(o.size.z()));
    add_furniture(static_mesh_, o.label, base, f3(o.size), static_cast<float>(o.yaw), tex, id);
    objects_.push_back({id, o.label, o.center, o.size, o.yaw});
    ++j;
  }
  apply_lights(static_mesh_, 0);

  bool has_people = false;
  for (const MoverSpec& m : movers_) has_people = has_people || m.type == "person";
  if (has_people) {
    for (Sprite& s : load_person_sprites(sc.assets)) {
      sprite_aspect_.push_back(s.aspect);
      sprite_texture_.push_back(add_texture(std::move(s.texture)));
    }
  }
  TextureSpec glass{"noise", {35, 40, 50}, {70, 80, 95}, 1.0, 0.5, 64, ""};
  for (const MoverSpec& m : movers_) {
    if (m.type == "person") {
      mover_texture_.push_back(-1);
      continue;
    }
    if (m.type == "vehicle" && glass_texture_ < 0)
      glass_texture_ = add_texture(make_texture(glass, seed_for(++k)));
    TextureSpec spec = m.texture;
    if (spec.style == "car") spec.style = "noise";  // paint; the cabin carries the windows
    mover_texture_.push_back(add_texture(make_texture(spec, seed_for(++k))));
  }
}

void World::mover_mesh(double t, const Vec3& camera_position, Mesh& out,
                       std::vector<bool>& moving) const {
  out.clear();
  moving.assign(movers_.size(), false);
  for (std::size_t i = 0; i < movers_.size(); ++i) {
    const MoverSpec& m = movers_[i];
    const MoverPose pose = mover_pose(m, t);
    moving[i] = pose.moving;
    const auto id = static_cast<std::uint16_t>(i + 1);
    const Vec3f p = f3(pose.position);
    const float yaw = static_cast<float>(pose.yaw);
    if (m.type == "person") {
      const std::size_t s = static_cast<std::size_t>(m.sprite) % sprite_texture_.size();
      const float h = static_cast<float>(m.height);
      const float w = h * static_cast<float>(sprite_aspect_[s]);
      // The cut-out turns to face the camera and, when seen from well above (a drone), also
      // leans back about its feet to face it: an upright flat photo seen from above is squashed
      // into something no detector calls a person. From eye level it stays upright.
      Vec3f to_cam = f3(camera_position) - (p + Vec3f(0, 0, 0.5f * h));
      Vec3f horizontal(to_cam.x(), to_cam.y(), 0);
      if (horizontal.norm() < 1e-3f) horizontal = Vec3f(std::cos(yaw), std::sin(yaw), 0);
      horizontal.normalize();
      const float elevation = std::atan2(to_cam.z(), std::hypot(to_cam.x(), to_cam.y()));
      const float ramp = std::clamp((elevation - 0.26f) / 0.35f, 0.0f, 1.0f);  // 15..35 deg
      const float lean = std::min(elevation, 1.2f) * ramp * ramp * (3 - 2 * ramp);
      const Vec3f n = std::cos(lean) * horizontal + std::sin(lean) * Vec3f::UnitZ();
      const Vec3f up_dir = -std::sin(lean) * horizontal + std::cos(lean) * Vec3f::UnitZ();
      const Vec3f right = up_dir.cross(n);  // viewer's right; right x up = n faces the camera
      const Vec3f up = h * up_dir;
      const Vertex v0{p - 0.5f * w * right, Vec2f(0.f, 1.f)},
          v1{p + 0.5f * w * right, Vec2f(1.f, 1.f)};
      const Vertex v2{p + 0.5f * w * right + up, Vec2f(1.f, 0.f)},
          v3{p - 0.5f * w * right + up, Vec2f(0.f, 0.f)};
      const float shade = face_shade(Vec3f(n.x(), n.y(), 0).normalized());
      out.push_back(Triangle{{v0, v1, v2}, sprite_texture_[s], id, shade});
      out.push_back(Triangle{{v0, v2, v3}, sprite_texture_[s], id, shade});
      // Texture coordinates at exactly 1.0 would wrap to the opposite edge.
      for (std::size_t k = out.size() - 2; k < out.size(); ++k)
        for (Vertex& v : out[k].v)
          v.uv = v.uv.cwiseMax(Vec2f(0.002f, 0.002f)).cwiseMin(Vec2f(0.998f, 0.998f));
    } else if (m.type == "vehicle") {
      const Vec3f sz = f3(m.size);
      const float body_h = 0.55f * sz.z();
      const Eigen::Matrix3f R = Eigen::AngleAxisf(yaw, Vec3f::UnitZ()).toRotationMatrix();
      add_box(out, p + Vec3f(0, 0, 0.5f * body_h + 0.15f), Vec3f(sz.x(), sz.y(), body_h), yaw,
              mover_texture_[i], id, 1.5f, kTile, BoxFaces{false, false, false});
      add_box(out,
              p + R * Vec3f(-0.1f * sz.x(), 0, body_h + 0.15f + 0.5f * (sz.z() - body_h - 0.15f)),
              Vec3f(0.55f * sz.x(), 0.92f * sz.y(), sz.z() - body_h - 0.15f), yaw, glass_texture_,
              id, 1.0f, kTile, BoxFaces{false, true, false});
      // Wheels fill the gap under the body so the vehicle stands on the ground.
      for (float ix : {-0.33f, 0.33f})
        for (float iy : {-0.42f, 0.42f})
          add_box(out, p + R * Vec3f(ix * sz.x(), iy * sz.y(), 0.15f), Vec3f(0.6f, 0.2f, 0.3f), yaw,
                  glass_texture_, id, 1.0f, kTile, BoxFaces{false, true, false});
    } else {
      const std::string label = m.type == "box" ? m.label : "chair";
      add_furniture(out, label, p, f3(m.size), yaw, mover_texture_[i], id);
    }
  }
  apply_lights(out, 0);
}

}  // namespace kestrel::sim
