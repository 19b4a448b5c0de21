#include "detect/darknet_onednn.hpp"

#include <omp.h>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <oneapi/dnnl/dnnl.hpp>
#include <optional>
#include <sstream>
#include <unordered_map>
#include <variant>

#include "core/error.hpp"

namespace kestrel::detect {

namespace {

using dt = dnnl::memory::data_type;
using tag = dnnl::memory::format_tag;

// ---- cfg ------------------------------------------------------------------------------------

struct Section {
  std::string type;                                           // "convolutional", "net", ...
  int line = 0;                                               // of the [type] header
  std::map<std::string, std::pair<std::string, int>> values;  // key -> (value, line)
  mutable std::map<std::string, bool> used;
};

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t\r");
  return s.substr(b, e - b + 1);
}

std::vector<Section> parse_cfg(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error::at(path, 0, "", "cannot open Darknet cfg");
  std::vector<Section> sections;
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    const auto hash = line.find_first_of("#;");
    if (hash != std::string::npos) line.resize(hash);
    line = trim(line);
    if (line.empty()) continue;
    if (line.front() == '[') {
      if (line.back() != ']') throw Error::at(path, n, "", "unterminated section header");
      sections.push_back({trim(line.substr(1, line.size() - 2)), n, {}, {}});
      continue;
    }
    const auto eq = line.find('=');
    if (eq == std::string::npos) throw Error::at(path, n, "", "expected key=value: " + line);
    if (sections.empty()) throw Error::at(path, n, "", "key=value before the first section");
    sections.back().values[trim(line.substr(0, eq))] = {trim(line.substr(eq + 1)), n};
  }
  if (sections.empty() || sections.front().type != "net") {
    throw Error::at(path, 0, "", "a Darknet cfg starts with a [net] section");
  }
  return sections;
}

class Reader {
 public:
  Reader(const std::string& path, const Section& s) : path_(path), s_(s) {}

  bool has(const std::string& key) const { return s_.values.contains(key); }

  int get_int(const std::string& key, std::optional<int> fallback = std::nullopt) const {
    const auto it = s_.values.find(key);
    if (it == s_.values.end()) {
      if (!fallback) throw Error::at(path_, s_.line, key, "missing in [" + s_.type + "]");
      return *fallback;
    }
    s_.used[key] = true;
    try {
      std::size_t pos = 0;
      const int v = std::stoi(it->second.first, &pos);
      if (pos != it->second.first.size()) throw std::invalid_argument("trailing");
      return v;
    } catch (const std::exception&) {
      throw Error::at(path_, it->second.second, key, "not an integer: " + it->second.first);
    }
  }

  float get_float(const std::string& key, float fallback) const {
    const auto it = s_.values.find(key);
    if (it == s_.values.end()) return fallback;
    s_.used[key] = true;
    try {
      return std::stof(it->second.first);
    } catch (const std::exception&) {
      throw Error::at(path_, it->second.second, key, "not a number: " + it->second.first);
    }
  }

  std::string get_string(const std::string& key, const std::string& fallback) const {
    const auto it = s_.values.find(key);
    if (it == s_.values.end()) return fallback;
    s_.used[key] = true;
    return it->second.first;
  }

  std::vector<int> get_ints(const std::string& key) const {
    const auto it = s_.values.find(key);
    if (it == s_.values.end()) throw Error::at(path_, s_.line, key, "missing in [" + s_.type + "]");
    s_.used[key] = true;
    std::vector<int> out;
    std::stringstream ss(it->second.first);
    std::string item;
    while (std::getline(ss, item, ',')) {
      item = trim(item);
      if (item.empty()) continue;
      try {
        out.push_back(std::stoi(item));
      } catch (const std::exception&) {
        throw Error::at(path_, it->second.second, key, "not a list of integers: " + item);
      }
    }
    if (out.empty()) throw Error::at(path_, it->second.second, key, "empty list");
    return out;
  }

  [[noreturn]] void fail(const std::string& key, const std::string& message) const {
    const auto it = s_.values.find(key);
    throw Error::at(path_, it == s_.values.end() ? s_.line : it->second.second, key, message);
  }

 private:
  const std::string& path_;
  const Section& s_;
};

// ---- weights --------------------------------------------------------------------------------

class WeightsFile {
 public:
  explicit WeightsFile(const std::string& path) : path_(path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error::at(path, 0, "", "cannot open Darknet weights");
    bytes_.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    std::int32_t major = 0, minor = 0, revision = 0;
    read_raw(&major, 4);
    read_raw(&minor, 4);
    read_raw(&revision, 4);
    // Darknet writes `seen` as 64 bits from format 0.2 on.
    if (major * 10 + minor >= 2 && major < 1000 && minor < 1000) {
      std::uint64_t seen = 0;
      read_raw(&seen, 8);
    } else {
      std::int32_t seen = 0;
      read_raw(&seen, 4);
    }
  }

