// Gmsh MSH 4.1 ASCII import and export of tetrahedral cell meshes.
//
// Reader: $MeshFormat, $PhysicalNames, $Entities (volume entity -> physical
// tags), $Nodes, $Elements; 4-node tetrahedra (type 4) are kept, every other
// element type is skipped, unknown sections are skipped. Gmsh orders a
// positive tetrahedron as det[x1 - x0, x2 - x0, x3 - x0] > 0 (its reference
// tet); tet_mesh.h wants det[x1 - x4, x2 - x4, x3 - x4] > 0 with vertex 4 the
// origin, so Gmsh (g0, g1, g2, g3) becomes (g1, g2, g3, g0).
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>
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

// Line-oriented reader that knows its line number for error messages.
class MshLines {
 public:
  MshLines(std::string path, std::string text) : path_(std::move(path)), text_(std::move(text)) {}

  // Next line without its end-of-line characters; false at the end of file.
  bool next(std::string_view& line) {
    if (pos_ >= text_.size()) return false;
    std::size_t end = text_.find('\n', pos_);
    if (end == std::string::npos) end = text_.size();
    line = std::string_view(text_).substr(pos_, end - pos_);
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ' || line.back() == '\t')) {
      line.remove_suffix(1);
    }
    pos_ = end + 1;
    ++line_number_;
    return true;
  }

  int line_number() const { return line_number_; }

  Status error(const std::string& what) const {
    return invalid_argument(path_ + ":" + std::to_string(line_number_) + ": " + what);
  }

  // Next line, or an error naming the section that was cut short.
  Status require(std::string_view& line, std::string_view section) {
    if (next(line)) return Status::ok_status();
    return invalid_argument(path_ + ":" + std::to_string(line_number_) + ": unexpected end of file in " +
                            std::string(section) + " (file truncated?)");
  }

 private:
  std::string path_;
  std::string text_;
  std::size_t pos_ = 0;
  int line_number_ = 0;
};

std::vector<std::string_view> split(std::string_view line) {
  std::vector<std::string_view> tokens;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    std::size_t j = i;
    while (j < line.size() && line[j] != ' ' && line[j] != '\t') ++j;
    if (j > i) tokens.push_back(line.substr(i, j - i));
    i = j;
  }
  return tokens;
}

template <class T>
bool parse_number(std::string_view token, T& value) {
  const char* end = token.data() + token.size();
  auto [ptr, ec] = std::from_chars(token.data(), end, value);
  return ec == std::errc() && ptr == end;
}

// Parses all tokens of `line` as numbers of type T; at least `min_count`.
template <class T>
bool parse_numbers(std::string_view line, std::size_t min_count, std::vector<T>& values) {
  values.clear();
  for (std::string_view token : split(line)) {
    T v{};
    if (!parse_number(token, v)) return false;
    values.push_back(v);
  }
  return values.size() >= min_count;
}

Status skip_section(MshLines& lines, std::string_view name) {
  const std::string end_marker = "$End" + std::string(name.substr(1));
  std::string_view line;
  while (true) {
    if (Status s = lines.require(line, name); !s.ok()) return s;
    if (line == end_marker) return Status::ok_status();
  }
}

Status expect_end(MshLines& lines, std::string_view section) {
  std::string_view line;
  if (Status s = lines.require(line, section); !s.ok()) return s;
  const std::string end_marker = "$End" + std::string(section.substr(1));
  if (line != end_marker) return lines.error("expected " + end_marker + ", got '" + std::string(line) + "'");
  return Status::ok_status();
}

struct MshContent {
  std::map<int, std::string> volume_group_names;         // physical tag -> name (dimension 3)
  std::map<int, std::vector<int>> volume_physical_tags;  // volume entity tag -> physical tags
  bool has_entities = false;
  std::vector<long long> node_tags;
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
  const auto tokens = split(line);
  double version = 0.0;
  int file_type = -1;
  if (tokens.size() < 3 || !parse_number(tokens[0], version) || !parse_number(tokens[1], file_type)) {
    return lines.error("garbled $MeshFormat line '" + std::string(line) + "'");
  }
  if (version < 4.05 || version >= 5.0) {
    return lines.error("MSH version " + std::string(tokens[0]) + " is not supported (need 4.1)");
  }
  if (file_type != 0) return lines.error("binary MSH files are not supported (need ASCII, file-type 0)");
  return expect_end(lines, "$MeshFormat");
}

