#include "io/kestrel_sequence.hpp"

#include <gtest/gtest.h>

#include <random>

#include "core/config.hpp"
#include "io/indexed_source.hpp"
#include "io/text_lines.hpp"
#include "tests/io/io_test_util.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::io {
namespace {

namespace fs = std::filesystem;

Image noise_image(int w, int h, int ch, PixelType type, std::mt19937& rng) {
  Image im = Image::allocate(w, h, ch, type);
  for (auto& b : *im.data) b = static_cast<std::uint8_t>(rng());
  return im;
}

struct Written {
  std::vector<Timestamp> frame_t;
  std::vector<Image> color, depth, mask;
  std::vector<ImuSample> imu;
  std::vector<std::pair<Timestamp, SE3>> gt;
  std::vector<SequenceBox> boxes;
  std::vector<SequenceObject> objects;
  Calibration calib;
};

Written write_sequence(const fs::path& dir) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-10.0, 10.0);
  Written w;
  w.calib.camera.fx = 500.123456789012345;
  w.calib.camera.cx = 319.75;
  w.calib.has_imu = true;
  w.calib.imu.gyro_noise = 1.23456789e-4;
  w.calib.T_body_camera = SE3(SO3::exp(Vec3(0.1, -0.2, 0.3)), Vec3(0.01, 0.02, 0.03));
  KestrelSequenceWriter writer(dir.string(), w.calib);
  const Timestamp t0 = 1'700'000'000'000'000'000;
  Timestamp t_imu = t0 - 3'000'000;
  for (int i = 0; i < 4; ++i) {
    const Timestamp t = t0 + i * 33'333'333;
    // IMU at 200 Hz up to and including the frame stamp.
    for (; t_imu <= t; t_imu += 5'000'000) {
      ImuSample s;
      s.t = t_imu;
      s.gyro = Vec3(u(rng), u(rng), u(rng)) * 1e-3;
      s.acc = Vec3(u(rng), u(rng), 9.81 + u(rng) / 3.0);
      writer.write_imu(s);
      w.imu.push_back(s);
    }
    w.frame_t.push_back(t);
    w.color.push_back(noise_image(32, 24, 3, PixelType::kU8, rng));
    w.depth.push_back(noise_image(32, 24, 1, PixelType::kU16, rng));
    w.mask.push_back(i % 2 ? Image{} : noise_image(32, 24, 1, PixelType::kU16, rng));
    writer.write_frame(t, w.color.back(), w.depth.back(), w.mask.back());
    const SE3 pose(SO3::exp(Vec3(u(rng), u(rng), u(rng)) * 0.1), Vec3(u(rng), u(rng), u(rng)));
    writer.write_ground_truth(t, pose);
    w.gt.emplace_back(t, pose);
    SequenceBox b;
    b.t = t;
    b.instance = 3 + i;
    b.label = i == 2 ? "dining table" : "person";
    b.x_min = u(rng) + 50, b.y_min = u(rng) + 50, b.x_max = b.x_min + 12.5,
    b.y_max = b.y_min + 30.25;
    b.moving = i % 2 == 0;
    b.occluded = 0.125 * i;
    writer.write_box(b);
    w.boxes.push_back(b);
  }
  SequenceObject o;
  o.id = 7;
  o.label = "chair";
  o.center = Vec3(1.0 / 3.0, -2.5, 0.45);
  o.size = Vec3(0.5, 0.5, 0.9);
  o.yaw = 0.7853981633974483;
  o.observations = 12;
  o.first_seen = 1700000000.1;
  o.last_seen = 1700000003.25;
  w.objects = {o, o};
  w.objects[1].id = 8;
  w.objects[1].label = "potted plant";
  writer.write_objects(w.objects);
  writer.write_scenario("name: test\nseed: 1\n");
  writer.close();
  return w;
}