  std::vector<float> floats(std::size_t n, const std::string& what) {
    std::vector<float> v(n);
    if (pos_ + n * 4 > bytes_.size()) {
      throw Error::at(path_, 0, "",
                      "weights file ends early (" + std::to_string(bytes_.size()) +
                          " bytes) while reading " + what + ": the cfg needs more weights");
    }
    std::memcpy(v.data(), bytes_.data() + pos_, n * 4);
    pos_ += n * 4;
    return v;
  }

  void expect_end() const {
    if (pos_ != bytes_.size()) {
      throw Error::at(path_, 0, "",
                      "weights file has " + std::to_string(bytes_.size() - pos_) +
                          " bytes more than the cfg uses: cfg and weights do not match");
    }
  }

 private:
  void read_raw(void* dst, std::size_t n) {
    if (pos_ + n > bytes_.size()) throw Error::at(path_, 0, "", "weights file header truncated");
    std::memcpy(dst, bytes_.data() + pos_, n);
    pos_ += n;
  }

  std::string path_;
  std::vector<char> bytes_;
  std::size_t pos_ = 0;
};

enum class Activation { kLinear, kLeaky };

Activation parse_activation(const Reader& r, const std::string& key) {
  const std::string a = r.get_string(key, "linear");
  if (a == "linear") return Activation::kLinear;
  if (a == "leaky") return Activation::kLeaky;
  r.fail(key, "activation '" + a + "' is not supported (linear, leaky)");
}

struct Shape {
  int c = 0, h = 0, w = 0;
};

struct YoloHead {
  int tensor = -1;
  Shape shape;
  std::vector<float> anchors;  // (w, h) pairs in input pixels, masked
  int classes = 0;
  float scale_x_y = 1.0f;
};

}  // namespace

// ---- the network ----------------------------------------------------------------------------

