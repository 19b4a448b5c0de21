#include "io/image_io.hpp"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "io/cv_image.hpp"
#include "tests/io/io_test_util.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::io {
namespace {

using test::shared_data;

const std::string kRgb = shared_data("tum_fr3/frame/rgb_1341846313.592026.png").string();
const std::string kDepth = shared_data("tum_fr3/frame/depth_1341846313.592088.png").string();

TEST(ImageIo, LoadsRealTumColourAndDepth) {
  const Image rgb = load_image(kRgb, ImageKind::kColor);
  EXPECT_EQ(rgb.width, 640);
  EXPECT_EQ(rgb.height, 480);
  EXPECT_EQ(rgb.channels, 3);
  EXPECT_EQ(rgb.type, PixelType::kU8);
  const Image depth = load_image(kDepth, ImageKind::kDepth);
  EXPECT_EQ(depth.channels, 1);
  EXPECT_EQ(depth.type, PixelType::kU16);
  // Same pixels as OpenCV's own decoder.
  const cv::Mat ref = cv::imread(kDepth, cv::IMREAD_UNCHANGED);
  ASSERT_EQ(ref.type(), CV_16UC1);
  EXPECT_EQ(cv::norm(ref, as_mat(depth), cv::NORM_INF), 0.0);
  const cv::Mat ref_rgb = cv::imread(kRgb, cv::IMREAD_COLOR);
  EXPECT_EQ(cv::norm(ref_rgb, as_mat(rgb), cv::NORM_INF), 0.0);
  // Typical TUM depth: mostly between 0.5 and 5 m.
  const double metres = cv::mean(as_mat(depth), as_mat(depth) > 0)[0] / 5000.0;
  EXPECT_GT(metres, 0.5);
  EXPECT_LT(metres, 5.0);
}

TEST(ImageIo, GreyConversion) {
  const Image grey = load_image(kRgb, ImageKind::kGrey);
  EXPECT_EQ(grey.channels, 1);
  EXPECT_EQ(grey.type, PixelType::kU8);
}

TEST(ImageIo, WrongPixelTypeNamesFile) {
  test::expect_error([] { load_image(kRgb, ImageKind::kDepth); },
                     {kRgb, "16-bit", "8-bit 3-channel"});
  test::expect_error([] { load_image(kDepth, ImageKind::kColor); }, {kDepth, "16-bit 1-channel"});
}

TEST(ImageIo, MissingFileNamesFile) {
  test::expect_error([] { load_image("/nonexistent/x.png"); },
                     {"/nonexistent/x.png", "cannot open"});
}

TEST(ImageIo, TruncatedPngIsDetected) {
  const auto dir = test::temp_dir("trunc_png");
  const auto bytes = test::read_bytes(kDepth);
  for (const double fraction : {0.5, 0.9, 0.999}) {
    const std::string path = (dir / "cut.png").string();
    const std::size_t n = static_cast<std::size_t>(static_cast<double>(bytes.size()) * fraction);
    test::write_file(path, std::string(bytes.begin(), bytes.begin() + static_cast<long>(n)));
    // What OpenCV alone does here varies (empty Mat or a partly grey image with a libpng
    // warning); the loader must refuse either way.
    test::expect_error([&] { load_image(path, ImageKind::kDepth); }, {path, "truncated"});
  }
  std::string why;
  EXPECT_TRUE(png_is_complete(bytes, &why)) << why;
  EXPECT_FALSE(png_is_complete({bytes.begin(), bytes.end() - 1}, &why));
}

TEST(ImageIo, TruncatedJpegIsDetected) {
  const std::string jpg = shared_data("images/dog.jpg").string();
  const auto bytes = test::read_bytes(jpg);
  EXPECT_NO_THROW(decode_image(bytes, jpg, ImageKind::kColor));
  const std::vector<std::uint8_t> cut(bytes.begin(),
                                      bytes.begin() + static_cast<long>(bytes.size() / 2));
  test::expect_error([&] { decode_image(cut, "dog_cut.jpg", ImageKind::kColor); },
                     {"dog_cut.jpg", "truncated"});
}

TEST(ImageIo, PngRoundTripIsExact) {
  const auto dir = test::temp_dir("png_rt");
  Image im16 = Image::allocate(37, 23, 1, PixelType::kU16);
  for (int y = 0; y < im16.height; ++y) {
    for (int x = 0; x < im16.width; ++x)
      im16.row<std::uint16_t>(y)[x] = static_cast<std::uint16_t>(x * 1771 + y * 31);
  }
  Image im8 = Image::allocate(41, 19, 3, PixelType::kU8);
  for (std::size_t i = 0; i < im8.data->size(); ++i)
    (*im8.data)[i] = static_cast<std::uint8_t>(i * 7);
  write_png((dir / "a.png").string(), im16);
  write_png((dir / "b.png").string(), im8);
  const Image back16 = load_image((dir / "a.png").string(), ImageKind::kDepth);
  const Image back8 = load_image((dir / "b.png").string(), ImageKind::kColor);
  EXPECT_EQ(*back16.data, *im16.data);
  EXPECT_EQ(*back8.data, *im8.data);
  EXPECT_FALSE(std::filesystem::exists(dir / "a.png.partial"));
}

TEST(CvImage, WrapsWithoutCopy) {
  Image im = Image::allocate(8, 4, 3, PixelType::kU8);
  cv::Mat m = as_mat(im);
  EXPECT_EQ(m.data, im.data->data());
  EXPECT_EQ(m.type(), CV_8UC3);
  m.at<cv::Vec3b>(2, 5) = cv::Vec3b(1, 2, 3);
  EXPECT_EQ(im.row<std::uint8_t>(2)[5 * 3 + 2], 3);
  const Image copy = to_image(m);
  EXPECT_NE(copy.data->data(), im.data->data());
  EXPECT_EQ(*copy.data, *im.data);
  EXPECT_THROW(to_image(cv::Mat(2, 2, CV_32F)), std::invalid_argument);
}

}  // namespace
}  // namespace kestrel::io
