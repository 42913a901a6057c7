// Plain CSV / TSV whose first non-comment line names the columns with units:
//   force_n, force (nN), force [pN]            -> force
//   height_um, piezo height (nm), z (um)        -> height (towards the sample)
//   deflection (nm)                             -> deflection
//   tip position (um), tip_position_m           -> tip position
//   indentation (um), deformation_m,
//   displacement_m                              -> tip position relative to contact
//   deformation (no unit: delta / 2R)           -> ignored (needs R; a length column must be there)
//   time_s, time (ms)                           -> time
//   segment                                     -> approach/extend/0, retract/1, pause/2
// A column with a dimension needs a unit; an unknown or mismatched unit is an
// error naming the column. Other columns are ignored (listed in the metadata).
// Without a segment column the whole file is one approach segment.
// Delimiter: tab if the header has one, else ',', else ';'. '#' lines are comments.
#include <array>

#include "io/afm/column_units.h"
#include "io/afm/curve_finish.h"
#include "io/afm/format_readers.h"
#include "io/afm/text_util.h"

namespace cellflow::afm {
namespace {

enum class Role { kForce, kHeight, kDeflection, kTip, kIndentation, kTime, kSegment, kIgnored };

Role role_of(std::string quantity) {
  for (char& c : quantity) {
    if (c == '_' || c == '-') c = ' ';
  }
  if (quantity == "segment") return Role::kSegment;
  if (quantity == "time" || quantity == "t") return Role::kTime;
  if (quantity.find("force") != std::string::npos) return Role::kForce;
  if (quantity.find("deflection") != std::string::npos) return Role::kDeflection;
  if (quantity.find("indentation") != std::string::npos ||
      quantity.find("deformation") != std::string::npos ||
      quantity.find("displacement") != std::string::npos) {
    return Role::kIndentation;
  }
  if (quantity.find("tip") != std::string::npos) return Role::kTip;
  if (quantity.find("height") != std::string::npos || quantity == "z" || quantity.find("piezo") == 0) {
    return Role::kHeight;
  }
  return Role::kIgnored;
}

Dimension dimension_of(Role r) {
  switch (r) {
    case Role::kForce:
      return Dimension::kForce;
    case Role::kTime:
      return Dimension::kTime;
    case Role::kSegment:
    case Role::kIgnored:
      return Dimension::kNone;
    default:
      return Dimension::kLength;
  }
}

std::optional<SegmentKind> parse_segment(std::string_view s) {
  const std::string v = to_lower(trim(s));
  if (v == "approach" || v == "extend" || v == "0") return SegmentKind::kApproach;
  if (v == "retract" || v == "1") return SegmentKind::kRetract;
  if (v == "pause" || v == "2") return SegmentKind::kPause;
  return std::nullopt;
}

struct Column {
  Role role = Role::kIgnored;
  double to_si = 1.0;
};

}  // namespace

StatusOr<ForceCurve> read_column_text(const std::string& path, std::string_view text,
                                      const ReadOptions& options) {
  const auto lines = split_lines(text);
  std::size_t row = 0;
  while (row < lines.size() && (trim(lines[row]).empty() || trim(lines[row]).front() == '#')) ++row;
  if (row == lines.size()) return invalid_argument(path + ": no header line (file has no content)");
  const std::string_view header = trim(lines[row]);
  const char delim = header.find('\t') != std::string_view::npos  ? '\t'
                     : header.find(',') != std::string_view::npos ? ','
                                                                  : ';';
  const std::string where_header = path + ": line " + std::to_string(row + 1);

  ForceCurve curve;
  curve.metadata.source_file = path;
  curve.metadata.format = "column-text";
  std::vector<Column> cols;
  std::array<int, 8> index;
  index.fill(-1);
  for (std::string_view name : split_fields(header, delim)) {
    const HeaderName h = split_header_name(name);
    Column c;
    c.role = role_of(h.quantity);
    // A deformation without a unit is the dimensionless delta / (2 R): the
    // reader knows no R, so it leaves the column to a length column beside
    // it (a file of cellflow-run or validation/fe has displacement_m too).
    if (c.role == Role::kIndentation && h.unit.empty() &&
        h.quantity.find("deformation") != std::string::npos) {
      c.role = Role::kIgnored;
    }
    const Dimension want = dimension_of(c.role);
    if (want != Dimension::kNone) {
      if (h.unit.empty()) {
        return invalid_argument(where_header + ": column '" + std::string(trim(name)) +
                                "' has no unit (write e.g. 'force (nN)' or 'force_n')");
      }
      auto u = parse_unit(h.unit);
      if (!u.ok()) {
        return invalid_argument(where_header + ": column '" + std::string(trim(name)) +
                                "': " + u.status().message());
      }
      if (u->dimension != want) {
        return invalid_argument(where_header + ": column '" + std::string(trim(name)) + "': unit '" + h.unit +
                                "' does not fit the quantity");
      }
      c.to_si = u->to_si;
    }
    const auto r = static_cast<std::size_t>(c.role);
    if (c.role == Role::kIgnored) {
      curve.metadata.entries["column-text.ignored-column." + std::to_string(cols.size())] =
          std::string(trim(name));
    } else if (index[r] >= 0) {
      return invalid_argument(where_header + ": two columns for the same quantity ('" +
                              std::string(trim(name)) + "')");
    } else {
      index[r] = static_cast<int>(cols.size());
    }
    cols.push_back(c);
  }
  auto col = [&](Role r) { return index[static_cast<std::size_t>(r)]; };
  const bool has_position = col(Role::kHeight) >= 0 || col(Role::kTip) >= 0 || col(Role::kIndentation) >= 0;
  if (col(Role::kForce) < 0 || !has_position) {
    return invalid_argument(where_header +
                            ": need a force column and a height, tip position, indentation or "
                            "deformation column");
  }
  curve.metadata.height_channel = col(Role::kHeight) >= 0 ? "height"
                                  : col(Role::kTip) >= 0  ? "tip position"
                                                          : "indentation";
  curve.metadata.spring_constant_n_per_m = options.spring_constant_n_per_m;
  curve.metadata.sensitivity_m_per_v = options.sensitivity_m_per_v;

  Segment* current = nullptr;
  for (std::size_t r = row + 1; r < lines.size(); ++r) {
    const std::string_view line = trim(lines[r]);
    if (line.empty() || line.front() == '#') continue;
    const std::string where = path + ": line " + std::to_string(r + 1);
    const auto cells = split_fields(line, delim);
    if (cells.size() != cols.size()) {
      return invalid_argument(where + ": " + std::to_string(cells.size()) + " fields, the header names " +
                              std::to_string(cols.size()));
    }
    SegmentKind kind = SegmentKind::kApproach;
    if (col(Role::kSegment) >= 0) {
      const auto k = parse_segment(cells[col(Role::kSegment)]);
      if (!k)
        return invalid_argument(where + ": unknown segment '" +
                                std::string(trim(cells[col(Role::kSegment)])) + "'");
      kind = *k;
    }
    std::array<double, 8> v{};
    for (std::size_t c = 0; c < cols.size(); ++c) {
      if (cols[c].role == Role::kIgnored || cols[c].role == Role::kSegment) continue;
      const auto x = parse_number(cells[c]);
      if (!x) {
        return invalid_argument(where + ": field " + std::to_string(c + 1) + " '" +
                                std::string(trim(cells[c])) + "' is not a number");
      }
      v[static_cast<std::size_t>(cols[c].role)] = *x * cols[c].to_si;
    }
    if (current == nullptr || current->kind != kind) {
      curve.segments.emplace_back();
      current = &curve.segments.back();
      current->kind = kind;
      current->name = segment_kind_name(kind);
    }
    auto val = [&](Role role) { return v[static_cast<std::size_t>(role)]; };
    current->force_n.push_back(val(Role::kForce));
    if (col(Role::kTime) >= 0) current->time_s.push_back(val(Role::kTime));
    if (col(Role::kDeflection) >= 0) current->deflection_m.push_back(val(Role::kDeflection));
    const bool tip_given = col(Role::kTip) >= 0 || col(Role::kIndentation) >= 0;
    const double tip = col(Role::kTip) >= 0 ? val(Role::kTip) : val(Role::kIndentation);
    if (col(Role::kHeight) >= 0) {
      current->height_m.push_back(val(Role::kHeight));
    } else {
      // Only the tip is known: the base sits a deflection behind it.
      const double deflection = col(Role::kDeflection) >= 0 ? val(Role::kDeflection)
                                : options.spring_constant_n_per_m && *options.spring_constant_n_per_m > 0
                                    ? val(Role::kForce) / *options.spring_constant_n_per_m
                                    : 0.0;
      current->height_m.push_back(tip + deflection);
    }
    if (tip_given) current->tip_position_m.push_back(tip);
  }
  if (curve.segments.empty()) return invalid_argument(path + ": no data rows after the header");
  Status finished = finish_curve(curve);
  if (!finished.ok()) return finished;
  return curve;
}

}  // namespace cellflow::afm
