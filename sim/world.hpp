#pragma once
// The scene of a scenario: textures, the static mesh (scenery and labelled objects) and the
// movers, whose mesh is rebuilt for each instant. Instance ids in the id buffer:
//   0                      scenery (walls, ground, buildings)
//   1 .. kMaxMovers        mover i has id i + 1 (also the id in dynamic/ masks)
//   kFirstObjectId + j     static object j
#include <cstdint>
#include <string>
#include <vector>

#include "sim/mesh.hpp"
#include "sim/mover_path.hpp"
#include "sim/person_sprites.hpp"
#include "sim/photo_cutouts.hpp"
#include "sim/scenario.hpp"
#include "sim/texture.hpp"

namespace kestrel::sim {

inline constexpr int kMaxMovers = 999;
inline constexpr std::uint16_t kFirstObjectId = 1000;
inline constexpr std::size_t kMaxInstances = 4096;

struct StaticObject {
  int id = 0;
  std::string label;
  Vec3 center = Vec3::Zero();
  Vec3 size = Vec3::Zero();
  double yaw = 0.0;
};

// A vehicle built from a side photo: the photo's silhouette, extruded across the width, gives
// the body (roof, bonnet, windscreen, ends); both sides show the cut-out.
struct VehicleLook {
  std::string name;
  int side_texture = -1;      // the cut-out (alpha)
  int paint_texture = -1;     // the photo's body colour, for roof and ends
  std::vector<float> top;     // silhouette top per column, fraction of the height from the top
  std::vector<float> bottom;  // and bottom
  bool front_left = true;     // the photo shows the front at its left
};

// Adds a photographic vehicle of `size` (length, width, height) standing at `base` (ground
// centre), heading `yaw`. glass: texture of windscreen and rear window.
void add_photo_vehicle(Mesh& mesh, const VehicleLook& look, const Vec3f& base, const Vec3f& size,
                       float yaw, int glass, std::uint16_t instance);

class World {
 public:
  // Builds every texture (deterministic in the scenario's seed). Throws kestrel::Error when an
  // asset is missing or the scenario has too many movers or objects.
  explicit World(const Scenario& scenario);

  const std::vector<Texture>& textures() const { return textures_; }
  const Mesh& static_mesh() const { return static_mesh_; }
  const std::vector<StaticObject>& objects() const { return objects_; }
  const std::vector<MoverSpec>& movers() const { return movers_; }

  // The movers at time t; people turn to face camera_position (they are flat cut-outs), birds
  // beat their wings. moving[i] tells whether mover i moves at t.
  void mover_mesh(double t, const Vec3& camera_position, Mesh& out,
                  std::vector<bool>& moving) const;

 private:
  int add_texture(Texture t);
  void apply_lights(Mesh& mesh, std::size_t from) const;

  std::vector<Texture> textures_;
  Mesh static_mesh_;
  std::vector<StaticObject> objects_;
  std::vector<MoverSpec> movers_;
  std::vector<LightZone> lights_;
  std::vector<int> mover_texture_;  // per mover
  std::vector<int> sprite_texture_;
  std::vector<double> sprite_aspect_;
  int glass_texture_ = -1;
  std::vector<VehicleLook> looks_;  // photographic vehicles, by cut-out
  std::vector<int> mover_look_;     // per mover: index in looks_, or -1
  // Returns the index in looks_ of vehicle cut-out `name`, loading it on first use.
  int look(const std::string& name, const std::string& assets, std::uint64_t seed);
};

// Furniture shapes shared by static objects and movers: a chair (seat, back, legs) or table
// (top, legs) filling the box whose floor centre is `base`; anything else is a plain box.
void add_furniture(Mesh& mesh, const std::string& label, const Vec3f& base, const Vec3f& size,
                   float yaw, int texture, std::uint16_t instance);

}  // namespace kestrel::sim
