// Reading back H5MD files: observables (read_observable, list_observables),
// parameters, strings and scalars, and the counts and frames of the position
// and field series.
#include <hdf5.h>

#include <algorithm>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "io/h5_handle.h"
#include "io/h5md.h"
#include "io/h5md_internal.h"

namespace cellflow::io {

using detail::dataset_dims;
using detail::h5_error;
using detail::Handle;
using detail::open_read_only;
using detail::path_exists;
using detail::read_string_dataset;

namespace {

template <class T>
Status read_all(hid_t file, const std::string& path, hid_t memory_type, std::vector<T>& out) {
  auto dims = dataset_dims(file, path);
  if (!dims.ok()) return dims.status();
  hsize_t total = 1;
  for (hsize_t d : *dims) total *= d;
  out.resize(total);
  Handle dataset(H5Dopen2(file, path.c_str(), H5P_DEFAULT));
  if (total == 0) return {};
  if (H5Dread(dataset.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()) < 0) {
    return h5_error("reading " + path, "");
  }
  return {};
}

}  // namespace

StatusOr<TimeSeries> read_observable(const std::string& path, std::string_view name) {
  auto file = open_read_only(path);
  if (!file.ok()) return file.status();
  const std::string base = "/observables/" + std::string(name);
  TimeSeries series;
  if (Status s = read_all(file->get(), base + "/step", H5T_NATIVE_INT64, series.step); !s.ok()) return s;
  if (Status s = read_all(file->get(), base + "/time", H5T_NATIVE_DOUBLE, series.time); !s.ok()) return s;
  if (Status s = read_all(file->get(), base + "/value", H5T_NATIVE_DOUBLE, series.value); !s.ok()) return s;
  auto dims = dataset_dims(file->get(), base + "/value");
  series.width = dims->size() > 1 ? static_cast<int>((*dims)[1]) : 1;
  if (series.step.size() != series.time.size() || series.value.size() != series.step.size() * series.width) {
    return Status(StatusCode::kInternal,
                  "observable " + std::string(name) + ": step/time/value lengths differ");
  }
  return series;
}

StatusOr<std::vector<std::string>> list_observables(const std::string& path) {
  auto file = open_read_only(path);
  if (!file.ok()) return file.status();
  if (!path_exists(file->get(), "/observables")) return std::vector<std::string>{};
  Handle group(H5Gopen2(file->get(), "/observables", H5P_DEFAULT));
  H5G_info_t info;
  H5Gget_info(group.get(), &info);
  std::vector<std::string> names;
  for (hsize_t i = 0; i < info.nlinks; ++i) {
    const ssize_t size =
        H5Lget_name_by_idx(group.get(), ".", H5_INDEX_NAME, H5_ITER_INC, i, nullptr, 0, H5P_DEFAULT);
    std::string name(static_cast<std::size_t>(size), '\0');
    H5Lget_name_by_idx(group.get(), ".", H5_INDEX_NAME, H5_ITER_INC, i, name.data(), name.size() + 1,
                       H5P_DEFAULT);
    names.push_back(name);
  }
  std::sort(names.begin(), names.end());
  return names;
}

StatusOr<std::string> read_parameters_json(const std::string& path) {
  return read_string(path, "/parameters/job_spec_json");
}

StatusOr<std::string> read_string(const std::string& path, std::string_view dataset) {
  auto file = open_read_only(path);
  if (!file.ok()) return file.status();
  return read_string_dataset(file->get(), std::string(dataset));
}

StatusOr<double> read_scalar(const std::string& path, std::string_view dataset) {
  auto file = open_read_only(path);
  if (!file.ok()) return file.status();
  const std::string name(dataset);
  auto dims = dataset_dims(file->get(), name);
  if (!dims.ok()) return dims.status();
  if (!dims->empty()) return Status(StatusCode::kInternal, name + " is not a scalar");
  double value = 0.0;
  Handle handle(H5Dopen2(file->get(), name.c_str(), H5P_DEFAULT));
  if (H5Dread(handle.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, &value) < 0) {
    return h5_error("reading " + name, path);
  }
  return value;
}

StatusOr<int> count_field_frames(const std::string& path, std::string_view name) {
  auto file = open_read_only(path);
  if (!file.ok()) return file.status();
  const std::string step = "/fields/" + std::string(name) + "/step";
  if (!path_exists(file->get(), step)) return 0;
  auto dims = dataset_dims(file->get(), step);
  if (!dims.ok()) return dims.status();
  return static_cast<int>((*dims)[0]);
}

StatusOr<int> count_position_frames(const std::string& path, std::string_view group) {
  auto file = open_read_only(path);
  if (!file.ok()) return file.status();
  auto dims = dataset_dims(file->get(), "/particles/" + std::string(group) + "/position/step");
  if (!dims.ok()) return dims.status();
  return static_cast<int>((*dims)[0]);
}

StatusOr<PositionFrame> read_position_frame(const std::string& path, std::string_view group, int frame) {
  auto file = open_read_only(path);
  if (!file.ok()) return file.status();
  const std::string base = "/particles/" + std::string(group) + "/position";
  std::vector<std::int64_t> steps;
  std::vector<double> times;
  if (Status s = read_all(file->get(), base + "/step", H5T_NATIVE_INT64, steps); !s.ok()) return s;
  if (Status s = read_all(file->get(), base + "/time", H5T_NATIVE_DOUBLE, times); !s.ok()) return s;
  if (frame < 0 || static_cast<std::size_t>(frame) >= steps.size()) {
    return Status(StatusCode::kNotFound, "no position frame " + std::to_string(frame));
  }
  auto dims = dataset_dims(file->get(), base + "/value");
  if (!dims.ok() || dims->size() != 3)
    return Status(StatusCode::kInternal, "position value is not [n][N][3]");
  PositionFrame out;
  out.step = steps[frame];
  out.time = times[frame];
  out.positions_m.resize((*dims)[1] * 3);
  Handle dataset(H5Dopen2(file->get(), (base + "/value").c_str(), H5P_DEFAULT));
  Handle file_space(H5Dget_space(dataset.get()));
  hsize_t start[3] = {static_cast<hsize_t>(frame), 0, 0};
  hsize_t count[3] = {1, (*dims)[1], 3};
  H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, nullptr, count, nullptr);
  Handle memory_space(H5Screate_simple(3, count, nullptr));
  if (H5Dread(dataset.get(), H5T_NATIVE_DOUBLE, memory_space.get(), file_space.get(), H5P_DEFAULT,
              out.positions_m.data()) < 0) {
    return h5_error("reading position frame", path);
  }
  return out;
}

}  // namespace cellflow::io
