// H5mdWriter: creation of an H5MD 1.1 file (h5md, author and creator
// metadata, the units module), tetrahedral connectivity with its object
// reference to the particle group, the box, time-dependent elements (step,
// time, value series) for positions, box edges, observables and vector fields
// on a uniform grid, parameters, scalars, integers and strings, flush and close.
#include <hdf5.h>

#include <algorithm>
#include <array>
#include <cmath>
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
  std::map<std::string, H5mdBox, std::less<>> boxes;     // particle groups whose box is written
  struct Field {
    Series step, time, value;
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
  // The units module: every dimensionful dataset carries a unit attribute.
  Handle units = create_group(file, "/h5md/modules/units");
  const std::array<int, 2> units_version = {1, 0};
  if (Status s = write_int_attribute(units.get(), "version", units_version); !s.ok()) return s;
  if (Status s = write_string_attribute(units.get(), "system", "SI"); !s.ok()) return s;
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
  // H5MD: a connectivity dataset refers to its particle group by an object reference.
  const std::string particles = "/particles/" + std::string(group);
  if (!path_exists(file, particles) && !create_group(file, particles).valid())
    return h5_error("creating " + particles, path_);
  hobj_ref_t reference;
  if (H5Rcreate(&reference, file, particles.c_str(), H5R_OBJECT, -1) < 0)
    return h5_error("referencing " + particles, path_);
  {
    Handle scalar(H5Screate(H5S_SCALAR));
    Handle attr(H5Acreate2(dataset.get(), "particles_group", H5T_STD_REF_OBJ, scalar.get(), H5P_DEFAULT,
                           H5P_DEFAULT));
    if (!attr.valid() || H5Awrite(attr.get(), H5T_STD_REF_OBJ, &reference) < 0)
      return h5_error("writing particles_group", path_);
  }
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

// The step and time series of a new element at `path`: time with the
// creator's unit (none when dimensionless) and meaning.
Status create_step_and_time(hid_t file, const std::string& path, const H5mdCreator& creator, Series& step,
                            Series& time) {
  auto step_series = create_series(file, path + "/step", H5T_STD_I64LE, H5T_NATIVE_INT64, {});
  if (!step_series.ok()) return step_series.status();
  auto time_series = create_series(file, path + "/time", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {});
  if (!time_series.ok()) return time_series.status();
  if (!creator.time_unit.empty()) {
    if (Status s = write_string_attribute(time_series->dataset.get(), "unit", creator.time_unit); !s.ok())
      return s;
  }
  if (!creator.time_meaning.empty()) {
    if (Status s = write_string_attribute(time_series->dataset.get(), "meaning", creator.time_meaning);
        !s.ok())
      return s;
  }
  step = std::move(*step_series);
  time = std::move(*time_series);
  return {};
}

// The element at `path`, created on first use with values of `file_type` /
// `memory_type` and `unit` (none when empty).
StatusOr<Element*> element_for(hid_t file, std::map<std::string, Element, std::less<>>& elements,
                               const std::string& path, std::vector<hsize_t> record_dims,
                               const H5mdCreator& creator, std::string_view unit,
                               hid_t file_type = H5T_IEEE_F64LE, hid_t memory_type = H5T_NATIVE_DOUBLE) {
  auto found = elements.find(path);
  if (found != elements.end()) return &found->second;
  Element element;
  if (Status s = create_step_and_time(file, path, creator, element.step, element.time); !s.ok()) return s;
  std::size_t width = 1;
  for (hsize_t d : record_dims) width *= d;
  auto value = create_series(file, path + "/value", file_type, memory_type, std::move(record_dims));
  if (!value.ok()) return value.status();
  if (!unit.empty()) {
    if (Status s = write_string_attribute(value->dataset.get(), "unit", unit); !s.ok()) return s;
  }
  element.value = std::move(*value);
  element.width = width;
  return &elements.emplace(path, std::move(element)).first->second;
}

Status append_element(Element& element, std::int64_t step, double time, const void* values) {
  if (Status s = append_record(element.step, &step); !s.ok()) return s;
  if (Status s = append_record(element.time, &time); !s.ok()) return s;
  return append_record(element.value, values);
}

}  // namespace

