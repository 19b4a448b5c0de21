// Arbitrary bytes into every dataset index parser (TUM lists and associations, ASL image and
// IMU csv, stamped vector logs, boxes.csv, objects.json) and the association step: each must
// parse or throw kestrel::Error — never crash, hang or read out of bounds. What parses must
// satisfy the parsers' promises (strictly increasing stamps, finite numbers).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/error.hpp"
#include "io/dataset_lists.hpp"
#include "io/kestrel_sequence.hpp"
#include "io/text_lines.hpp"

namespace {

template <typename F>
void guarded(F&& f) {
  try {
    f();
  } catch (const kestrel::Error&) {
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace kestrel;
  using namespace kestrel::io;
  const std::string text(reinterpret_cast<const char*>(data), size);
  TextTable table;
  try {
    table = TextTable::parse(text, "fuzz");
  } catch (const Error&) {
    return 0;
  }
  guarded([&] {
    const auto rgb = parse_tum_list(table);
    std::vector<Timestamp> stamps;
    for (std::size_t i = 0; i < rgb.size(); ++i) {
      if (i > 0 && rgb[i].t <= rgb[i - 1].t) __builtin_trap();
      stamps.push_back(rgb[i].t);
    }
    // Associating a list with itself, shifted, exercises the matcher on arbitrary stamps.
    std::vector<Timestamp> shifted = stamps;
    for (auto& t : shifted) t = t / 2 + 3;
    const auto pairs = associate(stamps, shifted, 20'000'000);
    for (const auto& [i, j] : pairs) {
      if (i >= stamps.size() || j >= shifted.size()) __builtin_trap();
      const Timestamp d = stamps[i] > shifted[j] ? stamps[i] - shifted[j] : shifted[j] - stamps[i];
      if (d >= 20'000'000) __builtin_trap();
    }
  });
  guarded([&] { (void)parse_association(table); });
  guarded([&] { (void)parse_asl_image_csv(table); });
  guarded([&] {
    for (const ImuSample& s : parse_asl_imu_csv(table)) {
      if (!s.gyro.allFinite() || !s.acc.allFinite()) __builtin_trap();
    }
  });
  guarded([&] { (void)parse_stamped_vectors(table, "x y z"); });
  guarded([&] { (void)parse_boxes(table); });
  guarded([&] { (void)parse_objects_json(text, "fuzz.json"); });
  return 0;
}
