#include "eval/report/image_embed.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "io/cv_image.hpp"

namespace kestrel::report {
namespace {

std::string data_uri(const Image& image, int max_width, const char* ext, const char* mime,
                     const std::vector<int>& params) {
  if (image.empty()) return "";
  cv::Mat m = io::as_mat(image);
  if (image.type == PixelType::kU16) m.convertTo(m, CV_8U, 255.0 / 65535.0);
  if (max_width > 0 && m.cols > max_width) {
    cv::Mat small;
    const double s = static_cast<double>(max_width) / m.cols;
    cv::resize(m, small, cv::Size(), s, s, cv::INTER_AREA);
    m = small;
  }
  std::vector<unsigned char> bytes;
  cv::imencode(ext, m, bytes, params);
  return std::string("data:") + mime + ";base64," + base64(bytes);
}

}  // namespace

std::string base64(const std::vector<unsigned char>& bytes) {
  static const char* kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const unsigned v = (bytes[i] << 16) | (bytes[i + 1] << 8) | bytes[i + 2];
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += kAlphabet[(v >> 6) & 63];
    out += kAlphabet[v & 63];
  }
  if (i + 1 == bytes.size()) {
    const unsigned v = bytes[i] << 16;
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += "==";
  } else if (i + 2 == bytes.size()) {
    const unsigned v = (bytes[i] << 16) | (bytes[i + 1] << 8);
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += kAlphabet[(v >> 6) & 63];
    out += '=';
  }
  return out;
}

std::string png_data_uri(const Image& image, int max_width) {
  return data_uri(image, max_width, ".png", "image/png", {});
}

std::string jpeg_data_uri(const Image& image, int max_width, int quality) {
  return data_uri(image, max_width, ".jpg", "image/jpeg", {cv::IMWRITE_JPEG_QUALITY, quality});
}

}  // namespace kestrel::report
