#pragma once
// Saving and loading the sparse map (multi-session: a later run relocalizes in it) and the
// outputs of a run that describe it: keyframe poses (TUM text) and map points (PLY).
//
// map.bin layout, little-endian, fixed-width fields:
//   "KSTRLMAP" (8 bytes), u32 version (kMapFormatVersion),
//   u64 keyframe count, then per keyframe: i64 id, i64 stamp ns, f64 tx ty tz qx qy qz qw
//     (T_w_c), i32 width height, f32 scale factor, i32 levels, u64 feature count, then per
//     feature: f64 px.x px.y un.x un.y, f32 angle response, i32 level, 32-byte descriptor,
//     f64 depth, f64 x y z (camera frame), u8 status, i64 map point (-1: none);
//     u64 connection count, then (i64 keyframe, i32 weight) pairs;
//   u64 point count, then per point: i64 id, f64 x y z (world), 32-byte descriptor, f64 normal
//     x y z, i64 first keyframe, i32 visible found, f64 min_distance max_distance, u64
//     observation count, then (i64 keyframe, i32 feature) pairs;
//   "KEND" (4 bytes).
#include <cstdint>
#include <string>

#include "mapping/map.hpp"

namespace kestrel::mapping {

inline constexpr std::uint32_t kMapFormatVersion = 1;

// Throws kestrel::Error naming the file when it cannot be written.
void save_map(const std::string& path, const Map& map);
// Throws kestrel::Error naming the file and the field on a missing file, bad magic, unknown
// version, truncation, trailing bytes, or links to keyframes, features or points that do not
// exist.
Map load_map(const std::string& path);

// The bytes save_map writes, and their parser (`name` is what errors call the data).
std::string serialize_map(const Map& map);
Map deserialize_map(const std::string& bytes, const std::string& name);

// Keyframe poses T_w_body = T_w_c * T_body_camera^-1, TUM format, in keyframe order.
void write_keyframes_tum(const std::string& path, const Map& map, const SE3& T_body_camera);
// Map points as a binary little-endian PLY: x y z (float), observations (uchar, capped at 255).
void write_points_ply(const std::string& path, const Map& map);

}  // namespace kestrel::mapping
