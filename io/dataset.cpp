#include "io/dataset.hpp"

#include <filesystem>

#include "core/error.hpp"
#include "io/euroc_reader.hpp"
#include "io/kestrel_sequence.hpp"
#include "io/openloris_reader.hpp"
#include "io/rgbd_list_source.hpp"
#include "io/tum_rgbd_reader.hpp"

namespace kestrel::io {
namespace fs = std::filesystem;

const char* dataset_kind_name(DatasetKind kind) {
  switch (kind) {
    case DatasetKind::kTum:
      return "tum";
    case DatasetKind::kEuroc:
      return "euroc";
    case DatasetKind::kTumVi:
      return "tumvi";
    case DatasetKind::kOpenLoris:
      return "openloris";
    case DatasetKind::kKestrel:
      return "kestrel";
  }
  return "?";
}

DatasetKind detect_dataset_kind(const std::string& dir) {
  const fs::path d(dir);
  if (!fs::is_directory(d)) throw Error::at(dir, 0, "", "no such directory");
  auto has = [&](const char* rel) { return fs::exists(d / rel); };
  if (has("calib.yaml") && has("rgb.txt") && (has("imu.csv") || has("boxes.csv"))) {
    return DatasetKind::kKestrel;
  }
  if (has("color.txt") && has("aligned_depth.txt")) return DatasetKind::kOpenLoris;
  if (has("mav0/cam0/data.csv") || has("cam0/data.csv")) {
    const bool tumvi = folder_name(dir).rfind("dataset-", 0) == 0 || has("dso/camchain.yaml");
    return tumvi ? DatasetKind::kTumVi : DatasetKind::kEuroc;
  }
  if ((has("rgb.txt") && has("depth.txt")) || has("associations.txt") || has("association.txt")) {
    return DatasetKind::kTum;
  }
  throw Error::at(dir, 0, "",
                  "cannot tell the dataset type (no rgb.txt/depth.txt, mav0/, color.txt or "
                  "calib.yaml); prefix it with tum:, euroc:, tumvi:, openloris: or kestrel:");
}

std::unique_ptr<MeasurementSource> open_dataset(const std::string& spec,
                                                const DatasetOptions& options) {
  std::string dir = spec;
  std::optional<DatasetKind> kind;
  const auto colon = spec.find(':');
  if (colon != std::string::npos) {
    const std::string prefix = spec.substr(0, colon);
    for (DatasetKind k : {DatasetKind::kTum, DatasetKind::kEuroc, DatasetKind::kTumVi,
                          DatasetKind::kOpenLoris, DatasetKind::kKestrel}) {
      if (prefix == dataset_kind_name(k)) kind = k;
    }
    if (kind) dir = spec.substr(colon + 1);
  }
  if (dir.empty()) throw Error::at(spec, 0, "", "no dataset folder given");
  if (!kind) kind = detect_dataset_kind(dir);
  switch (*kind) {
    case DatasetKind::kTum: {
      TumRgbdOptions o;
      o.config_file = options.config_file;
      return open_tum_rgbd(dir, o);
    }
    case DatasetKind::kEuroc:
    case DatasetKind::kTumVi: {
      EurocOptions o;
      o.config_file = options.config_file;
      o.name = dataset_kind_name(*kind);
      return open_euroc(dir, o);
    }
    case DatasetKind::kOpenLoris: {
      OpenLorisOptions o;
      o.config_file = options.config_file;
      return open_openloris(dir, o);
    }
    case DatasetKind::kKestrel:
      if (!options.config_file.empty()) {
        throw Error::at(options.config_file, 0, "",
                        "a Kestrel sequence carries its own calib.yaml; no --config override");
      }
      return open_kestrel_sequence(dir);
  }
  throw Error::at(spec, 0, "", "unknown dataset kind");
}

}  // namespace kestrel::io
