// The vocabulary file: "KVOC", format version, k, levels, node count, then per node (root
// first, parents before children) its parent (u32), IDF weight (f64) and 32 descriptor bytes.
// Little-endian, as every machine Kestrel targets.
#include <cstring>
#include <fstream>
#include <stdexcept>

#include "core/error.hpp"
#include "loop/vocabulary.hpp"

namespace kestrel::loop {
namespace {

constexpr char kMagic[4] = {'K', 'V', 'O', 'C'};
constexpr std::uint32_t kVersion = 1;
// Guards against reading garbage as a huge allocation (k=10, L=6 has 1.1 million nodes).
constexpr std::uint32_t kMaxNodes = 5'000'000;

template <typename T>
void put(std::ofstream& out, const T& v) {
  out.write(reinterpret_cast<const char*>(&v), sizeof(T));
}

template <typename T>
T get(std::ifstream& in, const std::string& path, const char* field) {
  T v{};
  if (!in.read(reinterpret_cast<char*>(&v), sizeof(T)))
    throw Error::at(path, 0, field, "file ends early (truncated vocabulary)");
  return v;
}

}  // namespace

void Vocabulary::save(const std::string& path) const {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw Error::at(path, 0, "", "cannot open for writing");
  out.write(kMagic, 4);
  put(out, kVersion);
  put(out, static_cast<std::uint32_t>(k_));
  put(out, static_cast<std::uint32_t>(levels_));
  put(out, static_cast<std::uint32_t>(nodes_.size()));
  for (const Node& n : nodes_) {
    put(out, static_cast<std::uint32_t>(n.parent));
    put(out, n.weight);
    std::uint8_t bytes[32];
    n.centroid.to_bytes(bytes);
    out.write(reinterpret_cast<const char*>(bytes), 32);
  }
  if (!out) throw Error::at(path, 0, "", "write failed");
}

Vocabulary Vocabulary::load(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error::at(path, 0, "", "cannot open vocabulary file");
  char magic[4] = {};
  if (!in.read(magic, 4) || std::memcmp(magic, kMagic, 4) != 0)
    throw Error::at(path, 0, "magic", "not a Kestrel vocabulary (expected \"KVOC\")");
  const auto version = get<std::uint32_t>(in, path, "version");
  if (version != kVersion)
    throw Error::at(path, 0, "version",
                    "unsupported version " + std::to_string(version) + " (expected " +
                        std::to_string(kVersion) + ")");
  const auto k = get<std::uint32_t>(in, path, "k");
  const auto levels = get<std::uint32_t>(in, path, "levels");
  const auto count = get<std::uint32_t>(in, path, "nodes");
  if (k < 2 || k > 1000) throw Error::at(path, 0, "k", "out of range: " + std::to_string(k));
  if (levels < 1 || levels > 16)
    throw Error::at(path, 0, "levels", "out of range: " + std::to_string(levels));
  if (count < 1 || count > kMaxNodes)
    throw Error::at(path, 0, "nodes", "out of range: " + std::to_string(count));
  std::vector<Node> nodes(count);
  for (std::uint32_t i = 0; i < count; ++i) {
    nodes[i].parent = get<std::uint32_t>(in, path, "node.parent");
    nodes[i].weight = get<double>(in, path, "node.weight");
    std::uint8_t bytes[32];
    if (!in.read(reinterpret_cast<char*>(bytes), 32))
      throw Error::at(path, 0, "node.descriptor", "file ends early (truncated vocabulary)");
    nodes[i].centroid = OrbDescriptor::from_bytes(bytes);
    if (i > 0 && nodes[i].parent >= i)
      throw Error::at(path, 0, "node.parent",
                      "node " + std::to_string(i) + " names parent " +
                          std::to_string(nodes[i].parent) + ", which does not precede it");
  }
  if (in.peek() != std::char_traits<char>::eof())
    throw Error::at(path, 0, "", "trailing bytes after the last node");
  try {
    return from_nodes(static_cast<int>(k), static_cast<int>(levels), std::move(nodes));
  } catch (const std::invalid_argument& e) {
    throw Error::at(path, 0, "nodes", e.what());
  }
}

}  // namespace kestrel::loop
