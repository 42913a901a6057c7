// The word-level reading and writing that the flow scenes' checkpoint
// formats share (shear_flow_checkpoint.h, the single cell;
// physics/scenes/suspension/suspension_checkpoint.h, N cells): little-endian
// 64-bit words and whole-word byte blocks, hashed as they pass (WordHash), a
// header checksum over every header word but the last, and refusals in one
// wording ("checkpoint refused: ..."). Internal to the flow scenes.
#pragma once

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <span>
#include <string>
#include <vector>

#include "physics/core/status.h"

namespace cellflow::scenes::shear_flow_detail {

static_assert(std::endian::native == std::endian::little, "the checkpoint formats are little-endian");

// The 64-bit checksum of the formats over whole words (multiply-xorshift; it
// guards against truncation and corruption, not against forgery).
struct WordHash {
  std::uint64_t state = 0x243F6A8885A308D3ULL;
  void add(std::uint64_t word) {
    state ^= word;
    state *= 0x9E3779B97F4A7C15ULL;
    state ^= state >> 32;
  }
};

// The precision word of both formats: bit 0 float populations, bit 1 float
// elastic forces. A run resumed with either precision changed would not
// continue the written trajectory, so a reader refuses a different word.
constexpr std::uint64_t checkpoint_precision_word(bool float_populations, bool float_elastic_forces) {
  return (float_populations ? 1u : 0u) | (float_elastic_forces ? 2u : 0u);
}

inline std::uint64_t word_of(double v) {
  return std::bit_cast<std::uint64_t>(v);
}
inline double double_of(std::uint64_t w) {
  return std::bit_cast<double>(w);
}

// Blocks are read in chunks of this size, so a short file fails at the first missing chunk.
inline constexpr std::size_t kCheckpointChunkBytes = std::size_t{1} << 20;

// Appends words and byte blocks (whole words) to a file, hashing them.
class CheckpointWriter {
 public:
  explicit CheckpointWriter(std::ofstream& out) : out_(out) {}
  void word(std::uint64_t w) {
    hash_.add(w);
    out_.write(reinterpret_cast<const char*>(&w), sizeof w);
    bytes_ += sizeof w;
  }
  void real(double v) { word(word_of(v)); }
  void reals(std::span<const double> v) {
    for (double x : v) hash_.add(word_of(x));
    out_.write(reinterpret_cast<const char*>(v.data()), static_cast<std::streamsize>(v.size() * 8));
    bytes_ += v.size() * 8;
  }
  void block(std::span<const std::byte> bytes) {
    const std::size_t words = bytes.size() / 8;
    for (std::size_t i = 0; i < words; ++i) {
      std::uint64_t w;
      std::memcpy(&w, bytes.data() + 8 * i, 8);
      hash_.add(w);
    }
    out_.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    bytes_ += bytes.size();
  }
  std::uint64_t checksum() const { return hash_.state; }
  std::uint64_t bytes() const { return bytes_; }

 private:
  std::ofstream& out_;
  WordHash hash_;
  std::uint64_t bytes_ = 0;
};

// Reads words and blocks of a payload whose size was checked against the file.
class CheckpointReader {
 public:
  explicit CheckpointReader(std::ifstream& in) : in_(in) {}
  bool word(std::uint64_t& w) {
    if (!in_.read(reinterpret_cast<char*>(&w), sizeof w)) return false;
    hash_.add(w);
    return true;
  }
  bool real(double& v) {
    std::uint64_t w;
    if (!word(w)) return false;
    v = double_of(w);
    return true;
  }
  // `count` was bounded by the caller against the file's checked size.
  bool reals(std::vector<double>& v, std::size_t count) {
    v.resize(count);
    return block({reinterpret_cast<std::byte*>(v.data()), count * 8});
  }
  bool block(std::span<std::byte> bytes) {
    for (std::size_t at = 0; at < bytes.size(); at += kCheckpointChunkBytes) {
      const std::size_t n = std::min(kCheckpointChunkBytes, bytes.size() - at);
      if (!in_.read(reinterpret_cast<char*>(bytes.data() + at), static_cast<std::streamsize>(n)))
        return false;
    }
    for (std::size_t i = 0; i < bytes.size() / 8; ++i) {
      std::uint64_t w;
      std::memcpy(&w, bytes.data() + 8 * i, 8);
      hash_.add(w);
    }
    return true;
  }
  std::uint64_t checksum() const { return hash_.state; }

