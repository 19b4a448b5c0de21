#include "io/image_io.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/error.hpp"
#include "io/cv_image.hpp"

namespace kestrel::io {
namespace {

// 64 megapixels: far above any dataset camera, far below what a forged header could demand.
constexpr std::uint64_t kMaxPixels = std::uint64_t{1} << 26;
constexpr std::uint8_t kPngSignature[8] = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};

bool is_png(const std::vector<std::uint8_t>& b) {
  return b.size() >= 8 && std::equal(std::begin(kPngSignature), std::end(kPngSignature), b.begin());
}
bool is_jpeg(const std::vector<std::uint8_t>& b) {
  return b.size() >= 3 && b[0] == 0xFF && b[1] == 0xD8 && b[2] == 0xFF;
}

// libjpeg, like libpng, fills a truncated file's missing rows with grey and only warns. A
// complete JPEG ends with the EOI marker (FF D9); some writers pad a few bytes after it.
bool jpeg_is_complete(const std::vector<std::uint8_t>& b) {
  constexpr std::size_t kMaxTrailing = 4096;
  const std::size_t stop = b.size() > kMaxTrailing + 2 ? b.size() - kMaxTrailing - 2 : 2;
  for (std::size_t i = b.size() - 1; i >= stop && i >= 1; --i) {
    if (b[i - 1] == 0xFF && b[i] == 0xD9) return true;
  }
  return false;
}

std::string describe_type(const cv::Mat& m) {
  return std::string(m.depth() == CV_16U  ? "16-bit"
                     : m.depth() == CV_8U ? "8-bit"
                                          : "non-8/16-bit") +
         " " + std::to_string(m.channels()) + "-channel";
}

cv::Mat convert(const cv::Mat& m, ImageKind kind, const std::string& name) {
  switch (kind) {
    case ImageKind::kAny:
      if (m.depth() != CV_8U && m.depth() != CV_16U) {
        throw Error::at(name, 0, "", "unsupported pixel type " + describe_type(m));
      }
      return m;
    case ImageKind::kColor:
      if (m.depth() != CV_8U || m.channels() == 2) {
        throw Error::at(name, 0, "",
                        "expected an 8-bit colour or grey image, got " + describe_type(m));
      }
      if (m.channels() == 4) {
        cv::Mat bgr;
        cv::cvtColor(m, bgr, cv::COLOR_BGRA2BGR);
        return bgr;
      }
      return m;
    case ImageKind::kGrey: {
      cv::Mat out;
      if (m.depth() == CV_16U && m.channels() == 1) {
        m.convertTo(out, CV_8U, 1.0 / 256.0);
        return out;
      }
      if (m.depth() != CV_8U || m.channels() == 2) {
        throw Error::at(name, 0, "", "expected a grey image, got " + describe_type(m));
      }
      if (m.channels() == 1) return m;
      cv::cvtColor(m, out, m.channels() == 4 ? cv::COLOR_BGRA2GRAY : cv::COLOR_BGR2GRAY);
      return out;
    }
    case ImageKind::kDepth:
      if (m.depth() != CV_16U || m.channels() != 1) {
        throw Error::at(name, 0, "",
                        "expected a 16-bit 1-channel depth image, got " + describe_type(m));
      }
      return m;
  }
  return m;
}

}  // namespace

bool png_is_complete(const std::vector<std::uint8_t>& b, std::string* why) {
  auto fail = [&](const std::string& w) {
    if (why) *why = w;
    return false;
  };
  if (!is_png(b)) return fail("no PNG signature");
  std::size_t pos = 8;
  while (true) {
    if (b.size() - pos < 8)
      return fail("truncated: file ends inside a chunk header at byte " + std::to_string(pos) +
                  " (no IEND chunk)");
    const std::uint32_t length = (std::uint32_t{b[pos]} << 24) | (std::uint32_t{b[pos + 1]} << 16) |
                                 (std::uint32_t{b[pos + 2]} << 8) | std::uint32_t{b[pos + 3]};
    const std::string type(reinterpret_cast<const char*>(&b[pos + 4]), 4);
    if (length > 0x7FFFFFFFu) return fail("corrupt chunk length at byte " + std::to_string(pos));
    const std::size_t need = std::size_t{12} + length;
    if (b.size() - pos < need) {
      return fail("truncated: chunk '" + type + "' at byte " + std::to_string(pos) + " needs " +
                  std::to_string(need) + " bytes, " + std::to_string(b.size() - pos) + " left");
    }
    if (pos == 8 && type != "IHDR") return fail("first chunk is '" + type + "', not IHDR");
    if (type == "IHDR" && length >= 8) {
      auto be32 = [&](std::size_t at) {
        return (std::uint64_t{b[at]} << 24) | (std::uint64_t{b[at + 1]} << 16) |
               (std::uint64_t{b[at + 2]} << 8) | std::uint64_t{b[at + 3]};
      };
      const std::uint64_t w = be32(pos + 8), h = be32(pos + 12);
      // A header can claim any size; refuse before the decoder allocates it.
      if (w == 0 || h == 0 || w * h > kMaxPixels) {
        return fail("implausible image size " + std::to_string(w) + "x" + std::to_string(h));
      }
    }
    pos += need;
    if (type == "IEND") return true;
  }
}

Image decode_image(const std::vector<std::uint8_t>& bytes, const std::string& name,
                   ImageKind kind) {
  if (bytes.empty()) throw Error::at(name, 0, "", "empty image file");
  std::string why;
  if (is_png(bytes) && !png_is_complete(bytes, &why)) {
    throw Error::at(name, 0, "", "corrupt PNG: " + why);
  }
  if (is_jpeg(bytes) && !jpeg_is_complete(bytes)) {
    throw Error::at(name, 0, "", "truncated JPEG: no end-of-image marker");
  }
  cv::Mat decoded;
  try {
    const cv::Mat raw(1, static_cast<int>(bytes.size()), CV_8U,
                      const_cast<std::uint8_t*>(bytes.data()));
    decoded = cv::imdecode(raw, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    throw Error::at(name, 0, "", std::string("cannot decode image: ") + e.what());
  }
  if (decoded.empty())
    throw Error::at(name, 0, "", "cannot decode image (unknown or corrupt format)");
  return to_image(convert(decoded, kind, name));
}

Image load_image(const std::string& path, ImageKind kind) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error::at(path, 0, "", "cannot open image file");
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                  std::istreambuf_iterator<char>());
  if (in.bad()) throw Error::at(path, 0, "", "read error");
  return decode_image(bytes, path, kind);
}

void write_png(const std::string& path, const Image& image) {
  if (image.empty()) throw Error::at(path, 0, "", "cannot write an empty image");
  if (image.channels < 1 || image.channels > 4 || image.channels == 2) {
    throw Error::at(path, 0, "",
                    "PNG needs 1, 3 or 4 channels, got " + std::to_string(image.channels));
  }
  std::vector<std::uint8_t> bytes;
  try {
    if (!cv::imencode(".png", as_mat(image), bytes)) {
      throw Error::at(path, 0, "", "PNG encoder failed");
    }
  } catch (const cv::Exception& e) {
    throw Error::at(path, 0, "", std::string("PNG encoder failed: ") + e.what());
  }
  const std::string tmp = path + ".partial";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw Error::at(path, 0, "", "cannot create file");
    out.write(reinterpret_cast<const char*>(bytes.data()),
              static_cast<std::streamsize>(bytes.size()));
    out.flush();
    if (!out) throw Error::at(path, 0, "", "write error");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw Error::at(path, 0, "", "cannot rename into place: " + ec.message());
}

}  // namespace kestrel::io
