#include "io/dataset.hpp"

#include <gtest/gtest.h>

#include "io/kestrel_sequence.hpp"
#include "tests/io/io_test_util.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::io {
namespace {

namespace fs = std::filesystem;

TEST(Dataset, DetectsAndOpensEuroc) {
  const std::string micro = test::shared_data("euroc/V1_01_micro").string();
  EXPECT_EQ(detect_dataset_kind(micro), DatasetKind::kEuroc);
  auto a = open_dataset(micro);
  auto b = open_dataset("euroc:" + micro);
  EXPECT_EQ(a->frame_count(), 95u);
  EXPECT_EQ(b->frame_count(), 95u);
  EXPECT_EQ(a->describe().rfind("euroc:", 0), 0u);
  EXPECT_EQ(open_dataset("tumvi:" + micro)->describe().rfind("tumvi:", 0), 0u);
}

TEST(Dataset, DetectsKestrelAndTum) {
  const fs::path root = test::temp_dir("detect");
  { KestrelSequenceWriter w((root / "k").string(), Calibration{}); }
  EXPECT_EQ(detect_dataset_kind((root / "k").string()), DatasetKind::kKestrel);
  EXPECT_EQ(open_dataset((root / "k").string())->frame_count(), 0u);
  test::write_file(root / "rgbd_dataset_freiburg2_desk/rgb.txt", "");
  test::write_file(root / "rgbd_dataset_freiburg2_desk/depth.txt", "");
  EXPECT_EQ(detect_dataset_kind((root / "rgbd_dataset_freiburg2_desk").string()),
            DatasetKind::kTum);
  EXPECT_EQ(open_dataset("tum:" + (root / "rgbd_dataset_freiburg2_desk").string())
                ->calibration()
                .camera.fx,
            520.9);
  test::write_file(root / "loris/color.txt", "");
  test::write_file(root / "loris/aligned_depth.txt", "");
  EXPECT_EQ(detect_dataset_kind((root / "loris").string()), DatasetKind::kOpenLoris);
}

TEST(Dataset, UnknownFolderIsAnError) {
  const fs::path root = test::temp_dir("detect_none");
  test::expect_error([&] { open_dataset(root.string()); }, {root.string(), "cannot tell"});
  test::expect_error([&] { open_dataset("/no/such/dir"); }, {"/no/such/dir"});
}

}  // namespace
}  // namespace kestrel::io
