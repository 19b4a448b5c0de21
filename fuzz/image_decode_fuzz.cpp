// Arbitrary bytes into the image decoder: the PNG structure check and OpenCV's decoders behind
// it must return an image or throw kestrel::Error, never crash.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/error.hpp"
#include "io/image_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace kestrel;
  const std::vector<std::uint8_t> bytes(data, data + size);
  (void)io::png_is_complete(bytes);
  try {
    const Image im = io::decode_image(bytes, "fuzz.png", io::ImageKind::kAny);
    if (im.data->size() != static_cast<std::size_t>(im.height) * im.step()) __builtin_trap();
  } catch (const Error&) {
  }
  return 0;
}
