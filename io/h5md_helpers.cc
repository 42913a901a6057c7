// The HDF5 helpers of the H5MD writer and reader (declared in
// h5md_internal.h): error status, string types and attributes, groups,
// extendable series with one record per append, dataset dimensions,
// read-only opening and scalar string datasets.
#include <hdf5.h>

#include <algorithm>
#include <string>
#include <string_view>
#include <vector>

#include "io/h5_handle.h"
#include "io/h5md_internal.h"

namespace cellflow::io::detail {

Status h5_error(const std::string& what, const std::string& path) {
  return {StatusCode::kInternal, "HDF5: " + what + " (" + path + ")"};
}

// A fixed-length, null-terminated string type of `size` bytes.
Handle string_type(std::size_t size) {
  Handle type(H5Tcopy(H5T_C_S1));
  H5Tset_size(type.get(), std::max<std::size_t>(size, 1));
  H5Tset_strpad(type.get(), H5T_STR_NULLTERM);
  return type;
}

Status write_string_attribute(hid_t object, const char* name, std::string_view value) {
  Handle type = string_type(value.size() + 1);
  Handle space(H5Screate(H5S_SCALAR));
  std::string buffer(value);
  Handle attr(H5Acreate2(object, name, type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT));
  if (!attr.valid() || H5Awrite(attr.get(), type.get(), buffer.c_str()) < 0) {
    return h5_error(std::string("writing attribute ") + name, "");
  }
  return {};
}

Status write_int_attribute(hid_t object, const char* name, std::span<const int> values) {
  hsize_t dims[1] = {values.size()};
  Handle space(values.size() == 1 ? H5Screate(H5S_SCALAR) : H5Screate_simple(1, dims, nullptr));
  Handle attr(H5Acreate2(object, name, H5T_STD_I32LE, space.get(), H5P_DEFAULT, H5P_DEFAULT));
  if (!attr.valid() || H5Awrite(attr.get(), H5T_NATIVE_INT, values.data()) < 0) {
    return h5_error(std::string("writing attribute ") + name, "");
  }
  return {};
}

Handle create_group(hid_t file, const std::string& path) {
  Handle lcpl(H5Pcreate(H5P_LINK_CREATE));
  H5Pset_create_intermediate_group(lcpl.get(), 1);
  return Handle(H5Gcreate2(file, path.c_str(), lcpl.get(), H5P_DEFAULT, H5P_DEFAULT));
}

StatusOr<Series> create_series(hid_t file, const std::string& path, hid_t file_type, hid_t memory_type,
                               std::vector<hsize_t> record_dims) {
  const int rank = 1 + static_cast<int>(record_dims.size());
  std::vector<hsize_t> dims(rank, 0), max_dims(rank), chunk(rank);
  max_dims[0] = H5S_UNLIMITED;
  hsize_t record_size = 1;
  for (std::size_t i = 0; i < record_dims.size(); ++i) {
    dims[i + 1] = max_dims[i + 1] = chunk[i + 1] = record_dims[i];
    record_size *= record_dims[i];
  }
  // 64 small records (512 B of doubles) per chunk: curves have tens to
  // thousands of points; one record per chunk for position frames.
  chunk[0] = std::max<hsize_t>(1, 64 / std::max<hsize_t>(record_size, 1));
  Handle space(H5Screate_simple(rank, dims.data(), max_dims.data()));
  Handle dcpl(H5Pcreate(H5P_DATASET_CREATE));
  H5Pset_chunk(dcpl.get(), rank, chunk.data());
  Handle lcpl(H5Pcreate(H5P_LINK_CREATE));
  H5Pset_create_intermediate_group(lcpl.get(), 1);
  Series series;
  series.dataset =
      Handle(H5Dcreate2(file, path.c_str(), file_type, space.get(), lcpl.get(), dcpl.get(), H5P_DEFAULT));
  if (!series.dataset.valid()) return h5_error("creating dataset " + path, "");
  series.record_dims = std::move(record_dims);
  series.memory_type = memory_type;
  return series;
}

Status append_record(Series& series, const void* data) {
  const int rank = 1 + static_cast<int>(series.record_dims.size());
  std::vector<hsize_t> dims(rank), start(rank, 0), count(rank);
  dims[0] = series.records + 1;
  start[0] = series.records;
  count[0] = 1;
  for (std::size_t i = 0; i < series.record_dims.size(); ++i)
    dims[i + 1] = count[i + 1] = series.record_dims[i];
  if (H5Dset_extent(series.dataset.get(), dims.data()) < 0) return h5_error("extending dataset", "");
  Handle file_space(H5Dget_space(series.dataset.get()));
  H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start.data(), nullptr, count.data(), nullptr);
  Handle memory_space(H5Screate_simple(rank, count.data(), nullptr));
  if (H5Dwrite(series.dataset.get(), series.memory_type, memory_space.get(), file_space.get(), H5P_DEFAULT,
               data) < 0) {
    return h5_error("writing record", "");
  }
  ++series.records;
  return {};
}

StatusOr<std::vector<hsize_t>> dataset_dims(hid_t file, const std::string& path) {
  if (!path_exists(file, path)) return Status(StatusCode::kNotFound, "no dataset " + path);
  Handle dataset(H5Dopen2(file, path.c_str(), H5P_DEFAULT));
  if (!dataset.valid()) return Status(StatusCode::kNotFound, "cannot open dataset " + path);
  Handle space(H5Dget_space(dataset.get()));
  const int rank = H5Sget_simple_extent_ndims(space.get());
  std::vector<hsize_t> dims(std::max(rank, 0));
  H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr);
  return dims;
}

StatusOr<Handle> open_read_only(const std::string& path) {
  hid_t file = H5I_INVALID_HID;
  H5E_BEGIN_TRY {
    file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  }
  H5E_END_TRY;
  if (file < 0) return Status(StatusCode::kNotFound, "cannot open HDF5 file " + path);
  return Handle(file);
}

// A scalar string dataset at `path` (intermediate groups created).
StatusOr<Handle> write_string_dataset(hid_t file, const std::string& path, std::string_view value) {
  if (path_exists(file, path)) return Status(StatusCode::kFailedPrecondition, path + " already written");
  Handle type = string_type(value.size() + 1);
  Handle space(H5Screate(H5S_SCALAR));
  Handle lcpl(H5Pcreate(H5P_LINK_CREATE));
  H5Pset_create_intermediate_group(lcpl.get(), 1);
  Handle dataset(
      H5Dcreate2(file, path.c_str(), type.get(), space.get(), lcpl.get(), H5P_DEFAULT, H5P_DEFAULT));
  std::string buffer(value);
  if (!dataset.valid() ||
      H5Dwrite(dataset.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, buffer.c_str()) < 0) {
    return h5_error("writing " + path, "");
  }
  return dataset;
}

StatusOr<std::string> read_string_dataset(hid_t file, const std::string& path) {
  if (!path_exists(file, path)) return Status(StatusCode::kNotFound, "no " + path);
  Handle dataset(H5Dopen2(file, path.c_str(), H5P_DEFAULT));
  Handle type(H5Dget_type(dataset.get()));
  if (H5Tget_class(type.get()) != H5T_STRING) return Status(StatusCode::kInternal, path + " is not a string");
  std::string buffer(H5Tget_size(type.get()), '\0');
  if (H5Dread(dataset.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, buffer.data()) < 0) {
    return h5_error("reading " + path, "");
  }
  buffer.resize(buffer.find('\0') == std::string::npos ? buffer.size() : buffer.find('\0'));
  return buffer;
}

}  // namespace cellflow::io::detail
