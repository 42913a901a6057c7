#include "jobs/study/study.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/util/json_util.h>

#include <nlohmann/json.hpp>
#include <set>

#include "jobs/spec_json.h"

namespace cellflow::jobs {
namespace {

using google::protobuf::Descriptor;
using google::protobuf::FieldDescriptor;
using Json = nlohmann::json;

std::vector<std::string> split_path(const std::string& path) {
  std::vector<std::string> parts;
  std::size_t start = 0;
  while (true) {
    const std::size_t dot = path.find('.', start);
    parts.push_back(path.substr(start, dot == std::string::npos ? std::string::npos : dot - start));
    if (dot == std::string::npos) break;
    start = dot + 1;
  }
  return parts;
}

const FieldDescriptor* find_field(const Descriptor* message, const std::string& name) {
  for (int i = 0; i < message->field_count(); ++i) {
    const FieldDescriptor* field = message->field(i);
    if (field->json_name() == name || field->name() == name) return field;
  }
  return nullptr;
}

std::string field_names(const Descriptor* message) {
  std::string names;
  for (int i = 0; i < message->field_count(); ++i) {
    names += (names.empty() ? "" : ", ") + message->field(i)->json_name();
  }
  return names;
}

// One step of a path: a field's JSON name and, for an element of a repeated
// message field ("cells[1]"), the element's index.
struct PathStep {
  std::string key;
  int index = -1;  // -1: the field itself
};

// Bound of an element index in a path: a spec cannot hold more elements in
// its 4 MiB anyway, and six digits cannot overflow an int.
constexpr std::size_t kMaxPathIndexDigits = 6;

// "cells[1]" -> {"cells", 1}; "cells" -> {"cells", -1}; an error text for a
// malformed index ("cells[", "cells[-1]", "cells[x]").
StatusOr<PathStep> parse_path_part(const std::string& path, const std::string& part) {
  const std::size_t open = part.find('[');
  if (open == std::string::npos) {
    if (part.find(']') != std::string::npos) {
      return invalid_argument("\"" + path + "\": \"" + part + "\" has a ']' without '['");
    }
    return PathStep{part, -1};
  }
  const std::string digits = part.substr(open + 1, part.size() - open - 2);
  if (part.back() != ']' || digits.empty() || digits.size() > kMaxPathIndexDigits ||
      digits.find_first_not_of("0123456789") != std::string::npos) {
    return invalid_argument("\"" + path + "\": \"" + part +
                            "\" is not NAME or NAME[INDEX] with a decimal INDEX (e.g. cells[0])");
  }
  return PathStep{part.substr(0, open), std::stoi(digits)};
}

// The JSON steps along `path`, checked against the spec's messages; an error
// text (without the field name) when the path names no settable field of
// `json`. An element of a list is reached by its index, and only when the
// spec has it: a study changes elements, it does not add them.
StatusOr<std::vector<PathStep>> resolve_path(const std::string& path, const Json& json) {
  if (path.empty()) return invalid_argument("empty (a field path such as compression.cell.youngsModulusPa)");
  if (path.size() > kMaxStudyPathBytes) {
    return invalid_argument(std::to_string(path.size()) + " bytes; at most " +
                            std::to_string(kMaxStudyPathBytes));
  }
  std::vector<PathStep> steps;
  const Descriptor* message = v1::JobSpec::descriptor();
  const Json* object = &json;
  std::string walked = "the spec";
  const std::vector<std::string> parts = split_path(path);
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const std::string& part = parts[i];
    if (message == nullptr) {
      return invalid_argument("\"" + path + "\": " + walked + " is not a message; \"" + part +
                              "\" cannot be a field of it");
    }
    if (part.empty()) return invalid_argument("\"" + path + "\": an empty name between dots");
    auto step = parse_path_part(path, part);
    if (!step.ok()) return step.status();
    const FieldDescriptor* field = find_field(message, step->key);
    if (field == nullptr) {
      return invalid_argument("\"" + path + "\": " + walked + " (" + message->full_name() +
                              ") has no field \"" + step->key + "\"; its fields: " + field_names(message));
    }
    if (message == v1::JobSpec::descriptor() && field->number() == v1::JobSpec::kStudyFieldNumber) {
      return invalid_argument("\"" + path + "\": a study cannot set a study (nested studies are refused)");
    }
    // A scene of the oneof other than the one the spec sets would make a second scene.
    if (const auto* oneof = field->real_containing_oneof()) {
      for (int k = 0; k < oneof->field_count(); ++k) {
        const FieldDescriptor* other = oneof->field(k);
        if (other != field && object != nullptr && object->is_object() &&
            object->contains(other->json_name())) {
          return invalid_argument("\"" + path + "\": the spec sets " + other->json_name() + ", not " +
                                  field->json_name() + " (one of " + oneof->name() + ")");
        }
      }
    }
    const bool indexed = step->index >= 0;
    if (indexed &&
        (!field->is_repeated() || field->is_map() || field->type() != FieldDescriptor::TYPE_MESSAGE)) {
      return invalid_argument("\"" + path + "\": " + field->json_name() +
                              " is not a list of messages; it takes no [index]");
    }
    const Json* value = object != nullptr && object->is_object() && object->contains(field->json_name())
                            ? &(*object)[field->json_name()]
                            : nullptr;
    if (indexed) {
      const std::size_t size = value != nullptr && value->is_array() ? value->size() : 0;
      if (static_cast<std::size_t>(step->index) >= size) {
        return invalid_argument("\"" + path + "\": " + field->json_name() + " has " + std::to_string(size) +
                                " element(s) in the spec, so [" + std::to_string(step->index) +
                                "] does not exist (a study changes elements; it does not add them)");
      }
      value = &(*value)[static_cast<std::size_t>(step->index)];
    }
    steps.push_back(PathStep{field->json_name(), step->index});
    const bool last = i + 1 == parts.size();
    if (!last) {
      if (field->type() != FieldDescriptor::TYPE_MESSAGE || (field->is_repeated() && !indexed)) {
        return invalid_argument("\"" + path + "\": " + field->json_name() + " is " +
                                (field->is_map() ? "a map"
                                 : field->is_repeated()
                                     ? "a list (name an element: " + field->json_name() + "[0])"
                                     : "not a message") +
                                "; only its whole value can be set");
      }
      // Well-known types have JSON forms of their own (a Timestamp is a string).
      if (field->message_type()->file()->package() == "google.protobuf") {
        return invalid_argument("\"" + path + "\": " + field->json_name() + " (" +
                                field->message_type()->full_name() +
                                ") has a JSON form of its own; set it whole");
      }
      message = field->message_type();
      walked = indexed ? field->json_name() + "[" + std::to_string(step->index) + "]" : field->json_name();
      object = value;
    }
  }
  return steps;
}

std::string spec_json_compact(const v1::JobSpec& spec) {
  std::string text;
  google::protobuf::util::JsonPrintOptions options;
  options.preserve_proto_field_names = false;
  (void)google::protobuf::util::MessageToJsonString(spec, &text, options);
  return text;
}

// Sets steps -> value in `json`, creating the objects on the way (the
// elements a step indexes exist: resolve_path checked them).
void set_at(Json& json, const std::vector<PathStep>& steps, Json value) {
  Json* node = &json;
  for (std::size_t i = 0; i < steps.size(); ++i) {
    const bool last = i + 1 == steps.size();
    Json& child = (*node)[steps[i].key];
    if (steps[i].index >= 0) {
      Json& element = child[static_cast<std::size_t>(steps[i].index)];
      if (last) {
        element = std::move(value);
        return;
      }
      if (!element.is_object()) element = Json::object();
      node = &element;
      continue;
    }
    if (last) {
      child = std::move(value);
      return;
    }
    if (!child.is_object()) child = Json::object();
    node = &child;
  }
}

StatusOr<Json> parse_value(const std::string& value_json) {
  if (value_json.size() > kMaxStudyValueBytes) {
    return invalid_argument(std::to_string(value_json.size()) + " bytes; at most " +
                            std::to_string(kMaxStudyValueBytes));
  }
  Json value = Json::parse(value_json, nullptr, /*allow_exceptions=*/false);
  if (value.is_discarded()) {
    return invalid_argument("\"" + value_json +
                            "\" is not a JSON value (a string needs quotes: \"\\\"TEXT\\\"\")");
  }
  return value;
}

Status prefixed(const std::string& field, const Status& status) {
  return invalid_argument(field + ": " + status.message());
}

}  // namespace

