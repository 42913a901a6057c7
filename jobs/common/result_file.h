// What the scenes' result recorders share: the HDF5 result file with the job
// spec as /parameters, the first write error kept (later writes still run, so
// the file holds all it can), the cell connectivity, the outcome of a run,
// the memory-estimate constants and the CSV number format.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "cellflow/v1/spec.pb.h"
#include "io/h5md.h"
#include "jobs/scene.h"
#include "physics/cell/cell_params.h"
#include "physics/core/status.h"
#include "physics/mesh/tet_mesh.h"

namespace cellflow::jobs {

// This build's version and commit, "0.1.0 (git abc1234)".
const char* creator_version();

// A result file named by `options`, with the job spec as /parameters; the
// author is the spec's (else options.default_author, else "unknown"), the
// creator version options.program_version (else creator_version()).
StatusOr<std::unique_ptr<io::H5mdWriter>> open_result(const v1::JobSpec& spec, const RunOptions& options,
                                                      const io::H5mdCreator& creator);

// The run's outcome: the scene's error first, else the result file's.
RunOutcome outcome_of(const Status& scene_status, const Status& written, int samples);

class ResultRecorder {
 protected:
  explicit ResultRecorder(io::H5mdWriter* writer) : writer_(writer) {}

  void keep(Status s) {
    if (status_.ok() && !s.ok()) status_ = std::move(s);
  }

  // The cell's tetrahedra with their region (as bytes) per tet.
  void write_connectivity(const mesh::TetMesh& mesh);

  io::H5mdWriter* writer_;
  Status status_;
};

// Memory estimates. A fixed process baseline (process, gRPC, HDF5) plus, per
// cell vertex, the mesh, the elastic precomputation, the 3N x 3N sparse
// tangent and its incomplete Cholesky factor. Measured peak RSS of
// cellflow-run (one load point): 23 MB at 3000 vertices, 62 MB at 10000, i.e.
// about 5.5 KiB per vertex; the estimate keeps a margin of about three.
inline constexpr std::int64_t kBaselineBytes = 64LL << 20;
inline constexpr std::int64_t kBytesPerVertex = 16LL << 10;

// Vertices the cell's mesh will have: the target count, or a bound from a
// mesh file's size (a Gmsh ASCII node line is at least ~30 bytes and
// tetrahedron lines outnumber node lines: size / 30 bounds the count).
std::int64_t cell_vertex_bound(const cell::CellParams& cell);

// A double with 17 significant digits, so that CSV values read back exactly.
std::string csv_number(double value);

}  // namespace cellflow::jobs
