// The demo path end to end (issue 9): `kestrel demo` on a 5 s scene, its printed table against
// the summary.json files it wrote, its report.html parsed, and the report opened in headless
// Chromium (a screenshot, no console errors).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include "tests/test_paths.hpp"

namespace kestrel {
namespace {

namespace fs = std::filesystem;

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

std::vector<std::string> cells(const std::string& row) {
  std::vector<std::string> out;
  std::stringstream ss(row);
  std::string cell;
  std::getline(ss, cell, '|');  // before the first bar
  while (std::getline(ss, cell, '|')) {
    const auto b = cell.find_first_not_of(' '), e = cell.find_last_not_of(' ');
    out.push_back(b == std::string::npos ? "" : cell.substr(b, e - b + 1));
  }
  if (!out.empty() && out.back().empty()) out.pop_back();
  return out;
}

// Tags must nest and close (void elements excepted): "parses as HTML" in the strict sense that
// a browser needs no error recovery. Returns "" or what is wrong.
std::string check_well_formed(const std::string& h) {
  static const std::vector<std::string> kVoid = {"meta", "br", "img", "hr", "input", "link"};
  std::vector<std::string> stack;
  std::size_t at = 0;
  while ((at = h.find('<', at)) != std::string::npos) {
    const std::size_t end = h.find('>', at);
    if (end == std::string::npos) return "unterminated tag at " + std::to_string(at);
    std::string tag = h.substr(at + 1, end - at - 1);
    at = end + 1;
    if (tag.rfind("!DOCTYPE", 0) == 0 || tag.rfind("!--", 0) == 0) continue;
    const bool closing = !tag.empty() && tag[0] == '/';
    const bool self_closing = !tag.empty() && tag.back() == '/';
    std::string name = tag.substr(closing ? 1 : 0);
    name = name.substr(0, name.find_first_of(" \t\n/"));
    if (name.empty()) return "empty tag name near " + std::to_string(at);
    if (closing) {
      if (stack.empty() || stack.back() != name) {
        return "</" + name + "> closes <" + (stack.empty() ? "nothing" : stack.back()) + ">";
      }
      stack.pop_back();
    } else if (!self_closing && std::find(kVoid.begin(), kVoid.end(), name) == kVoid.end()) {
      stack.push_back(name);
    }
  }
  return stack.empty() ? "" : "<" + stack.back() + "> never closed";
}

std::string without_data(std::string h) {
  for (auto at = h.find("base64,"); at != std::string::npos; at = h.find("base64,", at + 1)) {
    h.erase(at + 7, h.find('"', at) - at - 7);
  }
  return h;
}

class DemoReport : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    out_ = new fs::path(test::temp_dir("demo_report"));
    const fs::path kestrel = test::build_dir() / "kestrel";
    ASSERT_TRUE(fs::exists(kestrel)) << kestrel << " missing: build the kestrel target";
    const std::string cmd = "'" + kestrel.string() + "' demo --duration 5 --out '" +
                            out_->string() + "' > '" + (*out_ / "stdout.txt").string() + "' 2>&1";
    rc_ = std::system(cmd.c_str());
  }
  static void TearDownTestSuite() { delete out_; }
  static fs::path* out_;
  static int rc_;
};
fs::path* DemoReport::out_ = nullptr;
int DemoReport::rc_ = -1;

TEST_F(DemoReport, PrintedTableMatchesSummaryJson) {
  const std::string printed = slurp(*out_ / "stdout.txt");
  ASSERT_EQ(rc_, 0) << printed;
  int rows = 0;
  std::stringstream lines(printed);
  for (std::string line; std::getline(lines, line);) {
    const auto c = cells(line);
    if (c.size() != 9 || (c[0] != "hybrid" && c[0] != "off")) continue;
    ++rows;
    const auto j = nlohmann::json::parse(slurp(*out_ / c[0] / "summary.json"));
    SCOPED_TRACE(line);
    EXPECT_NEAR(std::stod(c[1]), j["ape_rmse_m"].get<double>(), 0.5e-4 + 1e-9);
    EXPECT_NEAR(std::stod(c[2]), j["dynamic_removed_percent"].get<double>(), 0.05 + 1e-9);
    EXPECT_NEAR(std::stod(c[3]), j["static_kept_percent"].get<double>(), 0.05 + 1e-9);
    EXPECT_NEAR(std::stod(c[4]), j["tracking_fps"].get<double>(), 0.05 + 1e-9);
    if (c[0] == "off") {
      EXPECT_EQ(c[5], "-");
      EXPECT_EQ(j["detector_fps"].get<double>(), 0.0);
    } else {
      EXPECT_NEAR(std::stod(c[5]), j["detector_fps"].get<double>(), 0.05 + 1e-9);
    }
    EXPECT_EQ(std::stoul(c[6]), j["lost"].get<std::size_t>());
    // Objects found: the entries of the run's objects.json (none without a detector).
    const auto objects = nlohmann::json::parse(slurp(*out_ / c[0] / "objects.json"));
    EXPECT_EQ(std::stoul(c[7]), objects.size());
    if (c[0] == "off") {
      EXPECT_EQ(objects.size(), 0u);
    }
    // Objects against the rendered world: "recall (matched of truth) / precision".
    ASSERT_TRUE(j.contains("objects")) << j.dump();
    const auto& o = j["objects"];
    char scored[64];
    std::snprintf(scored, sizeof scored, "%.2f (%d of %d) / %.2f", o["recall"].get<double>(),
                  o["matched"].get<int>(), o["truth"].get<int>(), o["precision"].get<double>());
    EXPECT_EQ(c[8], scored);
    EXPECT_EQ(o["reported"].get<std::size_t>(), objects.size());
    EXPECT_EQ(j["frames"].get<int>(), 151);
  }
  EXPECT_EQ(rows, 2) << printed;
  EXPECT_NE(printed.find("report: " + (*out_ / "report.html").string()), std::string::npos);
}

