#pragma once
// Typed access to YAML files the dataset readers meet (Kalibr camchains, OpenLORIS
// sensors.yaml and trans_matrix.yaml, ASL sensor.yaml extrinsics), with errors naming
// file:line:field. Include only in .cpp files: it pulls in yaml-cpp.
#include <yaml-cpp/yaml.h>

#include <string>
#include <vector>

#include "core/se3.hpp"

namespace kestrel::io {

class YamlFile {
 public:
  // Reads and parses; OpenCV's "%YAML:1.0" first line is accepted.
  static YamlFile read(const std::string& path);
  static YamlFile parse(const std::string& text, const std::string& name_for_errors);

  const YAML::Node& root() const { return root_; }
  const std::string& name() const { return name_; }

  [[noreturn]] void fail(const YAML::Node& node, const std::string& field,
                         const std::string& message) const;
  // node[key], or an error naming `field` at `node` when it is missing.
  YAML::Node require(const YAML::Node& node, const std::string& key,
                     const std::string& field) const;
  double number(const YAML::Node& node, const std::string& field) const;
  // A whole number in [lo, hi] (an image size: a double beyond int's range makes the cast
  // undefined), read from `node`, or `v` already read from it.
  int whole(const YAML::Node& node, const std::string& field, int lo, int hi) const;
  int whole(double v, const YAML::Node& node, const std::string& field, int lo, int hi) const;
  std::string text(const YAML::Node& node, const std::string& field) const;
  // A list of numbers, or an OpenCV matrix {rows, cols, data: [...]}.
  std::vector<double> numbers(const YAML::Node& node, const std::string& field) const;
  // A 4x4 (or 3x4) transform: 16/12 numbers, a list of rows, or an OpenCV matrix. The rotation
  // block is re-orthonormalized (calibration files print ~10 digits).
  SE3 transform(const YAML::Node& node, const std::string& field) const;

 private:
  std::string name_;
  YAML::Node root_;
};

}  // namespace kestrel::io