namespace {

// The network after parsing: tensors with their shapes, and the nodes that compute them.
struct ConvNode {
  int src = -1, dst = -1;
  int addend = -1;  // a fused shortcut: dst = act(conv(src)) + addend
  int filters = 0, size = 1, stride = 1, pad = 0, groups = 1;
  Activation act = Activation::kLinear;
  std::vector<float> weights, bias;  // batch norm folded in; weights [filters][in/groups][k][k]
};
struct AddNode {
  int a = -1, b = -1, dst = -1;
};
struct ConcatNode {
  std::vector<int> srcs;
  int dst = -1;
};
struct PoolNode {
  int src = -1, dst = -1, size = 1, stride = 1, pad = 0;  // pad = Darknet's total padding
};
struct UpsampleNode {
  int src = -1, dst = -1, stride = 2;
};
using Node = std::variant<ConvNode, AddNode, ConcatNode, PoolNode, UpsampleNode>;

struct Graph {
  int channels = 3;
  std::vector<Shape> shapes;  // per tensor; tensor 0 is the input
  std::vector<Node> nodes;
  std::vector<YoloHead> heads;
  std::string summary;
};

bool aliases(const std::string& type, const Reader& r) {
  if (type == "dropout") return true;
  return type == "route" && r.has("layers") && r.get_ints("layers").size() == 1;
}

Graph build_graph(const std::string& cfg, const std::string& weights, int width, int height) {
  const std::vector<Section> sections = parse_cfg(cfg);
  WeightsFile wf(weights);
  Graph g;
  {
    const Reader net(cfg, sections.front());
    g.channels = net.get_int("channels", 3);
    if (g.channels <= 0) net.fail("channels", "must be positive");
  }
  if (width < 32 || height < 32 || width % 32 != 0 || height % 32 != 0) {
    throw Error::at(cfg, 0, "",
                    "network input " + std::to_string(width) + "x" + std::to_string(height) +
                        " is not a positive multiple of 32");
  }
  const int num_layers = static_cast<int>(sections.size()) - 1;
  auto section = [&](int i) -> const Section& { return sections[static_cast<std::size_t>(i + 1)]; };
  auto resolve = [&](const Reader& r, const std::string& key, int index, int rel) {
    const int abs = rel < 0 ? index + rel : rel;
    if (abs < 0 || abs >= index) {
      r.fail(key,
             "layer " + std::to_string(rel) + " is out of range at layer " + std::to_string(index));
    }
    return abs;
  };

  // Pass 1: which layer each layer's output really is (dropouts and one-layer routes are
  // aliases), and how many layers read each real output.
  std::vector<int> root(static_cast<std::size_t>(num_layers));
  std::vector<int> readers(static_cast<std::size_t>(num_layers), 0);
  for (int i = 0; i < num_layers; ++i) {
    const Section& s = section(i);
    const Reader r(cfg, s);
    std::vector<int> inputs;
    if (s.type == "route") {
      for (int l : r.get_ints("layers")) inputs.push_back(resolve(r, "layers", i, l));
    } else {
      if (i == 0 && s.type != "convolutional") {
        throw Error::at(cfg, s.line, "", "the first layer must be [convolutional]");
      }
      if (i > 0) inputs.push_back(i - 1);
      if (s.type == "shortcut") inputs.push_back(resolve(r, "from", i, r.get_int("from")));
    }
    if (aliases(s.type, r)) {
      root[static_cast<std::size_t>(i)] =
          inputs.empty() ? i : root[static_cast<std::size_t>(inputs.front())];
    } else {
      root[static_cast<std::size_t>(i)] = i;
      for (int in : inputs) ++readers[static_cast<std::size_t>(root[static_cast<std::size_t>(in)])];
    }
  }

  // Pass 2: shapes, weights, nodes.
  g.shapes.push_back({g.channels, height, width});
  std::vector<int> layer_tensor(static_cast<std::size_t>(num_layers), -1);
  std::vector<int> conv_node_of_tensor(1, -1);
  auto add_tensor = [&](const Shape& s) {
    g.shapes.push_back(s);
    conv_node_of_tensor.push_back(-1);
    return static_cast<int>(g.shapes.size()) - 1;
  };
  std::ostringstream summary;
  int cur = 0;
  for (int i = 0; i < num_layers; ++i) {
    const Section& s = section(i);
    const Reader r(cfg, s);
    const Shape in = g.shapes[static_cast<std::size_t>(cur)];
    int out = -1;
    if (s.type == "convolutional") {
      ConvNode c;
      c.src = cur;
      c.filters = r.get_int("filters");
      c.size = r.get_int("size", 1);
      c.stride = r.get_int("stride", 1);
      c.groups = r.get_int("groups", 1);
      c.pad = r.get_int("padding", 0);
      if (r.get_int("pad", 0) != 0) c.pad = c.size / 2;
      c.act = parse_activation(r, "activation");
      const bool bn = r.get_int("batch_normalize", 0) != 0;
      if (c.filters <= 0) r.fail("filters", "must be positive");
      if (c.size <= 0) r.fail("size", "must be positive");
      if (c.stride <= 0) r.fail("stride", "must be positive");
      if (c.pad < 0) r.fail("padding", "must not be negative");
      if (c.groups <= 0 || in.c % c.groups != 0 || c.filters % c.groups != 0) {
        r.fail("groups", "must divide the input channels (" + std::to_string(in.c) +
                             ") and the filters (" + std::to_string(c.filters) + ")");
      }
      for (const char* key : {"dilation", "binary", "xnor", "share_index", "antialiasing"}) {
        if (r.has(key)) r.fail(key, "not supported");
      }
      const Shape o{c.filters, (in.h + 2 * c.pad - c.size) / c.stride + 1,
                    (in.w + 2 * c.pad - c.size) / c.stride + 1};
      if (o.h <= 0 || o.w <= 0) r.fail("size", "larger than the layer's input");
      const std::string what = "layer " + std::to_string(i) + " [convolutional]";
      const auto n = static_cast<std::size_t>(c.filters);
      c.bias = wf.floats(n, what + " biases");
      std::vector<float> scale(n, 1.0f);
      if (bn) {
        const std::vector<float> gamma = wf.floats(n, what + " scales");
        const std::vector<float> mean = wf.floats(n, what + " means");
        const std::vector<float> var = wf.floats(n, what + " variances");
        for (std::size_t f = 0; f < n; ++f) {
          // Darknet's batch norm at inference: gamma (x - mean) / sqrt(var + .00001) + bias.
          scale[f] = gamma[f] / std::sqrt(var[f] + 0.00001f);
          c.bias[f] -= mean[f] * scale[f];
        }
      }
      const std::size_t per_filter =
          static_cast<std::size_t>(in.c / c.groups) * static_cast<std::size_t>(c.size * c.size);
      c.weights = wf.floats(per_filter * n, what + " weights");
      for (std::size_t f = 0; f < n; ++f) {
        for (std::size_t k = 0; k < per_filter; ++k) c.weights[f * per_filter + k] *= scale[f];
      }
      out = add_tensor(o);
      c.dst = out;
      conv_node_of_tensor[static_cast<std::size_t>(out)] = static_cast<int>(g.nodes.size());
      summary << i << " conv " << c.filters << " " << c.size << "x" << c.size << "/" << c.stride
              << (c.groups > 1 ? " g" + std::to_string(c.groups) : std::string()) << "  " << in.w
              << "x" << in.h << "x" << in.c << " -> " << o.w << "x" << o.h << "x" << o.c << "\n";
      g.nodes.emplace_back(std::move(c));
    } else if (s.type == "shortcut") {
      const int from = resolve(r, "from", i, r.get_int("from"));
      if (parse_activation(r, "activation") != Activation::kLinear) {
        r.fail("activation", "only linear shortcuts are supported");
      }
      for (const char* key : {"weights_type", "weights_normalization"}) {
        if (r.has(key)) r.fail(key, "weighted shortcuts are not supported");
      }
      const int other = layer_tensor[static_cast<std::size_t>(from)];
      const Shape& os = g.shapes[static_cast<std::size_t>(other)];
      if (os.c != in.c || os.h != in.h || os.w != in.w) {
        r.fail("from", "adds layers of different shapes");
      }
      const int producer = conv_node_of_tensor[static_cast<std::size_t>(cur)];
      const bool sole_reader =
          readers[static_cast<std::size_t>(root[static_cast<std::size_t>(i - 1)])] == 1;
      if (producer >= 0 && sole_reader) {
        // The addition runs as the convolution's post-op, into its own output.
        std::get<ConvNode>(g.nodes[static_cast<std::size_t>(producer)]).addend = other;
        conv_node_of_tensor[static_cast<std::size_t>(cur)] = -1;
        out = cur;
      } else {
        out = add_tensor(in);
        g.nodes.emplace_back(AddNode{cur, other, out});
      }
      summary << i << " shortcut " << from << (producer >= 0 && sole_reader ? " (fused)" : "")
              << "\n";
    } else if (s.type == "route") {
      std::vector<int> srcs;
      for (int l : r.get_ints("layers")) {
        srcs.push_back(layer_tensor[static_cast<std::size_t>(resolve(r, "layers", i, l))]);
      }
      for (const char* key : {"groups", "group_id"}) {
        if (r.has(key)) r.fail(key, "grouped routes are not supported");
      }
      if (srcs.size() == 1) {
        out = srcs.front();
      } else {
        Shape o = g.shapes[static_cast<std::size_t>(srcs.front())];
        o.c = 0;
        for (int t : srcs) {
          const Shape& ts = g.shapes[static_cast<std::size_t>(t)];
          if (ts.h != o.h || ts.w != o.w) r.fail("layers", "routes layers of different sizes");
          o.c += ts.c;
        }
        out = add_tensor(o);
        g.nodes.emplace_back(ConcatNode{srcs, out});
      }
      const Shape& o = g.shapes[static_cast<std::size_t>(out)];
      summary << i << " route -> " << o.w << "x" << o.h << "x" << o.c << "\n";
    } else if (s.type == "maxpool") {
      PoolNode p;
      p.src = cur;
      p.size = r.get_int("size", 1);
      p.stride = r.get_int("stride", 1);
      p.pad = r.get_int("padding", p.size - 1);
      if (p.size <= 0) r.fail("size", "must be positive");
      if (p.stride <= 0) r.fail("stride", "must be positive");
      if (p.pad < 0) r.fail("padding", "must not be negative");
      for (const char* key : {"stride_x", "stride_y", "maxpool_depth", "antialiasing"}) {
        if (r.has(key)) r.fail(key, "not supported");
      }
      const Shape o{in.c, (in.h + p.pad - p.size) / p.stride + 1,
                    (in.w + p.pad - p.size) / p.stride + 1};
      if (o.h <= 0 || o.w <= 0) r.fail("size", "larger than the layer's input");
      out = add_tensor(o);
      p.dst = out;
      g.nodes.emplace_back(p);
      summary << i << " maxpool " << p.size << "/" << p.stride << "\n";
    } else if (s.type == "upsample") {
      UpsampleNode u;
      u.src = cur;
      u.stride = r.get_int("stride", 2);
      if (u.stride <= 0) r.fail("stride", "must be positive (down-sampling is not supported)");
      if (r.has("scale")) r.fail("scale", "not supported");
      out = add_tensor({in.c, in.h * u.stride, in.w * u.stride});
      u.dst = out;
      g.nodes.emplace_back(u);
      summary << i << " upsample " << u.stride << "\n";
    } else if (s.type == "dropout") {
      out = cur;
    } else if (s.type == "yolo") {
      YoloHead h;
      h.tensor = cur;
      h.shape = in;
      h.classes = r.get_int("classes");
      const int num = r.get_int("num", 1);
      const std::vector<int> mask = r.get_ints("mask");
      const std::vector<int> anchors = r.get_ints("anchors");
      h.scale_x_y = r.get_float("scale_x_y", 1.0f);
      if (h.classes <= 0) r.fail("classes", "must be positive");
      if (static_cast<int>(anchors.size()) != 2 * num) {
        r.fail("anchors", "needs num (" + std::to_string(num) + ") pairs");
      }
      for (int k : mask) {
        if (k < 0 || k >= num) r.fail("mask", "anchor index " + std::to_string(k) + " >= num");
        h.anchors.push_back(static_cast<float>(anchors[static_cast<std::size_t>(2 * k)]));
        h.anchors.push_back(static_cast<float>(anchors[static_cast<std::size_t>(2 * k + 1)]));
      }
      if (in.c != static_cast<int>(mask.size()) * (5 + h.classes)) {
        r.fail("mask", "the layer before has " + std::to_string(in.c) + " channels, expected " +
                           std::to_string(mask.size() * (5 + static_cast<std::size_t>(h.classes))));
      }
      if (r.get_int("new_coords", 0) != 0) r.fail("new_coords", "not supported");
      if (!g.heads.empty() && g.heads.front().classes != h.classes) {
        r.fail("classes", "differs between the [yolo] layers");
      }
      g.heads.push_back(h);
      out = cur;
      summary << i << " yolo " << in.w << "x" << in.h << "\n";
    } else {
      throw Error::at(cfg, s.line, "", "layer type [" + s.type + "] is not supported");
    }
    layer_tensor[static_cast<std::size_t>(i)] = out;
    cur = out;
  }
  wf.expect_end();
  if (g.heads.empty()) throw Error::at(cfg, 0, "", "the network has no [yolo] layer");
  g.summary = summary.str();
  return g;
}

dnnl::algorithm leaky_relu() { return dnnl::algorithm::eltwise_relu; }

}  // namespace

