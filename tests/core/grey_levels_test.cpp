// The 1st..99th percentile grey levels that tell a dim frame from a well-exposed one.
#include "core/grey_levels.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace kestrel {
namespace {

TEST(GreyLevels, PercentilesIgnoreTheOutermostPercent) {
  // 100 x 100, grey level 50 + x in column x (50..149); half of column 50 stuck dark and half
  // stuck bright: 0.5% each, inside the tails the percentiles leave out.
  const int w = 100, h = 100;
  std::vector<std::uint8_t> px(static_cast<std::size_t>(w) * h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) px[static_cast<std::size_t>(y) * w + x] = std::uint8_t(50 + x);
    px[static_cast<std::size_t>(y) * w + 50] = y < 50 ? 0 : 255;
  }
  const GreyRange r = grey_range(px.data(), w, h, w, 1);
  EXPECT_EQ(r.lo, 50);
  EXPECT_EQ(r.hi, 149);
  EXPECT_EQ(r.spread(), 99);
  // Every 2nd pixel of every 2nd row (columns 0, 2, ..., 98) of a clean ramp.
  for (int y = 0; y < h; ++y) px[static_cast<std::size_t>(y) * w + 50] = 100;
  const GreyRange sparse = grey_range(px.data(), w, h, w, 2);
  EXPECT_EQ(sparse.lo, 50);
  EXPECT_EQ(sparse.hi, 148);
}

TEST(GreyLevels, FlatAndEmptyImages) {
  const std::vector<std::uint8_t> flat(64 * 48, 77);
  const GreyRange r = grey_range(flat.data(), 64, 48, 64);
  EXPECT_EQ(r.lo, 77);
  EXPECT_EQ(r.hi, 77);
  EXPECT_EQ(r.spread(), 0);
  const GreyRange none = grey_range(nullptr, 0, 0, 0);
  EXPECT_EQ(none.spread(), 255);
}

}  // namespace
}  // namespace kestrel