Status H5mdWriter::set_box(std::string_view group, const H5mdBox& box) {
  if (!impl_ || !impl_->file.valid()) return {StatusCode::kFailedPrecondition, "writer closed"};
  const hid_t file = impl_->file.get();
  const std::string particles = "/particles/" + std::string(group);
  if (impl_->boxes.count(particles) != 0)
    return {StatusCode::kFailedPrecondition, particles + ": box already written"};
  if (box.has_edges) {
    for (double e : box.edges_m) {
      if (!(e > 0.0) || !std::isfinite(e))
        return invalid_argument("box edges: each must be positive and finite");
    }
  }
  Handle group_handle = path_exists(file, particles) ? Handle(H5Gopen2(file, particles.c_str(), H5P_DEFAULT))
                                                     : create_group(file, particles);
  Handle box_group = create_group(file, particles + "/box");
  if (!group_handle.valid() || !box_group.valid()) return h5_error("creating " + particles + "/box", path_);
  const std::array<int, 1> dimension = {3};
  if (Status s = write_int_attribute(box_group.get(), "dimension", dimension); !s.ok()) return s;
  // boundary: a string per dimension, "periodic" or "none" (H5MD 1.1).
  Handle type = string_type(9);
  hsize_t dims[1] = {3};
  Handle space(H5Screate_simple(1, dims, nullptr));
  Handle attr(H5Acreate2(box_group.get(), "boundary", type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT));
  char boundary[3][9] = {};
  for (int d = 0; d < 3; ++d)
    std::snprintf(boundary[d], sizeof boundary[d], "%s", box.periodic[d] ? "periodic" : "none");
  if (!attr.valid() || H5Awrite(attr.get(), type.get(), boundary) < 0) return h5_error("writing box", path_);
  impl_->boxes.emplace(particles, box);
  return {};
}

Status H5mdWriter::append_positions(std::string_view group, std::int64_t step, double time,
                                    std::span<const double> positions_m) {
  if (!impl_ || !impl_->file.valid()) return {StatusCode::kFailedPrecondition, "writer closed"};
  if (positions_m.size() % 3 != 0) return invalid_argument("positions: size not a multiple of 3");
  const hid_t file = impl_->file.get();
  const std::string particles = "/particles/" + std::string(group);
  if (impl_->boxes.count(particles) == 0) {
    if (Status s = set_box(group, H5mdBox{}); !s.ok()) return s;
  }
  const H5mdBox& box = impl_->boxes.at(particles);
  auto element = element_for(file, impl_->elements, particles + "/position", {positions_m.size() / 3, 3},
                             impl_->creator, "m");
  if (!element.ok()) return element.status();
  if ((*element)->width != positions_m.size()) {
    return invalid_argument("positions: particle count differs from the first frame");
  }
  if (box.has_edges) {
    // One edges record per position frame: readers (MDAnalysis) take frame
    // k's box from record k. The D x D matrix form (edge vectors as rows,
    // here diagonal): H5MD allows it for any box, and MDAnalysis 2.4 reads
    // only that form.
    auto edges = element_for(file, impl_->elements, particles + "/box/edges", {3, 3}, impl_->creator, "m");
    if (!edges.ok()) return edges.status();
    const double matrix[9] = {box.edges_m[0], 0.0, 0.0, 0.0, box.edges_m[1], 0.0, 0.0, 0.0, box.edges_m[2]};
    if (Status s = append_element(**edges, step, time, matrix); !s.ok()) return s;
  }
  return append_element(**element, step, time, positions_m.data());
}

Status H5mdWriter::append_observable(std::string_view name, std::int64_t step, double time,
                                     std::span<const double> values, std::string_view unit) {
  if (!impl_ || !impl_->file.valid()) return {StatusCode::kFailedPrecondition, "writer closed"};
  if (values.empty()) return invalid_argument("observable " + std::string(name) + ": no values");
  std::vector<hsize_t> record_dims;
  if (values.size() > 1) record_dims.push_back(values.size());
  auto element = element_for(impl_->file.get(), impl_->elements, "/observables/" + std::string(name),
                             std::move(record_dims), impl_->creator, unit);
  if (!element.ok()) return element.status();
  if ((*element)->width != values.size() || (*element)->value.memory_type != H5T_NATIVE_DOUBLE) {
    return invalid_argument("observable " + std::string(name) +
                            ": width or type differs from the first record");
  }
  return append_element(**element, step, time, values.data());
}

