#include "sim/world.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

#include "core/error.hpp"

namespace kestrel::sim {
namespace {

constexpr float kTile = 1.0f;  // metres: large faces are split so perspective stays accurate
// Silhouette samples along a vehicle photo: enough for bonnet, windscreen, roof and boot.
constexpr int kVehicleColumns = 16;

Vec3f f3(const Vec3& v) { return v.cast<float>(); }

// Texture coordinates at exactly 0 or 1 would wrap to the opposite edge of a cut-out.
Vec2f inside_uv(float u, float v) {
  return Vec2f(std::clamp(u, 0.002f, 0.998f), std::clamp(v, 0.002f, 0.998f));
}

// A bird flying at `center` (its body's centre) heading `yaw`: body, head, tail and two wings
// raised by `flap` radians about the body's long axis. Wings and tail are thin plates drawn
// from both sides (the rasterizer culls back faces).
void add_bird(Mesh& mesh, const Vec3f& center, const Vec3f& size, float yaw, float flap,
              int texture, std::uint16_t instance) {
  const Eigen::Matrix3f R = Eigen::AngleAxisf(yaw, Vec3f::UnitZ()).toRotationMatrix();
  const float len = size.x(), span = size.y(), body = size.z();
  const auto at = [&](float x, float y, float z) { return Vec3f(center + R * Vec3f(x, y, z)); };
  const auto plate = [&](const Vec3f& a, const Vec3f& b, const Vec3f& c, const Vec3f& d) {
    add_quad(mesh, a, b, c, d, Vec2f::Zero(), 0.3f, texture, instance, kTile);
    add_quad(mesh, d, c, b, a, Vec2f::Zero(), 0.3f, texture, instance, kTile);
  };
  add_box(mesh, center, Vec3f(len, body, body), yaw, texture, instance, 0.3f, kTile,
          BoxFaces{false, false, false});
  const float head = 0.6f * body;
  add_box(mesh, at(0.5f * len + 0.5f * head, 0, 0.25f * body), Vec3f(head, head, head), yaw,
          texture, instance, 0.3f, kTile, BoxFaces{false, false, false});
  plate(at(-0.5f * len, -0.3f * body, 0), at(-0.5f * len, 0.3f * body, 0),
        at(-0.9f * len, 0.6f * body, 0), at(-0.9f * len, -0.6f * body, 0));
  const float reach = std::max(0.05f, 0.5f * span - 0.5f * body);
  const float c = std::cos(flap), s = std::sin(flap);
  for (float side : {-1.f, 1.f}) {
    // Root chord along the body, a narrower chord swept back at the tip.
    const auto wing = [&](float x, float r) { return at(x, side * (0.5f * body + r * c), r * s); };
    plate(wing(-0.3f * len, 0), wing(0.25f * len, 0), wing(-0.05f * len, reach),
          wing(-0.35f * len, reach));
  }
}

}  // namespace

void add_photo_vehicle(Mesh& mesh, const VehicleLook& look, const Vec3f& base, const Vec3f& size,
                       float yaw, int glass, std::uint16_t instance) {
  const Eigen::Matrix3f R = Eigen::AngleAxisf(yaw, Vec3f::UnitZ()).toRotationMatrix();
  const float L = size.x(), W = size.y(), H = size.z();
  const auto at = [&](float x, float y, float z) { return Vec3f(base + R * Vec3f(x, y, z)); };
  // The photo's u runs from its left to its right edge; the vehicle's x points forward.
  const auto x_of = [&](float u) { return look.front_left ? 0.5f * L - u * L : -0.5f * L + u * L; };
  const int n = static_cast<int>(look.top.size());

  // Both sides show the cut-out, one strip per column (the mip level is chosen per triangle,
  // so narrow strips keep it right when the side is seen at a slant). The far side mirrors
  // itself: the front stays at the front.
  for (float side : {1.f, -1.f}) {
    const float shade = face_shade(R * Vec3f(0, side, 0));
    for (int c = 0; c < n; ++c) {
      float ua = static_cast<float>(c) / n, ub = static_cast<float>(c + 1) / n;
      float xa = x_of(ua), xb = x_of(ub);
      // Counter-clockwise seen from outside: along the bottom edge x falls on the +y side.
      if ((side > 0) != (xa > xb)) std::swap(xa, xb), std::swap(ua, ub);
      const float y = 0.5f * side * W;
      const Vertex v0{at(xa, y, 0), inside_uv(ua, 1)}, v1{at(xb, y, 0), inside_uv(ub, 1)};
      const Vertex v2{at(xb, y, H), inside_uv(ub, 0)}, v3{at(xa, y, H), inside_uv(ua, 0)};
      mesh.push_back(Triangle{{v0, v1, v2}, look.side_texture, instance, shade});
      mesh.push_back(Triangle{{v0, v2, v3}, look.side_texture, instance, shade});
    }
  }
  // The silhouette's top edge swept across the width: bonnet, windscreen, roof, boot, from the
  // rear (smallest x) forward so that every strip faces up.
  struct Point {
    float x, top, bottom;  // metres: x forward, top and bottom heights
  };
  std::vector<Point> profile;
  for (int c = 0; c < n; ++c) {
    const std::size_t i = static_cast<std::size_t>(c);
    if (look.top[i] >= look.bottom[i]) continue;  // an empty column
    const float u = (c + 0.5f) / n;
    const Point p{x_of(u), H * (1 - look.top[i]), H * (1 - look.bottom[i])};
    // The edge columns reach the ends of the body.
    if (profile.empty()) profile.push_back({x_of(0), p.top, p.bottom});
    profile.push_back(p);
  }
  if (profile.empty()) return;
  profile.push_back({x_of(1), profile.back().top, profile.back().bottom});
  std::sort(profile.begin(), profile.end(),
            [](const Point& a, const Point& b) { return a.x < b.x; });
  const float hw = 0.5f * W;
  for (std::size_t k = 0; k + 1 < profile.size(); ++k) {
    const Point &a = profile[k], &b = profile[k + 1];
    if (b.x - a.x < 1e-4f) continue;
    // Steep strips in the upper half are the windscreen and the rear window.
    const bool window =
        std::fabs(b.top - a.top) > 0.6f * (b.x - a.x) && std::min(a.top, b.top) > 0.5f * H;
    add_quad(mesh, at(a.x, -hw, a.top), at(b.x, -hw, b.top), at(b.x, hw, b.top), at(a.x, hw, a.top),
             Vec2f::Zero(), 1.0f, window ? glass : look.paint_texture, instance, kTile);
  }
  const Point &rear = profile.front(), &front = profile.back();
  add_quad(mesh, at(front.x, -hw, front.bottom), at(front.x, hw, front.bottom),
           at(front.x, hw, front.top), at(front.x, -hw, front.top), Vec2f::Zero(), 1.0f,
           look.paint_texture, instance, kTile);
  add_quad(mesh, at(rear.x, hw, rear.bottom), at(rear.x, -hw, rear.bottom),
           at(rear.x, -hw, rear.top), at(rear.x, hw, rear.top), Vec2f::Zero(), 1.0f,
           look.paint_texture, instance, kTile);
}

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

int World::look(const std::string& name, const std::string& assets, std::uint64_t seed) {
  for (std::size_t i = 0; i < looks_.size(); ++i)
    if (looks_[i].name == name) return static_cast<int>(i);
  Cutout c = load_cutout(assets, name, false, kVehicleColumns);
  VehicleLook v;
  v.name = name;
  v.side_texture = add_texture(std::move(c.texture));
  // Paint of the photo's colour with a little grain, so roof and ends carry some features.
  const std::array<int, 3> dark{c.paint[0] * 3 / 4, c.paint[1] * 3 / 4, c.paint[2] * 3 / 4};
  v.paint_texture =
      add_texture(make_texture(TextureSpec{"noise", c.paint, dark, 1.0, 0.4, 64, ""}, seed));
  v.top = std::move(c.top);
  v.bottom = std::move(c.bottom);
  v.front_left = c.front_left;
  looks_.push_back(std::move(v));
  return static_cast<int>(looks_.size()) - 1;
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
    const float scale = static_cast<float>(sc.ground_texture.scale);
    if (!sc.ground_shuffle) {
      add_quad(static_mesh_, c + Vec3f(-hx, -hy, 0), c + Vec3f(hx, -hy, 0), c + Vec3f(hx, hy, 0),
               c + Vec3f(-hx, hy, 0), Vec2f::Zero(), scale, tex, 0, kTile);
    } else {
      // One quad per texture repeat, each turned by a multiple of 90 degrees (the corner that
      // gets uv (0, 0) rotates) and lit a little differently, drawn from the seed: the same
      // texture, no longer periodic. Turning keeps the winding, so every cell faces up.
      const std::uint64_t cell_seed = seed_for(++k);
      const int nx = std::max(1, static_cast<int>(std::ceil(2 * hx / scale)));
      const int ny = std::max(1, static_cast<int>(std::ceil(2 * hy / scale)));
      for (int j = 0; j < ny; ++j) {
        for (int i = 0; i < nx; ++i) {
          const float x0 = -hx + i * scale, x1 = std::min(hx, x0 + scale);
          const float y0 = -hy + j * scale, y1 = std::min(hy, y0 + scale);
          const Vec3f corner[4] = {c + Vec3f(x0, y0, 0), c + Vec3f(x1, y0, 0), c + Vec3f(x1, y1, 0),
                                   c + Vec3f(x0, y1, 0)};
          const std::uint64_t h = hash_combine(
              cell_seed, static_cast<std::uint64_t>(j) * 65536u + static_cast<std::uint64_t>(i));
          const int turn = static_cast<int>(h & 3u);
          const float gain = 0.88f + 0.08f * static_cast<float>((h >> 2) % 4u);
          add_quad(static_mesh_, corner[turn], corner[(turn + 1) % 4], corner[(turn + 2) % 4],
                   corner[(turn + 3) % 4], Vec2f::Zero(), scale, tex, 0, kTile, gain);
        }
      }
    }
  }
  for (const StaticBoxSpec& b : sc.boxes) {
    const int tex = add_texture(make_texture(b.texture, seed_for(++k)));
    add_box(static_mesh_, f3(b.center), f3(b.size), static_cast<float>(b.yaw), tex, 0,
            static_cast<float>(b.texture.scale), kTile, BoxFaces{b.inward, true, false});
  }
  TextureSpec glass{"noise", {35, 40, 50}, {70, 80, 95}, 1.0, 0.5, 64, ""};
  const auto glass_texture = [&] {
    if (glass_texture_ < 0) glass_texture_ = add_texture(make_texture(glass, seed_for(++k)));
    return glass_texture_;
  };
  int j = 0;
  for (const ObjectSpec& o : sc.objects) {
    const int tex = add_texture(make_texture(o.texture, seed_for(++k)));
    const auto id = static_cast<std::uint16_t>(kFirstObjectId + j);
    const Vec3f base = f3(o.center) - Vec3f(0, 0, 0.5f * static_cast<float>(o.size.z()));
    if (!o.photo.empty()) {
      const int g = glass_texture();
      const VehicleLook& v =
          looks_[static_cast<std::size_t>(look(o.photo, sc.assets, seed_for(++k)))];
      add_photo_vehicle(static_mesh_, v, base, f3(o.size), static_cast<float>(o.yaw), g, id);
    } else {
      add_furniture(static_mesh_, o.label, base, f3(o.size), static_cast<float>(o.yaw), tex, id);
    }
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
  for (const MoverSpec& m : movers_) {
    mover_look_.push_back(-1);
    if (m.type == "person") {
      mover_texture_.push_back(-1);
      continue;
    }
    if (m.type == "vehicle") glass_texture();
    if (!m.photo.empty()) mover_look_.back() = look(m.photo, sc.assets, seed_for(++k));
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
    } else if (m.type == "vehicle" && mover_look_[i] >= 0) {
      add_photo_vehicle(out, looks_[static_cast<std::size_t>(mover_look_[i])], p, f3(m.size), yaw,
                        glass_texture_, id);
    } else if (m.type == "bird") {
      // Wings beat while it flies and are held half raised while it waits or glides to a stop.
      const double beat = 2.0 * M_PI * m.flap_hz * t;
      const float flap = pose.moving ? static_cast<float>(0.65 * std::sin(beat)) : 0.3f;
      add_bird(out, p, f3(m.size), yaw, flap, mover_texture_[i], id);
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
