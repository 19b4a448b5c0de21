#pragma once
// PNG / JPEG files to and from core Image. Every failure throws kestrel::Error naming the file:
// a missing file, a truncated or corrupt file, and a pixel type the caller did not ask for.
#include <cstdint>
#include <string>
#include <vector>

#include "core/image.hpp"

namespace kestrel::io {

enum class ImageKind {
  kAny,    // as stored: 8- or 16-bit, 1, 3 or 4 channels
  kColor,  // 8-bit BGR (3 channels) or grey (1 channel); alpha is dropped
  kGrey,   // 8-bit, 1 channel; colour is converted, 16-bit grey is scaled by 1/256
  kDepth,  // 16-bit, 1 channel; anything else is an error (an 8-bit "depth" is a wrong file)
};

// Reads and decodes an image file. `kind` says what the caller needs (see ImageKind).
Image load_image(const std::string& path, ImageKind kind = ImageKind::kAny);
// Decodes bytes already in memory; `name` is used in error messages.
Image decode_image(const std::vector<std::uint8_t>& bytes, const std::string& name,
                   ImageKind kind = ImageKind::kAny);
// Writes a lossless PNG (8- or 16-bit, 1/3/4 channels). The file is written beside the target
// and renamed into place, so a crash never leaves a truncated PNG under the final name.
void write_png(const std::string& path, const Image& image);

// True when `bytes` hold a structurally complete PNG: the signature, then chunks whose
// lengths fit, ending with IEND. OpenCV's decoder may return a partial image for a truncated
// file, so this is how truncation is detected.
bool png_is_complete(const std::vector<std::uint8_t>& bytes, std::string* why = nullptr);

}  // namespace kestrel::io
