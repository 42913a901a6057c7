#include "jobs/job_spec.h"

#include <google/protobuf/util/json_util.h>

#include "jobs/cell_spec.h"
#include "jobs/shear_flow/shear_flow_spec.h"

namespace cellflow::jobs {
namespace {

// Documented defaults for unset optional fields (see proto/cellflow/v1/*.proto);
// those of the cell are in spec/cell_spec.h. The cell's default mesh size is
// cell::CellParams' own (3000 vertices).
constexpr int kDefaultLoadPoints = 40;

scenes::QuasiStaticOptions to_numerics(const v1::QuasiStaticNumerics& n) {
  scenes::QuasiStaticOptions options;  // the struct holds the defaults
  if (n.has_residual_tolerance()) options.residual_tolerance = n.residual_tolerance();
  if (n.has_max_newton_iterations()) options.max_newton_iterations = n.max_newton_iterations();
  if (n.has_max_step_splits()) options.max_step_splits = n.max_step_splits();
  if (n.has_contact_stiffness_n_per_m()) options.contact_stiffness_n_per_m = n.contact_stiffness_n_per_m();
  if (n.has_contact_range_m()) options.contact_range_m = n.contact_range_m();
  if (n.volumetric_term() == v1::VOLUMETRIC_TERM_PER_TET) {
    options.volumetric = elastic::VolumetricTerm::kPerTet;
  } else if (n.volumetric_term() == v1::VOLUMETRIC_TERM_NODAL_AVERAGE) {
    options.volumetric = elastic::VolumetricTerm::kNodalAverage;
  }
  return options;
}

Status missing(std::string_view field) {
  return invalid_argument(std::string(field) + " must be set");
}

}  // namespace

StatusOr<scenes::CompressionParams> to_params(const v1::CompressionSpec& spec) {
  if (!spec.has_cell()) return missing("compression.cell");
  if (!spec.cell().has_material()) return missing("compression.cell.material");
  scenes::CompressionParams params;
  params.cell = to_cell(spec.cell(), cell::CellParams{});
  params.max_deformation = spec.max_deformation();
  params.load_points = spec.has_load_points() ? spec.load_points() : kDefaultLoadPoints;
  params.numerics = to_numerics(spec.numerics());
  if (Status s = scenes::validate(params, "compression."); !s.ok()) return s;
  return params;
}

StatusOr<scenes::IndentationParams> to_params(const v1::IndentationSpec& spec) {
  if (!spec.has_cell()) return missing("indentation.cell");
  if (!spec.cell().has_material()) return missing("indentation.cell.material");
  scenes::IndentationParams params;
  params.cell = to_cell(spec.cell(), cell::CellParams{});
  params.probe_radius_m = spec.probe_radius_m();
  params.max_indentation_m = spec.max_indentation_m();
  params.load_points = spec.has_load_points() ? spec.load_points() : kDefaultLoadPoints;
  params.numerics = to_numerics(spec.numerics());
  if (Status s = scenes::validate(params, "indentation."); !s.ok()) return s;
  return params;
}

Status validate(const v1::JobSpec& spec) {
  switch (spec.scene_case()) {
    case v1::JobSpec::kCompression:
      return to_params(spec.compression()).status();
    case v1::JobSpec::kIndentation:
      return to_params(spec.indentation()).status();
    case v1::JobSpec::kShearFlow:
      return validate(spec.shear_flow());
    case v1::JobSpec::SCENE_NOT_SET:
      break;
  }
  return invalid_argument("scene: one of compression, indentation, shear_flow must be set");
}

StatusOr<v1::JobSpec> job_spec_from_json(const std::string& json) {
  v1::JobSpec spec;
  google::protobuf::util::JsonParseOptions options;
  options.ignore_unknown_fields = false;  // a misspelt field is an error, not a silent default
  auto parsed = google::protobuf::util::JsonStringToMessage(json, &spec, options);
  if (!parsed.ok()) return invalid_argument("job spec JSON: " + std::string(parsed.message()));
  return spec;
}

std::string job_spec_to_json(const v1::JobSpec& spec) {
  std::string json;
  google::protobuf::util::JsonPrintOptions options;
  options.add_whitespace = true;
  options.preserve_proto_field_names = false;
  (void)google::protobuf::util::MessageToJsonString(spec, &json, options);
  return json;
}

}  // namespace cellflow::jobs
