// Gmsh MSH 4.1 ASCII import and export of tetrahedral cell meshes.
//
// Reader: $MeshFormat, $PhysicalNames, $Entities (volume entity -> physical
// tags), $Nodes, $Elements; 4-node tetrahedra (type 4) are kept, every other
// element type is skipped, unknown sections are skipped. Gmsh orders a
// positive tetrahedron as det[x1 - x0, x2 - x0, x3 - x0] > 0 (its reference
// tet); tet_mesh.h wants det[x1 - x4, x2 - x4, x3 - x4] > 0 with vertex 4 the
// origin, so Gmsh (g0, g1, g2, g3) becomes (g1, g2, g3, g0).
//
// Hostile input (issue 13): a path is read only when stat and fstat of the
// opened descriptor say it is a regular file (opened O_NONBLOCK, so a FIFO
// swapped in between cannot block open()), and never past
// MeshReadLimits::max_bytes; every declared count is checked against the
// limits and against the bytes left in the text (each entry needs a minimum
// number of bytes) before anything is allocated for it; no error message
// repeats file content (only the path or name, the line number, counts and
// parsed numbers).
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "physics/mesh/sphere_mesh.h"
#include "physics/mesh/tet_geometry.h"

namespace cellflow::mesh {
namespace {

constexpr int kGmshTetrahedron = 4;
constexpr int kNucleusPhysicalTag = 2;  // used when the group carries no name
constexpr double kDegenerateVolumeFraction = 1e-12;

// Fewest bytes an entry of each kind takes, end of line included: every
// token is at least one character followed by a space or the newline. A
// declared count times this must fit in the bytes left (plus one, for a last
// line without its newline).
constexpr std::size_t kMinPhysicalNameBytes = 7;  // 3 1 ""
constexpr std::size_t kMinPointEntityBytes = 10;  // tag x y z numPhysicalTags
constexpr std::size_t kMinEntityBytes = 16;       // tag 6 x bbox numPhysicalTags
constexpr std::size_t kMinBlockHeaderBytes = 8;   // 4 numbers
constexpr std::size_t kMinNodeBytes = 8;          // tag line + x y z line
constexpr std::size_t kMinElementBytes = 4;       // tag node (a point element)
constexpr std::size_t kMinTetBytes = 10;          // tag n1 n2 n3 n4
// Longest number list on one line that the reader parses (entity lines carry
// their physical tags and bounding entities; headers 4 numbers).
constexpr std::size_t kMaxLineNumbers = 1u << 16;

// Line-oriented reader over bytes it does not own; knows its line number for
// error messages, which name `name_` (the path) but never the line's text.
class MshLines {
 public:
  MshLines(std::string name, std::string_view text) : name_(std::move(name)), text_(text) {}

  // Next line without its end-of-line characters; false at the end of file.
  bool next(std::string_view& line) {
    if (pos_ >= text_.size()) return false;
    std::size_t end = text_.find('\n', pos_);
    if (end == std::string_view::npos) end = text_.size();
    line = text_.substr(pos_, end - pos_);
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ' || line.back() == '\t')) {
      line.remove_suffix(1);
    }
    pos_ = end + 1;
    ++line_number_;
    return true;
  }

  int line_number() const { return line_number_; }
  const std::string& name() const { return name_; }
  // Bytes after the current line.
  std::size_t remaining() const { return pos_ >= text_.size() ? 0 : text_.size() - pos_; }

  std::string where() const { return name_ + ":" + std::to_string(line_number_) + ": "; }
  Status error(const std::string& what) const { return invalid_argument(where() + what); }

  // Next line, or an error naming the section that was cut short.
  Status require(std::string_view& line, std::string_view section) {
    if (next(line)) return Status::ok_status();
    return invalid_argument(where() + "unexpected end of file in " + std::string(section) +
                            " (file truncated?)");
  }

