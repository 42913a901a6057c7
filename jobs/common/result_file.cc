#include "jobs/common/result_file.h"

#include <cstdio>
#include <filesystem>
#include <system_error>
#include <vector>

#include "jobs/spec_json.h"

namespace cellflow::jobs {

const char* creator_version() {
  return CELLFLOW_PROJECT_VERSION " (git " CELLFLOW_GIT_COMMIT ")";
}

StatusOr<std::unique_ptr<io::H5mdWriter>> open_result(const v1::JobSpec& spec, const RunOptions& options,
                                                      const io::H5mdCreator& creator) {
  io::H5mdCreator named = creator;
  named.program_version = options.program_version.empty() ? creator_version() : options.program_version;
  named.author = !spec.author().empty()            ? spec.author()
                 : !options.default_author.empty() ? options.default_author
                                                   : "unknown";
  auto writer = io::H5mdWriter::create(options.result_path, named);
  if (!writer.ok()) return writer.status();
  if (Status s = (*writer)->write_parameters_json(job_spec_to_json(spec)); !s.ok()) return s;
  return writer;
}

RunOutcome outcome_of(const Status& scene_status, const Status& written, int samples) {
  RunOutcome outcome;
  outcome.samples = samples;
  outcome.result_written = written.ok();
  outcome.status = !scene_status.ok() ? scene_status : written;
  return outcome;
}

void ResultRecorder::write_connectivity(const mesh::TetMesh& mesh) {
  std::vector<std::uint8_t> region(mesh.tet_region.size());
  for (std::size_t i = 0; i < region.size(); ++i) region[i] = static_cast<std::uint8_t>(mesh.tet_region[i]);
  keep(writer_->write_tetrahedra("cell", mesh.tets, region));
}

namespace {

// numNodes of the first $Nodes section of Gmsh 4.1 ASCII bytes (the line after
// "$Nodes": numEntityBlocks numNodes minNodeTag maxNodeTag); -1 if unreadable.
std::int64_t gmsh_declared_nodes(const std::string& bytes) {
  std::size_t at = bytes.find("$Nodes");
  while (at != std::string::npos && at > 0 && bytes[at - 1] != '\n') at = bytes.find("$Nodes", at + 1);
  if (at == std::string::npos) return -1;
  const std::size_t line = bytes.find('\n', at);
  if (line == std::string::npos) return -1;
  long long blocks = 0, nodes = 0;
  const std::string header = bytes.substr(line + 1, 200);
  if (std::sscanf(header.c_str(), "%lld %lld", &blocks, &nodes) != 2 || nodes < 0) return -1;
  return static_cast<std::int64_t>(nodes);
}

}  // namespace

std::int64_t cell_vertex_bound(const cell::CellParams& cell) {
  if (cell.mesh_bytes) {
    // The declared count of the mesh's header (an uploaded mesh was read
    // whole at upload); the size bound when the header cannot be read.
    const std::int64_t declared = gmsh_declared_nodes(*cell.mesh_bytes);
    return declared >= 0 ? declared : static_cast<std::int64_t>(cell.mesh_bytes->size() / 30);
  }
  if (!cell.mesh_file.empty()) {
    std::error_code error;
    const auto size = std::filesystem::file_size(cell.mesh_file, error);
    return error ? 20000 : static_cast<std::int64_t>(size / 30);
  }
  return std::max(cell.target_vertex_count, 0);
}

std::string csv_number(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.17g", value);
  return buffer;
}

}  // namespace cellflow::jobs
