// Tab-separated export with a JSON metadata block (afmformats' .tab): '#'
// comment lines, the JSON object between "# BEGIN METADATA" and
// "# END METADATA", a '#' line naming the columns, then rows. Columns are in
// SI already: force (N), height (measured) / height (piezo) (m), time (s),
// segment (False/True or 0/1: approach/retract).
// Known defect of some exports (version 0.13.3 among them): the column line
// lacks its line break, so the first data row is glued to the last column
// name ("...\ttime-6.77e-10\t5.51e-05..."). The reader splits it off again and
// notes it in the metadata ("tab.glued-first-row").
#include <nlohmann/json.hpp>

#include "io/afm/curve_finish.h"
#include "io/afm/format_readers.h"
#include "io/afm/text_util.h"

namespace cellflow::afm {
namespace {

// "time-6.77e-10" -> {"time", "-6.77e-10"}: the shortest tail that is a number.
std::optional<std::pair<std::string, std::string>> split_glued(std::string_view field) {
  for (std::size_t i = 1; i < field.size(); ++i) {
    if (parse_number(field.substr(i)))
      return std::pair{std::string(field.substr(0, i)), std::string(field.substr(i))};
  }
  return std::nullopt;
}

std::optional<int> segment_code(std::string_view s) {
  s = trim(s);
  if (s == "False" || s == "false" || s == "0") return 0;
  if (s == "True" || s == "true" || s == "1") return 1;
  return std::nullopt;
}

}  // namespace

bool looks_like_tab_export(std::string_view text) {
  return text.substr(0, 4096).find("# BEGIN METADATA") != std::string_view::npos;
}

StatusOr<ForceCurve> read_tab_export(const std::string& path, std::string_view text,
                                     const ReadOptions& options) {
  const auto lines = split_lines(text);
  ForceCurve curve;
  curve.metadata.source_file = path;
  curve.metadata.format = "tab-export";

  std::string json_text;
  bool in_json = false, json_done = false;
  std::vector<std::string> names;
  std::vector<std::string_view> glued_row;
  std::size_t row = 0;
  std::size_t header_line = 0;
  for (; row < lines.size(); ++row) {
    std::string_view line = trim(lines[row]);
    if (line.empty()) continue;
    if (line.front() != '#') break;
    line.remove_prefix(1);
    if (trim(line) == "BEGIN METADATA") {
      in_json = true;
    } else if (trim(line) == "END METADATA") {
      in_json = false;
      json_done = true;
    } else if (in_json) {
      json_text.append(line).push_back('\n');
    } else if (json_done && !trim(line).empty()) {
      header_line = row + 1;
      names.clear();
      glued_row.clear();
      for (std::string_view f : split_fields(trim(line), '\t')) {
        if (!glued_row.empty() || parse_number(f)) {
          glued_row.push_back(f);
        } else {
          names.emplace_back(trim(f));
        }
      }
    }
  }
  if (!json_done) return invalid_argument(path + ": no complete BEGIN/END METADATA block");
  if (names.empty()) return invalid_argument(path + ": no column-name line after the metadata block");
  if (!glued_row.empty()) {
    auto split = split_glued(names.back());
    if (!split || glued_row.size() + 1 != names.size()) {
      return invalid_argument(path + ": line " + std::to_string(header_line) +
                              ": malformed column-name line");
    }
    names.back() = split->first;
    curve.metadata.entries["tab.glued-first-row"] = "true";
  }

  const nlohmann::json meta = nlohmann::json::parse(json_text, nullptr, /*allow_exceptions=*/false);
  if (meta.is_discarded() || !meta.is_object())
    return invalid_argument(path + ": metadata block is not valid JSON");
  for (const auto& [key, value] : meta.items()) {
    curve.metadata.entries[key] = value.is_string() ? value.get<std::string>() : value.dump();
  }
  if (meta.contains("spring constant") && meta["spring constant"].is_number()) {
    curve.metadata.spring_constant_n_per_m = meta["spring constant"].get<double>();
  }
  if (meta.contains("sensitivity") && meta["sensitivity"].is_number()) {
    curve.metadata.sensitivity_m_per_v = meta["sensitivity"].get<double>();
  }
  // A user calibration replaces the stored one; force is what was measured,
  // so the deflection follows the spring constant (finish_curve).
  if (options.spring_constant_n_per_m)
    curve.metadata.spring_constant_n_per_m = options.spring_constant_n_per_m;
  if (options.sensitivity_m_per_v) curve.metadata.sensitivity_m_per_v = options.sensitivity_m_per_v;

  auto column = [&](const char* name) -> int {
    for (std::size_t i = 0; i < names.size(); ++i) {
      if (names[i] == name) return static_cast<int>(i);
    }
    return -1;
  };
  const int c_force = column("force"), c_seg = column("segment"), c_time = column("time");
  int c_height = column("height (measured)");
  curve.metadata.height_channel = "height (measured)";
  if (c_height < 0) {
    c_height = column("height (piezo)");
    curve.metadata.height_channel = "height (piezo)";
  }
  if (c_force < 0 || c_height < 0)
    return invalid_argument(path + ": needs 'force' and a 'height (...)' column");

  Segment* current = nullptr;
  int current_code = -1;
  auto add_row = [&](const std::vector<std::string_view>& cells, std::size_t line_no) -> Status {
    if (cells.size() != names.size()) {
      return invalid_argument(path + ": line " + std::to_string(line_no) + ": " +
                              std::to_string(cells.size()) + " columns, the header names " +
                              std::to_string(names.size()));
    }
    const int code = c_seg >= 0 ? segment_code(cells[c_seg]).value_or(-1) : 0;
    if (code < 0) return invalid_argument(path + ": line " + std::to_string(line_no) + ": bad segment value");
    const auto f = parse_number(cells[c_force]);
    const auto h = parse_number(cells[c_height]);
    const auto t = c_time >= 0 ? parse_number(cells[c_time]) : std::optional<double>(0.0);
    if (!f || !h || !t)
      return invalid_argument(path + ": line " + std::to_string(line_no) + ": non-numeric value");
    if (current == nullptr || code != current_code) {
      curve.segments.emplace_back();
      current = &curve.segments.back();
      current->kind = code == 0 ? SegmentKind::kApproach : SegmentKind::kRetract;
      current->name = code == 0 ? "approach" : "retract";
      current_code = code;
    }
    current->force_n.push_back(*f);
    current->height_m.push_back(*h);
    if (c_time >= 0) current->time_s.push_back(*t);
    return Status::ok_status();
  };

  if (!glued_row.empty()) {
    std::vector<std::string_view> cells;
    const auto split = split_glued(split_fields(trim(lines[header_line - 1]), '\t')[names.size() - 1]);
    std::vector<std::string> keep{split->second};
    cells.push_back(keep[0]);
    for (auto g : glued_row) cells.push_back(g);
    if (Status s = add_row(cells, header_line); !s.ok()) return s;
  }
  for (; row < lines.size(); ++row) {
    const std::string_view line = trim(lines[row]);
    if (line.empty() || line.front() == '#') continue;
    if (Status s = add_row(split_fields(line, '\t'), row + 1); !s.ok()) return s;
  }
  if (curve.segments.empty()) return invalid_argument(path + ": no data rows");
  Status finished = finish_curve(curve);
  if (!finished.ok()) return finished;
  return curve;
}

}  // namespace cellflow::afm
