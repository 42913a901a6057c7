#include "server/memory_estimate.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <system_error>

#include "physics/scenes/shear_flow/shear_flow.h"
#include "jobs/shear_flow/shear_flow_spec.h"

namespace cellflow::server {

namespace {

constexpr std::int64_t kBaselineBytes = 64LL << 20;   // process, gRPC, HDF5
constexpr std::int64_t kBytesPerVertex = 16LL << 10;  // see the header
constexpr int kDefaultVertexCount = 3000;             // CellSpec.target_vertex_count default (also in flow)

std::int64_t vertex_count(const v1::CellSpec& cell) {
  if (!cell.mesh_file().empty()) {
    // A Gmsh ASCII node line is at least ~30 bytes, and tetrahedron lines
    // outnumber node lines: file size / 30 bounds the vertex count.
    std::error_code error;
    const auto size = std::filesystem::file_size(cell.mesh_file(), error);
    return error ? 20000 : static_cast<std::int64_t>(size / 30);
  }
  return cell.has_target_vertex_count() ? std::max(cell.target_vertex_count(), 0) : kDefaultVertexCount;
}

std::int64_t shear_flow_bytes(const v1::ShearFlowSpec& flow) {
  // The server estimates only validated specs; an invalid one has no lattice to count.
  const StatusOr<scenes::ShearFlowParams> params = jobs::to_params(flow);
  if (!params.ok()) return vertex_count(flow.cell()) * kBytesPerVertex;
  const StatusOr<scenes::ShearFlowSetup> setup = scenes::plan_shear_flow(*params);
  if (!setup.ok()) return vertex_count(flow.cell()) * kBytesPerVertex;
  const double nodes = static_cast<double>(setup->nx) * setup->ny * setup->nz;
  // Double buffers of the scene beside the lattice, not alive at the same
  // time: the start profile (u_x and a zero field) and one velocity snapshot.
  const double transient_values = params->numerics.fluid_snapshots ? 3.0 : 2.0;
  const double bytes = static_cast<double>(setup->lattice_bytes) + nodes * transient_values * 8.0;
  return static_cast<std::int64_t>(std::min(bytes, 9e18)) + vertex_count(flow.cell()) * kBytesPerVertex;
}

}  // namespace

std::int64_t estimate_job_memory_bytes(const v1::JobSpec& spec) {
  switch (spec.scene_case()) {
    case v1::JobSpec::kCompression:
      return kBaselineBytes + vertex_count(spec.compression().cell()) * kBytesPerVertex;
    case v1::JobSpec::kIndentation:
      return kBaselineBytes + vertex_count(spec.indentation().cell()) * kBytesPerVertex;
    case v1::JobSpec::kShearFlow:
      return kBaselineBytes + shear_flow_bytes(spec.shear_flow());
    case v1::JobSpec::SCENE_NOT_SET:
      break;
  }
  return kBaselineBytes;
}

}  // namespace cellflow::server