Status parse_physical_names(MshLines& lines, MshContent& content) {
  std::string_view line;
  if (Status s = lines.require(line, "$PhysicalNames"); !s.ok()) return s;
  long long count = 0;
  if (!parse_number(line, count) || count < 0) return lines.error("expected the number of physical names");
  for (long long i = 0; i < count; ++i) {
    if (Status s = lines.require(line, "$PhysicalNames"); !s.ok()) return s;
    const std::size_t open = line.find('"');
    const std::size_t close = line.rfind('"');
    if (open == std::string_view::npos || close == open)
      return lines.error("expected: dimension tag \"name\"");
    const auto tokens = split(line.substr(0, open));
    int dim = 0;
    int tag = 0;
    if (tokens.size() != 2 || !parse_number(tokens[0], dim) || !parse_number(tokens[1], tag)) {
      return lines.error("expected: dimension tag \"name\"");
    }
    if (dim == 3) content.volume_group_names[tag] = std::string(line.substr(open + 1, close - open - 1));
  }
  return expect_end(lines, "$PhysicalNames");
}

Status parse_entities(MshLines& lines, MshContent& content) {
  std::string_view line;
  if (Status s = lines.require(line, "$Entities"); !s.ok()) return s;
  std::vector<long long> counts;
  if (!parse_numbers(line, 4, counts) || counts.size() != 4) {
    return lines.error("expected: numPoints numCurves numSurfaces numVolumes");
  }
  std::vector<double> values;
  for (int dim = 0; dim < 4; ++dim) {
    for (long long i = 0; i < counts[static_cast<std::size_t>(dim)]; ++i) {
      if (Status s = lines.require(line, "$Entities"); !s.ok()) return s;
      // point: tag x y z nPhys phys...; others: tag 6 x bbox nPhys phys... nBound bound...
      const std::size_t header = dim == 0 ? 4 : 7;
      if (!parse_numbers(line, header + 1, values)) return lines.error("garbled entity line");
      const auto num_physical = static_cast<std::size_t>(values[header]);
      if (values[header] < 0 || values.size() < header + 1 + num_physical) {
        return lines.error("entity line shorter than its physical tag count");
      }
      if (dim == 3) {
        std::vector<int>& tags = content.volume_physical_tags[static_cast<int>(values[0])];
        for (std::size_t k = 0; k < num_physical; ++k) {
          tags.push_back(static_cast<int>(std::abs(values[header + 1 + k])));
        }
      }
    }
  }
  content.has_entities = true;
  return expect_end(lines, "$Entities");
}

Status parse_nodes(MshLines& lines, MshContent& content) {
  std::string_view line;
  if (Status s = lines.require(line, "$Nodes"); !s.ok()) return s;
  std::vector<long long> header;
  if (!parse_numbers(line, 4, header))
    return lines.error("expected: numEntityBlocks numNodes minNodeTag maxNodeTag");
  const long long num_blocks = header[0];
  content.node_tags.reserve(static_cast<std::size_t>(std::max(0LL, header[1])));
  content.node_xyz.reserve(3 * static_cast<std::size_t>(std::max(0LL, header[1])));
  std::vector<long long> block;
  std::vector<double> xyz;
  for (long long b = 0; b < num_blocks; ++b) {
    if (Status s = lines.require(line, "$Nodes"); !s.ok()) return s;
    if (!parse_numbers(line, 4, block)) {
      return lines.error("expected node block header: entityDim entityTag parametric numNodesInBlock");
    }
    const long long count = block[3];
    if (count < 0) return lines.error("negative node count");
    const std::size_t first = content.node_tags.size();
    for (long long i = 0; i < count; ++i) {
      if (Status s = lines.require(line, "$Nodes"); !s.ok()) return s;
      long long tag = 0;
      if (!parse_number(line, tag))
        return lines.error("expected a node tag, got '" + std::string(line) + "'");
      content.node_tags.push_back(tag);
    }
    for (long long i = 0; i < count; ++i) {
      if (Status s = lines.require(line, "$Nodes"); !s.ok()) return s;
      if (!parse_numbers(line, 3, xyz)) return lines.error("expected node coordinates x y z");
      if (!std::isfinite(xyz[0]) || !std::isfinite(xyz[1]) || !std::isfinite(xyz[2])) {
        return lines.error("non-finite node coordinate for node " +
                           std::to_string(content.node_tags[first + i]));
      }
      content.node_xyz.insert(content.node_xyz.end(), xyz.begin(), xyz.begin() + 3);
    }
  }
  return expect_end(lines, "$Nodes");
}

