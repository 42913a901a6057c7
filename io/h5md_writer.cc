// H5mdWriter: creation of an H5MD 1.1 file (h5md, author and creator
// metadata), tetrahedral connectivity, time-dependent elements (step, time,
// value series) for positions and observables with the 2-D position copies
// of the XDMF sidecar, parameters, scalars and strings, vector fields on a
// uniform grid, flush and close.
#include <hdf5.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "io/h5_handle.h"
#include "io/h5md.h"
#include "io/h5md_internal.h"

namespace cellflow::io {

using detail::append_record;
using detail::create_group;
using detail::create_series;
using detail::h5_error;
using detail::Handle;
using detail::path_exists;
using detail::Series;
using detail::string_type;
using detail::write_int_attribute;
using detail::write_string_attribute;
using detail::write_string_dataset;

namespace {

// step, time and value of one H5MD time-dependent element.
struct Element {
  Series step, time, value;
  std::size_t width = 0;
};

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

}  // namespace cellflow::io
