#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <optional>

#include "semantic/object_database.hpp"
#include "tests/test_paths.hpp"

using namespace kestrel;
using namespace kestrel::semantic;

namespace {

PinholeCamera camera() {
  PinholeCamera c;
  c.width = 320;
  c.height = 240;
  c.fx = c.fy = 262.5;
  c.cx = 159.5;
  c.cy = 119.5;
  return c;
}

// Camera at eye looking at `target` (world z up), OpenCV camera axes.
SE3 look_at(const Vec3& eye, const Vec3& target) {
  const Vec3 z = (target - eye).normalized();
  const Vec3 x = z.cross(Vec3::UnitZ()).normalized();
  const Vec3 y = z.cross(x);
  Mat3 R;
  R.col(0) = x;
  R.col(1) = y;
  R.col(2) = z;
  return SE3(SO3(R), eye);
}

struct AxisBox {
  Vec3 lo, hi;
};

// Scene: floor z = 0, wall x = 5, and axis-aligned boxes. Returns depth (5000 / m).
Image render(const PinholeCamera& cam, const SE3& T_w_c, const std::vector<AxisBox>& boxes) {
  Image d = Image::allocate(cam.width, cam.height, 1, PixelType::kU16);
  const Vec3 o = T_w_c.translation();
  for (int v = 0; v < cam.height; ++v)
    for (int u = 0; u < cam.width; ++u) {
      const Vec3 ray_c = cam.unproject(Vec2(u, v));  // z = 1
      const Vec3 r = T_w_c.rotation() * ray_c;
      double best = std::numeric_limits<double>::infinity();
      if (r.z() < 0) best = std::min(best, -o.z() / r.z());
      if (r.x() > 0) best = std::min(best, (5.0 - o.x()) / r.x());
      for (const AxisBox& b : boxes) {
        double t0 = 0, t1 = 1e9;
        for (int k = 0; k < 3; ++k) {
          if (std::abs(r[k]) < 1e-12) {
            if (o[k] < b.lo[k] || o[k] > b.hi[k]) t0 = 1e18;
            continue;
          }
          double a = (b.lo[k] - o[k]) / r[k], c = (b.hi[k] - o[k]) / r[k];
          if (a > c) std::swap(a, c);
          t0 = std::max(t0, a);
          t1 = std::min(t1, c);
        }
        if (t0 <= t1 && t0 > 0) best = std::min(best, t0);
      }
      // With ray z_c = 1 the ray parameter is the camera depth.
      d.row<std::uint16_t>(v)[u] = std::isfinite(best) && best < 13.0
                                       ? static_cast<std::uint16_t>(std::lround(best * 5000))
                                       : 0;
    }
  return d;
}

detect::Detection box_of(const PinholeCamera& cam, const SE3& T_w_c, const AxisBox& b,
                         const std::string& label) {
  detect::Detection d;
  d.label = label;
  d.score = 0.9f;
  d.x_min = d.y_min = 1e9f;
  d.x_max = d.y_max = -1e9f;
  for (int k = 0; k < 8; ++k) {
    const Vec3 p((k & 1 ? b.hi : b.lo).x(), (k & 2 ? b.hi : b.lo).y(), (k & 4 ? b.hi : b.lo).z());
    const auto uv = cam.project(T_w_c.inverse() * p);
    d.x_min = std::min(d.x_min, static_cast<float>(uv->x()));
    d.y_min = std::min(d.y_min, static_cast<float>(uv->y()));
    d.x_max = std::max(d.x_max, static_cast<float>(uv->x()));
    d.y_max = std::max(d.y_max, static_cast<float>(uv->y()));
  }
  d.x_min = std::max(d.x_min, 0.0f);
  d.y_min = std::max(d.y_min, 0.0f);
  d.x_max = std::min(d.x_max, static_cast<float>(cam.width));
  d.y_max = std::min(d.y_max, static_cast<float>(cam.height));
  return d;
}

const AxisBox kChair{Vec3(2.0, -0.3, 0.0), Vec3(2.5, 0.3, 0.9)};
const AxisBox kChair2{Vec3(2.5, 1.5, 0.0), Vec3(3.0, 2.1, 0.9)};

// One keyframe per pose (ids and seconds first_id..), each of the first `labels.size()` boxes
// detected with its label (the rest only rendered). Returns the stats of the last update.
ObjectUpdateStats update_views(ObjectDatabase& db, const std::vector<SE3>& poses,
                               const std::vector<AxisBox>& boxes,
                               const std::vector<std::string>& labels, int first_id = 0) {
  const PinholeCamera cam = camera();
  ObjectUpdateStats stats;
  for (std::size_t k = 0; k < poses.size(); ++k) {
    const SE3& T = poses[k];
    const Image depth = render(cam, T, boxes);
    ObjectKeyframe kf;
    kf.keyframe_id = first_id + static_cast<std::int64_t>(k);
    kf.T_w_c = T;
    kf.stamp = from_seconds(static_cast<double>(kf.keyframe_id));
    kf.depth = &depth;
    kf.camera = cam;
    for (std::size_t i = 0; i < boxes.size() && i < labels.size(); ++i)
      kf.static_boxes.push_back(box_of(cam, T, boxes[i], labels[i]));
    stats = db.update(kf);
  }
  return stats;
}

// Views from a short arc in front of the boxes; keyframe ids 0..n-1.
void observe(ObjectDatabase& db, int n, const std::vector<AxisBox>& boxes,
             const std::vector<std::string>& labels, std::vector<SE3>* poses = nullptr) {
  std::vector<SE3> views;
  for (int k = 0; k < n; ++k) {
    const double a = -0.5 + k * (1.0 / std::max(1, n - 1));
    views.push_back(
        look_at(Vec3(2.25 - 1.8 * std::cos(a), 0.6 + 1.8 * std::sin(a), 1.3), Vec3(2.5, 0.6, 0.4)));
  }
  update_views(db, views, boxes, labels);
  if (poses) poses->insert(poses->end(), views.begin(), views.end());
}

// Five views from 2.5 m in front of (2.5, 0), stepping sideways, at `height`.
std::vector<SE3> views_from_front(double height) {
  std::vector<SE3> views;
  for (int k = 0; k < 5; ++k)
    views.push_back(look_at(Vec3(0.0, -0.1 + 0.05 * k, height), Vec3(2.5, 0.0, 0.4)));
  return views;
}

std::optional<SemanticObject> find_label(const std::vector<SemanticObject>& objs,
                                         const std::string& label) {
  for (const SemanticObject& o : objs)
    if (o.label == label) return o;
  return std::nullopt;
}

}  // namespace

