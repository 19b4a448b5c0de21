#pragma once
// Time is int64 nanoseconds everywhere inside Kestrel. Decimal-second strings from dataset
// files are parsed digit by digit, so "1341846313.592026" becomes exactly 1341846313592026000 ns
// and no stamp is disturbed by a round trip through double.
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace kestrel {

using Timestamp = std::int64_t;  // nanoseconds

constexpr Timestamp kNanosPerSecond = 1'000'000'000;

constexpr double to_seconds(Timestamp t) { return static_cast<double>(t) * 1e-9; }
Timestamp from_seconds(double seconds);

// Parses "[-]S[.F][e±X]" decimal seconds exactly (up to ns resolution). nullopt on bad syntax.
std::optional<Timestamp> parse_seconds(std::string_view text);
// Parses an integer nanosecond count (EuRoC style). nullopt on bad syntax or overflow.
std::optional<Timestamp> parse_nanoseconds(std::string_view text);
// "S.FFFFFFFFF" with nine decimals, the inverse of parse_seconds.
std::string format_seconds(Timestamp t);

}  // namespace kestrel
