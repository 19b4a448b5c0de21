#pragma once
// One entry point for every dataset: "tum:DIR", "euroc:DIR", "tumvi:DIR", "openloris:DIR",
// "kestrel:DIR", or a bare DIR whose layout says what it is (see detect_dataset_kind).
#include <memory>
#include <string>

#include "io/measurement_source.hpp"

namespace kestrel::io {

enum class DatasetKind { kTum, kEuroc, kTumVi, kOpenLoris, kKestrel };

const char* dataset_kind_name(DatasetKind kind);

struct DatasetOptions {
  std::string config_file;  // calibration override, passed to the reader
};

// Looks at the folder: calib.yaml + rgb.txt -> kestrel; color.txt + aligned_depth.txt ->
// openloris; mav0/ or cam0/data.csv -> euroc, or tumvi when the folder is named
// "dataset-..." (TUM-VI's naming) or has dso/camchain.yaml; rgb.txt + depth.txt or an
// association file -> tum. Throws kestrel::Error naming DIR when none fits.
DatasetKind detect_dataset_kind(const std::string& dir);

std::unique_ptr<MeasurementSource> open_dataset(const std::string& spec,
                                                const DatasetOptions& options = {});

}  // namespace kestrel::io