TEST(ObjectDatabase, FusesViewsIntoOneObjectPerBox) {
  ObjectDatabase db;
  observe(db, 6, {kChair, kChair2}, {"chair", "chair"});
  EXPECT_NEAR(db.floor_height(), 0.0, 0.02);
  const auto objs = db.objects();
  ASSERT_EQ(objs.size(), 2u);
  for (const SemanticObject& o : objs) {
    const AxisBox& truth = o.box.center.y() < 0.75 ? kChair : kChair2;
    const Vec3 c = (truth.lo + truth.hi) / 2;
    EXPECT_LT((o.box.center - c).norm(), 0.06) << o.box.center.transpose();
    EXPECT_NEAR(o.box.size.z(), 0.9, 0.06);
    EXPECT_NEAR(std::max(o.box.size.x(), o.box.size.y()), 0.6, 0.08);
    EXPECT_EQ(o.label, "chair");
    EXPECT_EQ(o.observations, 6);
    EXPECT_EQ(o.first_seen, from_seconds(0));
    EXPECT_EQ(o.last_seen, from_seconds(5));
    EXPECT_GT(o.confidence(), 0.7);
  }
}

// A box that sees only a part of a larger surface (market: a table mostly hidden by the stall
// in front of it, whose box the stall fills) is not a view of the box's object: the stall's
// face goes on past the box's bottom and right edges. The object it would make is held as
// tentative and not reported; the stall's own box, where the face ends, is.
TEST(ObjectDatabase, ABoxFilledByALargerSurfaceIsTentative) {
  const AxisBox stall{Vec3(2.0, -0.4, 0.0), Vec3(2.4, 1.0, 1.0)};
  const AxisBox top_part{Vec3(2.0, -0.4, 0.7), Vec3(2.4, 0.2, 1.0)};
  const PinholeCamera cam = camera();
  ObjectDatabase db;
  for (int k = 0; k < 6; ++k) {
    const double a = -0.5 + k * 0.2;
    const SE3 T =
        look_at(Vec3(2.25 - 1.8 * std::cos(a), 0.6 + 1.8 * std::sin(a), 1.3), Vec3(2.5, 0.6, 0.4));
    const Image depth = render(cam, T, {stall});
    ObjectKeyframe kf;
    kf.keyframe_id = k;
    kf.T_w_c = T;
    kf.stamp = from_seconds(k);
    kf.depth = &depth;
    kf.camera = cam;
    kf.static_boxes.push_back(box_of(cam, T, top_part, "dining table"));
    db.update(kf);
  }
  EXPECT_TRUE(db.objects().empty());
  ASSERT_EQ(db.all_objects().size(), 1u);
  EXPECT_GE(db.all_objects()[0].observations, 3);
  EXPECT_EQ(db.all_objects()[0].whole_observations, 0);

  ObjectDatabase whole;
  observe(whole, 6, {stall}, {"bench"});
  ASSERT_EQ(whole.objects().size(), 1u);
  EXPECT_EQ(whole.objects()[0].whole_observations, whole.objects()[0].observations);
}

