// NT-MDT Nova text export: no header, three tab-separated columns with a
// decimal comma: piezo height (nm), DFL signal on approach, DFL signal on
// retract (nA, the photodiode current). The file stores no calibration, so
// ReadOptions must give the sensitivity (metres per unit of DFL signal, i.e.
// m/A, shown as "m/V" by Nova) and the spring constant.
// Rows run from the deepest point to the farthest, so the approach is read
// backwards. Nova pads the start of a column with a repeated constant value
// (an export artefact); that run is cropped to its last sample.
#include "io/afm/curve_finish.h"
#include "io/afm/format_readers.h"
#include "io/afm/text_util.h"

namespace cellflow::afm {
namespace {

constexpr double kNanometre = 1e-9;
constexpr double kNanoampere = 1e-9;

// Index of the first sample to keep: the last one of the constant run at the start.
std::size_t padding_end(const std::vector<double>& v) {
  std::size_t i = 1;
  while (i < v.size() && v[i] == v[0]) ++i;
  return i - 1;
}

}  // namespace

bool looks_like_ntmdt_txt(std::string_view text) {
  const auto lines = split_lines(text.substr(0, 512));
  if (lines.size() < 2) return false;
  const auto cells = split_fields(lines[0], '\t');
  if (cells.size() != 3) return false;
  for (auto c : cells) {
    if (!parse_number(c, true)) return false;
  }
  return trim(lines[0]).find(',') != std::string_view::npos;
}

StatusOr<ForceCurve> read_ntmdt_txt(const std::string& path, std::string_view text,
                                    const ReadOptions& options) {
  if (!options.spring_constant_n_per_m || !options.sensitivity_m_per_v) {
    return invalid_argument(
        path +
        ": NT-MDT text exports store no calibration; give ReadOptions "
        "spring_constant_n_per_m and sensitivity_m_per_v (metres per ampere of DFL signal)");
  }
  std::vector<double> height, dfl_approach, dfl_retract;
  const auto lines = split_lines(text);
  for (std::size_t r = 0; r < lines.size(); ++r) {
    if (trim(lines[r]).empty()) continue;
    const auto cells = split_fields(trim(lines[r]), '\t');
    if (cells.size() != 3) {
      return invalid_argument(path + ": line " + std::to_string(r + 1) + ": expected 3 columns, found " +
                              std::to_string(cells.size()));
    }
    double v[3];
    for (int c = 0; c < 3; ++c) {
      const auto x = parse_number(cells[c], true);
      if (!x) {
        return invalid_argument(path + ": line " + std::to_string(r + 1) + ": column " +
                                std::to_string(c + 1) + ": '" + std::string(trim(cells[c])) +
                                "' is not a number");
      }
      v[c] = *x;
    }
    height.push_back(v[0] * kNanometre);
    dfl_approach.push_back(v[1] * kNanoampere);
    dfl_retract.push_back(v[2] * kNanoampere);
  }
  if (height.size() < 2) return invalid_argument(path + ": fewer than 2 data rows");

  ForceCurve curve;
  curve.metadata.source_file = path;
  curve.metadata.format = "ntmdt-txt";
  curve.metadata.height_channel = "piezo height";
  curve.metadata.spring_constant_n_per_m = options.spring_constant_n_per_m;
  curve.metadata.sensitivity_m_per_v = options.sensitivity_m_per_v;
  const double sens = *options.sensitivity_m_per_v, k = *options.spring_constant_n_per_m;

  const std::size_t a0 = padding_end(dfl_approach), r0 = padding_end(dfl_retract);
  curve.metadata.entries["ntmdt.cropped-rows-approach"] = std::to_string(a0);
  curve.metadata.entries["ntmdt.cropped-rows-retract"] = std::to_string(r0);
  Segment approach{"approach", SegmentKind::kApproach, {}, {}, {}, {}, {}};
  for (std::size_t i = height.size(); i-- > a0;) {
    approach.height_m.push_back(height[i]);
    approach.deflection_m.push_back(dfl_approach[i] * sens);
    approach.force_n.push_back(dfl_approach[i] * sens * k);
  }
  Segment retract{"retract", SegmentKind::kRetract, {}, {}, {}, {}, {}};
  for (std::size_t i = r0; i < height.size(); ++i) {
    retract.height_m.push_back(height[i]);
    retract.deflection_m.push_back(dfl_retract[i] * sens);
    retract.force_n.push_back(dfl_retract[i] * sens * k);
  }
  curve.segments.push_back(std::move(approach));
  curve.segments.push_back(std::move(retract));
  Status finished = finish_curve(curve);
  if (!finished.ok()) return finished;
  return curve;
}

}  // namespace cellflow::afm