 private:
  std::ifstream& in_;
  WordHash hash_;
};

// The checksum of a header: every word but the last (which holds it).
inline std::uint64_t header_checksum(std::span<const std::uint64_t> header) {
  WordHash hash;
  for (std::size_t i = 0; i + 1 < header.size(); ++i) hash.add(header[i]);
  return hash.state;
}

inline bool all_finite(std::span<const double> v) {
  return std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
}

inline Status checkpoint_refused(const std::string& why) {
  return Status(StatusCode::kFailedPrecondition, "checkpoint refused: " + why);
}

inline std::string checkpoint_mismatch(const char* what, std::uint64_t file, std::uint64_t run) {
  return std::string(what) + " " + std::to_string(file) + " in the file, " + std::to_string(run) +
         " in this run";
}

// Ends a checkpoint written to `temporary` after a placeholder header: checks
// the payload's size against the one the header promised, fills in the payload
// checksum (at `payload_checksum_word`) and the header checksum (the last word),
// writes the header over the placeholder and renames the file to `path`, so a
// reader finds the previous checkpoint or the whole new one. Returns the
// file's size in bytes.
inline StatusOr<std::uint64_t> finish_checkpoint_file(std::ofstream& out, std::span<std::uint64_t> header,
                                                      std::size_t payload_checksum_word,
                                                      const CheckpointWriter& w, std::uint64_t payload,
                                                      const std::string& temporary, const std::string& path) {
  if (w.bytes() != payload) return Status(StatusCode::kInternal, "checkpoint: payload size disagrees");
  header[payload_checksum_word] = w.checksum();
  header[header.size() - 1] = header_checksum(header);
  out.seekp(0);
  out.write(reinterpret_cast<const char*>(header.data()), static_cast<std::streamsize>(header.size_bytes()));
  out.flush();
  if (!out) return Status(StatusCode::kInternal, "checkpoint: cannot write " + temporary);
  out.close();
  std::error_code error;
  std::filesystem::rename(temporary, path, error);
  if (error)
    return Status(StatusCode::kInternal, "checkpoint: cannot rename to " + path + ": " + error.message());
  return header.size_bytes() + payload;
}

// Opens the checkpoint at `path` into `in` and reads its header (word 0 the
// magic, word 1 the format version, the last word the header checksum),
// refusing a file that cannot be opened or sized, is shorter than its header,
// is not a `kind` checkpoint, has another format version or a header checksum
// that fails. Returns the file's size in bytes; `in` stands after the header.
inline StatusOr<std::uint64_t> read_checkpoint_header(const std::string& path, std::ifstream& in,
                                                      std::span<std::uint64_t> header, std::uint64_t magic,
                                                      std::uint64_t version, const std::string& kind) {
  in.open(path, std::ios::binary);
  if (!in) return checkpoint_refused("cannot open " + path);
  std::error_code error;
  const std::uint64_t file_bytes = std::filesystem::file_size(path, error);
  if (error) return checkpoint_refused("cannot size " + path);
  if (file_bytes < header.size_bytes() ||
      !in.read(reinterpret_cast<char*>(header.data()), static_cast<std::streamsize>(header.size_bytes()))) {
    return checkpoint_refused("shorter than its header (" + std::to_string(file_bytes) + " bytes)");
  }
  if (header[0] != magic) return checkpoint_refused("not a " + kind + " checkpoint (magic)");
  if (header[1] != version) {
    return checkpoint_refused("format version " + std::to_string(header[1]) + ", this program reads " +
                              std::to_string(version));
  }
  if (header[header.size() - 1] != header_checksum(header))
    return checkpoint_refused("header checksum mismatch");
  return file_bytes;
}

}  // namespace cellflow::scenes::shear_flow_detail