TEST(ObjectDatabase, ReanchoringKeyframesMovesTheirObjects) {
  ObjectDatabase db;
  std::vector<SE3> poses;
  observe(db, 4, {kChair}, {"chair"}, &poses);
  const Vec3 before = db.objects().at(0).box.center;
  const SE3 shift(SO3(), Vec3(0.0, 1.0, 0.0));
  for (int k = 0; k < 4; ++k) db.reanchor(k, shift * poses[static_cast<std::size_t>(k)]);
  const Vec3 after = db.objects().at(0).box.center;
  EXPECT_NEAR(after.y() - before.y(), 1.0, 1e-4);
  EXPECT_NEAR(after.x(), before.x(), 1e-4);
}

TEST(ObjectDatabase, RareLabelsAreNotReported) {
  ObjectDatabase db;
  observe(db, 2, {kChair}, {"couch"});
  EXPECT_TRUE(db.objects().empty());
  ASSERT_EQ(db.all_objects().size(), 1u);
  EXPECT_EQ(db.all_objects()[0].observations, 2);
}

// YOLO calls a parked pickup a car in one view and a truck in the next: one object, under the
// label its views gave most (by detector score), not a car and a truck on the same spot.
TEST(ObjectDatabase, AVehicleCalledCarThenTruckIsOneObjectUnderTheLabelSeenMost) {
  ObjectDatabase db;
  const std::vector<SE3> poses = views_from_front(0.8);
  int id = 0;
  for (const char* label : {"truck", "truck", "car", "car", "car"})
    update_views(db, {poses[static_cast<std::size_t>(id)]}, {kChair}, {label}, id), ++id;
  const auto objs = db.objects();
  ASSERT_EQ(objs.size(), 1u);
  EXPECT_EQ(objs[0].label, "car");
  EXPECT_EQ(objs[0].observations, 5);
  // A chair is never a car.
  ObjectDatabase other;
  update_views(other, {poses[0], poses[1], poses[2]}, {kChair}, {"chair"});
  update_views(other, {poses[3], poses[4]}, {kChair}, {"car"}, 3);
  ASSERT_EQ(other.all_objects().size(), 2u);
}

TEST(ObjectDatabase, AChairSeenMovingLeavesTheDatabase) {
  ObjectDatabase db;
  observe(db, 4, {kChair}, {"chair"});
  ASSERT_EQ(db.objects().size(), 1u);
  const PinholeCamera cam = camera();
  const SE3 T = look_at(Vec3(0.45, 0.6, 1.3), Vec3(2.5, 0.6, 0.4));
  const Image depth = render(cam, T, {});
  ObjectKeyframe kf;
  kf.keyframe_id = 10;
  kf.T_w_c = T;
  kf.depth = &depth;
  kf.camera = cam;
  kf.moving_boxes.push_back(box_of(cam, T, kChair, "chair"));
  EXPECT_EQ(db.update(kf).removed_moving, 1);
  EXPECT_TRUE(db.all_objects().empty());
}

// Taken away: its place shows neither its box nor its surfaces (the wall behind it instead).
// Three such keyframes in a row remove it; two do not.
TEST(ObjectDatabase, AnObjectTakenAwayLeavesAfterThreeKeyframesShowItsPlaceEmpty) {
  ObjectDatabase db;
  std::vector<SE3> poses;
  observe(db, 4, {kChair}, {"chair"}, &poses);
  ASSERT_EQ(db.objects().size(), 1u);
  const std::vector<SE3> again(poses.begin(), poses.begin() + 3);
  update_views(db, {again[0], again[1]}, {}, {}, 10);
  EXPECT_EQ(db.objects().size(), 1u);
  EXPECT_EQ(update_views(db, {again[2]}, {}, {}, 12).removed_absent, 1);
  EXPECT_TRUE(db.all_objects().empty());
}