  // A declared count: not negative, within `limit` (< 0: none), and small
  // enough that `count` entries of at least `min_bytes` fit in what is left.
  Status check_count(long long count, std::size_t min_bytes, long long limit, const std::string& what) const {
    if (count < 0) return error("negative " + what + " count " + std::to_string(count));
    if (limit >= 0 && count > limit) {
      return Status(StatusCode::kResourceExhausted, where() + "declares " + std::to_string(count) + " " +
                                                        what + ", more than the limit of " +
                                                        std::to_string(limit));
    }
    const std::size_t room = (remaining() + 1) / min_bytes;
    if (static_cast<unsigned long long>(count) > room) {
      return error("declares " + std::to_string(count) + " " + what + " but only " +
                   std::to_string(remaining()) + " bytes follow (each needs at least " +
                   std::to_string(min_bytes) + "): file truncated or corrupt");
    }
    return Status::ok_status();
  }

 private:
  std::string name_;
  std::string_view text_;
  std::size_t pos_ = 0;
  int line_number_ = 0;
};

// Whitespace-separated tokens of a line, one at a time (no allocation).
class Tokens {
 public:
  explicit Tokens(std::string_view line) : line_(line) {}
  bool next(std::string_view& token) {
    while (i_ < line_.size() && (line_[i_] == ' ' || line_[i_] == '\t')) ++i_;
    if (i_ >= line_.size()) return false;
    std::size_t j = i_;
    while (j < line_.size() && line_[j] != ' ' && line_[j] != '\t') ++j;
    token = line_.substr(i_, j - i_);
    i_ = j;
    return true;
  }