Status parse_elements(MshLines& lines, MshContent& content) {
  std::string_view line;
  if (Status s = lines.require(line, "$Elements"); !s.ok()) return s;
  std::vector<long long> header;
  if (!parse_numbers(line, 4, header)) {
    return lines.error("expected: numEntityBlocks numElements minElementTag maxElementTag");
  }
  std::vector<long long> values;
  for (long long b = 0; b < header[0]; ++b) {
    if (Status s = lines.require(line, "$Elements"); !s.ok()) return s;
    if (!parse_numbers(line, 4, values)) {
      return lines.error("expected element block header: entityDim entityTag elementType numElementsInBlock");
    }
    const int dim = static_cast<int>(values[0]);
    const int entity = static_cast<int>(values[1]);
    const int type = static_cast<int>(values[2]);
    const long long count = values[3];
    if (count < 0) return lines.error("negative element count");
    const bool keep = dim == 3 && type == kGmshTetrahedron;
    for (long long i = 0; i < count; ++i) {
      if (Status s = lines.require(line, "$Elements"); !s.ok()) return s;
      if (!keep) continue;
      if (!parse_numbers(line, 5, values) || values.size() != 5) {
        return lines.error("expected a tetrahedron: elementTag n1 n2 n3 n4, got '" + std::string(line) + "'");
      }
      MshContent::Tet tet{
          values[0], entity, {values[1], values[2], values[3], values[4]}, lines.line_number()};
      content.tets.push_back(tet);
    }
  }
  return expect_end(lines, "$Elements");
}

std::string format_double(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.17g", v);
  return buffer;
}

}  // namespace

StatusOr<TetMesh> read_gmsh_msh(const std::string& path, double length_scale_m) {
  if (!(length_scale_m > 0.0) || !std::isfinite(length_scale_m)) {
    return invalid_argument("length_scale_m must be > 0 (got " + format_double(length_scale_m) + ")");
  }
  std::ifstream file(path, std::ios::binary);
  if (!file) {
    return Status(StatusCode::kNotFound, "cannot open mesh file " + path + ": " + std::strerror(errno));
  }
  std::ostringstream buffer;
  buffer << file.rdbuf();
  if (file.bad()) return invalid_argument("cannot read mesh file " + path);
  MshLines lines(path, buffer.str());

  MshContent content;
  bool seen_format = false;
  bool seen_nodes = false;
  bool seen_elements = false;
  std::string_view line;
  while (lines.next(line)) {
    if (line.empty()) continue;
    Status s;
    if (line == "$MeshFormat") {
      s = parse_mesh_format(lines);
      seen_format = true;
    } else if (!seen_format) {
      return lines.error("not a Gmsh MSH file: expected $MeshFormat, got '" +
                         std::string(line.substr(0, 40)) + "'");
    } else if (line == "$PhysicalNames") {
      s = parse_physical_names(lines, content);
    } else if (line == "$Entities") {
      s = parse_entities(lines, content);
    } else if (line == "$Nodes") {
      s = parse_nodes(lines, content);
      seen_nodes = true;
    } else if (line == "$Elements") {
      s = parse_elements(lines, content);
      seen_elements = true;
    } else if (line.front() == '$' && line.substr(0, 4) != "$End") {
      s = skip_section(lines, line);
    } else {
      return lines.error("unexpected line outside of any section: '" + std::string(line.substr(0, 40)) + "'");
    }
    if (!s.ok()) return s;
  }
  if (!seen_format) return invalid_argument(path + ": empty file, not a Gmsh MSH file");
  if (!seen_nodes || !seen_elements) {
    return invalid_argument(path + ": missing " + std::string(!seen_nodes ? "$Nodes" : "$Elements") +
                            " section (file truncated?)");
  }
  if (content.tets.empty()) {
    return Status(StatusCode::kFailedPrecondition,
                  path + ": no tetrahedra (element type 4) in $Elements; a volume mesh is required");
  }

  // Physical groups that mark the nucleus.
  std::set<int> nucleus_tags;
  for (const auto& [tag, name] : content.volume_group_names) {
    std::string lower = name;
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
      return invalid_argument(path + ": node tag " + std::to_string(content.node_tags[i]) + " appears twice");
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
    for (int d = 0; d < 3; ++d) mesh.positions_m.push_back(content.node_xyz[3 * i + d] * length_scale_m);
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
