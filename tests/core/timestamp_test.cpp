#include "core/timestamp.hpp"

#include <gtest/gtest.h>

namespace kestrel {
namespace {

TEST(Timestamp, ParsesDecimalSecondsExactly) {
  EXPECT_EQ(parse_seconds("1341846313.592026"), 1341846313592026000LL);
  EXPECT_EQ(parse_seconds("1403715274.302000000"), 1403715274302000000LL);
  EXPECT_EQ(parse_seconds("0.5"), 500000000LL);
  EXPECT_EQ(parse_seconds("-1.25"), -1250000000LL);
  EXPECT_EQ(parse_seconds("12"), 12000000000LL);
  EXPECT_EQ(parse_seconds("1.0000000004"), 1000000000LL);
  EXPECT_EQ(parse_seconds("1.0000000006"), 1000000001LL);
  EXPECT_EQ(parse_seconds("1.037359e-01"), 103735900LL);
}

TEST(Timestamp, RejectsGarbage) {
  EXPECT_FALSE(parse_seconds(""));
  EXPECT_FALSE(parse_seconds("abc"));
  EXPECT_FALSE(parse_seconds("1.2.3"));
  EXPECT_FALSE(parse_seconds("."));
  EXPECT_FALSE(parse_seconds("nan"));
  EXPECT_FALSE(parse_seconds("1e400"));
  EXPECT_FALSE(parse_seconds("99999999999999999999"));
  EXPECT_FALSE(parse_nanoseconds("12x"));
  EXPECT_FALSE(parse_nanoseconds(""));
}

TEST(Timestamp, FormatRoundTrips) {
  for (Timestamp t : {0LL, 1LL, 999999999LL, 1341846313592026000LL, -1250000000LL, -1LL}) {
    EXPECT_EQ(parse_seconds(format_seconds(t)), t) << format_seconds(t);
  }
  EXPECT_EQ(format_seconds(1341846313592026000LL), "1341846313.592026000");
}

}  // namespace
}  // namespace kestrel
