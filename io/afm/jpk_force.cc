// JPK .jpk-force reader: a zip of Java .properties headers and big-endian
// channel data, one folder per segment (segments/N/). Channel definitions are
// either in the segment header itself or, in newer files, shared: the segment
// says "channel.height.lcd-info.*=0" and shared-data/header.properties holds
// "lcd-info.0.*". The same indirection exists for the segment settings
// ("force-segment-header.force-segment-header-info.*=N").
#include <algorithm>
#include <charconv>
#include <map>

#include "io/afm/curve_finish.h"
#include "io/afm/format_readers.h"
#include "io/afm/java_properties.h"
#include "io/afm/jpk_channel.h"
#include "io/afm/text_util.h"
#include "io/afm/zip_archive.h"

namespace cellflow::afm {
namespace {

// Copies shared "GROUP.N.rest" entries to "PARENT.rest" for every
// "PARENT.GROUP.*=N" entry of the segment header; entries already present in
// the segment win.
void resolve_shared_references(Properties& seg, const Properties& shared) {
  std::vector<std::pair<std::string, std::string>> refs;
  for (const auto& [key, value] : seg) {
    if (key.size() > 2 && key.compare(key.size() - 2, 2, ".*") == 0) refs.emplace_back(key, value);
  }
  for (const auto& [key, value] : refs) {
    const std::string stem = key.substr(0, key.size() - 2);  // "channel.height.lcd-info"
    const std::size_t dot = stem.rfind('.');
    if (dot == std::string::npos) continue;
    const std::string parent = stem.substr(0, dot);  // "channel.height"
    const std::string group = stem.substr(dot + 1);  // "lcd-info"
    const std::string prefix = group + "." + std::string(trim(value)) + ".";
    for (auto it = shared.lower_bound(prefix); it != shared.end() && it->first.rfind(prefix, 0) == 0; ++it) {
      seg.try_emplace(parent + "." + it->first.substr(prefix.size()), it->second);
    }
  }
}

std::optional<std::size_t> parse_count(const std::string* s) {
  if (s == nullptr) return std::nullopt;
  const std::string_view v = trim(*s);
  std::size_t n = 0;
  auto [end, ec] = std::from_chars(v.data(), v.data() + v.size(), n);
  if (ec != std::errc() || end != v.data() + v.size()) return std::nullopt;
  return n;
}

const std::string* find(const Properties& p, const std::string& key) {
  const auto it = p.find(key);
  return it == p.end() ? nullptr : &it->second;
}

SegmentKind kind_of(const Properties& seg, std::string& name) {
  const std::string* n = find(seg, "force-segment-header.name.name");
  if (n == nullptr) n = find(seg, "force-segment-header.settings.segment-settings.identifier.name");
  name = n ? *n : "";
  const std::string* style = find(seg, "force-segment-header.settings.style");
  if (style == nullptr) style = find(seg, "force-segment-header.settings.segment-settings.style");
  const std::string s = style ? *style : name;
  if (s.find("extend") != std::string::npos) return SegmentKind::kApproach;
  if (s.find("retract") != std::string::npos) return SegmentKind::kRetract;
  if (s.find("pause") != std::string::npos) return SegmentKind::kPause;
  return SegmentKind::kUnknown;
}

bool has_channel(const Properties& seg, const std::string& channel) {
  const std::string* list = find(seg, "channels.list");
  if (list == nullptr) return false;
  for (std::string_view c : split_fields(*list, ' ')) {
    if (c == channel) return true;
  }
  return false;
}

// Measured height first (a sensor, linear), the piezo's own height otherwise.
struct HeightChoice {
  std::string channel, slot;
};
std::optional<HeightChoice> choose_height(const Properties& seg) {
  for (const char* c : {"strainGaugeHeight", "capacitiveSensorHeight", "measuredHeight"}) {
    if (has_channel(seg, c)) return HeightChoice{c, "nominal"};
  }
  for (const char* c : {"height", "head-height"}) {
    if (has_channel(seg, c)) return HeightChoice{c, "calibrated"};
  }
  return std::nullopt;
}

// Segment indices N of every "segments/N/segment-header.properties", sorted.
std::vector<std::size_t> segment_indices(const ZipArchive& zip) {
  std::vector<std::size_t> out;
  const std::string head = "segments/", tail = "/segment-header.properties";
  for (const std::string& name : zip.names()) {
    if (name.size() <= head.size() + tail.size() || name.rfind(head, 0) != 0 ||
        name.compare(name.size() - tail.size(), tail.size(), tail) != 0) {
      continue;
    }
    const std::string mid = name.substr(head.size(), name.size() - head.size() - tail.size());
    if (auto n = parse_count(&mid)) out.push_back(*n);
  }
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace

StatusOr<ForceCurve> read_jpk_force(const std::string& path, const std::string& bytes,
                                    const ReadOptions& options) {
  ZipLimits limits;
  limits.max_entry_bytes = options.max_entry_bytes;
  limits.max_total_bytes = options.max_total_uncompressed_bytes;
  auto zip = ZipArchive::open(bytes, path, limits);
  if (!zip.ok()) return zip.status();

  auto header_text = zip->read("header.properties");
  if (!header_text.ok()) return header_text.status();
  const Properties header = parse_java_properties(*header_text);
  Properties shared;
  if (zip->contains("shared-data/header.properties")) {
    auto shared_text = zip->read("shared-data/header.properties");
    if (!shared_text.ok()) return shared_text.status();
    shared = parse_java_properties(*shared_text);
  }

  ForceCurve curve;
  curve.metadata.source_file = path;
  curve.metadata.format = "jpk-force";
  for (const auto& [k, v] : header) curve.metadata.entries.emplace(k, v);

  const std::vector<std::size_t> indices = segment_indices(*zip);
  if (indices.empty())
    return invalid_argument(path + ": no segments/N/segment-header.properties in the archive");
  curve.metadata.entries["jpk.segments-in-archive"] = std::to_string(indices.size());

  std::map<std::string, double> deflection_overrides;  // slot -> multiplier
  if (options.sensitivity_m_per_v) deflection_overrides["distance"] = *options.sensitivity_m_per_v;
  if (options.spring_constant_n_per_m) deflection_overrides["force"] = *options.spring_constant_n_per_m;

  std::optional<HeightChoice> height;
  double t0 = 0.0;
  for (std::size_t index : indices) {
    const std::string dir = "segments/" + std::to_string(index) + "/";
    const std::string seg_name = dir + "segment-header.properties";
    auto seg_text = zip->read(seg_name);
    if (!seg_text.ok()) return seg_text.status();
    Properties seg = parse_java_properties(*seg_text);
    resolve_shared_references(seg, shared);

    const auto num_points = parse_count(find(seg, "force-segment-header.num-points"));
    if (!num_points) return invalid_argument(path + ": " + seg_name + ": missing or invalid num-points");

    Segment out;
    out.kind = kind_of(seg, out.name);
    if (!height) {
      height = choose_height(seg);
      if (!height) return invalid_argument(path + ": " + seg_name + ": no height channel in channels.list");
      curve.metadata.height_channel = height->channel + " (" + height->slot + ")";
    }
    if (!has_channel(seg, "vDeflection")) {
      return invalid_argument(path + ": " + seg_name + ": no vDeflection channel in channels.list");
    }
    if (!has_channel(seg, height->channel)) {
      return invalid_argument(path + ": " + seg_name + ": height channel " + height->channel +
                              " missing in this segment");
    }

    // Calibration of the deflection, from the first segment that has one.
    if (!curve.metadata.spring_constant_n_per_m) {
      curve.metadata.spring_constant_n_per_m = jpk_conversion_multiplier(seg, "vDeflection", "force");
      curve.metadata.sensitivity_m_per_v = jpk_conversion_multiplier(seg, "vDeflection", "distance");
    }

    auto decode = [&](const std::string& channel, const std::string& slot,
                      const std::map<std::string, double>& overrides) -> StatusOr<std::vector<double>> {
      const std::string* file = jpk_channel_key(seg, channel, "file.name");
      if (file == nullptr)
        return invalid_argument(path + ": " + seg_name + ": channel " + channel + " has no data file");
      const std::string entry = dir + *file;
      std::size_t points = *num_points;
      if (auto own = parse_count(jpk_channel_key(seg, channel, "num-points"))) {
        if (*own != points) {
          return invalid_argument(path + ": " + entry + ": channel declares " + std::to_string(*own) +
                                  " points, the segment " + std::to_string(points));
        }
      }
      auto data = zip->read(entry);
      if (!data.ok()) return data.status();
      return decode_jpk_channel(seg, *data, {channel, slot, points, path + ": " + entry, overrides});
    };

    auto h = decode(height->channel, height->slot, {});
    if (!h.ok()) return h.status();
    auto d = decode("vDeflection", "distance", deflection_overrides);
    if (!d.ok()) return d.status();
    auto f = decode("vDeflection", "force", deflection_overrides);
    if (!f.ok()) return f.status();
    out.height_m = std::move(*h);
    out.deflection_m = std::move(*d);
    out.force_n = std::move(*f);

    if (const std::string* dur = find(seg, "force-segment-header.duration")) {
      if (auto seconds = parse_number(*dur); seconds && *num_points > 0) {
        out.time_s.resize(*num_points);
        for (std::size_t i = 0; i < *num_points; ++i) out.time_s[i] = t0 + *seconds * i / *num_points;
        t0 += *seconds;
      }
    }
    curve.segments.push_back(std::move(out));
  }
  if (options.spring_constant_n_per_m)
    curve.metadata.spring_constant_n_per_m = options.spring_constant_n_per_m;
  if (options.sensitivity_m_per_v) curve.metadata.sensitivity_m_per_v = options.sensitivity_m_per_v;

  Status finished = finish_curve(curve);
  if (!finished.ok()) return finished;
  return curve;
}

}  // namespace cellflow::afm