 private:
  std::string_view line_;
  std::size_t i_ = 0;
};

template <class T>
bool parse_number(std::string_view token, T& value) {
  const char* end = token.data() + token.size();
  auto [ptr, ec] = std::from_chars(token.data(), end, value);
  return ec == std::errc() && ptr == end;
}

// Parses the tokens of `line` as numbers of type T: at least `min_count`, at
// most `max_count`.
template <class T>
bool parse_numbers(std::string_view line, std::size_t min_count, std::size_t max_count,
                   std::vector<T>& values) {
  values.clear();
  Tokens tokens(line);
  std::string_view token;
  while (tokens.next(token)) {
    T v{};
    if (values.size() >= max_count || !parse_number(token, v)) return false;
    values.push_back(v);
  }
  return values.size() >= min_count;
}

// The first `count` tokens of `line` as numbers; the rest is not looked at.
template <class T>
bool parse_prefix(std::string_view line, std::size_t count, std::vector<T>& values) {
  values.clear();
  Tokens tokens(line);
  std::string_view token;
  while (values.size() < count && tokens.next(token)) {
    T v{};
    if (!parse_number(token, v)) return false;
    values.push_back(v);
  }
  return values.size() == count;
}

// An integer-valued double within int range (entity and physical tags).
bool to_int(double v, int& out) {
  if (!(v >= std::numeric_limits<int>::min() && v <= std::numeric_limits<int>::max()) || v != std::floor(v)) {
    return false;
  }
  out = static_cast<int>(v);
  return true;
}

bool fits_int(long long v) {
  return v >= std::numeric_limits<int>::min() && v <= std::numeric_limits<int>::max();
}

// A section name fit for a message: $ and up to 32 letters, digits or '_';
// anything else is not repeated.
std::string section_label(std::string_view name) {
  bool plain = name.size() >= 2 && name.size() <= 33 && name[0] == '$';
  for (std::size_t i = 1; plain && i < name.size(); ++i) {
    plain = std::isalnum(static_cast<unsigned char>(name[i])) != 0 || name[i] == '_';
  }
  return plain ? std::string(name) : std::string("an unknown section");
}

std::string format_double(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.17g", v);
  return buffer;
}

Status skip_section(MshLines& lines, std::string_view name) {
  const std::string end_marker = "$End" + std::string(name.substr(1));
  const std::string label = section_label(name);
  std::string_view line;
  while (true) {
    if (Status s = lines.require(line, label); !s.ok()) return s;
    if (line == end_marker) return Status::ok_status();
  }
}

Status expect_end(MshLines& lines, std::string_view section) {
  std::string_view line;
  if (Status s = lines.require(line, section); !s.ok()) return s;
  const std::string end_marker = "$End" + std::string(section.substr(1));
  if (line != end_marker) return lines.error("expected " + end_marker + " (more entries than declared?)");
  return Status::ok_status();
}

struct MshContent {
  std::map<int, std::string> volume_group_names;         // physical tag -> name (dimension 3)
  std::map<int, std::vector<int>> volume_physical_tags;  // volume entity tag -> physical tags
  bool has_entities = false;
  std::vector<long long> node_tags;
  std::vector<int> node_tag_line;  // line of each tag, for messages
  std::vector<double> node_xyz;
  struct Tet {
    long long element_tag;
    int entity_tag;
    long long nodes[4];
    int line;
  };
  std::vector<Tet> tets;
};

Status parse_mesh_format(MshLines& lines) {
  std::string_view line;
  if (Status s = lines.require(line, "$MeshFormat"); !s.ok()) return s;
  Tokens tokens(line);
  std::string_view version_token;
  std::string_view type_token;
  std::string_view size_token;
  double version = 0.0;
  int file_type = -1;
  if (!tokens.next(version_token) || !tokens.next(type_token) || !tokens.next(size_token) ||
      !parse_number(version_token, version) || !parse_number(type_token, file_type)) {
    return lines.error("garbled $MeshFormat line (expected: version file-type data-size)");
  }
  if (!(version >= 4.05 && version < 5.0)) {
    return lines.error("MSH version " + format_double(version) + " is not supported (need 4.1)");
  }
  if (file_type != 0) return lines.error("binary MSH files are not supported (need ASCII, file-type 0)");
  return expect_end(lines, "$MeshFormat");
}

Status parse_physical_names(MshLines& lines, MshContent& content) {
  std::string_view line;
  if (Status s = lines.require(line, "$PhysicalNames"); !s.ok()) return s;
  long long count = 0;
  if (!parse_number(line, count)) return lines.error("expected the number of physical names");
  if (Status s = lines.check_count(count, kMinPhysicalNameBytes, -1, "physical names in $PhysicalNames");
      !s.ok()) {
    return s;
  }
  std::vector<long long> values;
  for (long long i = 0; i < count; ++i) {
    if (Status s = lines.require(line, "$PhysicalNames"); !s.ok()) return s;
    const std::size_t open = line.find('"');
    const std::size_t close = line.rfind('"');
    if (open == std::string_view::npos || close == open) {
      return lines.error("expected: dimension tag \"name\"");
    }
    if (!parse_numbers(line.substr(0, open), 2, 2, values) || !fits_int(values[0]) || !fits_int(values[1])) {
      return lines.error("expected: dimension tag \"name\"");
    }
    if (values[0] == 3) {
      content.volume_group_names[static_cast<int>(values[1])] =
          std::string(line.substr(open + 1, close - open - 1));
    }
  }
  return expect_end(lines, "$PhysicalNames");
}

Status parse_entities(MshLines& lines, MshContent& content) {
  std::string_view line;
  if (Status s = lines.require(line, "$Entities"); !s.ok()) return s;
  std::vector<long long> counts;
  if (!parse_numbers(line, 4, 4, counts)) {
    return lines.error("expected: numPoints numCurves numSurfaces numVolumes");
  }
  static const char* const kKinds[4] = {"points", "curves", "surfaces", "volumes"};
  for (int dim = 0; dim < 4; ++dim) {
    if (Status s = lines.check_count(counts[static_cast<std::size_t>(dim)],
                                     dim == 0 ? kMinPointEntityBytes : kMinEntityBytes, -1,
                                     std::string(kKinds[dim]) + " in $Entities");
        !s.ok()) {
      return s;
    }
  }
  std::vector<double> values;
  for (int dim = 0; dim < 4; ++dim) {
    for (long long i = 0; i < counts[static_cast<std::size_t>(dim)]; ++i) {
      if (Status s = lines.require(line, "$Entities"); !s.ok()) return s;
      // point: tag x y z nPhys phys...; others: tag 6 x bbox nPhys phys... nBound bound...
      const std::size_t header = dim == 0 ? 4 : 7;
      if (!parse_prefix(line, header + 1, values)) return lines.error("garbled entity line");
      int tag = 0;
      int num_physical = 0;
      if (!to_int(values[0], tag)) return lines.error("entity tag is not an integer in int range");
      // Each physical tag takes at least 2 bytes of the line.
      if (!to_int(values[header], num_physical) || num_physical < 0 ||
          static_cast<std::size_t>(num_physical) > line.size() / 2 ||
          static_cast<std::size_t>(num_physical) > kMaxLineNumbers ||
          !parse_prefix(line, header + 1 + static_cast<std::size_t>(num_physical), values)) {
        return lines.error("entity line shorter than its physical tag count");
      }
      if (dim == 3) {
        std::vector<int>& tags = content.volume_physical_tags[tag];
        for (int k = 0; k < num_physical; ++k) {
          int physical = 0;
          if (!to_int(values[header + 1 + static_cast<std::size_t>(k)], physical) ||
              physical == std::numeric_limits<int>::min()) {
            return lines.error("physical tag is not an integer in int range");
          }
          tags.push_back(std::abs(physical));
        }
      }
    }
  }
  content.has_entities = true;
  return expect_end(lines, "$Entities");
}

Status parse_nodes(MshLines& lines, MshContent& content, const MeshReadLimits& limits) {
  std::string_view line;
  if (Status s = lines.require(line, "$Nodes"); !s.ok()) return s;
  std::vector<long long> header;
  if (!parse_numbers(line, 4, 4, header)) {
    return lines.error("expected: numEntityBlocks numNodes minNodeTag maxNodeTag");
  }
  const long long num_blocks = header[0];
  const long long num_nodes = header[1];
  if (Status s = lines.check_count(num_blocks, kMinBlockHeaderBytes, -1, "node blocks in $Nodes"); !s.ok())
    return s;
  if (Status s = lines.check_count(num_nodes, kMinNodeBytes, limits.max_nodes, "nodes in $Nodes"); !s.ok())
    return s;
  // Counts are checked: the reserve is at most what the text can hold.
  content.node_tags.reserve(static_cast<std::size_t>(num_nodes));
  content.node_tag_line.reserve(static_cast<std::size_t>(num_nodes));
  content.node_xyz.reserve(3 * static_cast<std::size_t>(num_nodes));
  std::vector<long long> block;
  std::vector<double> xyz;
  long long seen = 0;
  for (long long b = 0; b < num_blocks; ++b) {
    if (Status s = lines.require(line, "$Nodes"); !s.ok()) return s;
    if (!parse_numbers(line, 4, 4, block)) {
      return lines.error("expected node block header: entityDim entityTag parametric numNodesInBlock");
    }
    const long long count = block[3];
    if (Status s = lines.check_count(count, kMinNodeBytes, num_nodes - seen,
                                     "nodes in a $Nodes block (of the numNodes declared)");
        !s.ok()) {
      return s;
    }
    seen += count;
    const std::size_t first = content.node_tags.size();
    for (long long i = 0; i < count; ++i) {
      if (Status s = lines.require(line, "$Nodes"); !s.ok()) return s;
      long long tag = 0;
      if (!parse_number(line, tag)) return lines.error("expected a node tag (one integer)");
      content.node_tags.push_back(tag);
      content.node_tag_line.push_back(lines.line_number());
    }
    for (long long i = 0; i < count; ++i) {
      if (Status s = lines.require(line, "$Nodes"); !s.ok()) return s;
      // x y z, and u (v w) for parametric nodes.
      if (!parse_numbers(line, 3, 6, xyz)) return lines.error("expected node coordinates x y z");
      if (!std::isfinite(xyz[0]) || !std::isfinite(xyz[1]) || !std::isfinite(xyz[2])) {
        return lines.error("non-finite node coordinate for node " +
                           std::to_string(content.node_tags[first + static_cast<std::size_t>(i)]));
      }
      content.node_xyz.insert(content.node_xyz.end(), xyz.begin(), xyz.begin() + 3);
    }
  }
  return expect_end(lines, "$Nodes");
}

Status parse_elements(MshLines& lines, MshContent& content, const MeshReadLimits& limits) {
  std::string_view line;
  if (Status s = lines.require(line, "$Elements"); !s.ok()) return s;
  std::vector<long long> header;
  if (!parse_numbers(line, 4, 4, header)) {
    return lines.error("expected: numEntityBlocks numElements minElementTag maxElementTag");
  }
  const long long num_blocks = header[0];
  const long long num_elements = header[1];
  if (Status s = lines.check_count(num_blocks, kMinBlockHeaderBytes, -1, "element blocks in $Elements");
      !s.ok()) {
    return s;
  }
  if (Status s =
          lines.check_count(num_elements, kMinElementBytes, limits.max_elements, "elements in $Elements");
      !s.ok()) {
    return s;
  }
  std::vector<long long> values;
  long long seen = 0;
  for (long long b = 0; b < num_blocks; ++b) {
    if (Status s = lines.require(line, "$Elements"); !s.ok()) return s;
    if (!parse_numbers(line, 4, 4, values) || !fits_int(values[0]) || !fits_int(values[1]) ||
        !fits_int(values[2])) {
      return lines.error("expected element block header: entityDim entityTag elementType numElementsInBlock");
    }
    const int dim = static_cast<int>(values[0]);
    const int entity = static_cast<int>(values[1]);
    const int type = static_cast<int>(values[2]);
    const long long count = values[3];
    const bool keep = dim == 3 && type == kGmshTetrahedron;
    if (Status s = lines.check_count(count, keep ? kMinTetBytes : kMinElementBytes, num_elements - seen,
                                     "elements in an $Elements block (of the numElements declared)");
        !s.ok()) {
      return s;
    }
    seen += count;
    if (keep) content.tets.reserve(content.tets.size() + static_cast<std::size_t>(count));
    for (long long i = 0; i < count; ++i) {
      if (Status s = lines.require(line, "$Elements"); !s.ok()) return s;
      if (!keep) continue;
      if (!parse_numbers(line, 5, 5, values)) {
        return lines.error("expected a tetrahedron: elementTag n1 n2 n3 n4 (five integers)");
      }
      MshContent::Tet tet{
          values[0], entity, {values[1], values[2], values[3], values[4]}, lines.line_number()};
      content.tets.push_back(tet);
    }
  }
  return expect_end(lines, "$Elements");
}

const char* file_kind(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  if (S_ISLNK(mode)) return "a symbolic link";
  return "not a regular file";
}

Status check_regular(const std::string& path, const struct stat& st, std::uint64_t max_bytes) {
  if (!S_ISREG(st.st_mode)) {
    return invalid_argument("mesh file " + path + " is " + file_kind(st.st_mode) +
                            ", not a regular file; refused");
  }
  if (st.st_size < 0 || static_cast<std::uint64_t>(st.st_size) > max_bytes) {
    return Status(StatusCode::kResourceExhausted, "mesh file " + path + " is " + std::to_string(st.st_size) +
                                                      " bytes, more than the limit of " +
                                                      std::to_string(max_bytes) + " bytes");
  }
  return Status::ok_status();
}

class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  int get() const { return fd_; }

