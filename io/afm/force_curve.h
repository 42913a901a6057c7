// Data model of a measured AFM / FluidFM force curve. Every array is in SI
// units whatever the instrument wrote, so that fits and comparisons with the
// simulation never see nm, nN or volts.
//
// Sign conventions (all readers normalise to these):
//  - height_m: position of the cantilever base (piezo or measured height), with
//    the positive direction pointing towards the sample; during the approach it
//    increases. Instruments that count height away from the sample (JPK, NT-MDT)
//    are flipped by the reader; its origin is the instrument's.
//  - deflection_m: cantilever bending, positive when the tip is pushed back by
//    a repulsive force; force_n = spring constant * deflection_m (plus the
//    instrument's baseline offset, which readers keep: preprocessing removes it).
//  - tip_position_m = height_m - deflection_m: the tip's position, positive
//    towards the sample, so that indentation = tip position - contact position.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

namespace cellflow::afm {

enum class SegmentKind { kApproach, kPause, kRetract, kUnknown };

const char* segment_kind_name(SegmentKind kind);

struct Segment {
  std::string name;  // the instrument's name, e.g. "extend-spm"
  SegmentKind kind = SegmentKind::kUnknown;
  std::vector<double> time_s;        // empty when the file has no time base
  std::vector<double> height_m;      // see the sign convention above
  std::vector<double> deflection_m;  // empty when the spring constant is unknown
  std::vector<double> force_n;
  std::vector<double> tip_position_m;  // empty when deflection is unknown

  std::size_t size() const { return force_n.size(); }
};

struct CurveMetadata {
  std::string source_file;
  std::string format;  // "jpk-force", "afm-workshop-csv", "ntmdt-txt", "tab-export", "column-text"
  std::optional<double> spring_constant_n_per_m;
  std::optional<double> sensitivity_m_per_v;   // NT-MDT: metres per unit of DFL signal
  std::string height_channel;                  // which recorded height fills height_m
  bool height_sign_flipped = false;            // the reader negated the instrument's height
  std::map<std::string, std::string> entries;  // other header entries, verbatim
};

struct ForceCurve {
  CurveMetadata metadata;
  std::vector<Segment> segments;

  // First segment of that kind, or nullptr.
  const Segment* find(SegmentKind kind) const;
};

}  // namespace cellflow::afm
