// Studies (sweeps): a base job spec expanded over axes of values. Each axis
// names a field by its path in the protobuf JSON form of the spec
// ("compression.cell.youngsModulusPa") and lists JSON values; a point sets
// every axis' value in the JSON form and parses the result again with the
// strict parser, so a point is exactly the spec a user could have written.
// Light (protobuf and nlohmann_json): the server expands studies with it and
// the client edits specs with it (`cellflow submit --set PATH=VALUE`).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "cellflow/v1/spec.pb.h"
#include "physics/core/status.h"

namespace cellflow::jobs {

// Bounds of a study, checked before anything is expanded.
inline constexpr int kMaxStudyPoints = 10000;  // children of one study
inline constexpr int kMaxStudyAxes = 16;       // swept fields
inline constexpr std::size_t kMaxStudyPathBytes = 256;
inline constexpr std::size_t kMaxStudyValueBytes = 4096;

// Sets the field at `path` (dot-separated protobuf JSON names, or the proto
// field names; an element of a list of messages by its index, as in
// "suspension.cells[1].volumeFraction", when the spec has that element) of
// `spec` to the JSON value `value_json`. INVALID_ARGUMENT
// names `path_field` when the path is not a field of the spec (unknown, not
// a message on the way, a scene the spec does not set, a study) and
// `value_field` when the value is not JSON or not of the field's type.
StatusOr<v1::JobSpec> set_spec_field(const v1::JobSpec& spec, const std::string& path,
                                     const std::string& value_json, const std::string& path_field = "path",
                                     const std::string& value_field = "value");

// What a user types after `--set PATH=`: JSON stays as it is; anything that
// is not JSON (an enum name, a word) is taken as a JSON string.
std::string value_text_as_json(const std::string& text);
// "1,2,[3,4],\"a,b\"" -> {"1", "2", "[3,4]", "\"a,b\""}: commas inside
// brackets, braces or quotes do not split.
std::vector<std::string> split_value_list(const std::string& text);

struct StudyPoint {
  v1::JobSpec spec;
  std::vector<int> value_index;  // per axis: the index of its value at this point
  std::string label;             // "path=value, path=value"
};

// The number of points of a study (GRID: the product of the axis lengths,
// ZIP: the common length), or INVALID_ARGUMENT naming the field when the
// axes are malformed or there are more than max_points.
StatusOr<int> count_study_points(const v1::StudySpec& study, int max_points = kMaxStudyPoints);

// Every point of the study, in child order (GRID: the last axis varies
// fastest). Refuses nested studies, a base without a scene, unknown paths
// and values of the wrong type, naming study.base, study.axes[i].path or
// study.axes[i].values[k].
StatusOr<std::vector<StudyPoint>> expand_study(const v1::StudySpec& study, int max_points = kMaxStudyPoints);

}  // namespace cellflow::jobs
