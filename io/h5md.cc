#include "io/h5md.h"

#include <algorithm>
#include <array>
#include <cstdio>
#include <map>

#include "io/h5_handle.h"

namespace cellflow::io {

using detail::Handle;
using detail::path_exists;

namespace {

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

// An extendable dataset whose first dimension grows by one record per append.
struct Series {
  Handle dataset;
  std::vector<hsize_t> record_dims;  // dims of one record (may be empty: scalar)
  hsize_t records = 0;
  hid_t memory_type = H5I_INVALID_HID;
};

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

// step, time and value of one H5MD time-dependent element.
struct Element {
  Series step, time, value;
  std::size_t width = 0;
};

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

}  // namespace

struct H5mdWriter::Impl {
  Handle file;
  H5mdCreator creator;
  std::map<std::string, Element, std::less<>> elements;  // keyed by the element's path
  std::map<std::string, int, std::less<>> frames;        // position frames per particle group
  struct Field {
    Series step, time;
    UniformGrid grid;
  };
  std::map<std::string, Field, std::less<>> fields;  // vector fields by name
};

H5mdWriter::H5mdWriter(std::string path, std::unique_ptr<Impl> impl)
    : path_(std::move(path)), impl_(std::move(impl)) {}

H5mdWriter::~H5mdWriter() {
  (void)close();
}

StatusOr<std::unique_ptr<H5mdWriter>> H5mdWriter::create(const std::string& path,
                                                         const H5mdCreator& creator) {
  auto impl = std::make_unique<Impl>();
  impl->creator = creator;
  hid_t file = H5I_INVALID_HID;
  H5E_BEGIN_TRY {
    file = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  }
  H5E_END_TRY;
  if (file < 0) return h5_error("cannot create file", path);
  impl->file = Handle(file);

  Handle h5md = create_group(file, "/h5md");
  const std::array<int, 2> version = {1, 1};
  if (Status s = write_int_attribute(h5md.get(), "version", version); !s.ok()) return s;
  Handle author = create_group(file, "/h5md/author");
  if (Status s = write_string_attribute(author.get(), "name", creator.author); !s.ok()) return s;
  Handle program = create_group(file, "/h5md/creator");
  if (Status s = write_string_attribute(program.get(), "name", creator.program); !s.ok()) return s;
  if (Status s = write_string_attribute(program.get(), "version", creator.program_version); !s.ok()) return s;
  Handle observables = create_group(file, "/observables");
  Handle particles = create_group(file, "/particles");
  Handle parameters = create_group(file, "/parameters");
  if (!observables.valid() || !particles.valid() || !parameters.valid())
    return h5_error("creating groups", path);
  return std::unique_ptr<H5mdWriter>(new H5mdWriter(path, std::move(impl)));
}

Status H5mdWriter::write_tetrahedra(std::string_view group, std::span<const std::int32_t> tets,
                                    std::span<const std::uint8_t> region) {
  if (!impl_ || !impl_->file.valid()) return {StatusCode::kFailedPrecondition, "writer closed"};
  if (tets.size() % 4 != 0) return invalid_argument("tetrahedra: size not a multiple of 4");
  const hid_t file = impl_->file.get();
  Handle connectivity = path_exists(file, "/connectivity")
                            ? Handle(H5Gopen2(file, "/connectivity", H5P_DEFAULT))
                            : create_group(file, "/connectivity");
  const std::string path = "/connectivity/" + std::string(group);
  hsize_t dims[2] = {tets.size() / 4, 4};
  Handle space(H5Screate_simple(2, dims, nullptr));
  Handle dataset(
      H5Dcreate2(file, path.c_str(), H5T_STD_I32LE, space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
  if (!dataset.valid() ||
      H5Dwrite(dataset.get(), H5T_NATIVE_INT32, H5S_ALL, H5S_ALL, H5P_DEFAULT, tets.data()) < 0) {
    return h5_error("writing " + path, path_);
  }
  // H5MD: a connectivity dataset names the particle group its indices refer to.
  const std::string particles = "/particles/" + std::string(group);
  if (Status s = write_string_attribute(dataset.get(), "particles_group", particles); !s.ok()) return s;
  if (Status s = write_string_attribute(dataset.get(), "cell_type", "tetrahedron"); !s.ok()) return s;
  if (!region.empty()) {
    if (region.size() != tets.size() / 4)
      return invalid_argument("tetrahedra: one region id per tetrahedron");
    const std::string region_path = path + "_region";
    hsize_t region_dims[1] = {region.size()};
    Handle region_space(H5Screate_simple(1, region_dims, nullptr));
    Handle region_set(H5Dcreate2(file, region_path.c_str(), H5T_STD_U8LE, region_space.get(), H5P_DEFAULT,
                                 H5P_DEFAULT, H5P_DEFAULT));
    if (!region_set.valid() ||
        H5Dwrite(region_set.get(), H5T_NATIVE_UINT8, H5S_ALL, H5S_ALL, H5P_DEFAULT, region.data()) < 0) {
      return h5_error("writing " + region_path, path_);
    }
    if (Status s = write_string_attribute(region_set.get(), "meaning", "0 cytoplasm, 1 nucleus"); !s.ok()) {
      return s;
    }
  }
  return {};
}

namespace {

StatusOr<Element*> element_for(hid_t file, std::map<std::string, Element, std::less<>>& elements,
                               const std::string& path, std::vector<hsize_t> record_dims,
                               const std::string& time_unit) {
  auto found = elements.find(path);
  if (found != elements.end()) return &found->second;
  Element element;
  auto step = create_series(file, path + "/step", H5T_STD_I64LE, H5T_NATIVE_INT64, {});
  if (!step.ok()) return step.status();
  auto time = create_series(file, path + "/time", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {});
  if (!time.ok()) return time.status();
  if (Status s = write_string_attribute(time->dataset.get(), "unit", time_unit); !s.ok()) return s;
  std::size_t width = 1;
  for (hsize_t d : record_dims) width *= d;
  auto value =
      create_series(file, path + "/value", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, std::move(record_dims));
  if (!value.ok()) return value.status();
  element.step = std::move(*step);
  element.time = std::move(*time);
  element.value = std::move(*value);
  element.width = width;
  return &elements.emplace(path, std::move(element)).first->second;
}

Status append_element(Element& element, std::int64_t step, double time, const double* values) {
  if (Status s = append_record(element.step, &step); !s.ok()) return s;
  if (Status s = append_record(element.time, &time); !s.ok()) return s;
  return append_record(element.value, values);
}

}  // namespace

Status H5mdWriter::append_positions(std::string_view group, std::int64_t step, double time,
                                    std::span<const double> positions_m) {
  if (!impl_ || !impl_->file.valid()) return {StatusCode::kFailedPrecondition, "writer closed"};
  if (positions_m.size() % 3 != 0) return invalid_argument("positions: size not a multiple of 3");
  const hid_t file = impl_->file.get();
  const std::string particles = "/particles/" + std::string(group);
  if (!path_exists(file, particles + "/box")) {
    Handle box = create_group(file, particles + "/box");
    const std::array<int, 1> dimension = {3};
    if (Status s = write_int_attribute(box.get(), "dimension", dimension); !s.ok()) return s;
    // boundary: a string per dimension; "none" = not periodic.
    Handle type = string_type(5);
    hsize_t dims[1] = {3};
    Handle space(H5Screate_simple(1, dims, nullptr));
    Handle attr(H5Acreate2(box.get(), "boundary", type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT));
    const char boundary[3][5] = {"none", "none", "none"};
    if (!attr.valid() || H5Awrite(attr.get(), type.get(), boundary) < 0)
      return h5_error("writing box", path_);
  }
  auto element = element_for(file, impl_->elements, particles + "/position", {positions_m.size() / 3, 3},
                             impl_->creator.time_unit);
  if (!element.ok()) return element.status();
  if ((*element)->width != positions_m.size()) {
    return invalid_argument("positions: particle count differs from the first frame");
  }
  if (Status s = append_element(**element, step, time, positions_m.data()); !s.ok()) return s;

  // The XDMF sidecar cannot address a slice without HyperSlab: keep a 2-D copy.
  int& frame = impl_->frames[std::string(group)];
  char name[32];
  std::snprintf(name, sizeof name, "/frame_%06d", frame);
  const std::string copy_path = "/xdmf/" + std::string(group) + name;
  hsize_t dims[2] = {positions_m.size() / 3, 3};
  Handle space(H5Screate_simple(2, dims, nullptr));
  Handle lcpl(H5Pcreate(H5P_LINK_CREATE));
  H5Pset_create_intermediate_group(lcpl.get(), 1);
  Handle copy(
      H5Dcreate2(file, copy_path.c_str(), H5T_IEEE_F64LE, space.get(), lcpl.get(), H5P_DEFAULT, H5P_DEFAULT));
  if (!copy.valid() ||
      H5Dwrite(copy.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, positions_m.data()) < 0) {
    return h5_error("writing " + copy_path, path_);
  }
  Handle scalar(H5Screate(H5S_SCALAR));
  Handle step_attr(H5Acreate2(copy.get(), "step", H5T_STD_I64LE, scalar.get(), H5P_DEFAULT, H5P_DEFAULT));
  Handle time_attr(H5Acreate2(copy.get(), "time", H5T_IEEE_F64LE, scalar.get(), H5P_DEFAULT, H5P_DEFAULT));
  if (H5Awrite(step_attr.get(), H5T_NATIVE_INT64, &step) < 0 ||
      H5Awrite(time_attr.get(), H5T_NATIVE_DOUBLE, &time) < 0) {
    return h5_error("writing frame attributes", path_);
  }
  ++frame;
  return {};
}

Status H5mdWriter::append_observable(std::string_view name, std::int64_t step, double time,
                                     std::span<const double> values) {
  if (!impl_ || !impl_->file.valid()) return {StatusCode::kFailedPrecondition, "writer closed"};
  if (values.empty()) return invalid_argument("observable " + std::string(name) + ": no values");
  std::vector<hsize_t> record_dims;
  if (values.size() > 1) record_dims.push_back(values.size());
  auto element = element_for(impl_->file.get(), impl_->elements, "/observables/" + std::string(name),
                             std::move(record_dims), impl_->creator.time_unit);
  if (!element.ok()) return element.status();
  if ((*element)->width != values.size()) {
    return invalid_argument("observable " + std::string(name) + ": width differs from the first record");
  }
  return append_element(**element, step, time, values.data());
}

Status H5mdWriter::write_parameters_json(std::string_view json) {
  if (!impl_ || !impl_->file.valid()) return {StatusCode::kFailedPrecondition, "writer closed"};
  auto dataset = write_string_dataset(impl_->file.get(), "/parameters/job_spec_json", json);
  if (!dataset.ok()) return dataset.status();
  return write_string_attribute(dataset->get(), "format", "protobuf JSON mapping of cellflow.v1.JobSpec");
}

Status H5mdWriter::write_string(std::string_view path, std::string_view value) {
  if (!impl_ || !impl_->file.valid()) return {StatusCode::kFailedPrecondition, "writer closed"};
  return write_string_dataset(impl_->file.get(), std::string(path), value).status();
}

Status H5mdWriter::write_scalar(std::string_view path, double value, std::string_view unit) {
  if (!impl_ || !impl_->file.valid()) return {StatusCode::kFailedPrecondition, "writer closed"};
  const hid_t file = impl_->file.get();
  const std::string name(path);
  if (path_exists(file, name)) return {StatusCode::kFailedPrecondition, name + " already written"};
  Handle space(H5Screate(H5S_SCALAR));
  Handle lcpl(H5Pcreate(H5P_LINK_CREATE));
  H5Pset_create_intermediate_group(lcpl.get(), 1);
  Handle dataset(
      H5Dcreate2(file, name.c_str(), H5T_IEEE_F64LE, space.get(), lcpl.get(), H5P_DEFAULT, H5P_DEFAULT));
  if (!dataset.valid() ||
      H5Dwrite(dataset.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, &value) < 0)
    return h5_error("writing " + name, path_);
  if (!unit.empty()) return write_string_attribute(dataset.get(), "unit", unit);
  return {};
}

Status H5mdWriter::append_vector_field(std::string_view name, std::int64_t step, double time,
                                       const UniformGrid& grid, std::span<const double> x,
                                       std::span<const double> y, std::span<const double> z) {
  if (!impl_ || !impl_->file.valid()) return {StatusCode::kFailedPrecondition, "writer closed"};
  const std::size_t nodes = static_cast<std::size_t>(std::max(grid.nx, 0)) * std::max(grid.ny, 0) *
                            static_cast<std::size_t>(std::max(grid.nz, 0));
  if (nodes == 0 || x.size() != nodes || y.size() != nodes || z.size() != nodes) {
    return invalid_argument("field " + std::string(name) + ": each component needs nx * ny * nz values");
  }
  const hid_t file = impl_->file.get();
  const std::string base = "/fields/" + std::string(name);
  auto found = impl_->fields.find(base);
  if (found == impl_->fields.end()) {
    Impl::Field field;
    auto step_series = create_series(file, base + "/step", H5T_STD_I64LE, H5T_NATIVE_INT64, {});
    if (!step_series.ok()) return step_series.status();
    auto time_series = create_series(file, base + "/time", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {});
    if (!time_series.ok()) return time_series.status();
    if (Status s = write_string_attribute(time_series->dataset.get(), "unit", impl_->creator.time_unit);
        !s.ok())
      return s;
    Handle group(H5Gopen2(file, base.c_str(), H5P_DEFAULT));
    const std::array<int, 3> dimensions = {grid.nx, grid.ny, grid.nz};
    if (Status s = write_int_attribute(group.get(), "dimensions", dimensions); !s.ok()) return s;
    hsize_t three[1] = {3};
    Handle vector_space(H5Screate_simple(1, three, nullptr));
    Handle scalar_space(H5Screate(H5S_SCALAR));
    Handle spacing(
        H5Acreate2(group.get(), "spacing_m", H5T_IEEE_F64LE, scalar_space.get(), H5P_DEFAULT, H5P_DEFAULT));
    Handle origin(
        H5Acreate2(group.get(), "origin_m", H5T_IEEE_F64LE, vector_space.get(), H5P_DEFAULT, H5P_DEFAULT));
    if (H5Awrite(spacing.get(), H5T_NATIVE_DOUBLE, &grid.spacing_m) < 0 ||
        H5Awrite(origin.get(), H5T_NATIVE_DOUBLE, grid.origin_m) < 0) {
      return h5_error("writing grid of " + base, path_);
    }
    field.step = std::move(*step_series);
    field.time = std::move(*time_series);
    field.grid = grid;
    found = impl_->fields.emplace(base, std::move(field)).first;
  }
  Impl::Field& field = found->second;
  if (field.grid.nx != grid.nx || field.grid.ny != grid.ny || field.grid.nz != grid.nz) {
    return invalid_argument("field " + std::string(name) + ": grid differs from the first frame");
  }
  char frame_name[32];
  std::snprintf(frame_name, sizeof frame_name, "/frame_%06d", static_cast<int>(field.step.records));
  const std::string frame_path = base + frame_name;
  hsize_t dims[4] = {static_cast<hsize_t>(grid.nz), static_cast<hsize_t>(grid.ny),
                     static_cast<hsize_t>(grid.nx), 3};
  Handle space(H5Screate_simple(4, dims, nullptr));
  Handle frame(H5Dcreate2(file, frame_path.c_str(), H5T_IEEE_F32LE, space.get(), H5P_DEFAULT, H5P_DEFAULT,
                          H5P_DEFAULT));
  if (!frame.valid()) return h5_error("creating " + frame_path, path_);
  // Each component array goes to every third value: no interleaved copy of the field.
  const std::span<const double> components[3] = {x, y, z};
  hsize_t count[4] = {dims[0], dims[1], dims[2], 1};
  hsize_t memory_dims[1] = {nodes};
  Handle memory_space(H5Screate_simple(1, memory_dims, nullptr));
  for (hsize_t c = 0; c < 3; ++c) {
    hsize_t start[4] = {0, 0, 0, c};
    Handle file_space(H5Dget_space(frame.get()));
    H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, nullptr, count, nullptr);
    if (H5Dwrite(frame.get(), H5T_NATIVE_DOUBLE, memory_space.get(), file_space.get(), H5P_DEFAULT,
                 components[c].data()) < 0) {
      return h5_error("writing " + frame_path, path_);
    }
  }
  Handle scalar(H5Screate(H5S_SCALAR));
  Handle step_attr(H5Acreate2(frame.get(), "step", H5T_STD_I64LE, scalar.get(), H5P_DEFAULT, H5P_DEFAULT));
  Handle time_attr(H5Acreate2(frame.get(), "time", H5T_IEEE_F64LE, scalar.get(), H5P_DEFAULT, H5P_DEFAULT));
  if (H5Awrite(step_attr.get(), H5T_NATIVE_INT64, &step) < 0 ||
      H5Awrite(time_attr.get(), H5T_NATIVE_DOUBLE, &time) < 0) {
    return h5_error("writing frame attributes", path_);
  }
  if (Status s = append_record(field.step, &step); !s.ok()) return s;
  return append_record(field.time, &time);
}

Status H5mdWriter::flush() {
  if (!impl_ || !impl_->file.valid()) return {StatusCode::kFailedPrecondition, "writer closed"};
  if (H5Fflush(impl_->file.get(), H5F_SCOPE_LOCAL) < 0) return h5_error("flush", path_);
  return {};
}

Status H5mdWriter::close() {
  if (!impl_ || !impl_->file.valid()) return {};
  Status status = flush();
  impl_->elements.clear();
  impl_->fields.clear();
  impl_->file.reset();
  return status;
}

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