 private:
  int fd_;
};

}  // namespace

StatusOr<std::string> read_mesh_file_bytes(const std::string& path, const MeshReadLimits& limits) {
  if (path.empty() || path.find('\0') != std::string::npos) {
    return invalid_argument("mesh file path is empty or contains a NUL byte");
  }
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    const int err = errno;
    return Status(err == ENOENT || err == ENOTDIR ? StatusCode::kNotFound : StatusCode::kInvalidArgument,
                  "cannot open mesh file " + path + ": " + std::strerror(err));
  }
  if (Status s = check_regular(path, st, limits.max_bytes); !s.ok()) return s;
  // O_NONBLOCK: if the path was swapped for a FIFO since stat, open() does
  // not wait for a writer; fstat of the descriptor then refuses it.
  const Fd fd(::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY));
  if (fd.get() < 0) {
    const int err = errno;
    return Status(err == ENOENT ? StatusCode::kNotFound : StatusCode::kInvalidArgument,
                  "cannot open mesh file " + path + ": " + std::strerror(err));
  }
  if (::fstat(fd.get(), &st) != 0) {
    return invalid_argument("cannot stat mesh file " + path + ": " + std::strerror(errno));
  }
  if (Status s = check_regular(path, st, limits.max_bytes); !s.ok()) return s;
  const int flags = ::fcntl(fd.get(), F_GETFL);
  if (flags < 0 || ::fcntl(fd.get(), F_SETFL, flags & ~O_NONBLOCK) != 0) {
    return invalid_argument("cannot configure mesh file " + path + ": " + std::strerror(errno));
  }
  const auto expected = static_cast<std::uint64_t>(st.st_size);
  std::string bytes;
  bytes.reserve(static_cast<std::size_t>(expected));
  // Read at most one byte past the size stat reported (and never past
  // max_bytes + 1): a pseudo-file (procfs reports 0 bytes) or a growing file
  // is refused without reading on.
  const std::uint64_t cap = std::min<std::uint64_t>(expected, limits.max_bytes) + 1;
  char chunk[65536];
  while (bytes.size() < cap) {
    const std::size_t want =
        static_cast<std::size_t>(std::min<std::uint64_t>(sizeof(chunk), cap - bytes.size()));
    const ssize_t got = ::read(fd.get(), chunk, want);
    if (got < 0) {
      if (errno == EINTR) continue;
      return invalid_argument("cannot read mesh file " + path + ": " + std::strerror(errno));
    }
    if (got == 0) break;
    bytes.append(chunk, static_cast<std::size_t>(got));
  }
  if (bytes.size() != expected) {
    return invalid_argument("mesh file " + path + " reported " + std::to_string(expected) + " bytes but " +
                            (bytes.size() > expected ? "more" : std::to_string(bytes.size())) +
                            " were read (a pseudo-file such as /proc or /sys, or a file changed while "
                            "being read); refused");
  }
  return bytes;
}

