// pipeline/progress.hpp (header-only) in its non-terminal form: what CI logs show.
#include "pipeline/progress.hpp"

#include <gtest/gtest.h>

#include <sstream>

namespace kestrel::pipeline {
namespace {

TEST(ProgressBar, PrintsAPlainLineEveryTenthWhenNotATerminal) {
  testing::internal::CaptureStdout();  // stdout becomes a file: not a terminal
  ProgressBar bar(200, "frames");
  for (std::size_t i = 1; i <= 200; ++i) bar.update(i, "ok");
  bar.update(200, "ok");  // a repeated final update prints nothing more
  const std::string out = testing::internal::GetCapturedStdout();
  std::stringstream ss(out);
  std::vector<std::string> lines;
  for (std::string l; std::getline(ss, l);) lines.push_back(l);
  ASSERT_EQ(lines.size(), 10u) << out;
  EXPECT_EQ(lines.front().rfind("  20/200 frames, ", 0), 0u) << lines.front();
  EXPECT_EQ(lines.back().rfind("  200/200 frames, ", 0), 0u) << lines.back();
  EXPECT_NE(lines.back().find("/s, 0s left, ok"), std::string::npos) << lines.back();
  EXPECT_EQ(out.find('\r'), std::string::npos);
}

TEST(ProgressBar, DisabledOrEmptyPrintsNothing) {
  testing::internal::CaptureStdout();
  ProgressBar off(10, "runs", false);
  for (std::size_t i = 0; i <= 10; ++i) off.update(i);
  ProgressBar empty(0, "runs");
  empty.update(0);
  EXPECT_EQ(testing::internal::GetCapturedStdout(), "");
}

}  // namespace
}  // namespace kestrel::pipeline