StatusOr<v1::JobSpec> set_spec_field(const v1::JobSpec& spec, const std::string& path,
                                     const std::string& value_json, const std::string& path_field,
                                     const std::string& value_field) {
  Json json = Json::parse(spec_json_compact(spec), nullptr, false);
  if (json.is_discarded()) return Status(StatusCode::kInternal, "the spec did not print as JSON");
  auto keys = resolve_path(path, json);
  if (!keys.ok()) return prefixed(path_field, keys.status());
  auto value = parse_value(value_json);
  if (!value.ok()) return prefixed(value_field, value.status());
  set_at(json, *keys, std::move(*value));
  auto parsed = job_spec_from_json(json.dump());
  if (!parsed.ok()) {
    return invalid_argument(value_field + ": " + value_json + " does not fit " + path + " (" +
                            parsed.status().message() + ")");
  }
  return parsed;
}

std::string value_text_as_json(const std::string& text) {
  const Json value = Json::parse(text, nullptr, false);
  return value.is_discarded() ? Json(text).dump() : text;
}

std::vector<std::string> split_value_list(const std::string& text) {
  std::vector<std::string> values;
  std::string current;
  int depth = 0;
  bool in_string = false;
  bool escaped = false;
  for (char c : text) {
    if (in_string) {
      current += c;
      if (escaped) {
        escaped = false;
      } else if (c == '\\') {
        escaped = true;
      } else if (c == '"') {
        in_string = false;
      }
      continue;
    }
    if (c == '"') in_string = true;
    if (c == '[' || c == '{') ++depth;
    if ((c == ']' || c == '}') && depth > 0) --depth;
    if (c == ',' && depth == 0) {
      values.push_back(current);
      current.clear();
      continue;
    }
    current += c;
  }
  values.push_back(current);
  return values;
}