StatusOr<TetMesh> read_gmsh_msh(const std::string& path, double length_scale_m,
                                const MeshReadLimits& limits) {
  if (!(length_scale_m > 0.0) || !std::isfinite(length_scale_m)) {
    return invalid_argument("length_scale_m must be > 0 (got " + format_double(length_scale_m) + ")");
  }
  StatusOr<std::string> bytes = read_mesh_file_bytes(path, limits);
  if (!bytes.ok()) return bytes.status();
  return read_gmsh_msh_from_bytes(*bytes, path, length_scale_m, limits);
}

StatusOr<TetMesh> read_gmsh_msh_from_bytes(std::string_view bytes, std::string_view name,
                                           double length_scale_m, const MeshReadLimits& limits) {
  const std::string path(name);
  if (!(length_scale_m > 0.0) || !std::isfinite(length_scale_m)) {
    return invalid_argument("length_scale_m must be > 0 (got " + format_double(length_scale_m) + ")");
  }
  if (bytes.size() > limits.max_bytes) {
    return Status(StatusCode::kResourceExhausted, path + ": " + std::to_string(bytes.size()) +
                                                      " bytes, more than the limit of " +
                                                      std::to_string(limits.max_bytes) + " bytes");
  }
  MshLines lines(path, bytes);

  MshContent content;
  bool seen_format = false;
  bool seen_nodes = false;
  bool seen_elements = false;
  std::string_view line;
  while (lines.next(line)) {
    if (line.empty()) continue;
    Status s;
    if (line == "$MeshFormat") {
      if (seen_format) return lines.error("second $MeshFormat section");
      s = parse_mesh_format(lines);
      seen_format = true;
    } else if (!seen_format) {
      return lines.error("not a Gmsh MSH file: expected $MeshFormat (line of " + std::to_string(line.size()) +
                         " bytes)");
    } else if (line == "$PhysicalNames") {
      s = parse_physical_names(lines, content);
    } else if (line == "$Entities") {
      s = parse_entities(lines, content);
    } else if (line == "$Nodes") {
      if (seen_nodes) return lines.error("second $Nodes section");
      s = parse_nodes(lines, content, limits);
      seen_nodes = true;
    } else if (line == "$Elements") {
      if (seen_elements) return lines.error("second $Elements section");
      s = parse_elements(lines, content, limits);
      seen_elements = true;
    } else if (line.front() == '$' && line.substr(0, 4) != "$End") {
      s = skip_section(lines, line);
    } else {
      return lines.error("unexpected line outside of any section");
    }
    if (!s.ok()) return s;
  }
  if (!seen_format) return lines.error("empty file, not a Gmsh MSH file");
  if (!seen_nodes || !seen_elements) {
    return lines.error("missing " + std::string(!seen_nodes ? "$Nodes" : "$Elements") +
                       " section at the end of the file (file truncated?)");
  }
  if (content.tets.empty()) {
    return Status(StatusCode::kFailedPrecondition,
                  lines.where() + "no tetrahedra (element type 4) in $Elements; a volume mesh is required");
  }

  // Physical groups that mark the nucleus.
  std::set<int> nucleus_tags;
  for (const auto& [tag, group_name] : content.volume_group_names) {
    std::string lower = group_name;
    std::transform(lower.begin(), lower.end(), lower.begin(),
                   [](unsigned char c) { return std::tolower(c); });
    if (lower == "nucleus") nucleus_tags.insert(tag);
  }
  if (nucleus_tags.empty() && content.volume_group_names.count(kNucleusPhysicalTag) == 0) {
    nucleus_tags.insert(kNucleusPhysicalTag);
  }
  auto is_nucleus_entity = [&](int entity) {
    auto it = content.volume_physical_tags.find(entity);
    if (it == content.volume_physical_tags.end()) return false;
    return std::any_of(it->second.begin(), it->second.end(),
                       [&](int t) { return nucleus_tags.count(t) > 0; });
  };

  // Keep only the nodes the tetrahedra use, in file order.
  std::unordered_map<long long, std::size_t> node_index;
  node_index.reserve(content.node_tags.size());
  for (std::size_t i = 0; i < content.node_tags.size(); ++i) {
    if (!node_index.emplace(content.node_tags[i], i).second) {
      return invalid_argument(path + ":" + std::to_string(content.node_tag_line[i]) + ": node tag " +
                              std::to_string(content.node_tags[i]) + " appears twice");
    }
  }
  std::vector<std::int32_t> new_index(content.node_tags.size(), -1);
  for (const auto& tet : content.tets) {
    for (long long node : tet.nodes) {
      auto it = node_index.find(node);
      if (it == node_index.end()) {
        return invalid_argument(path + ":" + std::to_string(tet.line) + ": element " +
                                std::to_string(tet.element_tag) + " references unknown node " +
                                std::to_string(node));
      }
      new_index[it->second] = 0;
    }
  }
  TetMesh mesh;
  std::int32_t next = 0;
  for (std::size_t i = 0; i < new_index.size(); ++i) {
    if (new_index[i] < 0) continue;
    new_index[i] = next++;
    for (int d = 0; d < 3; ++d) {
      const double x = content.node_xyz[3 * i + d] * length_scale_m;
      if (!std::isfinite(x)) {
        return invalid_argument(path + ":" + std::to_string(content.node_tag_line[i]) + ": node " +
                                std::to_string(content.node_tags[i]) +
                                ": coordinate times length_scale_m overflows");
      }
      mesh.positions_m.push_back(x);
    }
  }
  const std::size_t num_tets = content.tets.size();
  mesh.tets.resize(4 * num_tets);
  mesh.tet_region.resize(num_tets);
  for (std::size_t t = 0; t < num_tets; ++t) {
    const auto& tet = content.tets[t];
    // Gmsh (g0, g1, g2, g3) -> (g1, g2, g3, g0): see the file comment.
    for (int k = 0; k < 4; ++k) mesh.tets[4 * t + k] = new_index[node_index[tet.nodes[(k + 1) % 4]]];
    mesh.tet_region[t] = is_nucleus_entity(tet.entity_tag) ? Region::kNucleus : Region::kCytoplasm;
  }

  // Orientation and degeneracy, against the mean |volume|.
  std::vector<double> volume(num_tets);
  double mean_abs_volume = 0.0;
  for (std::size_t t = 0; t < num_tets; ++t) {
    volume[t] = tet_signed_volume(mesh.positions_m.data(), &mesh.tets[4 * t]);
    mean_abs_volume += std::abs(volume[t]) / static_cast<double>(num_tets);
  }
  for (std::size_t t = 0; t < num_tets; ++t) {
    const auto& tet = content.tets[t];
    if (!std::isfinite(volume[t]) || !std::isfinite(mean_abs_volume)) {
      return Status(StatusCode::kFailedPrecondition,
                    path + ":" + std::to_string(tet.line) + ": element " + std::to_string(tet.element_tag) +
                        " has a volume that is not a finite number (coordinates too large)");
    }
    if (std::abs(volume[t]) <= kDegenerateVolumeFraction * mean_abs_volume) {
      return Status(StatusCode::kFailedPrecondition,
                    path + ":" + std::to_string(tet.line) + ": element " + std::to_string(tet.element_tag) +
                        " is a degenerate tetrahedron (volume " + format_double(volume[t]) + " m^3, mean " +
                        format_double(mean_abs_volume) + " m^3)");
    }
    if (volume[t] < 0.0) {
      return Status(StatusCode::kFailedPrecondition,
                    path + ":" + std::to_string(tet.line) + ": element " + std::to_string(tet.element_tag) +
                        " is an inverted tetrahedron (det[x1-x0, x2-x0, x3-x0] < 0 in Gmsh node order)");
    }
  }
  mark_surface_vertices(mesh);
  return mesh;
}