namespace {

// OpenMP's thread count for the calling thread while in scope (n > 0), restored afterwards.
class ThreadScope {
 public:
  explicit ThreadScope(int n) : saved_(n > 0 ? omp_get_max_threads() : 0) {
    if (n > 0) omp_set_num_threads(n);
  }
  ~ThreadScope() {
    if (saved_ > 0) omp_set_num_threads(saved_);
  }
  ThreadScope(const ThreadScope&) = delete;
  ThreadScope& operator=(const ThreadScope&) = delete;

 private:
  int saved_;
};

}  // namespace

struct DarknetOneDnn::Impl {
  dnnl::engine eng{dnnl::engine::kind::cpu, 0};
  dnnl::stream strm{eng};
  int width = 0, height = 0, channels = 0, threads = 1;
  std::string cfg;
  Graph graph;
  bool int8 = false;
  // Activations, NHWC: graph tensor i is tensors[i] (f32, or s8 in int8 mode where every reader
  // is an int8 convolution); int8 mode adds s8 copies of f32 tensors after them.
  std::vector<dnnl::memory> tensors;
  std::vector<float> scale;  // per tensor: s8 value = x * scale (int8 mode)
  std::vector<std::pair<dnnl::primitive, std::unordered_map<int, dnnl::memory>>> steps;
  std::vector<YoloHeadRows> rows;

