#include "loop/vocabulary.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <random>

#include "core/error.hpp"
#include "tests/loop/loop_test_data.hpp"

namespace kestrel::loop {
namespace {

std::vector<std::vector<OrbDescriptor>> training_set() {
  std::vector<std::vector<OrbDescriptor>> images;
  for (const auto& name : test_data::training_images())
    images.push_back(test_data::image_descriptors(name));
  return images;
}

const Vocabulary& small_vocabulary() {
  static const Vocabulary voc = Vocabulary::train(training_set(), {.k = 10, .levels = 4});
  return voc;
}

TEST(Vocabulary, TreeShapeAndWeights) {
  const Vocabulary& voc = small_vocabulary();
  ASSERT_FALSE(voc.empty());
  EXPECT_LE(voc.num_words(), 10000u);
  EXPECT_GT(voc.num_words(), 2000u);  // several thousand descriptors fill most of the tree
  for (const auto& n : voc.nodes()) {
    EXPECT_LE(n.children.size(), 10u);
    EXPECT_LE(n.depth, 4);
    if (n.word >= 0) {
      EXPECT_GE(n.weight, 0.0);
      EXPECT_LE(n.weight, std::log(5.0) + 1e-9);
    }
  }
}

TEST(Vocabulary, TrainingIsDeterministic) {
  const Vocabulary again = Vocabulary::train(training_set(), {.k = 10, .levels = 4});
  const Vocabulary& voc = small_vocabulary();
  ASSERT_EQ(again.num_nodes(), voc.num_nodes());
  for (std::size_t i = 0; i < voc.num_nodes(); ++i) {
    EXPECT_EQ(again.nodes()[i].centroid, voc.nodes()[i].centroid);
    EXPECT_EQ(again.nodes()[i].parent, voc.nodes()[i].parent);
  }
  const Vocabulary other_seed = Vocabulary::train(training_set(), {.k = 8, .levels = 3, .seed = 7});
  bool differs = other_seed.num_nodes() != voc.num_nodes();
  for (std::size_t i = 0; !differs && i < voc.num_nodes(); ++i)
    differs = other_seed.nodes()[i].centroid != voc.nodes()[i].centroid;
  EXPECT_TRUE(differs);
}

TEST(Vocabulary, SelfScoreIsOneAndUnrelatedImageScoresLow) {
  const Vocabulary& voc = small_vocabulary();
  const auto dog = test_data::image_descriptors("images/dog.jpg");
  const auto tum = test_data::image_descriptors("tum_fr3/frame/rgb_1341846313.592026.png");
  const auto unseen = test_data::image_descriptors("images/person.jpg");
  const BowVector a = voc.transform(dog);
  double sum = 0.0;
  for (const auto& [w, v] : a.entries) sum += v;
  EXPECT_NEAR(sum, 1.0, 1e-9);
  EXPECT_NEAR(l1_score(a, a), 1.0, 1e-9);
  const double vs_tum = l1_score(a, voc.transform(tum));
  const double vs_unseen = l1_score(a, voc.transform(unseen));
  std::printf("dog vs dog 1.0, dog vs tum %.3f, dog vs person %.3f\n", vs_tum, vs_unseen);
  EXPECT_LT(vs_tum, 0.25);
  EXPECT_LT(vs_unseen, 0.25);

  // Half of the features of the same image still score far above an unrelated image.
  std::vector<OrbDescriptor> half(dog.begin(), dog.begin() + static_cast<long>(dog.size() / 2));
  EXPECT_GT(l1_score(a, voc.transform(half)), 2.0 * vs_tum);
}

TEST(Vocabulary, DirectIndexGroupsEveryFeatureUnderADepthTwoNode) {
  const Vocabulary& voc = small_vocabulary();
  const auto dog = test_data::image_descriptors("images/dog.jpg");
  FeatureVector fv;
  voc.transform(dog, &fv, 2);
  std::size_t total = 0;
  for (const auto& [node, features] : fv) {
    EXPECT_EQ(voc.nodes()[node].depth, 2);
    total += features.size();
  }
  EXPECT_EQ(total, dog.size());
}

TEST(Vocabulary, SaveLoadRoundTrip) {
  const Vocabulary& voc = small_vocabulary();
  const auto dir = kestrel::test::temp_dir("vocabulary_round_trip");
  const std::string path = (dir / "voc.kvoc").string();
  voc.save(path);
  const Vocabulary loaded = Vocabulary::load(path);
  ASSERT_EQ(loaded.num_nodes(), voc.num_nodes());
  EXPECT_EQ(loaded.num_words(), voc.num_words());
  EXPECT_EQ(loaded.k(), 10);
  EXPECT_EQ(loaded.levels(), 4);
  const auto dog = test_data::image_descriptors("images/dog.jpg");
  const BowVector a = voc.transform(dog);
  const BowVector b = loaded.transform(dog);
  ASSERT_EQ(a.entries.size(), b.entries.size());
  for (std::size_t i = 0; i < a.entries.size(); ++i) {
    EXPECT_EQ(a.entries[i].first, b.entries[i].first);
    EXPECT_DOUBLE_EQ(a.entries[i].second, b.entries[i].second);
  }
}

TEST(Vocabulary, LoadErrorsNameTheFile) {
  const auto dir = kestrel::test::temp_dir("vocabulary_errors");
  const std::string missing = (dir / "missing.kvoc").string();
  try {
    Vocabulary::load(missing);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(missing), std::string::npos);
  }
  // Truncated: a valid file cut in the middle of its nodes.
  const std::string good = (dir / "good.kvoc").string();
  small_vocabulary().save(good);
  std::ifstream in(good, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string cut = (dir / "cut.kvoc").string();
  std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  try {
    Vocabulary::load(cut);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(cut), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("truncated"), std::string::npos);
  }
  const std::string bad = (dir / "bad.kvoc").string();
  std::ofstream(bad, std::ios::binary) << "KVOX" << bytes.substr(4);
  EXPECT_THROW(Vocabulary::load(bad), Error);
}

TEST(Vocabulary, RejectsBadOptionsAndEmptyInput) {
  EXPECT_THROW(Vocabulary::train({}, {}), std::invalid_argument);
  EXPECT_THROW(Vocabulary::train(training_set(), {.k = 1}), std::invalid_argument);
}

}  // namespace
}  // namespace kestrel::loop
