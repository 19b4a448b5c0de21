#include "core/timestamp.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>

namespace kestrel {

Timestamp from_seconds(double seconds) { return std::llround(seconds * 1e9); }

std::optional<Timestamp> parse_nanoseconds(std::string_view text) {
  Timestamp value = 0;
  const char* end = text.data() + text.size();
  auto [ptr, ec] = std::from_chars(text.data(), end, value);
  if (ec != std::errc() || ptr != end || text.empty()) return std::nullopt;
  return value;
}

std::optional<Timestamp> parse_seconds(std::string_view text) {
  if (text.empty()) return std::nullopt;
  // Exponent form (e.g. KITTI times "1.037359e-01") cannot be split exactly into digits
  // cheaply; it is rare and only ever written with few significant digits, so use double.
  if (text.find_first_of("eE") != std::string_view::npos) {
    double v = 0.0;
    const char* end = text.data() + text.size();
    auto [ptr, ec] = std::from_chars(text.data(), end, v);
    if (ec != std::errc() || ptr != end || !std::isfinite(v)) return std::nullopt;
    if (std::fabs(v) > 9.2e9) return std::nullopt;
    return from_seconds(v);
  }
  bool negative = false;
  std::size_t i = 0;
  if (text[0] == '-' || text[0] == '+') {
    negative = text[0] == '-';
    i = 1;
  }
  std::int64_t whole = 0;
  std::int64_t frac = 0;
  int frac_digits = 0;
  bool any_digit = false;
  bool round_up = false;
  for (; i < text.size() && text[i] != '.'; ++i) {
    const char c = text[i];
    if (c < '0' || c > '9') return std::nullopt;
    if (whole > (std::numeric_limits<std::int64_t>::max() / kNanosPerSecond) / 10) {
      return std::nullopt;
    }
    whole = whole * 10 + (c - '0');
    any_digit = true;
  }
  if (i < text.size()) {
    ++i;  // '.'
    for (; i < text.size(); ++i) {
      const char c = text[i];
      if (c < '0' || c > '9') return std::nullopt;
      any_digit = true;
      if (frac_digits < 9) {
        frac = frac * 10 + (c - '0');
        ++frac_digits;
      } else if (frac_digits == 9) {
        round_up = c >= '5';
        ++frac_digits;
      }
    }
  }
  if (!any_digit) return std::nullopt;
  for (int d = std::min(frac_digits, 9); d < 9; ++d) frac *= 10;
  Timestamp t = whole * kNanosPerSecond + frac + (round_up ? 1 : 0);
  return negative ? -t : t;
}

std::string format_seconds(Timestamp t) {
  const bool negative = t < 0;
  const std::uint64_t a =
      negative ? static_cast<std::uint64_t>(-(t + 1)) + 1u : static_cast<std::uint64_t>(t);
  char buf[48];
  std::snprintf(buf, sizeof(buf), "%s%llu.%09llu", negative ? "-" : "",
                static_cast<unsigned long long>(a / kNanosPerSecond),
                static_cast<unsigned long long>(a % kNanosPerSecond));
  return buf;
}

}  // namespace kestrel