// A detector that misses an object for a while removes nothing while the depth still shows it;
// neither does something nearer that hides it.
TEST(ObjectDatabase, AMissedDetectionOrAHiddenObjectStays) {
  ObjectDatabase db;
  std::vector<SE3> poses;
  observe(db, 4, {kChair}, {"chair"}, &poses);
  ASSERT_EQ(db.objects().size(), 1u);
  EXPECT_EQ(update_views(db, poses, {kChair}, {}, 10).removed_absent, 0);
  ASSERT_EQ(db.objects().size(), 1u);
  // A screen between the cameras and the chair, the chair taken away behind it.
  const AxisBox screen{Vec3(1.2, -1.5, 0.0), Vec3(1.3, 2.5, 2.0)};
  EXPECT_EQ(update_views(db, poses, {screen}, {}, 20).removed_absent, 0);
  EXPECT_EQ(db.objects().size(), 1u);
}

// Pushed while the detector keeps calling it a chair and no one flags it as moving: its
// measurements walk away from where it stood, it leaves the report, follows them, and returns
// where they stay still, under the same id.
TEST(ObjectDatabase, AChairWhoseMeasurementsWalkAwayLeavesAndReturnsWhereItStops) {
  ObjectDatabase db;
  std::vector<SE3> poses;
  observe(db, 4, {kChair}, {"chair"}, &poses);
  ASSERT_EQ(db.objects().size(), 1u);
  const int id = db.objects()[0].id;
  const SE3 T = poses[1];
  int first_id = 10, left = -1;
  AxisBox chair = kChair;
  for (int k = 0; k < 5; ++k) {  // 0.2 m a keyframe (a second) sideways
    chair.lo.y() += 0.2;
    chair.hi.y() += 0.2;
    update_views(db, {T}, {chair}, {"chair"}, first_id++);
    if (left < 0 && db.objects().empty()) left = k;
  }
  EXPECT_EQ(left, 3);  // three measurements past a quarter metre (the first step was within)
  EXPECT_TRUE(db.objects().empty());  // still moving
  ASSERT_EQ(db.all_objects().size(), 1u);
  EXPECT_TRUE(db.all_objects()[0].moving);
  for (int k = 0; k < 3; ++k) update_views(db, {T}, {chair}, {"chair"}, first_id++);
  const auto objs = db.objects();
  ASSERT_EQ(objs.size(), 1u);
  EXPECT_EQ(objs[0].id, id);
  EXPECT_FALSE(objs[0].moving);
  EXPECT_NEAR(objs[0].box.center.y(), (chair.lo.y() + chair.hi.y()) / 2, 0.06);
  EXPECT_LE(objs[0].observations, 4);  // only views of where it stands now
}

TEST(ObjectDatabase, WritesObjectsJson) {
  ObjectDatabase db;
  observe(db, 3, {kChair}, {"chair"});
  const auto dir = test::temp_dir("semantic-out");
  db.write_outputs(dir.string());
  const auto back = io::read_objects((dir / "objects.json").string());
  ASSERT_EQ(back.size(), 1u);
  EXPECT_EQ(back[0].label, "chair");
  EXPECT_EQ(back[0].observations, 3);
  EXPECT_NEAR(back[0].center.x(), db.objects()[0].box.center.x(), 1e-6);
}

TEST(ObjectDatabase, BadInputIsIgnoredNotThrown) {
  ObjectDatabase db;
  ObjectKeyframe kf;
  kf.camera = camera();
  EXPECT_EQ(db.update(kf).boxes, 0);
  Image wrong = Image::allocate(10, 10, 1, PixelType::kU16);
  kf.depth = &wrong;
  kf.static_boxes.push_back({});
  EXPECT_EQ(db.update(kf).boxes, 0);
}

// A bench seen end-on is 2 m deep and 0.5 m wide in its box: its far end lies well past the
// depth extent that a box's width allows (what keeps the table behind a tucked-in chair out of
// the chair), but no other box claims those pixels, so they are the bench's.
TEST(ObjectDatabase, AnObjectSeenEndOnKeepsItsFarEnd) {
  const AxisBox bench{Vec3(1.5, -0.25, 0.0), Vec3(3.5, 0.25, 0.5)};
  auto length = [&](bool extend) {
    ObjectDatabaseOptions opt;
    opt.extend_past_depth_extent = extend;
    opt.size_priors = false;  // what the depth shows, not a bench's typical length
    ObjectDatabase db(opt);
    const PinholeCamera cam = camera();
    for (int k = 0; k < 4; ++k) {
      // Low and to one side: its end and one long side face the camera.
      const SE3 T = look_at(Vec3(0.0, 0.8 + 0.05 * k, 0.6), Vec3(2.5, 0.0, 0.25));
      const Image depth = render(cam, T, {bench});
      ObjectKeyframe kf;
      kf.keyframe_id = k;
      kf.T_w_c = T;
      kf.stamp = from_seconds(k);
      kf.depth = &depth;
      kf.camera = cam;
      kf.static_boxes.push_back(box_of(cam, T, bench, "bench"));
      db.update(kf);
    }
    const auto objs = db.objects();
    EXPECT_EQ(objs.size(), 1u) << extend;
    return objs.empty() ? 0.0 : objs.front().box.size.x();
  };
  EXPECT_LT(length(false), 1.2);
  EXPECT_NEAR(length(true), 2.0, 0.25);
}