TEST(KestrelSequence, WriteThenReadBackIdentically) {
  const fs::path dir = test::temp_dir("kseq") / "seq";
  const Written w = write_sequence(dir);

  auto src = open_kestrel_sequence(dir.string());
  EXPECT_EQ(src->frame_count(), 4u);
  const Calibration& c = src->calibration();
  EXPECT_EQ(c.camera.fx, w.calib.camera.fx);
  EXPECT_EQ(c.camera.cx, w.calib.camera.cx);
  EXPECT_TRUE(c.has_imu);
  EXPECT_EQ(c.imu.gyro_noise, w.calib.imu.gyro_noise);
  EXPECT_LT((c.T_body_camera.matrix() - w.calib.T_body_camera.matrix()).cwiseAbs().maxCoeff(),
            1e-15);

  std::size_t fi = 0, ii = 0;
  while (auto m = src->next()) {
    if (const auto* s = std::get_if<ImuSample>(&*m)) {
      ASSERT_LT(ii, w.imu.size());
      EXPECT_EQ(s->t, w.imu[ii].t);
      EXPECT_EQ(s->gyro, w.imu[ii].gyro);  // bit-exact through %.17g
      EXPECT_EQ(s->acc, w.imu[ii].acc);
      ++ii;
    } else {
      const RgbdFrame& f = std::get<RgbdFrame>(*m);
      ASSERT_LT(fi, w.frame_t.size());
      EXPECT_EQ(f.t, w.frame_t[fi]);
      EXPECT_EQ(*f.color.data, *w.color[fi].data);
      EXPECT_EQ(*f.depth.data, *w.depth[fi].data);
      const Image mask = read_dynamic_mask(dir.string(), f.t);
      if (w.mask[fi].empty()) {
        EXPECT_TRUE(mask.empty());
      } else {
        EXPECT_EQ(*mask.data, *w.mask[fi].data);
      }
      ++fi;
    }
  }
  EXPECT_EQ(fi, 4u);
  EXPECT_EQ(ii, w.imu.size());

  const auto gt = src->ground_truth();
  ASSERT_TRUE(gt.has_value());
  ASSERT_EQ(gt->size(), w.gt.size());
  for (std::size_t k = 0; k < gt->size(); ++k) {
    EXPECT_NEAR(gt->stamps[k], to_seconds(w.gt[k].first), 1e-6);
    EXPECT_LT((gt->poses[k].matrix() - w.gt[k].second.matrix()).cwiseAbs().maxCoeff(), 1e-12);
  }

  const auto boxes = read_boxes((dir / "boxes.csv").string());
  ASSERT_EQ(boxes.size(), w.boxes.size());
  for (std::size_t k = 0; k < boxes.size(); ++k) {
    EXPECT_EQ(boxes[k].t, w.boxes[k].t);
    EXPECT_EQ(boxes[k].instance, w.boxes[k].instance);
    EXPECT_EQ(boxes[k].label, w.boxes[k].label);
    EXPECT_EQ(boxes[k].x_min, w.boxes[k].x_min);
    EXPECT_EQ(boxes[k].y_max, w.boxes[k].y_max);
    EXPECT_EQ(boxes[k].moving, w.boxes[k].moving);
    EXPECT_EQ(boxes[k].occluded, w.boxes[k].occluded);
  }
  const auto objects = read_objects((dir / "objects.json").string());
  ASSERT_EQ(objects.size(), 2u);
  EXPECT_EQ(objects[1].label, "potted plant");
  EXPECT_EQ(objects[0].center, w.objects[0].center);
  EXPECT_EQ(objects[0].yaw, w.objects[0].yaw);
  EXPECT_EQ(objects[0].first_seen, w.objects[0].first_seen);
  EXPECT_EQ(objects[1].observations, 12);

  // The files are what the contract says: TUM lists, EuRoC-column csv with a '#' header.
  const TextTable rgb = TextTable::read((dir / "rgb.txt").string());
  ASSERT_EQ(rgb.rows().size(), 4u);
  EXPECT_EQ(rgb.rows()[0].fields[1], "rgb/" + format_seconds(w.frame_t[0]) + ".png");
  std::ifstream imu_csv(dir / "imu.csv");
  std::string header;
  std::getline(imu_csv, header);
  EXPECT_EQ(header.rfind("#timestamp [ns],w_RS_S_x", 0), 0u);
  std::ifstream boxes_csv(dir / "boxes.csv");
  std::getline(boxes_csv, header);
  EXPECT_EQ(header, "#stamp,instance,label,x_min,y_min,x_max,y_max,moving,occluded");
  EXPECT_TRUE(fs::exists(dir / "scenario.yaml"));
  EXPECT_FALSE(fs::exists(dir / "objects.json.partial"));
}

TEST(KestrelSequence, IndexIsOnDiskBeforeClose) {
  const fs::path dir = test::temp_dir("kseq_flush") / "seq";
  std::mt19937 rng(3);
  KestrelSequenceWriter writer(dir.string(), Calibration{});
  ImuSample s;
  s.t = 5;
  writer.write_imu(s);
  writer.write_frame(10, noise_image(8, 8, 3, PixelType::kU8, rng),
                     noise_image(8, 8, 1, PixelType::kU16, rng), Image{});
  // Not closed yet: a crash now must still leave a readable sequence with this frame.
  auto src = open_kestrel_sequence(dir.string());
  EXPECT_EQ(src->frame_count(), 1u);
  EXPECT_EQ(dynamic_cast<IndexedSource&>(*src).imu_count(), 1u);
  test::expect_error(
      [&] { writer.write_frame(10, noise_image(8, 8, 3, PixelType::kU8, rng), Image{}, Image{}); },
      {"rgb.txt", "not after"});
  writer.close();
  writer.close();  // idempotent
}

TEST(KestrelSequence, BadObjectsJsonNamesFileAndLine) {
  const fs::path dir = test::temp_dir("kseq_json");
  test::write_file(dir / "objects.json", "[\n {\"id\": 1,\n  \"label\": \"chair\",,\n}\n]\n");
  test::expect_error([&] { read_objects((dir / "objects.json").string()); },
                     {(dir / "objects.json").string() + ":3"});
  test::write_file(dir / "o2.json", R"([{"id": 1, "label": "x", "center": [1, 2], "size": [1,1,1],
    "yaw": 0, "observations": 1, "first_seen": 0, "last_seen": 1}])");
  test::expect_error([&] { read_objects((dir / "o2.json").string()); }, {"o2.json", "[0].center"});
}

}  // namespace
}  // namespace kestrel::io