  dnnl::memory::desc desc(int t) const { return tensors[static_cast<std::size_t>(t)].get_desc(); }
  const dnnl::memory& mem(int t) const { return tensors[static_cast<std::size_t>(t)]; }
  bool is_s8(int t) const { return desc(t).data_type() == dt::s8; }
  const Shape& shape(int t) const { return graph.shapes[static_cast<std::size_t>(t)]; }

  // `src` and `dst` are tensor indices (an s8 source makes an int8 convolution).
  void add_conv(const ConvNode& c, int src, int dst) {
    const Shape& in = shape(c.src);
    const bool q = is_s8(src);
    const dnnl::memory::dims wdims =
        c.groups == 1
            ? dnnl::memory::dims{c.filters, in.c, c.size, c.size}
            : dnnl::memory::dims{c.groups, c.filters / c.groups, in.c / c.groups, c.size, c.size};
    const dt wdt = q ? dt::s8 : dt::f32;
    const dnnl::memory::desc bias_md({c.filters}, dt::f32, tag::x);
    const dnnl::convolution_forward::desc d(
        dnnl::prop_kind::forward_inference, dnnl::algorithm::convolution_direct, desc(src),
        dnnl::memory::desc(wdims, wdt, tag::any), bias_md, desc(dst), {c.stride, c.stride},
        {c.pad, c.pad}, {c.pad, c.pad});
    dnnl::post_ops po;
    if (c.act == Activation::kLeaky) po.append_eltwise(1.0f, leaky_relu(), 0.1f, 0.0f);
    if (c.addend >= 0) po.append_binary(dnnl::algorithm::binary_add, desc(c.addend));
    dnnl::primitive_attr attr;
    attr.set_post_ops(po);
    std::vector<float> bias = c.bias;
    dnnl::memory user_w({wdims, wdt, c.groups == 1 ? tag::oihw : tag::goihw}, eng);
    if (q) {
      // Per output channel symmetric weights; oneDNN 2.x adds the bias to the accumulator
      // before the output scale, so it is given in the accumulator's units.
      const std::size_t per = c.weights.size() / static_cast<std::size_t>(c.filters);
      const float s_in = scale[static_cast<std::size_t>(src)];
      const float s_out = is_s8(dst) ? scale[static_cast<std::size_t>(dst)] : 1.0f;
      std::vector<float> out_scales(static_cast<std::size_t>(c.filters));
      auto* w8 = static_cast<std::int8_t*>(user_w.get_data_handle());
      for (std::size_t f = 0; f < out_scales.size(); ++f) {
        const float* w = c.weights.data() + f * per;
        float m = 0.0f;
        for (std::size_t k = 0; k < per; ++k) m = std::max(m, std::abs(w[k]));
        const float s_w = m > 0.0f ? 127.0f / m : 1.0f;
        for (std::size_t k = 0; k < per; ++k) {
          w8[f * per + k] = static_cast<std::int8_t>(std::lround(w[k] * s_w));
        }
        bias[f] *= s_in * s_w;
        out_scales[f] = s_out / (s_in * s_w);
      }
      attr.set_output_scales(1 << 1, out_scales);
    } else {
      std::memcpy(user_w.get_data_handle(), c.weights.data(), c.weights.size() * sizeof(float));
    }
    const dnnl::convolution_forward::primitive_desc pd(d, attr, eng);
    dnnl::memory w = user_w;
    if (pd.weights_desc() != user_w.get_desc()) {
      w = dnnl::memory(pd.weights_desc(), eng);
      dnnl::reorder(user_w, w).execute(strm, user_w, w);
    }
    dnnl::memory b(bias_md, eng);
    std::memcpy(b.get_data_handle(), bias.data(), bias.size() * sizeof(float));
    std::unordered_map<int, dnnl::memory> args{{DNNL_ARG_SRC, mem(src)},
                                               {DNNL_ARG_WEIGHTS, w},
                                               {DNNL_ARG_BIAS, b},
                                               {DNNL_ARG_DST, mem(dst)}};
    if (c.addend >= 0) {
      const int index = c.act == Activation::kLeaky ? 1 : 0;
      args[DNNL_ARG_ATTR_MULTIPLE_POST_OP(index) | DNNL_ARG_SRC_1] = mem(c.addend);
    }
    steps.emplace_back(dnnl::convolution_forward(pd), std::move(args));
  }

