#include <gtest/gtest.h>

#include <cmath>

#include "core/error.hpp"
#include "detect/oracle_detector.hpp"

namespace kestrel::detect {
namespace {

constexpr Timestamp kFramePeriod = 100'000'000;  // 10 Hz
constexpr int kFrames = 500;

Timestamp stamp(int i) { return 1'000'000'000 + i * kFramePeriod; }

// Two boxes per frame: a moving person whose x_min is 10 * frame index, and a static chair.
std::vector<io::SequenceBox> truth() {
  std::vector<io::SequenceBox> boxes;
  for (int i = 0; i < kFrames; ++i) {
    io::SequenceBox person;
    person.t = stamp(i);
    person.instance = 1;
    person.label = "person";
    person.x_min = 100 + (i % 30) * 10;
    person.y_min = 100;
    person.x_max = person.x_min + 80;
    person.y_max = 300;
    person.moving = true;
    boxes.push_back(person);
    io::SequenceBox chair = person;
    chair.instance = 2;
    chair.label = "chair";
    chair.x_min = 20;
    chair.x_max = 90;
    chair.y_min = 300;
    chair.y_max = 400;
    chair.moving = false;
    boxes.push_back(chair);
  }
  return boxes;
}

TEST(OracleDetector, NoNoiseGivesTheTruth) {
  OracleDetector oracle(truth());
  const DetectionSet set = oracle.detect(Image{}, stamp(7));
  EXPECT_EQ(set.t, stamp(7));
  ASSERT_EQ(set.boxes.size(), 2u);
  EXPECT_EQ(set.boxes[0].label, "person");
  EXPECT_EQ(set.boxes[0].class_id, 0);
  EXPECT_FLOAT_EQ(set.boxes[0].x_min, 170);
  EXPECT_FLOAT_EQ(set.boxes[0].y_max, 300);
  EXPECT_EQ(set.boxes[1].label, "chair");
  // Within the match tolerance (5 ms) the same frame; outside it nothing.
  EXPECT_EQ(oracle.detect(Image{}, stamp(7) + 3'000'000).boxes.size(), 2u);
  EXPECT_EQ(oracle.detect(Image{}, stamp(7) - 3'000'000).boxes.size(), 2u);
  EXPECT_TRUE(oracle.detect(Image{}, stamp(7) + 20'000'000).boxes.empty());
  EXPECT_TRUE(oracle.detect(Image{}, stamp(kFrames + 5)).boxes.empty());
}

TEST(OracleDetector, OnlyMovingBoxesWhenAsked) {
  OracleOptions o;
  o.include_static = false;
  OracleDetector oracle(truth(), o);
  const DetectionSet set = oracle.detect(Image{}, stamp(3));
  ASSERT_EQ(set.boxes.size(), 1u);
  EXPECT_EQ(set.boxes[0].label, "person");
}

TEST(OracleDetector, FalseNegativeRateIsHonoured) {
  OracleOptions o;
  o.false_negative_rate = 0.3;
  o.seed = 42;
  OracleDetector oracle(truth(), o);
  std::size_t kept = 0;
  for (int i = 0; i < kFrames; ++i) kept += oracle.detect(Image{}, stamp(i)).boxes.size();
  const double rate = 1.0 - static_cast<double>(kept) / (2.0 * kFrames);
  // 1000 Bernoulli trials: standard error 0.0145; 4 sigma.
  EXPECT_NEAR(rate, 0.3, 0.058) << "kept " << kept;
}

TEST(OracleDetector, JitterHasTheRequestedSpread) {
  OracleOptions o;
  o.jitter_px = 2.0;
  o.seed = 7;
  o.include_static = false;
  OracleDetector oracle(truth(), o);
  double sum = 0, sum2 = 0;
  int n = 0;
  for (int i = 0; i < kFrames; ++i) {
    const DetectionSet set = oracle.detect(Image{}, stamp(i));
    ASSERT_EQ(set.boxes.size(), 1u);
    const Detection& d = set.boxes[0];
    for (double e : {d.x_min - (100.0 + (i % 30) * 10), d.y_min - 100.0, d.y_max - 300.0}) {
      sum += e;
      sum2 += e * e;
      ++n;
    }
  }
  const double mean = sum / n;
  const double sd = std::sqrt(sum2 / n - mean * mean);
  EXPECT_NEAR(mean, 0.0, 0.25);  // standard error 2 / sqrt(1500) = 0.05
  EXPECT_NEAR(sd, 2.0, 0.15);    // relative standard error of sd ~ 1.8 %
}

TEST(OracleDetector, FalsePositivesArePoissonAndInsideTheImage) {
  OracleOptions o;
  o.false_positives_per_frame = 0.5;
  o.false_positive_labels = {"dog", "car"};
  o.seed = 3;
  OracleDetector oracle(truth(), o);
  const Image image = Image::allocate(320, 240, 3, PixelType::kU8);
  int fp = 0;
  int dogs = 0;
  for (int i = 0; i < kFrames; ++i) {
    for (const Detection& d : oracle.detect(image, stamp(i)).boxes) {
      if (d.label == "person" || d.label == "chair") continue;
      ++fp;
      dogs += d.label == "dog";
      EXPECT_TRUE(d.label == "dog" || d.label == "car");
      EXPECT_GE(d.x_min, 0);
      EXPECT_LE(d.x_max, 320);
      EXPECT_GE(d.y_min, 0);
      EXPECT_LE(d.y_max, 240);
      EXPECT_GT(d.area(), 0);
      EXPECT_LT(d.score, 1.0f);
    }
  }
  // Poisson mean 0.5 over 500 frames: standard error 0.032.
  EXPECT_NEAR(fp / static_cast<double>(kFrames), 0.5, 0.13);
  EXPECT_NEAR(dogs / static_cast<double>(fp), 0.5, 0.15);
}

TEST(OracleDetector, ReproducibleAndIndependentOfCallOrder) {
  OracleOptions o;
  o.false_negative_rate = 0.2;
  o.jitter_px = 3.0;
  o.false_positives_per_frame = 1.0;
  o.seed = 99;
  OracleDetector a(truth(), o);
  OracleDetector b(truth(), o);
  // b sees the frames backwards and skips some.
  std::vector<DetectionSet> from_b(kFrames);
  for (int i = kFrames - 1; i >= 0; i -= 2)
    from_b[static_cast<std::size_t>(i)] = b.detect(Image{}, stamp(i));
  for (int i = kFrames - 1; i >= 0; i -= 2) {
    const DetectionSet sa = a.detect(Image{}, stamp(i));
    const DetectionSet& sb = from_b[static_cast<std::size_t>(i)];
    ASSERT_EQ(sa.boxes.size(), sb.boxes.size()) << i;
    for (std::size_t k = 0; k < sa.boxes.size(); ++k) {
      EXPECT_EQ(sa.boxes[k].label, sb.boxes[k].label);
      EXPECT_EQ(sa.boxes[k].x_min, sb.boxes[k].x_min);
      EXPECT_EQ(sa.boxes[k].y_max, sb.boxes[k].y_max);
    }
  }
  o.seed = 100;
  OracleDetector c(truth(), o);
  const auto fingerprint = [](const DetectionSet& set) {
    double f = static_cast<double>(set.boxes.size());
    for (const Detection& d : set.boxes) f += d.x_min + 3.0 * d.y_max;
    return f;
  };
  int differ = 0;
  for (int i = 0; i < 20; ++i) {
    differ += fingerprint(a.detect(Image{}, stamp(i))) != fingerprint(c.detect(Image{}, stamp(i)));
  }
  EXPECT_GT(differ, 10);
}

TEST(OracleDetector, LatencyShiftsTheBoxesBack) {
  OracleOptions o;
  o.latency = 2 * kFramePeriod;
  OracleDetector oracle(truth(), o);
  const DetectionSet set = oracle.detect(Image{}, stamp(10));
  EXPECT_EQ(set.t, stamp(10));
  EXPECT_DOUBLE_EQ(set.latency_ms, 200.0);
  ASSERT_EQ(set.boxes.size(), 2u);
  EXPECT_FLOAT_EQ(set.boxes[0].x_min, 100 + 8 * 10);  // frame 8's person
  // The first two frames have nothing to report yet.
  EXPECT_TRUE(oracle.detect(Image{}, stamp(1)).boxes.empty());
}

TEST(OracleDetector, BadOptionsNameTheField) {
  OracleOptions o;
  o.false_negative_rate = 1.5;
  try {
    OracleDetector oracle(truth(), o);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("false_negative_rate"), std::string::npos);
  }
  o = {};
  o.jitter_px = -1;
  EXPECT_THROW(OracleDetector(truth(), o), Error);
  o = {};
  o.false_positives_per_frame = 1;
  o.false_positive_labels.clear();
  EXPECT_THROW(OracleDetector(truth(), o), Error);
}

}  // namespace
}  // namespace kestrel::detect