Status H5mdWriter::append_count(std::string_view name, std::int64_t step, double time, std::int64_t value) {
  if (!impl_ || !impl_->file.valid()) return {StatusCode::kFailedPrecondition, "writer closed"};
  auto element = element_for(impl_->file.get(), impl_->elements, "/observables/" + std::string(name), {},
                             impl_->creator, "", H5T_STD_I64LE, H5T_NATIVE_INT64);
  if (!element.ok()) return element.status();
  if ((*element)->value.memory_type != H5T_NATIVE_INT64) {
    return invalid_argument("observable " + std::string(name) + ": not a count");
  }
  return append_element(**element, step, time, &value);
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

namespace {

// One scalar dataset of `file_type` at `name`, intermediate groups created;
// the dataset, or an invalid handle when creating or writing it failed.
Handle write_scalar_dataset(hid_t file, const std::string& name, hid_t file_type, hid_t memory_type,
                            const void* value) {
  Handle space(H5Screate(H5S_SCALAR));
  Handle lcpl(H5Pcreate(H5P_LINK_CREATE));
  H5Pset_create_intermediate_group(lcpl.get(), 1);
  Handle dataset(
      H5Dcreate2(file, name.c_str(), file_type, space.get(), lcpl.get(), H5P_DEFAULT, H5P_DEFAULT));
  if (!dataset.valid() || H5Dwrite(dataset.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, value) < 0)
    return Handle();
  return dataset;
}

}  // namespace

Status H5mdWriter::write_scalar(std::string_view path, double value, std::string_view unit) {
  if (!impl_ || !impl_->file.valid()) return {StatusCode::kFailedPrecondition, "writer closed"};
  const hid_t file = impl_->file.get();
  const std::string name(path);
  if (path_exists(file, name)) return {StatusCode::kFailedPrecondition, name + " already written"};
  Handle dataset = write_scalar_dataset(file, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &value);
  if (!dataset.valid()) return h5_error("writing " + name, path_);
  if (!unit.empty()) return write_string_attribute(dataset.get(), "unit", unit);
  return {};
}

Status H5mdWriter::write_integer(std::string_view path, std::int64_t value) {
  if (!impl_ || !impl_->file.valid()) return {StatusCode::kFailedPrecondition, "writer closed"};
  const hid_t file = impl_->file.get();
  const std::string name(path);
  if (path_exists(file, name)) return {StatusCode::kFailedPrecondition, name + " already written"};
  if (!write_scalar_dataset(file, name, H5T_STD_I64LE, H5T_NATIVE_INT64, &value).valid())
    return h5_error("writing " + name, path_);
  return {};
}

Status H5mdWriter::write_integers(std::string_view path, std::span<const std::int64_t> values) {
  if (!impl_ || !impl_->file.valid()) return {StatusCode::kFailedPrecondition, "writer closed"};
  const hid_t file = impl_->file.get();
  const std::string name(path);
  if (path_exists(file, name)) return {StatusCode::kFailedPrecondition, name + " already written"};
  const hsize_t dims[1] = {values.size()};
  Handle space(H5Screate_simple(1, dims, nullptr));
  Handle lcpl(H5Pcreate(H5P_LINK_CREATE));
  H5Pset_create_intermediate_group(lcpl.get(), 1);
  Handle dataset(
      H5Dcreate2(file, name.c_str(), H5T_STD_I64LE, space.get(), lcpl.get(), H5P_DEFAULT, H5P_DEFAULT));
  // An empty array is a valid dataset of size 0 (nothing to write into it).
  if (!dataset.valid() || (!values.empty() && H5Dwrite(dataset.get(), H5T_NATIVE_INT64, H5S_ALL, H5S_ALL,
                                                       H5P_DEFAULT, values.data()) < 0))
    return h5_error("writing " + name, path_);
  return {};
}

Status H5mdWriter::append_vector_field(std::string_view name, std::int64_t step, double time,
                                       const UniformGrid& grid, std::span<const double> x,
                                       std::span<const double> y, std::span<const double> z,
                                       std::string_view unit) {
  if (!impl_ || !impl_->file.valid()) return {StatusCode::kFailedPrecondition, "writer closed"};
  const std::size_t nodes = static_cast<std::size_t>(std::max(grid.nx, 0)) * std::max(grid.ny, 0) *
                            static_cast<std::size_t>(std::max(grid.nz, 0));
  if (nodes == 0 || x.size() != nodes || y.size() != nodes || z.size() != nodes) {
    return invalid_argument("field " + std::string(name) + ": each component needs nx * ny * nz values");
  }
  const hid_t file = impl_->file.get();
  const std::string base = "/fields/" + std::string(name);
  const hsize_t nz = static_cast<hsize_t>(grid.nz), ny = static_cast<hsize_t>(grid.ny),
                nx = static_cast<hsize_t>(grid.nx);
  auto found = impl_->fields.find(base);
  if (found == impl_->fields.end()) {
    Impl::Field field;
    if (Status s = create_step_and_time(file, base, impl_->creator, field.step, field.time); !s.ok())
      return s;
    // value [frames][nz][ny][nx][3], chunked by z plane of one frame: each
    // component is written plane by plane into a chunk that stays cached.
    hsize_t dims[5] = {0, nz, ny, nx, 3};
    hsize_t max_dims[5] = {H5S_UNLIMITED, nz, ny, nx, 3};
    hsize_t chunk[5] = {1, 1, ny, nx, 3};
    Handle space(H5Screate_simple(5, dims, max_dims));
    Handle dcpl(H5Pcreate(H5P_DATASET_CREATE));
    H5Pset_chunk(dcpl.get(), 5, chunk);
    const std::string value_path = base + "/value";
    field.value.dataset = Handle(H5Dcreate2(file, value_path.c_str(), H5T_IEEE_F32LE, space.get(),
                                            H5P_DEFAULT, dcpl.get(), H5P_DEFAULT));
    if (!field.value.dataset.valid()) return h5_error("creating " + value_path, path_);
    field.value.record_dims = {nz, ny, nx, 3};
    field.value.memory_type = H5T_NATIVE_DOUBLE;
    if (!unit.empty()) {
      if (Status s = write_string_attribute(field.value.dataset.get(), "unit", unit); !s.ok()) return s;
    }
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
    field.grid = grid;
    found = impl_->fields.emplace(base, std::move(field)).first;
  }
  Impl::Field& field = found->second;
  if (field.grid.nx != grid.nx || field.grid.ny != grid.ny || field.grid.nz != grid.nz) {
    return invalid_argument("field " + std::string(name) + ": grid differs from the first frame");
  }
  const hsize_t record = field.value.records;
  hsize_t extent[5] = {record + 1, nz, ny, nx, 3};
  if (H5Dset_extent(field.value.dataset.get(), extent) < 0) return h5_error("extending " + base, path_);
  // Each component array goes to every third value, one z plane at a time:
  // no interleaved copy of the field.
  const std::span<const double> components[3] = {x, y, z};
  Handle file_space(H5Dget_space(field.value.dataset.get()));
  hsize_t memory_dims[1] = {nodes};
  Handle memory_space(H5Screate_simple(1, memory_dims, nullptr));
  const hsize_t plane = ny * nx;
  for (hsize_t k = 0; k < nz; ++k) {
    for (hsize_t c = 0; c < 3; ++c) {
      hsize_t start[5] = {record, k, 0, 0, c};
      hsize_t count[5] = {1, 1, ny, nx, 1};
      H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, nullptr, count, nullptr);
      hsize_t memory_start[1] = {k * plane}, memory_count[1] = {plane};
      H5Sselect_hyperslab(memory_space.get(), H5S_SELECT_SET, memory_start, nullptr, memory_count, nullptr);
      if (H5Dwrite(field.value.dataset.get(), H5T_NATIVE_DOUBLE, memory_space.get(), file_space.get(),
                   H5P_DEFAULT, components[c].data()) < 0) {
        return h5_error("writing " + base + "/value", path_);
      }
    }
  }
  field.value.records = record + 1;
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
