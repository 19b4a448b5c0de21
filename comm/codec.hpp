#pragma once
// Encodes and decodes schema messages (comm/schema.hpp). Decoding never throws and never
// trusts its input: oversized, malformed, unknown-version and unknown-kind payloads are
// rejected, counted per reason and logged (rate-limited) with the topic and the offending field.
#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "comm/schema.hpp"

namespace kestrel::comm {

enum class Encoding { kCbor, kJson };

// Large enough for a grid keyframe of a 1000x1000 map, small enough to bound memory.
constexpr std::size_t kMaxMessageBytes = 1 << 20;

enum class DecodeError { kOversized, kMalformed, kUnknownVersion, kUnknownKind, kBadField };
const char* to_string(DecodeError e);

struct DecodeCounts {
  std::uint64_t ok = 0;
  std::uint64_t oversized = 0;
  std::uint64_t malformed = 0;
  std::uint64_t unknown_version = 0;
  std::uint64_t unknown_kind = 0;
  std::uint64_t bad_field = 0;
  std::uint64_t rejected() const {
    return oversized + malformed + unknown_version + unknown_kind + bad_field;
  }
};

std::vector<std::uint8_t> encode(const Message& m, Encoding e = Encoding::kCbor);

class Decoder {
 public:
  using LogFn = std::function<void(const std::string&)>;
  // log defaults to stderr; at most one line per reason per second is written.
  explicit Decoder(LogFn log = {});

  // nullopt when rejected; `where` (usually the topic) goes into the log line.
  std::optional<Message> decode(std::span<const std::uint8_t> bytes, std::string_view where = {});
  DecodeCounts counts() const;

 private:
  void reject(DecodeError e, std::string_view where, const std::string& detail);

  LogFn log_;
  std::atomic<std::uint64_t> ok_{0};
  std::atomic<std::uint64_t> errors_[5] = {};
  std::atomic<std::int64_t> last_log_ns_[5] = {};
};

}  // namespace kestrel::comm