Status write_gmsh_msh(const TetMesh& mesh, const std::string& path) {
  const std::size_t num_vertices = mesh.num_vertices();
  const std::size_t num_tets = mesh.num_tets();
  if (mesh.tet_region.size() != num_tets) {
    return invalid_argument("mesh.tet_region has " + std::to_string(mesh.tet_region.size()) +
                            " entries for " + std::to_string(num_tets) + " tetrahedra");
  }
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) {
    return Status(StatusCode::kNotFound, "cannot open " + path + " for writing: " + std::strerror(errno));
  }
  // Volume entity 1 / physical 1 "cytoplasm", entity 2 / physical 2 "nucleus".
  std::vector<std::size_t> by_region[2];
  for (std::size_t t = 0; t < num_tets; ++t) {
    by_region[mesh.tet_region[t] == Region::kNucleus ? 1 : 0].push_back(t);
  }
  double lo[3] = {0, 0, 0};
  double hi[3] = {0, 0, 0};
  for (int d = 0; d < 3 && num_vertices > 0; ++d) {
    lo[d] = hi[d] = mesh.positions_m[static_cast<std::size_t>(d)];
    for (std::size_t v = 0; v < num_vertices; ++v) {
      lo[d] = std::min(lo[d], mesh.positions_m[3 * v + d]);
      hi[d] = std::max(hi[d], mesh.positions_m[3 * v + d]);
    }
  }
  std::string bbox;
  for (double v : {lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]}) {
    bbox += ' ';
    bbox += format_double(v);
  }
  const int num_volumes = by_region[1].empty() ? 1 : 2;

  out << "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n";
  out << "$PhysicalNames\n" << num_volumes << "\n3 1 \"cytoplasm\"\n";
  if (num_volumes == 2) out << "3 2 \"nucleus\"\n";
  out << "$EndPhysicalNames\n";
  out << "$Entities\n0 0 0 " << num_volumes << "\n";
  for (int e = 1; e <= num_volumes; ++e) out << e << bbox << " 1 " << e << " 0\n";
  out << "$EndEntities\n";
  out << "$Nodes\n1 " << num_vertices << " 1 " << num_vertices << "\n";
  out << "3 1 0 " << num_vertices << "\n";
  for (std::size_t v = 0; v < num_vertices; ++v) out << v + 1 << "\n";
  for (std::size_t v = 0; v < num_vertices; ++v) {
    out << format_double(mesh.positions_m[3 * v]) << " " << format_double(mesh.positions_m[3 * v + 1]) << " "
        << format_double(mesh.positions_m[3 * v + 2]) << "\n";
  }
  out << "$EndNodes\n";
  out << "$Elements\n" << num_volumes << " " << num_tets << " 1 " << num_tets << "\n";
  std::size_t element_tag = 1;
  for (int e = 1; e <= num_volumes; ++e) {
    const auto& tets = by_region[e - 1];
    out << "3 " << e << " " << kGmshTetrahedron << " " << tets.size() << "\n";
    for (std::size_t t : tets) {
      const std::int32_t* v = &mesh.tets[4 * t];
      // Ours (t0, t1, t2, t3) -> Gmsh (t3, t0, t1, t2), 1-based node tags.
      out << element_tag++ << " " << v[3] + 1 << " " << v[0] + 1 << " " << v[1] + 1 << " " << v[2] + 1
          << "\n";
    }
  }
  out << "$EndElements\n";
  out.flush();
  if (!out) return Status(StatusCode::kInternal, "error writing " + path);
  return Status::ok_status();
}

}  // namespace cellflow::mesh