TEST_F(DemoReport, ReportParsesAndHoldsPlotsAndTables) {
  ASSERT_EQ(rc_, 0);
  const std::string h = slurp(*out_ / "report.html");
  ASSERT_FALSE(h.empty());
  EXPECT_EQ(h.rfind("<!DOCTYPE html>", 0), 0u);
  EXPECT_EQ(check_well_formed(h), "");
  const std::string text = without_data(h);
  // Top view, height, APE along time and resident memory along the run.
  std::size_t plots = 0;
  for (auto at = text.find("<svg class=\"plot\""); at != std::string::npos;
       at = text.find("<svg class=\"plot\"", at + 1)) {
    ++plots;
  }
  EXPECT_EQ(plots, 4u);
  EXPECT_NE(text.find("Resident memory along the run"), std::string::npos);
  EXPECT_NE(text.find("<table id=\"summary\""), std::string::npos);
  EXPECT_NE(text.find("<table id=\"removal\""), std::string::npos);
  EXPECT_NE(text.find("<table class=\"timing\""), std::string::npos);
  EXPECT_NE(text.find("data:image/jpeg;base64,"), std::string::npos);    // the frame strip
  EXPECT_NE(text.find(" demo --duration 5 --out "), std::string::npos);  // the command
  EXPECT_NE(text.find("kestrel " KESTREL_VERSION), std::string::npos);
  // Nothing to fetch: no URL at all outside the embedded images.
  EXPECT_EQ(text.find("http:"), std::string::npos);
  EXPECT_EQ(text.find("https:"), std::string::npos);
  EXPECT_EQ(text.find("src=\"//"), std::string::npos);
  // The figures in the report are the ones in summary.json.
  for (const char* run : {"hybrid", "off"}) {
    const auto j = nlohmann::json::parse(slurp(*out_ / run / "summary.json"));
    char cell[64];
    std::snprintf(cell, sizeof cell, "<td>%.4f</td>", j["ape_rmse_m"].get<double>());
    EXPECT_NE(text.find(cell), std::string::npos) << run << " " << cell;
    std::snprintf(cell, sizeof cell, "<td>%.1f%%</td>", j["dynamic_removed_percent"].get<double>());
    EXPECT_NE(text.find(cell), std::string::npos) << run << " " << cell;
  }
}

TEST_F(DemoReport, OpensInHeadlessChromiumWithoutConsoleErrors) {
  ASSERT_EQ(rc_, 0);
  const fs::path chromium = "/usr/bin/chromium";
  ASSERT_TRUE(fs::exists(chromium))
      << "chromium is missing: scripts/setup installs it (Debian package chromium)";
  const fs::path profile = *out_ / "chromium-profile";
  const fs::path shot = *out_ / "report.png";
  const fs::path log = *out_ / "chromium.log";
  fs::create_directories(profile);
  const std::string cmd =
      "timeout 120 " + chromium.string() +
      " --headless --no-sandbox --disable-gpu --disable-quic --no-first-run"
      " --disable-background-networking --disable-component-update --disable-sync"
      " --enable-logging=stderr --v=0 --user-data-dir='" +
      profile.string() + "' --screenshot='" + shot.string() + "' --window-size=1280,2000 'file://" +
      (*out_ / "report.html").string() + "' > '" + log.string() + "' 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << slurp(log);
  const std::string png = slurp(shot);
  ASSERT_GT(png.size(), 10000u) << slurp(log);
  ASSERT_EQ(png.substr(1, 3), "PNG");
  // IHDR: big-endian width and height at bytes 16..23.
  auto be32 = [&](std::size_t at) {
    return (static_cast<unsigned>(static_cast<unsigned char>(png[at])) << 24) |
           (static_cast<unsigned>(static_cast<unsigned char>(png[at + 1])) << 16) |
           (static_cast<unsigned>(static_cast<unsigned char>(png[at + 2])) << 8) |
           static_cast<unsigned>(static_cast<unsigned char>(png[at + 3]));
  };
  EXPECT_EQ(be32(16), 1280u);
  EXPECT_EQ(be32(20), 2000u);
  // The page has no script: any console message (Chromium logs them as CONSOLE) is an error.
  std::stringstream lines(slurp(log));
  for (std::string line; std::getline(lines, line);) {
    EXPECT_EQ(line.find("CONSOLE"), std::string::npos) << line;
    EXPECT_EQ(line.find("Uncaught"), std::string::npos) << line;
    EXPECT_EQ(line.find("Failed to load resource"), std::string::npos) << line;
  }
  std::printf("screenshot: %s\n", shot.c_str());
}

}  // namespace
}  // namespace kestrel