  // Builds the primitives: fp32 when `absmax` is empty, else int8 where it pays (see
  // quantize_int8) with per-tensor scales 127 / absmax.
  void build(const std::vector<float>& absmax) {
    const Graph& g = graph;
    const std::size_t n = g.shapes.size();
    dnnl::memory input = tensors.empty() ? dnnl::memory() : tensors.front();
    tensors.clear();
    steps.clear();
    scale.assign(n, 1.0f);
    // Which tensors are s8: produced by a convolution without a fused shortcut from a tensor
    // other than the input, and read only as the source of convolutions.
    std::vector<bool> s8(n, false);
    if (!absmax.empty()) {
      std::vector<int> producer(n, -1);
      std::vector<bool> conv_only(n, true);
      std::vector<int> readers(n, 0);
      for (std::size_t i = 0; i < g.nodes.size(); ++i) {
        const Node& node = g.nodes[i];
        auto read_other = [&](int t) { conv_only[static_cast<std::size_t>(t)] = false; };
        if (const auto* c = std::get_if<ConvNode>(&node)) {
          ++readers[static_cast<std::size_t>(c->src)];
          if (c->addend >= 0) {
            read_other(c->addend);
          } else if (c->src != 0) {
            producer[static_cast<std::size_t>(c->dst)] = static_cast<int>(i);
          }
        } else if (const auto* a = std::get_if<AddNode>(&node)) {
          read_other(a->a);
          read_other(a->b);
        } else if (const auto* k = std::get_if<ConcatNode>(&node)) {
          for (int t : k->srcs) read_other(t);
        } else if (const auto* p = std::get_if<PoolNode>(&node)) {
          read_other(p->src);
        } else if (const auto* u = std::get_if<UpsampleNode>(&node)) {
          read_other(u->src);
        }
      }
      for (const YoloHead& h : g.heads) conv_only[static_cast<std::size_t>(h.tensor)] = false;
      for (std::size_t t = 1; t < n; ++t) {
        // Only at 1/8 of the input resolution or coarser: the earlier stages are thin (4 to 32
        // channels), where 8 bits lose the most accuracy and save the least time.
        const bool coarse = g.shapes[t].h * 8 <= height && g.shapes[t].w * 8 <= width;
        s8[t] = producer[t] >= 0 && conv_only[t] && readers[t] > 0 && absmax[t] > 0.0f && coarse;
        scale[t] = absmax[t] > 0.0f ? 127.0f / absmax[t] : 1.0f;
      }
    }
    for (std::size_t t = 0; t < n; ++t) {
      const Shape& s = g.shapes[t];
      if (t == 0 && input) {
        tensors.push_back(input);
        continue;
      }
      tensors.emplace_back(
          dnnl::memory::desc({1, s.c, s.h, s.w}, s8[t] ? dt::s8 : dt::f32, tag::nhwc), eng);
    }
    std::vector<int> copy_of(n, -1);  // s8 copy of an f32 tensor, made before its first use
    auto s8_copy = [&](int t) {
      int& c = copy_of[static_cast<std::size_t>(t)];
      if (c >= 0) return c;
      const Shape& s = shape(t);
      tensors.emplace_back(dnnl::memory::desc({1, s.c, s.h, s.w}, dt::s8, tag::nhwc), eng);
      c = static_cast<int>(tensors.size()) - 1;
      scale.push_back(scale[static_cast<std::size_t>(t)]);
      dnnl::primitive_attr attr;
      attr.set_output_scales(0, {scale[static_cast<std::size_t>(t)]});
      steps.emplace_back(
          dnnl::reorder(dnnl::reorder::primitive_desc(mem(t), mem(c), attr)),
          std::unordered_map<int, dnnl::memory>{{DNNL_ARG_FROM, mem(t)}, {DNNL_ARG_TO, mem(c)}});
      return c;
    };
    for (const Node& node : g.nodes) {
      if (const auto* c = std::get_if<ConvNode>(&node)) {
        int src = c->src;
        if (s8[static_cast<std::size_t>(c->dst)] && !is_s8(src)) src = s8_copy(src);
        add_conv(*c, src, c->dst);
      } else if (const auto* a = std::get_if<AddNode>(&node)) {
        const dnnl::binary::desc d(dnnl::algorithm::binary_add, desc(a->a), desc(a->b),
                                   desc(a->dst));
        steps.emplace_back(dnnl::binary(dnnl::binary::primitive_desc(d, eng)),
                           std::unordered_map<int, dnnl::memory>{{DNNL_ARG_SRC_0, mem(a->a)},
                                                                 {DNNL_ARG_SRC_1, mem(a->b)},
                                                                 {DNNL_ARG_DST, mem(a->dst)}});
      } else if (const auto* k = std::get_if<ConcatNode>(&node)) {
        std::vector<dnnl::memory::desc> mds;
        std::unordered_map<int, dnnl::memory> args{{DNNL_ARG_DST, mem(k->dst)}};
        for (std::size_t j = 0; j < k->srcs.size(); ++j) {
          mds.push_back(desc(k->srcs[j]));
          args[DNNL_ARG_MULTIPLE_SRC + static_cast<int>(j)] = mem(k->srcs[j]);
        }
        steps.emplace_back(dnnl::concat(dnnl::concat::primitive_desc(desc(k->dst), 1, mds, eng)),
                           std::move(args));
      } else if (const auto* p = std::get_if<PoolNode>(&node)) {
        const Shape& in = shape(p->src);
        const Shape& o = shape(p->dst);
        // Darknet pads by pad/2 before and the rest after; padding never wins a max.
        const int before = p->pad / 2;
        const int after_h = (o.h - 1) * p->stride + p->size - in.h - before;
        const int after_w = (o.w - 1) * p->stride + p->size - in.w - before;
        const dnnl::pooling_forward::desc d(
            dnnl::prop_kind::forward_inference, dnnl::algorithm::pooling_max, desc(p->src),
            desc(p->dst), {p->stride, p->stride}, {p->size, p->size}, {before, before},
            {std::max(after_h, 0), std::max(after_w, 0)});
        steps.emplace_back(dnnl::pooling_forward(dnnl::pooling_forward::primitive_desc(d, eng)),
                           std::unordered_map<int, dnnl::memory>{{DNNL_ARG_SRC, mem(p->src)},
                                                                 {DNNL_ARG_DST, mem(p->dst)}});
      } else if (const auto* u = std::get_if<UpsampleNode>(&node)) {
        const dnnl::resampling_forward::desc d(dnnl::prop_kind::forward_inference,
                                               dnnl::algorithm::resampling_nearest, desc(u->src),
                                               desc(u->dst));
        steps.emplace_back(
            dnnl::resampling_forward(dnnl::resampling_forward::primitive_desc(d, eng)),
            std::unordered_map<int, dnnl::memory>{{DNNL_ARG_SRC, mem(u->src)},
                                                  {DNNL_ARG_DST, mem(u->dst)}});
      }
    }
    strm.wait();
    int8 = !absmax.empty();
  }