// A chair behind a table, its box nearly the table's (cafe: a chair tucked behind its table,
// seen across it): the nearest surface in the chair's box is the table's, but where the table's
// box does not reach (above the table) the chair's box sees the chair alone. The table's surface
// is not taken for the chair, and the table keeps it.
TEST(ObjectDatabase, AChairBehindATableIsNotTheTablesFront) {
  const AxisBox table{Vec3(1.8, -0.45, 0.0), Vec3(2.6, 0.45, 0.75)};
  const AxisBox chair{Vec3(2.7, -0.675, 0.0), Vec3(3.2, 0.675, 0.95)};
  auto run = [&](const ObjectDatabaseOptions& o) {
    ObjectDatabase db(o);
    update_views(db, views_from_front(0.8), {table, chair}, {"dining table", "chair"});
    return db.all_objects();
  };
  const auto objs = run({});
  const auto t = find_label(objs, "dining table");
  ASSERT_TRUE(t.has_value());
  EXPECT_EQ(t->observations, 5);
  // Its front face where it is (its depth is the size prior's: the far side was never seen).
  EXPECT_NEAR(t->box.center.x() - t->box.size.x() / 2, 1.8, 0.05) << t->box.center.transpose();
  EXPECT_NEAR(t->box.center.y(), 0.0, 0.05);
  if (const auto c = find_label(objs, "chair")) {
    EXPECT_GT(c->box.center.x(), 2.65) << c->box.center.transpose();  // behind the table
  }
  // What the check prevents: the chair's box, smaller, chose first and took the table's front.
  ObjectDatabaseOptions off;
  off.min_own_region_share = 2.0;
  const auto without = run(off);
  const auto c_off = find_label(without, "chair");
  ASSERT_TRUE(c_off.has_value());
  EXPECT_LT(c_off->box.center.x(), 2.6) << c_off->box.center.transpose();
}

// What hides an object's middle cuts it in two clusters (a chair behind a table top: its back
// above, its legs below). Neither alone fits the chair's box; the parts at the depth of the
// one seen in the box's own region are measured together.
TEST(ObjectDatabase, AnObjectCutInTwoByWhatHidesItsMiddleIsMeasuredWhole) {
  const AxisBox top{Vec3(1.8, -0.8, 0.45), Vec3(2.6, 0.8, 0.6)};
  const AxisBox chair{Vec3(2.7, -0.3, 0.0), Vec3(3.2, 0.3, 0.95)};
  auto run = [&](const ObjectDatabaseOptions& o) {
    ObjectDatabase db(o);
    update_views(db, views_from_front(0.5), {top, chair}, {"dining table", "chair"});
    return find_label(db.all_objects(), "chair");
  };
  const auto c = run({});
  ASSERT_TRUE(c.has_value());
  EXPECT_EQ(c->observations, 5);
  EXPECT_LT((c->box.center.head<2>() - Vec2(2.95, 0.0)).norm(), 0.08) << c->box.center.transpose();
  EXPECT_NEAR(c->box.center.z() + c->box.size.z() / 2, 0.95, 0.05);  // its back's top
  ObjectDatabaseOptions apart;
  apart.join_parts = false;
  EXPECT_FALSE(run(apart).has_value());  // neither part fits the box alone
}

// A "chair" 1.6 m long is several things taken for one chair: not measured.
TEST(ObjectDatabase, AMeasurementFarLongerThanItsClassIsDropped) {
  const AxisBox long_block{Vec3(2.0, -0.2, 0.0), Vec3(2.5, 1.4, 0.9)};
  ObjectDatabase db;
  observe(db, 4, {long_block}, {"chair"});
  EXPECT_TRUE(db.all_objects().empty());
  ObjectDatabaseOptions any;
  any.max_length_over_prior = 1e9;
  ObjectDatabase kept(any);
  observe(kept, 4, {long_block}, {"chair"});
  ASSERT_EQ(kept.all_objects().size(), 1u);
  EXPECT_NEAR(std::max(kept.all_objects()[0].box.size.x(), kept.all_objects()[0].box.size.y()), 1.6,
              0.1);
}
