#include "jobs/spec_json.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/util/json_util.h>

namespace cellflow::jobs {

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

std::string_view scene_name(const v1::JobSpec& spec) {
  const google::protobuf::OneofDescriptor* oneof = v1::JobSpec::descriptor()->FindOneofByName("scene");
  const google::protobuf::FieldDescriptor* field = spec.GetReflection()->GetOneofFieldDescriptor(spec, oneof);
  return field ? std::string_view(field->name()) : std::string_view();
}

std::vector<SceneCell> scene_cells(v1::JobSpec& spec, std::string* scene) {
  using google::protobuf::FieldDescriptor;
  std::vector<SceneCell> cells;
  const google::protobuf::OneofDescriptor* oneof = spec.GetDescriptor()->FindOneofByName("scene");
  const google::protobuf::Reflection* reflection = spec.GetReflection();
  const FieldDescriptor* field = oneof ? reflection->GetOneofFieldDescriptor(spec, oneof) : nullptr;
  if (field == nullptr || field->type() != FieldDescriptor::TYPE_MESSAGE) return cells;
  if (scene != nullptr) *scene = field->name();
  google::protobuf::Message* message = reflection->MutableMessage(&spec, field);
  // The set "cell" field of `m` (a CellSpec), if any.
  auto cell_of = [](google::protobuf::Message* m) -> v1::CellSpec* {
    const FieldDescriptor* cell = m->GetDescriptor()->FindFieldByName("cell");
    if (cell == nullptr || cell->is_repeated() || cell->message_type() != v1::CellSpec::descriptor() ||
        !m->GetReflection()->HasField(*m, cell))
      return nullptr;
    return static_cast<v1::CellSpec*>(m->GetReflection()->MutableMessage(m, cell));
  };
  if (v1::CellSpec* cell = cell_of(message)) cells.push_back({field->name() + ".cell", cell});
  const google::protobuf::Descriptor* type = message->GetDescriptor();
  for (int i = 0; i < type->field_count(); ++i) {
    const FieldDescriptor* repeated = type->field(i);
    if (!repeated->is_repeated() || repeated->type() != FieldDescriptor::TYPE_MESSAGE) continue;
    const int n = message->GetReflection()->FieldSize(*message, repeated);
    for (int k = 0; k < n; ++k) {
      google::protobuf::Message* element =
          message->GetReflection()->MutableRepeatedMessage(message, repeated, k);
      if (v1::CellSpec* cell = cell_of(element)) {
        cells.push_back({field->name() + "." + repeated->name() + "[" + std::to_string(k) + "].cell", cell});
      }
    }
  }
  return cells;
}

}  // namespace cellflow::jobs
