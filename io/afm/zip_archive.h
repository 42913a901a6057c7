// Read-only view of a zip archive held in memory (libzip). The limits are
// checked against the declared sizes before anything is inflated, and every
// entry is checked to inflate to exactly its declared size, so a zip bomb or a
// truncated entry is an error rather than a crash or a short array.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "physics/core/status.h"

struct zip;

namespace cellflow::afm {

struct ZipLimits {
  std::uint64_t max_entry_bytes = 256ull << 20;
  std::uint64_t max_total_bytes = 1ull << 30;
  std::uint64_t max_entries = 100000;
};

class ZipArchive {
 public:
  // bytes must outlive the archive; label names the file in errors.
  static StatusOr<ZipArchive> open(const std::string& bytes, std::string label, const ZipLimits& limits);

  bool contains(const std::string& name) const;
  const std::vector<std::string>& names() const { return names_; }
  StatusOr<std::string> read(const std::string& name) const;

 private:
  struct Closer {
    void operator()(zip* z) const;
  };
  ZipArchive(std::unique_ptr<zip, Closer> z, std::string label, ZipLimits limits)
      : zip_(std::move(z)), label_(std::move(label)), limits_(limits) {}

  std::unique_ptr<zip, Closer> zip_;
  std::string label_;
  ZipLimits limits_;
  std::vector<std::string> names_;
  std::vector<std::uint64_t> sizes_;
};

}  // namespace cellflow::afm