StatusOr<int> count_study_points(const v1::StudySpec& study, int max_points) {
  if (study.axes_size() == 0)
    return invalid_argument("study.axes: at least one axis (a path and its values)");
  if (study.axes_size() > kMaxStudyAxes) {
    return invalid_argument("study.axes: " + std::to_string(study.axes_size()) + " axes; at most " +
                            std::to_string(kMaxStudyAxes));
  }
  if (!v1::StudySpec::Combination_IsValid(study.combination())) {
    return invalid_argument("study.combination: unknown (GRID or ZIP)");
  }
  std::set<std::string> paths;
  for (int i = 0; i < study.axes_size(); ++i) {
    const std::string field = "study.axes[" + std::to_string(i) + "]";
    if (study.axes(i).values_size() == 0) return invalid_argument(field + ".values: at least one value");
    if (!paths.insert(study.axes(i).path()).second) {
      return invalid_argument(field + ".path: \"" + study.axes(i).path() +
                              "\" is swept by an earlier axis too");
    }
  }
  const bool zip = study.combination() == v1::StudySpec::ZIP;
  std::int64_t points = zip ? study.axes(0).values_size() : 1;
  for (int i = 0; i < study.axes_size(); ++i) {
    const int n = study.axes(i).values_size();
    if (zip && n != points) {
      return invalid_argument("study.axes[" + std::to_string(i) + "].values: " + std::to_string(n) +
                              " values, axis 0 has " + std::to_string(points) +
                              " (ZIP takes axes of equal length)");
    }
    if (!zip) points *= n;
    if (points > max_points) {
      return invalid_argument("study.axes: " + std::string(zip ? "" : "at least ") + std::to_string(points) +
                              " points; a study has at most " + std::to_string(max_points));
    }
  }
  return static_cast<int>(points);
}

StatusOr<std::vector<StudyPoint>> expand_study(const v1::StudySpec& study, int max_points) {
  if (!study.has_base() || scene_name(study.base()).empty()) {
    return invalid_argument(
        "study.base: a job spec with a scene (compression, indentation, shearFlow, fit, suspension)");
  }
  if (study.base().has_study()) {
    return invalid_argument("study.base: a study cannot hold a study (nested studies are refused)");
  }
  auto count = count_study_points(study, max_points);
  if (!count.ok()) return count.status();

  // Every path and value checked once, before the points are made.
  const Json base = Json::parse(spec_json_compact(study.base()), nullptr, false);
  std::vector<std::vector<PathStep>> keys(study.axes_size());
  std::vector<std::vector<Json>> values(study.axes_size());
  for (int i = 0; i < study.axes_size(); ++i) {
    const std::string field = "study.axes[" + std::to_string(i) + "]";
    auto resolved = resolve_path(study.axes(i).path(), base);
    if (!resolved.ok()) return prefixed(field + ".path", resolved.status());
    keys[i] = *resolved;
    for (int k = 0; k < study.axes(i).values_size(); ++k) {
      const std::string value_field = field + ".values[" + std::to_string(k) + "]";
      auto value = parse_value(study.axes(i).values(k));
      if (!value.ok()) return prefixed(value_field, value.status());
      // Each value alone on the base: a type error names this value.
      Json single = base;
      set_at(single, keys[i], *value);
      if (auto parsed = job_spec_from_json(single.dump()); !parsed.ok()) {
        return invalid_argument(value_field + ": " + study.axes(i).values(k) + " does not fit " +
                                study.axes(i).path() + " (" + parsed.status().message() + ")");
      }
      values[i].push_back(std::move(*value));
    }
  }

  const bool zip = study.combination() == v1::StudySpec::ZIP;
  std::vector<StudyPoint> points;
  points.reserve(static_cast<std::size_t>(*count));
  for (int p = 0; p < *count; ++p) {
    StudyPoint point;
    point.value_index.resize(static_cast<std::size_t>(study.axes_size()));
    int rest = p;
    for (int i = study.axes_size() - 1; i >= 0; --i) {
      const int n = study.axes(i).values_size();
      point.value_index[static_cast<std::size_t>(i)] = zip ? p : rest % n;
      if (!zip) rest /= n;
    }
    Json json = base;
    for (int i = 0; i < study.axes_size(); ++i) {
      const int k = point.value_index[static_cast<std::size_t>(i)];
      set_at(json, keys[static_cast<std::size_t>(i)],
             values[static_cast<std::size_t>(i)][static_cast<std::size_t>(k)]);
      point.label += (i == 0 ? "" : ", ") + study.axes(i).path() + "=" + study.axes(i).values(k);
    }
    auto parsed = job_spec_from_json(json.dump());
    if (!parsed.ok())
      return invalid_argument("study point " + std::to_string(p) + " (" + point.label +
                              "): " + parsed.status().message());
    point.spec = std::move(*parsed);
    points.push_back(std::move(point));
  }
  return points;
}

}  // namespace cellflow::jobs
