#include "io/yaml_fields.hpp"

#include <Eigen/SVD>
#include <cmath>
#include <fstream>
#include <sstream>

#include "core/error.hpp"

namespace kestrel::io {

YamlFile YamlFile::read(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error::at(path, 0, "", "cannot open file");
  std::stringstream ss;
  ss << in.rdbuf();
  return parse(ss.str(), path);
}

YamlFile YamlFile::parse(const std::string& text_in, const std::string& name) {
  std::string text = text_in;
  // "%YAML:1.0" (OpenCV FileStorage) is not a valid YAML directive. Blank it, keeping the
  // line so that line numbers in errors match the file.
  if (text.rfind("%YAML:", 0) == 0) {
    const auto eol = text.find('\n');
    text.replace(0, eol == std::string::npos ? text.size() : eol, "");
  }
  YamlFile f;
  f.name_ = name;
  try {
    f.root_ = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw Error::at(name, e.mark.line + 1, "", "YAML syntax error: " + e.msg);
  }
  return f;
}

void YamlFile::fail(const YAML::Node& node, const std::string& field,
                    const std::string& message) const {
  int line = 0;
  if (node.IsDefined() && node.Mark().line >= 0) line = node.Mark().line + 1;
  throw Error::at(name_, line, field, message);
}

YAML::Node YamlFile::require(const YAML::Node& node, const std::string& key,
                             const std::string& field) const {
  if (!node.IsMap()) fail(node, field, "expected a map holding '" + key + "'");
  YAML::Node child = node[key];
  if (!child.IsDefined() || child.IsNull()) fail(node, field, "missing");
  return child;
}

double YamlFile::number(const YAML::Node& node, const std::string& field) const {
  if (!node.IsScalar()) fail(node, field, "expected a number");
  double v = 0.0;
  try {
    v = node.as<double>();
  } catch (const YAML::Exception&) {
    fail(node, field, "expected a number, got '" + node.Scalar() + "'");
  }
  if (!std::isfinite(v)) fail(node, field, "must be finite, got '" + node.Scalar() + "'");
  return v;
}

int YamlFile::whole(double v, const YAML::Node& node, const std::string& field, int lo,
                    int hi) const {
  if (v != std::floor(v) || v < lo || v > hi) {
    fail(node, field,
         "must be a whole number in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
  }
  return static_cast<int>(v);
}

int YamlFile::whole(const YAML::Node& node, const std::string& field, int lo, int hi) const {
  return whole(number(node, field), node, field, lo, hi);
}

std::string YamlFile::text(const YAML::Node& node, const std::string& field) const {
  if (!node.IsScalar()) fail(node, field, "expected a string");
  return node.Scalar();
}

std::vector<double> YamlFile::numbers(const YAML::Node& node, const std::string& field) const {
  if (node.IsMap()) return numbers(require(node, "data", field + ".data"), field + ".data");
  if (!node.IsSequence()) fail(node, field, "expected a list of numbers");
  std::vector<double> out;
  for (std::size_t i = 0; i < node.size(); ++i) {
    const YAML::Node item = node[i];
    if (item.IsSequence()) {  // a list of rows
      for (double v : numbers(item, field + "[" + std::to_string(i) + "]")) out.push_back(v);
    } else {
      out.push_back(number(item, field + "[" + std::to_string(i) + "]"));
    }
  }
  return out;
}

SE3 YamlFile::transform(const YAML::Node& node, const std::string& field) const {
  const std::vector<double> v = numbers(node, field);
  if (v.size() != 16 && v.size() != 12) {
    fail(node, field, "expected a 4x4 matrix (16 numbers), got " + std::to_string(v.size()));
  }
  Mat4 m = Mat4::Identity();
  for (int r = 0; r < static_cast<int>(v.size()) / 4; ++r) {
    for (int c = 0; c < 4; ++c) m(r, c) = v[static_cast<std::size_t>(r * 4 + c)];
  }
  const Mat3 R = m.topLeftCorner<3, 3>();
  if (std::abs(R.determinant() - 1.0) > 1e-3 || !(R * R.transpose()).isIdentity(1e-3)) {
    fail(node, field, "the rotation block is not a rotation");
  }
  Eigen::JacobiSVD<Mat3> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Mat3 R_clean = svd.matrixU() * svd.matrixV().transpose();
  return SE3(SO3(R_clean), Vec3(m.topRightCorner<3, 1>()));
}

}  // namespace kestrel::io