  void run() {
    for (auto& [prim, args] : steps) prim.execute(strm, args);
    strm.wait();
  }
};

DarknetOneDnn::DarknetOneDnn(const std::string& cfg, const std::string& weights, int width,
                             int height, const DarknetOneDnnOptions& options)
    : impl_(std::make_unique<Impl>()) {
  const int threads = options.threads;
  if (threads < 0) throw Error::at("DarknetOneDnnOptions", 0, "threads", "must not be negative");
  if (!(std::isfinite(options.input_scale) && options.input_scale > 0.0f)) {
    throw Error::at("DarknetOneDnnOptions", 0, "input_scale", "must be positive");
  }
  impl_->threads = threads;
  impl_->cfg = cfg;
  if (!std::filesystem::is_regular_file(cfg)) throw Error::at(cfg, 0, "", "cfg file not found");
  if (!std::filesystem::is_regular_file(weights)) {
    throw Error::at(weights, 0, "", "weights file not found");
  }
  Graph g = build_graph(cfg, weights, width, height);
  {
    // The input transform, folded into layer 0 (a convolution of tensor 0; build_graph checks).
    ConvNode& first = std::get<ConvNode>(g.nodes.front());
    const std::size_t ic = static_cast<std::size_t>(g.channels / first.groups);
    const std::size_t kk =
        static_cast<std::size_t>(first.size) * static_cast<std::size_t>(first.size);
    if (options.swap_rb && (g.channels != 3 || first.groups != 1)) {
      throw Error::at(cfg, 0, "", "swap_rb needs a 3-channel input and an ungrouped first layer");
    }
    for (std::size_t f = 0; f < static_cast<std::size_t>(first.filters); ++f) {
      float* w = first.weights.data() + f * ic * kk;
      for (std::size_t k = 0; k < ic * kk; ++k) w[k] *= options.input_scale;
      if (options.swap_rb) std::swap_ranges(w, w + kk, w + 2 * kk);
    }
  }
  // oneDNN fixes a primitive's thread count when it creates it: the primitives are made under
  // `threads` too, not only run under it.
  const ThreadScope scope(threads);
  Impl& m = *impl_;
  m.width = width;
  m.height = height;
  m.channels = g.channels;
  m.graph = std::move(g);
  try {
    m.build({});
  } catch (const dnnl::error& e) {
    throw Error::at(cfg, 0, "", std::string("oneDNN cannot build this network: ") + e.what());
  }
  for (const YoloHead& h : m.graph.heads) {
    YoloHeadRows r;
    r.rows = h.shape.h * h.shape.w * static_cast<int>(h.anchors.size() / 2);
    r.cols = 5 + h.classes;
    r.data.assign(static_cast<std::size_t>(r.rows) * static_cast<std::size_t>(r.cols), 0.0f);
    m.rows.push_back(std::move(r));
  }
}

