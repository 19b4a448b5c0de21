#include "maps/ply_writer.hpp"

#include <bit>
#include <cstring>
#include <fstream>
#include <sstream>

#include "core/error.hpp"

namespace kestrel::maps {
namespace {

constexpr std::size_t kRecord = 3 * 4 + 3 + 2;
const char* const kProperties[] = {
    "property float x",     "property float y",    "property float z",     "property uchar red",
    "property uchar green", "property uchar blue", "property ushort label"};

static_assert(std::endian::native == std::endian::little, "PLY writer assumes little endian");

}  // namespace

void write_ply(const std::string& path, const std::vector<CloudPoint>& points) {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw Error::at(path, 0, "", "cannot write the point cloud");
  out << "ply\nformat binary_little_endian 1.0\ncomment kestrel dense map, world frame, metres\n"
      << "comment label: 0 none, else COCO class id + 1\nelement vertex " << points.size() << "\n";
  for (const char* p : kProperties) out << p << "\n";
  out << "end_header\n";
  std::vector<char> buf(points.size() * kRecord);
  char* w = buf.data();
  for (const CloudPoint& c : points) {
    std::memcpy(w, c.p.data(), 12);
    w[12] = static_cast<char>(c.r);
    w[13] = static_cast<char>(c.g);
    w[14] = static_cast<char>(c.b);
    std::memcpy(w + 15, &c.label, 2);
    w += kRecord;
  }
  out.write(buf.data(), static_cast<std::streamsize>(buf.size()));
  if (!out) throw Error::at(path, 0, "", "write failed");
}

std::vector<CloudPoint> read_ply(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error::at(path, 0, "", "cannot open the point cloud");
  std::string line;
  int n_line = 0;
  auto next = [&](const std::string& field) {
    if (!std::getline(in, line)) throw Error::at(path, n_line, field, "file ends in the header");
    ++n_line;
    return line;
  };
  if (next("magic") != "ply") throw Error::at(path, 1, "magic", "not a PLY file");
  if (next("format") != "format binary_little_endian 1.0")
    throw Error::at(path, n_line, "format",
                    "expected binary_little_endian 1.0, got '" + line + "'");
  std::size_t count = 0;
  while (next("element").rfind("comment", 0) == 0) {
  }
  {
    std::istringstream ss(line);
    std::string element, name;
    ss >> element >> name >> count;
    if (element != "element" || name != "vertex" || !ss)
      throw Error::at(path, n_line, "element", "expected 'element vertex N', got '" + line + "'");
  }
  for (const char* p : kProperties)
    if (next("property") != p)
      throw Error::at(path, n_line, "property",
                      "expected '" + std::string(p) + "', got '" + line + "'");
  if (next("end_header") != "end_header")
    throw Error::at(path, n_line, "end_header", "expected end_header, got '" + line + "'");
  std::vector<char> buf(count * kRecord);
  in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
  if (in.gcount() != static_cast<std::streamsize>(buf.size()))
    throw Error::at(path, 0, "vertex", "expected " + std::to_string(count) + " vertices");
  std::vector<CloudPoint> out(count);
  const char* r = buf.data();
  for (CloudPoint& c : out) {
    std::memcpy(c.p.data(), r, 12);
    c.r = static_cast<std::uint8_t>(r[12]);
    c.g = static_cast<std::uint8_t>(r[13]);
    c.b = static_cast<std::uint8_t>(r[14]);
    std::memcpy(&c.label, r + 15, 2);
    r += kRecord;
  }
  return out;
}

}  // namespace kestrel::maps
