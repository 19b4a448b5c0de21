#include "eval/report/svg_plot.hpp"

#include <gtest/gtest.h>

#include "eval/report/image_embed.hpp"

namespace kestrel::report {
namespace {

TEST(NiceTicks, StepsAreOneTwoOrFiveTimesAPowerOfTen) {
  const auto t = nice_ticks(0.0, 10.0, 5);
  ASSERT_EQ(t.size(), 6u);
  EXPECT_DOUBLE_EQ(t.front(), 0.0);
  EXPECT_DOUBLE_EQ(t[1], 2.0);
  EXPECT_DOUBLE_EQ(t.back(), 10.0);
  const auto u = nice_ticks(-0.013, 0.041, 6);
  ASSERT_GE(u.size(), 3u);
  EXPECT_NEAR(u[1] - u[0], 0.01, 1e-12);
  EXPECT_GE(u.front(), -0.013);
  EXPECT_LE(u.back(), 0.041);
}

TEST(NiceTicks, DegenerateRangeGivesOneTick) { EXPECT_EQ(nice_ticks(3.0, 3.0).size(), 1u); }

TEST(XmlEscape, EscapesMarkup) {
  EXPECT_EQ(xml_escape("a<b & \"c\"'>"), "a&lt;b &amp; &quot;c&quot;&#39;&gt;");
}

TEST(Base64, MatchesRfc4648Vectors) {
  auto b = [](const std::string& s) { return base64({s.begin(), s.end()}); };
  EXPECT_EQ(b(""), "");
  EXPECT_EQ(b("f"), "Zg==");
  EXPECT_EQ(b("fo"), "Zm8=");
  EXPECT_EQ(b("foo"), "Zm9v");
  EXPECT_EQ(b("foob"), "Zm9vYg==");
  EXPECT_EQ(b("fooba"), "Zm9vYmE=");
  EXPECT_EQ(b("foobar"), "Zm9vYmFy");
}

TEST(SvgPlot, DrawsEverySeriesWithLegendAndAxisLabels) {
  SvgPlot p("title <1>", "t (s)", "z (m)");
  p.add({"first", "#ff0000", {0, 1, 2}, {0, 1, 4}, false, false});
  p.add({"second", "#00ff00", {0, 2}, {1, 1}, true, false});
  p.add({"objects", "#0000ff", {1}, {2}, false, true});
  const std::string s = p.svg();
  EXPECT_EQ(s.rfind("<svg", 0), 0u);
  EXPECT_NE(s.find("</svg>"), std::string::npos);
  EXPECT_NE(s.find("title &lt;1&gt;"), std::string::npos);
  EXPECT_NE(s.find("t (s)"), std::string::npos);
  EXPECT_NE(s.find("stroke=\"#ff0000\""), std::string::npos);
  EXPECT_NE(s.find("stroke-dasharray"), std::string::npos);
  EXPECT_NE(s.find("<circle"), std::string::npos);
  EXPECT_NE(s.find(">second</text>"), std::string::npos);
  // Two line series -> two polylines.
  std::size_t n = 0;
  for (std::size_t at = s.find("<polyline"); at != std::string::npos;
       at = s.find("<polyline", at + 1)) {
    ++n;
  }
  EXPECT_EQ(n, 2u);
}

TEST(SvgPlot, EmptyPlotStillRenders) {
  SvgPlot p("empty", "x", "y");
  const std::string s = p.svg();
  EXPECT_NE(s.find("</svg>"), std::string::npos);
  EXPECT_EQ(s.find("nan"), std::string::npos);
}

}  // namespace
}  // namespace kestrel::report
