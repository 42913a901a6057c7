// Decoding of one JPK channel (.dat) to physical units. A JPK channel is raw
// big-endian numbers; the encoder turns them into the base slot (volts, or
// metres for some sensors), then the conversion set walks from the requested
// slot back to the base via each conversion's base-calibration-slot, e.g.
// force <- distance <- volts, each step a linear offset + multiplier.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "io/afm/java_properties.h"
#include "physics/core/status.h"

namespace cellflow::afm {

// A channel key as written directly ("channel.X.data.encoder...") or after the
// lcd-info indirection was resolved ("channel.X.encoder..."); nullptr if absent.
const std::string* jpk_channel_key(const Properties& props, const std::string& channel,
                                   const std::string& suffix);

// Multiplier of one conversion of the channel (e.g. vDeflection "force" is
// the spring constant in N/m, "distance" the sensitivity in m/V).
std::optional<double> jpk_conversion_multiplier(const Properties& props, const std::string& channel,
                                                const std::string& slot);

struct JpkDecodeRequest {
  std::string channel;     // "vDeflection"
  std::string slot;        // wanted slot; the default slot when not in the set
  std::size_t num_points;  // declared point count
  std::string where;       // "file.jpk-force: segments/0/channels/height.dat" for errors
  // slot -> multiplier replacing the stored one (user calibration overrides).
  std::map<std::string, double> multiplier_overrides;
};

StatusOr<std::vector<double>> decode_jpk_channel(const Properties& props, std::string_view data,
                                                 const JpkDecodeRequest& request);

}  // namespace cellflow::afm
