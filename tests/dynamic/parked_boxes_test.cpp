#include "dynamic/parked_boxes.hpp"

#include <gtest/gtest.h>

namespace kestrel::dynamic {
namespace {

constexpr Timestamp kFrame = kNanosPerSecond / 30;

DynamicFilterResult judged(std::vector<bool> moving, std::vector<int> features,
                           std::vector<int> off = {}) {
  DynamicFilterResult r;
  off.resize(features.size(), 0);
  r.box_moving = std::move(moving);
  r.box_features = std::move(features);
  r.box_violating = std::move(off);
  return r;
}

// One box per frame, drifting `step` px a frame, judged still or moving with `features` of its
// own (`off` of them off the ego-motion); returns whether it was parked when it came.
struct Feed {
  ParkedBoxTracker tracker;
  Timestamp t = 0;
  float x = 100;
  bool frame(bool parkable, bool moving, int features, int off = 0, float step = 0.5f) {
    std::vector<BoxRegion> boxes = {{x, 100, x + 120, 180}};
    tracker.assign(t, boxes, {parkable});
    const bool parked = boxes[0].parked;
    tracker.observe(judged({moving}, {features}, {off}));
    t += kFrame;
    x += step;
    return parked;
  }
};

TEST(ParkedBoxes, AVehicleStillForParkSecondsIsParkedAndMovingUnparksIt) {
  Feed f;
  int first_parked = -1;
  for (int k = 0; k < 90; ++k)
    if (f.frame(true, false, 30) && first_parked < 0) first_parked = k;
  // Parked from the frame after 0.5 s of still judgements (frame 15 is judged at 0.5 s).
  EXPECT_NEAR(first_parked, 16, 1);
  EXPECT_TRUE(f.frame(true, true, 30));    // parked when it came; found moving in it
  EXPECT_FALSE(f.frame(true, false, 30));  // a mover again ...
  for (int k = 0; k < 14; ++k) EXPECT_FALSE(f.frame(true, false, 30));
  int again = 0;
  for (int k = 0; k < 5; ++k) again += f.frame(true, false, 30);
  EXPECT_GT(again, 0);  // ... until still for park_seconds once more
}

TEST(ParkedBoxes, PeopleNeverParkAndUnjudgedFramesDoNotCount) {
  Feed person;
  for (int k = 0; k < 120; ++k) EXPECT_FALSE(person.frame(false, false, 30));
  // Too few features of its own: no judgement, however long.
  Feed bare;
  for (int k = 0; k < 120; ++k) EXPECT_FALSE(bare.frame(true, false, 2));
  // A vehicle whose own features drift off the ego-motion, too few for the box to be called
  // moving (a car driving along the camera's path: the 2D test misses it, some 3D residuals
  // do not), is not still.
  Feed creeping;
  for (int k = 0; k < 120; ++k) EXPECT_FALSE(creeping.frame(true, false, 30, 4));
  // A frame without geometry calls every box moving with no features of its own judged: it
  // neither parks nor unparks.
  Feed f;
  for (int k = 0; k < 60; ++k) f.frame(true, false, 30);
  EXPECT_TRUE(f.frame(true, true, 0));
  EXPECT_TRUE(f.frame(true, false, 30));
}

TEST(ParkedBoxes, ATrackEndsWhenItsBoxIsGoneOrJumps) {
  Feed f;
  for (int k = 0; k < 60; ++k) f.frame(true, false, 30);
  EXPECT_TRUE(f.frame(true, false, 30));
  f.t += kNanosPerSecond;  // a second without the box: a new track
  EXPECT_FALSE(f.frame(true, false, 30));
  EXPECT_EQ(f.tracker.tracks(), 1u);
  for (int k = 0; k < 60; ++k) f.frame(true, false, 30);
  f.x += 200;  // no overlap: another object
  EXPECT_FALSE(f.frame(true, false, 30));
}

TEST(ParkedBoxes, TwoBoxesAreFollowedApart) {
  ParkedBoxTracker tracker;
  Timestamp t = 0;
  float x = 300;
  bool parked_still = false, parked_mover = false;
  for (int k = 0; k < 90; ++k, t += kFrame, x += 4.0f) {
    // A parked car on the left, a car driving past on the right.
    std::vector<BoxRegion> boxes = {{50, 100, 170, 180}, {x, 100, x + 120, 180}};
    tracker.assign(t, boxes, {true, true});
    parked_still = boxes[0].parked;
    parked_mover = boxes[1].parked;
    tracker.observe(judged({false, true}, {30, 30}));
  }
  EXPECT_TRUE(parked_still);
  EXPECT_FALSE(parked_mover);
}

}  // namespace
}  // namespace kestrel::dynamic
