// Internal to cellflow::io, shared by the H5MD writer (h5md_writer.cc) and
// reader (h5md_reader.cc) and defined in h5md_helpers.cc; not part of the
// public API (io/h5md.h): HDF5 error status, string types and attributes,
// groups, extendable series of records, dataset dimensions, read-only opening
// and scalar string datasets.
#pragma once

#include <hdf5.h>

#include <cstddef>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "io/h5_handle.h"
#include "physics/core/status.h"

namespace cellflow::io::detail {

// kInternal "HDF5: what (path)".
Status h5_error(const std::string& what, const std::string& path);

// A fixed-length, null-terminated string type of `size` bytes.
Handle string_type(std::size_t size);

// A scalar string attribute; an integer attribute (scalar for one value).
Status write_string_attribute(hid_t object, const char* name, std::string_view value);
Status write_int_attribute(hid_t object, const char* name, std::span<const int> values);

// The group at `path`, intermediate groups created.
Handle create_group(hid_t file, const std::string& path);

// An extendable dataset whose first dimension grows by one record per append.
struct Series {
  Handle dataset;
  std::vector<hsize_t> record_dims;  // dims of one record (may be empty: scalar)
  hsize_t records = 0;
  hid_t memory_type = H5I_INVALID_HID;
};

// An empty series at `path` (intermediate groups created); append_record
// writes one more record.
StatusOr<Series> create_series(hid_t file, const std::string& path, hid_t file_type, hid_t memory_type,
                               std::vector<hsize_t> record_dims);
Status append_record(Series& series, const void* data);

// The dimensions of the dataset at `path` (kNotFound without one).
StatusOr<std::vector<hsize_t>> dataset_dims(hid_t file, const std::string& path);

// The HDF5 file at `path`, read-only (kNotFound if it cannot be opened).
StatusOr<Handle> open_read_only(const std::string& path);

// A scalar string dataset at `path` (intermediate groups created), and its reading.
StatusOr<Handle> write_string_dataset(hid_t file, const std::string& path, std::string_view value);
StatusOr<std::string> read_string_dataset(hid_t file, const std::string& path);

}  // namespace cellflow::io::detail
