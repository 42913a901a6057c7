// AFM Workshop single-curve CSV: "Force-Distance Curve", "Key:<tab>value"
// header lines, then four comma-separated columns: extend Z-sense, extend
// force, retract Z-sense, retract force, with units in the column names
// ("Extend Z-Sense(nm)"). The two segments may differ in length, so trailing
// cells of the shorter one are empty. No spring constant is stored: deflection
// and tip position stay empty unless ReadOptions gives one.
#include <array>

#include "io/afm/column_units.h"
#include "io/afm/curve_finish.h"
#include "io/afm/format_readers.h"
#include "io/afm/text_util.h"

namespace cellflow::afm {

bool looks_like_afm_workshop_csv(std::string_view text) {
  const auto lines = split_lines(text.substr(0, 256));
  return !lines.empty() && starts_with_ci(trim(lines[0]), "Force-Distance Curve");
}

StatusOr<ForceCurve> read_afm_workshop_csv(const std::string& path, std::string_view text,
                                           const ReadOptions& options) {
  const auto lines = split_lines(text);
  ForceCurve curve;
  curve.metadata.source_file = path;
  curve.metadata.format = "afm-workshop-csv";
  curve.metadata.height_channel = "Z-Sense";

  // Header: key/value lines up to the column-name line.
  std::size_t row = 1;
  for (; row < lines.size(); ++row) {
    const std::string_view line = trim(lines[row]);
    if (line.empty()) continue;
    if (line.find("Z-Sense") != std::string_view::npos) break;
    const std::size_t colon = line.find(':');
    if (colon != std::string_view::npos) {
      curve.metadata.entries[std::string(trim(line.substr(0, colon)))] =
          std::string(trim(line.substr(colon + 1)));
    }
  }
  if (row == lines.size()) return invalid_argument(path + ": no column header line (with 'Z-Sense') found");

  const auto names = split_fields(lines[row], ',');
  if (names.size() != 4) {
    return invalid_argument(path + ": line " + std::to_string(row + 1) + ": expected 4 columns, found " +
                            std::to_string(names.size()));
  }
  std::array<UnitSpec, 4> units;
  for (std::size_t c = 0; c < 4; ++c) {
    const HeaderName h = split_header_name(names[c]);
    auto u = parse_unit(h.unit);
    const Dimension want = (c % 2 == 0) ? Dimension::kLength : Dimension::kForce;
    if (!u.ok() || u->dimension != want) {
      return invalid_argument(path + ": line " + std::to_string(row + 1) + ": column '" +
                              std::string(trim(names[c])) + "': unit '" + h.unit + "' is not a " +
                              (want == Dimension::kLength ? "length" : "force") + " unit");
    }
    units[c] = *u;
  }

  Segment extend, retract;
  extend.name = "extend";
  extend.kind = SegmentKind::kApproach;
  retract.name = "retract";
  retract.kind = SegmentKind::kRetract;
  for (std::size_t r = row + 1; r < lines.size(); ++r) {
    if (trim(lines[r]).empty()) continue;
    const auto cells = split_fields(lines[r], ',');
    if (cells.size() > 4) {
      return invalid_argument(path + ": line " + std::to_string(r + 1) + ": more than 4 columns");
    }
    for (std::size_t seg = 0; seg < 2; ++seg) {
      const std::string_view z = 2 * seg < cells.size() ? trim(cells[2 * seg]) : std::string_view();
      const std::string_view f = 2 * seg + 1 < cells.size() ? trim(cells[2 * seg + 1]) : std::string_view();
      if (z.empty() && f.empty()) continue;
      const auto zv = parse_number(z);
      const auto fv = parse_number(f);
      if (!zv || !fv) {
        return invalid_argument(path + ": line " + std::to_string(r + 1) +
                                ": non-numeric or missing value in " + (seg == 0 ? "extend" : "retract") +
                                " columns");
      }
      Segment& s = seg == 0 ? extend : retract;
      s.height_m.push_back(*zv * units[2 * seg].to_si);
      s.force_n.push_back(*fv * units[2 * seg + 1].to_si);
    }
  }
  if (extend.size() == 0) return invalid_argument(path + ": no extend data rows");
  curve.metadata.spring_constant_n_per_m = options.spring_constant_n_per_m;
  curve.metadata.sensitivity_m_per_v = options.sensitivity_m_per_v;
  curve.segments.push_back(std::move(extend));
  if (retract.size() > 0) curve.segments.push_back(std::move(retract));
  Status finished = finish_curve(curve);
  if (!finished.ok()) return finished;
  return curve;
}

}  // namespace cellflow::afm
