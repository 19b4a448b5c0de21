#include "maps/grid_io.hpp"

#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/error.hpp"
#include "io/yaml_fields.hpp"

namespace kestrel::maps {
namespace {

struct Pgm {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> pixels;  // row 0 is the top of the image
};

// PGM header tokens, skipping '#' comments; counts lines so errors can name them.
class PgmHeader {
 public:
  PgmHeader(std::istream& in, const std::string& path) : in_(in), path_(path) {}
  std::string token(const std::string& field) {
    std::string tok;
    while (true) {
      const int c = in_.get();
      if (c == EOF) {
        if (!tok.empty()) return tok;
        throw Error::at(path_, line_, field, "file ends inside the PGM header");
      }
      if (c == '#') {
        std::string rest;
        std::getline(in_, rest);
        ++line_;
        if (!tok.empty()) return tok;
        continue;
      }
      if (std::isspace(c)) {
        if (c == '\n' && tok.empty()) ++line_;
        if (!tok.empty()) {
          if (c == '\n') pending_newline_ = true;
          return tok;
        }
        continue;
      }
      if (pending_newline_) {
        ++line_;
        pending_newline_ = false;
      }
      tok.push_back(static_cast<char>(c));
    }
  }
  int integer(const std::string& field, int lo, int hi) {
    const std::string tok = token(field);
    int v = 0;
    try {
      std::size_t used = 0;
      v = std::stoi(tok, &used);
      if (used != tok.size()) throw std::invalid_argument(tok);
    } catch (const std::exception&) {
      throw Error::at(path_, line_, field, "expected an integer, got '" + tok + "'");
    }
    if (v < lo || v > hi)
      throw Error::at(
          path_, line_, field,
          "must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " + tok);
    return v;
  }
  int line() const { return line_; }

