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

v1::CellSpec* mutable_scene_cell(v1::JobSpec& spec, std::string* scene) {
  const google::protobuf::OneofDescriptor* oneof = spec.GetDescriptor()->FindOneofByName("scene");
  const google::protobuf::Reflection* reflection = spec.GetReflection();
  const google::protobuf::FieldDescriptor* field =
      oneof ? reflection->GetOneofFieldDescriptor(spec, oneof) : nullptr;
  if (field == nullptr || field->type() != google::protobuf::FieldDescriptor::TYPE_MESSAGE) return nullptr;
  google::protobuf::Message* message = reflection->MutableMessage(&spec, field);
  const google::protobuf::FieldDescriptor* cell = message->GetDescriptor()->FindFieldByName("cell");
  if (cell == nullptr || cell->message_type() != v1::CellSpec::descriptor() ||
      !message->GetReflection()->HasField(*message, cell)) {
    return nullptr;
  }
  if (scene != nullptr) *scene = field->name();
  return static_cast<v1::CellSpec*>(message->GetReflection()->MutableMessage(message, cell));
}

}  // namespace cellflow::jobs