void DarknetOneDnn::quantize_int8(const std::function<void(std::size_t, float*)>& fill,
                                  std::size_t count) {
  Impl& m = *impl_;
  if (m.int8) throw Error::at(m.cfg, 0, "", "quantize_int8: the network is already int8");
  if (count == 0) throw Error::at(m.cfg, 0, "", "quantize_int8 needs calibration inputs");
  const ThreadScope scope(m.threads);
  std::vector<float> absmax(m.graph.shapes.size(), 0.0f);
  for (std::size_t i = 0; i < count; ++i) {
    fill(i, input());
    m.run();
    for (std::size_t t = 1; t < absmax.size(); ++t) {
      const auto* x = static_cast<const float*>(m.tensors[t].get_data_handle());
      const Shape& s = m.graph.shapes[t];
      const std::size_t len = static_cast<std::size_t>(s.c) * s.h * s.w;
      float a = absmax[t];
      for (std::size_t k = 0; k < len; ++k) a = std::max(a, std::abs(x[k]));
      absmax[t] = a;
    }
  }
  try {
    m.build(absmax);
  } catch (const dnnl::error& e) {
    throw Error::at(m.cfg, 0, "", std::string("oneDNN cannot build the int8 network: ") + e.what());
  }
}

bool DarknetOneDnn::int8() const { return impl_->int8; }

DarknetOneDnn::~DarknetOneDnn() = default;

int DarknetOneDnn::width() const { return impl_->width; }
int DarknetOneDnn::height() const { return impl_->height; }
int DarknetOneDnn::channels() const { return impl_->channels; }
int DarknetOneDnn::classes() const { return impl_->graph.heads.front().classes; }
float* DarknetOneDnn::input() {
  return static_cast<float*>(impl_->tensors.front().get_data_handle());
}
std::string DarknetOneDnn::summary() const { return impl_->graph.summary; }

namespace {
inline float sigmoid(float x) { return 1.0f / (1.0f + std::exp(-x)); }
}  // namespace

const std::vector<YoloHeadRows>& DarknetOneDnn::forward(float score_floor) {
  Impl& m = *impl_;
  const ThreadScope scope(m.threads);
  m.run();
  for (std::size_t k = 0; k < m.graph.heads.size(); ++k) {
    const YoloHead& h = m.graph.heads[k];
    YoloHeadRows& out = m.rows[k];
    const float* src = static_cast<const float*>(m.mem(h.tensor).get_data_handle());
    const int anchors = static_cast<int>(h.anchors.size() / 2);
    const int per_anchor = 5 + h.classes;
    const float s = h.scale_x_y, shift = -0.5f * (s - 1.0f);
    int row = 0;
    for (int y = 0; y < h.shape.h; ++y) {
      for (int x = 0; x < h.shape.w; ++x) {
        const float* cell = src + (static_cast<std::size_t>(y) * h.shape.w + x) * h.shape.c;
        for (int a = 0; a < anchors; ++a, ++row) {
          const float* v = cell + a * per_anchor;
          float* o = out.data.data() + static_cast<std::size_t>(row) * out.cols;
          o[0] =
              (static_cast<float>(x) + sigmoid(v[0]) * s + shift) / static_cast<float>(h.shape.w);
          o[1] =
              (static_cast<float>(y) + sigmoid(v[1]) * s + shift) / static_cast<float>(h.shape.h);
          o[2] = std::exp(v[2]) * h.anchors[static_cast<std::size_t>(2 * a)] /
                 static_cast<float>(m.width);
          o[3] = std::exp(v[3]) * h.anchors[static_cast<std::size_t>(2 * a + 1)] /
                 static_cast<float>(m.height);
          const float obj = sigmoid(v[4]);
          o[4] = obj;
          if (obj < score_floor) {
            std::fill(o + 5, o + out.cols, 0.0f);
          } else {
            for (int c = 0; c < h.classes; ++c) o[5 + c] = obj * sigmoid(v[5 + c]);
          }
        }
      }
    }
  }
  return m.rows;
}

}  // namespace kestrel::detect