 private:
  std::istream& in_;
  std::string path_;
  int line_ = 1;
  bool pending_newline_ = false;
};

Pgm read_pgm(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error::at(path, 0, "", "cannot open the map image");
  PgmHeader header(in, path);
  const std::string magic = header.token("magic");
  if (magic != "P5" && magic != "P2")
    throw Error::at(path, 1, "magic", "expected a PGM (P5 or P2), got '" + magic + "'");
  Pgm pgm;
  pgm.width = header.integer("width", 1, 1 << 15);
  pgm.height = header.integer("height", 1, 1 << 15);
  const int maxval = header.integer("maxval", 1, 255);
  pgm.pixels.resize(static_cast<std::size_t>(pgm.width) * pgm.height);
  if (magic == "P5") {
    in.read(reinterpret_cast<char*>(pgm.pixels.data()),
            static_cast<std::streamsize>(pgm.pixels.size()));
    if (in.gcount() != static_cast<std::streamsize>(pgm.pixels.size()))
      throw Error::at(path, header.line(), "pixels",
                      "expected " + std::to_string(pgm.pixels.size()) + " bytes, file has " +
                          std::to_string(in.gcount()));
  } else {
    for (auto& p : pgm.pixels) p = static_cast<std::uint8_t>(header.integer("pixel", 0, maxval));
  }
  if (maxval != 255)
    for (auto& p : pgm.pixels) p = static_cast<std::uint8_t>(p * 255 / maxval);
  return pgm;
}

}  // namespace

MapMetadata read_map_metadata(const std::string& yaml_path) {
  const io::YamlFile f = io::YamlFile::read(yaml_path);
  const YAML::Node& root = f.root();
  if (!root.IsMap()) f.fail(root, "", "expected a map_server YAML map");
  MapMetadata m;
  m.image = f.text(f.require(root, "image", "image"), "image");
  m.resolution = f.number(f.require(root, "resolution", "resolution"), "resolution");
  if (!(m.resolution > 0.0)) f.fail(root["resolution"], "resolution", "must be positive");
  const YAML::Node origin = f.require(root, "origin", "origin");
  const std::vector<double> o = f.numbers(origin, "origin");
  if (o.size() != 3) f.fail(origin, "origin", "expected [x, y, yaw]");
  m.origin_x = o[0];
  m.origin_y = o[1];
  m.origin_yaw = o[2];
  if (std::abs(m.origin_yaw) > 1e-9)
    f.fail(origin, "origin", "a rotated map (yaw != 0) is not supported");
  if (root["negate"]) {
    const double n = f.number(root["negate"], "negate");
    if (n != 0.0 && n != 1.0) f.fail(root["negate"], "negate", "must be 0 or 1");
    m.negate = n != 0.0;
  }
  if (root["occupied_thresh"])
    m.occupied_thresh = f.number(root["occupied_thresh"], "occupied_thresh");
  if (root["free_thresh"]) m.free_thresh = f.number(root["free_thresh"], "free_thresh");
  if (m.occupied_thresh < 0.0 || m.occupied_thresh > 1.0)
    f.fail(root["occupied_thresh"], "occupied_thresh", "must be in [0, 1]");
  if (m.free_thresh < 0.0 || m.free_thresh > m.occupied_thresh)
    f.fail(root["free_thresh"], "free_thresh", "must be in [0, occupied_thresh]");
  if (root["mode"] && f.text(root["mode"], "mode") != "trinary")
    f.fail(root["mode"], "mode", "only the trinary mode is supported");
  return m;
}

OccupancyGrid read_map(const std::string& yaml_path) {
  const MapMetadata m = read_map_metadata(yaml_path);
  std::filesystem::path image(m.image);
  if (image.is_relative()) image = std::filesystem::path(yaml_path).parent_path() / image;
  const Pgm pgm = read_pgm(image.string());
  OccupancyGrid grid(pgm.width, pgm.height, m.resolution, Vec2(m.origin_x, m.origin_y));
  for (int r = 0; r < pgm.height; ++r) {
    for (int x = 0; x < pgm.width; ++x) {
      const double v = pgm.pixels[static_cast<std::size_t>(r) * pgm.width + x];
      const double p = m.negate ? v / 255.0 : (255.0 - v) / 255.0;
      std::int8_t cell = kUnknown;
      if (p > m.occupied_thresh)
        cell = kOccupied;
      else if (p < m.free_thresh)
        cell = kFree;
      // Image row 0 is the top, grid row 0 the bottom.
      grid.set({x, pgm.height - 1 - r}, cell);
    }
  }
  return grid;
}

void write_map(const std::string& yaml_path, const OccupancyGrid& grid) {
  const std::filesystem::path yp(yaml_path);
  const std::string pgm_name = yp.stem().string() + ".pgm";
  const std::filesystem::path pgm_path = yp.parent_path() / pgm_name;
  {
    std::ofstream out(pgm_path, std::ios::binary);
    if (!out) throw Error::at(pgm_path.string(), 0, "", "cannot write the map image");
    out << "P5\n# kestrel occupancy grid, " << grid.resolution() << " m/pix\n"
        << grid.width() << " " << grid.height() << "\n255\n";
    std::vector<std::uint8_t> row(static_cast<std::size_t>(grid.width()));
    for (int r = grid.height() - 1; r >= 0; --r) {
      for (int x = 0; x < grid.width(); ++x) {
        const std::int8_t v = grid.at({x, r});
        row[x] = v < 0 ? 205 : (v >= 65 ? 0 : (v <= 19 ? 254 : 205));
      }
      out.write(reinterpret_cast<const char*>(row.data()),
                static_cast<std::streamsize>(row.size()));
    }
    if (!out) throw Error::at(pgm_path.string(), 0, "", "write failed");
  }
  std::ofstream y(yp);
  if (!y) throw Error::at(yaml_path, 0, "", "cannot write the map YAML");
  std::ostringstream s;
  s.precision(9);
  s << "image: " << pgm_name << "\nmode: trinary\nresolution: " << grid.resolution()
    << "\norigin: [" << grid.origin().x() << ", " << grid.origin().y()
    << ", 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";
  y << s.str();
  if (!y) throw Error::at(yaml_path, 0, "", "write failed");
}

}  // namespace kestrel::maps
