// The result files match the schemas written down beside each scene
// (jobs/<scene>/result_schema.json): every listed entry exists (an optional
// one: when present) with its kind, element type, shape and unit attribute
// (the schema's "unit"; null: none, dimensionless), named dimensions agree
// across entries, and every observable the file holds is listed (the schema
// is complete).
#include <gtest/gtest.h>
#include <hdf5.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "jobs/registry.h"

namespace cellflow {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

json load_schema(const std::string& relative) {
  std::ifstream in(std::string(CELLFLOW_SOURCE_DIR) + "/" + relative);
  EXPECT_TRUE(in) << relative;
  return json::parse(in);
}

// The element type of a dataset as the schema names it.
std::string type_name(hid_t dataset) {
  const hid_t type = H5Dget_type(dataset);
  std::string name = "other";
  const H5T_class_t cls = H5Tget_class(type);
  const size_t size = H5Tget_size(type);
  if (cls == H5T_FLOAT && size == 8) name = "float64";
  if (cls == H5T_FLOAT && size == 4) name = "float32";
  if (cls == H5T_STRING) name = "string";
  if (cls == H5T_INTEGER) {
    const bool is_signed = H5Tget_sign(type) == H5T_SGN_2;
    name = std::string(is_signed ? "int" : "uint") + std::to_string(8 * size);
  }
  H5Tclose(type);
  return name;
}

std::vector<hsize_t> shape_of(hid_t dataset) {
  const hid_t space = H5Dget_space(dataset);
  std::vector<hsize_t> dims(static_cast<std::size_t>(H5Sget_simple_extent_ndims(space)));
  H5Sget_simple_extent_dims(space, dims.data(), nullptr);
  H5Sclose(space);
  return dims;
}

// The unit attribute of `dataset`; "" when it has none.
std::string unit_of(hid_t dataset) {
  if (H5Aexists(dataset, "unit") <= 0) return "";
  const hid_t attr = H5Aopen(dataset, "unit", H5P_DEFAULT);
  const hid_t type = H5Aget_type(attr);
  std::string value(H5Tget_size(type), '\0');
  H5Aread(attr, type, value.data());
  H5Tclose(type);
  H5Aclose(attr);
  value.resize(value.find('\0') == std::string::npos ? value.size() : value.find('\0'));
  return value;
}

bool exists(hid_t file, const std::string& path) {
  // Each prefix must exist before the next is asked for.
  std::size_t pos = 0;
  while ((pos = path.find('/', pos + 1)) != std::string::npos) {
    if (H5Lexists(file, path.substr(0, pos).c_str(), H5P_DEFAULT) <= 0) return false;
  }
  return H5Lexists(file, path.c_str(), H5P_DEFAULT) > 0;
}

void check_against_schema(const std::string& h5_path, const json& schema) {
  const hid_t file = H5Fopen(h5_path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(file, 0) << h5_path;
  std::map<std::string, hsize_t> dimension;  // named dimension -> length seen first
  std::vector<std::string> listed_observables;
  for (const json& entry : schema["entries"]) {
    const std::string path = entry["path"];
    const std::string kind = entry["kind"];
    SCOPED_TRACE(path);
    if (path.rfind("/observables/", 0) == 0)
      listed_observables.push_back(path.substr(13, path.find('/', 13) - 13));
    if (entry.value("optional", false) && !exists(file, path)) continue;
    ASSERT_TRUE(exists(file, path)) << "missing in " << h5_path;
    if (kind == "group") {
      const hid_t group = H5Gopen2(file, path.c_str(), H5P_DEFAULT);
      ASSERT_GE(group, 0) << "not a group";
      for (const std::string attribute : entry.value("attributes", json::array()))
        EXPECT_GT(H5Aexists(group, attribute.c_str()), 0) << "attribute " << attribute;
      H5Gclose(group);
      continue;
    }
    const hid_t dataset = H5Dopen2(file, path.c_str(), H5P_DEFAULT);
    ASSERT_GE(dataset, 0) << "not a dataset";
    for (const std::string attribute : entry.value("attributes", json::array()))
      EXPECT_GT(H5Aexists(dataset, attribute.c_str()), 0) << "attribute " << attribute;
    if (entry.contains("unit")) {
      const std::string expected = entry["unit"].is_null() ? "" : entry["unit"].get<std::string>();
      EXPECT_EQ(unit_of(dataset), expected) << "unit attribute";
    }
    const std::vector<hsize_t> shape = shape_of(dataset);
    if (kind == "string") {
      EXPECT_EQ(type_name(dataset), "string");
    } else if (kind == "scalar") {
      EXPECT_EQ(type_name(dataset), entry["type"].get<std::string>());
      EXPECT_TRUE(shape.empty()) << "a scalar has rank 0";
    } else {
      EXPECT_EQ(type_name(dataset), entry["type"].get<std::string>());
      const json& dims = entry["shape"];
      ASSERT_EQ(shape.size(), dims.size()) << "rank";
      for (std::size_t d = 0; d < shape.size(); ++d) {
        if (dims[d].is_number()) {
          EXPECT_EQ(shape[d], dims[d].get<hsize_t>()) << "dimension " << d;
        } else {
          const auto [it, first] = dimension.emplace(dims[d].get<std::string>(), shape[d]);
          EXPECT_EQ(shape[d], it->second) << "dimension " << dims[d] << " differs between entries";
        }
      }
    }
    H5Dclose(dataset);
  }
  // Completeness: every observable of the file is in the schema.
  const hid_t observables = H5Gopen2(file, "/observables", H5P_DEFAULT);
  ASSERT_GE(observables, 0);
  H5G_info_t info;
  H5Gget_info(observables, &info);
  for (hsize_t i = 0; i < info.nlinks; ++i) {
    char name[256];
    H5Lget_name_by_idx(observables, ".", H5_INDEX_NAME, H5_ITER_INC, i, name, sizeof name, H5P_DEFAULT);
    EXPECT_NE(std::find(listed_observables.begin(), listed_observables.end(), name), listed_observables.end())
        << "/observables/" << name << " is not in the schema";
  }
  H5Gclose(observables);
  H5Fclose(file);
}

std::string run_to_file(const v1::JobSpec& spec, const std::string& stem) {
  const std::string path =
      (fs::temp_directory_path() / ("cellflow_schema_" + stem + "_" + std::to_string(::getpid()) + ".h5"))
          .string();
  const jobs::SceneRegistry registry;
  auto prepared = registry.prepare(spec);
  EXPECT_TRUE(prepared.ok()) << prepared.status().to_string();
  if (!prepared.ok()) return path;
  jobs::RunOptions options;
  options.result_path = path;
  options.threads = 1;
  const jobs::RunOutcome outcome = (*prepared)->run(spec, options, {});
  EXPECT_TRUE(outcome.status.ok()) << outcome.status.to_string();
  EXPECT_TRUE(outcome.result_written);
  return path;
}

TEST(ResultSchema, CompressionAndIndentationFilesMatchTheQuasiStaticSchema) {
  const json schema = load_schema("jobs/quasi_static/result_schema.json");
  v1::JobSpec spec;
  auto* c = spec.mutable_compression();
  c->mutable_cell()->set_radius_m(5e-6);
  c->mutable_cell()->mutable_material()->set_youngs_modulus_pa(1000.0);
  c->mutable_cell()->set_target_vertex_count(300);
  c->set_max_deformation(0.1);
  c->set_load_points(3);
  const std::string compression = run_to_file(spec, "compression");
  check_against_schema(compression, schema);
  fs::remove(compression);

  v1::JobSpec probe;
  auto* i = probe.mutable_indentation();
  *i->mutable_cell() = c->cell();
  i->set_probe_radius_m(5e-6);
  i->set_max_indentation_m(0.5e-6);
  i->set_load_points(3);
  const std::string indentation = run_to_file(probe, "indentation");
  check_against_schema(indentation, schema);
  fs::remove(indentation);
}

TEST(ResultSchema, ShearFlowFileMatchesItsSchema) {
  const json schema = load_schema("jobs/shear_flow/result_schema.json");
  v1::JobSpec spec;
  auto* flow = spec.mutable_shear_flow();
  flow->mutable_cell()->set_radius_m(4e-6);
  flow->mutable_cell()->mutable_material()->set_youngs_modulus_pa(50.0);
  flow->mutable_cell()->set_target_vertex_count(300);
  flow->set_capillary_number(0.2);
  auto* n = flow->mutable_numerics();
  n->set_cells_per_radius(3);
  n->set_box_x_radii(5);
  n->set_box_y_radii(6);
  n->set_box_z_radii(4);
  n->set_max_strain(1.0);
  n->set_fluid_snapshots(true);  // the optional /fields entries are checked too
  const std::string path = run_to_file(spec, "shear_flow");
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  EXPECT_GT(H5Lexists(file, "/fields", H5P_DEFAULT), 0);
  H5Fclose(file);
  check_against_schema(path, schema);
  fs::remove(path);
}

TEST(ResultSchema, SuspensionFileMatchesItsSchema) {
  const json schema = load_schema("jobs/suspension/result_schema.json");
  v1::JobSpec spec;
  auto* s = spec.mutable_suspension();
  auto* cells = s->add_cells();
  cells->mutable_cell()->set_radius_m(4e-6);
  cells->mutable_cell()->mutable_material()->set_youngs_modulus_pa(50.0);
  cells->mutable_cell()->set_target_vertex_count(300);
  cells->set_count(2);
  s->set_capillary_number(0.2);
  auto* n = s->mutable_numerics();
  n->set_average_after_strain(0.2);
  n->mutable_flow()->set_cells_per_radius(3);
  n->mutable_flow()->set_max_strain(0.5);
  n->mutable_flow()->set_fluid_snapshots(true);  // the optional /fields entries are checked too
  const std::string path = run_to_file(spec, "suspension");
  check_against_schema(path, schema);
  fs::remove(path);
}

// A fit of one Hertz curve (the Hertz model needs no library simulation).
TEST(ResultSchema, FitFileMatchesItsSchema) {
  const json schema = load_schema("jobs/fit/result_schema.json");
  v1::JobSpec spec;
  auto* fit = spec.mutable_fit();
  fit->set_geometry(v1::FIT_GEOMETRY_PLATES);
  fit->set_radius_m(5e-6);
  fit->set_model(v1::FIT_MODEL_HERTZ);
  auto* curve = fit->add_curves();
  curve->set_name("hertz");
  for (int i = -5; i <= 40; ++i) {
    const double x = i * 0.02e-6, eps = x / 10e-6;
    curve->add_indentation_m(x);
    curve->add_force_n(eps > 0 ? 4.0 / 3.0 / (1 - 0.48 * 0.48) * 100.0 * 25e-12 * std::pow(eps, 1.5) : 0.0);
  }
  const std::string path = run_to_file(spec, "fit");
  check_against_schema(path, schema);
  fs::remove(path);
}

}  // namespace
}  // namespace cellflow
