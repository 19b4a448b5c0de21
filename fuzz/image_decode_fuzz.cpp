// Arbitrary bytes into the image decoder: the PNG structure check and OpenCV's decoders behind
// it must return an image or throw kestrel::Error, never crash.
#include <unistd.h>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
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

// Seeds for the replay driver: small valid PNGs of each kind Kestrel reads (8-bit grey, 8-bit
// colour, 16-bit depth), written by the project's own writer so they are real PNG streams.
extern "C" void KestrelFuzzSeeds(void (*add)(const std::uint8_t*, std::size_t)) {
  using namespace kestrel;
  const std::string dir = std::filesystem::temp_directory_path().string();
  struct Kind {
    int channels;
    PixelType type;
  };
  int n = 0;
  for (const Kind k :
       {Kind{1, PixelType::kU8}, Kind{3, PixelType::kU8}, Kind{1, PixelType::kU16}}) {
    Image im = Image::allocate(7, 5, k.channels, k.type);
    for (std::size_t i = 0; i < im.data->size(); ++i)
      (*im.data)[i] = static_cast<std::uint8_t>(i * 37);
    const std::string path = dir + "/kestrel-fuzz-seed-" + std::to_string(::getpid()) + "-" +
                             std::to_string(n++) + ".png";
    io::write_png(path, im);
    std::ifstream in(path, std::ios::binary);
    const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                          std::istreambuf_iterator<char>());
    std::filesystem::remove(path);
    add(bytes.data(), bytes.size());
  }
}
