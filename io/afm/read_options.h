// Options shared by every force-curve reader.
#pragma once

#include <cstdint>
#include <optional>

namespace cellflow::afm {

struct ReadOptions {
  // Calibration overrides: a user who re-calibrated the cantilever (thermal
  // noise, contact slope) replaces what the instrument stored. For JPK files the
  // overrides replace the multipliers of the force and distance conversions, so
  // both deflection_m and force_n follow them.
  std::optional<double> spring_constant_n_per_m;
  std::optional<double> sensitivity_m_per_v;

  // Bounds against hostile or broken files: the file itself, every zip entry's
  // declared uncompressed size, and the sum of those sizes.
  std::uint64_t max_file_bytes = 256ull << 20;
  std::uint64_t max_entry_bytes = 256ull << 20;
  std::uint64_t max_total_uncompressed_bytes = 1ull << 30;
};

}  // namespace cellflow::afm
